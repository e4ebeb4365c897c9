//! A chi-square goodness-of-fit harness for direction samplers, in the style of Mitsuba 3's
//! and pbrt-v4's: bin the sphere in (cos θ, φ), count samples, integrate the claimed pdf over
//! each cell, pool cells expecting fewer than 5 samples, and test with Pearson's statistic.

use glam::DVec3;

use crate::SplitMix64;
use crate::counts::chi_square_p_value;

/// The outcome of one chi-square test.
#[derive(Clone, Copy, Debug)]
pub struct ChiSquareOutcome {
    /// Pearson's p-value.
    pub p_value: f64,
    /// The fraction of sample attempts that produced a direction.
    pub valid_fraction: f64,
    /// ∫ pdf over the sphere by the cell quadrature.
    pub pdf_integral: f64,
}

/// Bins: `theta_bins` in cos θ over [−1, 1] and `phi_bins` in φ; each cell's expected
/// probability by a `sub`×`sub` midpoint rule of the pdf (in the cell's (cos θ, φ) measure,
/// which is solid angle). `sample` maps two uniforms to a direction (or nothing).
pub fn chi_square_directions(
    mut sample: impl FnMut([f64; 2]) -> Option<DVec3>,
    pdf: impl Fn(DVec3) -> f64,
    samples: usize,
    theta_bins: usize,
    phi_bins: usize,
    sub: usize,
    seed: u64,
) -> ChiSquareOutcome {
    let cell = |w: DVec3| {
        let t = (((w.z.clamp(-1.0, 1.0) + 1.0) * 0.5) * theta_bins as f64) as usize;
        let phi = w.y.atan2(w.x).rem_euclid(std::f64::consts::TAU);
        let p = (phi / std::f64::consts::TAU * phi_bins as f64) as usize;
        t.min(theta_bins - 1) * phi_bins + p.min(phi_bins - 1)
    };
    let mut observed = vec![0.0; theta_bins * phi_bins];
    let mut rng = SplitMix64::new(seed);
    let mut valid = 0usize;
    for _ in 0..samples {
        if let Some(w) = sample([rng.uniform(), rng.uniform()])
            && w.is_finite()
        {
            observed[cell(w.normalize())] += 1.0;
            valid += 1;
        }
    }
    let mut expected = vec![0.0; theta_bins * phi_bins];
    let d_cos = 2.0 / theta_bins as f64;
    let d_phi = std::f64::consts::TAU / phi_bins as f64;
    let mut integral = 0.0;
    for t in 0..theta_bins {
        for p in 0..phi_bins {
            let mut sum = 0.0;
            for i in 0..sub {
                for j in 0..sub {
                    let cos = -1.0 + (t as f64 + (i as f64 + 0.5) / sub as f64) * d_cos;
                    let phi = (p as f64 + (j as f64 + 0.5) / sub as f64) * d_phi;
                    let sin = (1.0 - cos * cos).max(0.0).sqrt();
                    sum += pdf(DVec3::new(sin * phi.cos(), sin * phi.sin(), cos));
                }
            }
            let probability = sum / (sub * sub) as f64 * d_cos * d_phi;
            integral += probability;
            expected[t * phi_bins + p] = probability * samples as f64;
        }
    }
    ChiSquareOutcome {
        p_value: chi_square_p_value(&observed, &expected),
        valid_fraction: valid as f64 / samples as f64,
        pdf_integral: integral,
    }
}

/// The Šidák-corrected per-test significance for `tests` tests at family-wise level `alpha`.
#[must_use]
pub fn sidak(alpha: f64, tests: usize) -> f64 {
    1.0 - (1.0 - alpha).powf(1.0 / tests as f64)
}
