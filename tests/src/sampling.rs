//! A chi-square goodness-of-fit harness for direction samplers, in the style of Mitsuba 3's
//! and pbrt-v4's: bin the sphere in (cos θ, φ), count samples, integrate the claimed pdf over
//! each cell, pool cells expecting fewer than 5 samples, and test with Pearson's statistic.

use glam::DVec3;
use glint_brdf::{
    Bxdf, DiscreteBrdf, DistributionKind, Fresnel, GlintParameters, Microfacet, MicrofacetBrdf,
    NormalSampling, PdfQuadrature,
};

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

/// A sampler to test: a name, the sampler, and the incident polar angle.
pub struct SamplerCase {
    /// What is tested.
    pub name: String,
    /// The sampler whose directions and density are compared.
    pub sampler: Sampler,
    /// θ_i in radians.
    pub theta_i: f64,
    /// For lobes too narrow for bins over the whole sphere: bins over the cap of this radius
    /// (radians) around the mirror direction ([`chi_square_in_cap`]).
    pub cap: Option<f64>,
}

/// The samplers of glint-brdf.
#[derive(Debug)]
pub enum Sampler {
    /// A smooth BRDF's [`Bxdf::sample`] and [`Bxdf::pdf`] (two uniform numbers).
    Smooth(MicrofacetBrdf),
    /// The glint sampler of Sec. 3.4, [`DiscreteBrdf::sample_direction`] and
    /// [`DiscreteBrdf::sampling_pdf`] (four uniform numbers), which the footprint-bound BxDF's
    /// `sample` and `pdf` call; its pdf is a convolution, so the test uses coarser bins.
    Glint(Box<DiscreteBrdf>),
}

/// Every sampling routine of glint-brdf: smooth Beckmann and GGX (isotropic and anisotropic)
/// from p(m) and from their visible normals, and the glint sampler (α_s = 2α, then the cone;
/// its pdf with 1024 QMC points, so that the test compares against the density itself), at
/// incidence from the normal to 85°.
///
/// # Panics
/// Never for the fixed parameters here.
#[must_use]
pub fn sampler_cases() -> Vec<SamplerCase> {
    let angles = [0.0, 45f64.to_radians(), 85f64.to_radians()];
    let roughness = [(0.2, 0.2), (0.6, 0.6), (0.15, 0.5)];
    let mut cases = Vec::new();
    // Every kind sampled from p, and from its visible normals where it has them.
    let samplings = [NormalSampling::Distribution, NormalSampling::Visible];
    for (sampling, kind) in samplings
        .into_iter()
        .flat_map(|s| DistributionKind::ALL.map(|kind| (s, kind)))
        .filter(|&(s, kind)| s == NormalSampling::Distribution || kind.samples_visible_normals())
    {
        for (ax, ay) in roughness {
            let d = Microfacet::new(kind, ax, ay).expect("valid roughness");
            for &theta_i in &angles {
                let brdf = MicrofacetBrdf::new(d, Fresnel::None, sampling).expect("valid BRDF");
                cases.push(SamplerCase {
                    name: format!(
                        "{kind:?} {sampling:?} α ({ax}, {ay}) θ {:.0}°",
                        theta_i.to_degrees()
                    ),
                    sampler: Sampler::Smooth(brdf),
                    theta_i,
                    cap: None,
                });
            }
        }
    }
    // Every kind with the default pdf (the 7-point cubature here) at every angle, and with the
    // paper's QMC rule of many points at 45°.
    let rules = angles
        .iter()
        .map(|&theta_i| (theta_i, PdfQuadrature::default()))
        .chain([(angles[1], PdfQuadrature::QuasiMonteCarlo)]);
    for kind in DistributionKind::ALL {
        for (theta_i, rule) in rules.clone() {
            let mut parameters =
                GlintParameters::new(Microfacet::new(kind, 0.15, 0.15).expect("valid roughness"));
            parameters.gamma_radians = 3f64.to_radians();
            if rule == PdfQuadrature::QuasiMonteCarlo {
                parameters.pdf_quadrature = rule;
                parameters.pdf_points = 1024;
            }
            cases.push(SamplerCase {
                name: format!(
                    "glint {kind:?} α 0.15 γ 3° θ {:.0}° ({:?} pdf)",
                    theta_i.to_degrees(),
                    parameters.pdf_quadrature
                ),
                sampler: Sampler::Glint(Box::new(
                    DiscreteBrdf::new(parameters).expect("valid material"),
                )),
                theta_i,
                cap: None,
            });
        }
    }
    cases.extend(wide_cone_cases(&angles));
    cases
}

/// The glint sampler where the cone is wide against the lobe (γ up to 60°, α down to 10⁻⁴) or
/// the lobe extremely anisotropic, as each kind states them
/// ([`glint_brdf::KindChecks::sampler_cones`]):
/// its pdf there comes from the slope-space rule. (An anisotropic lobe of α_x = 10⁻⁴ is a line
/// of ω′, so its pdf is a band 2γ wide: γ = 10° keeps the band wide against the bins; at 3°
/// the bins' midpoint rule misses 3% of its mass.)
fn wide_cone_cases(angles: &[f64]) -> Vec<SamplerCase> {
    let mut cases = Vec::new();
    for kind in DistributionKind::ALL {
        for cone in kind.checks().sampler_cones {
            let ((ax, ay), gamma_degrees) = (cone.alpha, cone.gamma_degrees);
            for &theta_i in angles {
                let distribution = Microfacet::new(kind, ax, ay).expect("valid roughness");
                let mut parameters = GlintParameters::new(distribution);
                parameters.gamma_radians = f64::to_radians(gamma_degrees);
                cases.push(SamplerCase {
                    name: format!(
                        "glint {kind:?} α ({ax}, {ay}) γ {gamma_degrees}° θ {:.0}°",
                        theta_i.to_degrees()
                    ),
                    sampler: Sampler::Glint(Box::new(
                        DiscreteBrdf::new(parameters).expect("valid material"),
                    )),
                    theta_i,
                    cap: cone.cap_degrees.map(f64::to_radians),
                });
            }
        }
    }
    cases
}

impl SamplerCase {
    /// Whether this is the glint sampler.
    #[must_use]
    pub fn is_glint(&self) -> bool {
        matches!(self.sampler, Sampler::Glint(_))
    }
}

/// [`chi_square_directions`] over the cap of radius `cap` around unit `axis`: `rings` bins in
/// (1 − cos θ′)/(1 − cos cap) (equal solid angle) times `phi_bins` in φ′, θ′ and φ′ measured in
/// a frame around `axis`. Samples outside the cap are counted in
/// [`ChiSquareOutcome::valid_fraction`] but not binned; the caller checks that the cap holds
/// them all (∫pdf over the cap against the valid fraction).
#[allow(clippy::too_many_arguments)]
pub fn chi_square_in_cap(
    mut sample: impl FnMut([f64; 2]) -> Option<DVec3>,
    pdf: impl Fn(DVec3) -> f64,
    axis: DVec3,
    cap: f64,
    samples: usize,
    (rings, phi_bins, sub): (usize, usize, usize),
    seed: u64,
) -> ChiSquareOutcome {
    let tangent = crate::geometry::perpendicular(axis);
    let bitangent = axis.cross(tangent);
    let versine = 1.0 - cap.cos();
    let cell = |w: DVec3| {
        let t = (1.0 - w.dot(axis)) / versine;
        if t >= 1.0 {
            return None;
        }
        let phi = w
            .dot(bitangent)
            .atan2(w.dot(tangent))
            .rem_euclid(std::f64::consts::TAU);
        let p = (phi / std::f64::consts::TAU * phi_bins as f64) as usize;
        Some(((t * rings as f64) as usize).min(rings - 1) * phi_bins + p.min(phi_bins - 1))
    };
    let mut observed = vec![0.0; rings * phi_bins];
    let mut rng = SplitMix64::new(seed);
    let mut valid = 0usize;
    for _ in 0..samples {
        if let Some(w) = sample([rng.uniform(), rng.uniform()])
            && w.is_finite()
        {
            valid += 1;
            if let Some(c) = cell(w.normalize()) {
                observed[c] += 1.0;
            }
        }
    }
    let mut expected = vec![0.0; rings * phi_bins];
    let mut integral = 0.0;
    let d_phi = std::f64::consts::TAU / phi_bins as f64;
    for r in 0..rings {
        for p in 0..phi_bins {
            let mut sum = 0.0;
            for i in 0..sub {
                for j in 0..sub {
                    let t = (r as f64 + (i as f64 + 0.5) / sub as f64) / rings as f64;
                    let cos = 1.0 - t * versine;
                    let sin = (1.0 - cos * cos).max(0.0).sqrt();
                    let phi = (p as f64 + (j as f64 + 0.5) / sub as f64) * d_phi;
                    let w = cos * axis + sin * (phi.cos() * tangent + phi.sin() * bitangent);
                    sum += pdf(w);
                }
            }
            let probability = sum / (sub * sub) as f64 * (versine / rings as f64) * d_phi;
            integral += probability;
            expected[r * phi_bins + p] = probability * samples as f64;
        }
    }
    ChiSquareOutcome {
        p_value: chi_square_p_value(&observed, &expected),
        valid_fraction: valid as f64 / samples as f64,
        pdf_integral: integral,
    }
}

impl std::fmt::Debug for SamplerCase {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SamplerCase")
            .field("name", &self.name)
            .field("theta_i", &self.theta_i)
            .finish_non_exhaustive()
    }
}

/// Runs the chi-square test of one case with `samples` samples (bins chosen by the case).
#[must_use]
pub fn test_sampler(case: &SamplerCase, samples: usize, seed: u64) -> ChiSquareOutcome {
    let wi = crate::geometry::direction(case.theta_i, 0.3);
    let mut rng = SplitMix64::new(seed ^ 0x5A3);
    // The midpoint rule's error in a cell must stay below what the samples resolve: finer
    // sub-grids for larger runs (grazing lobes are steep within a cell).
    let fine = samples > 500_000;
    // The glint pdf is smooth across its coarse cells except at grazing incidence, where the
    // lobe meets the horizon: 3 × 3 midpoints per cell there bias the expected counts enough to
    // fail at 10⁵ samples (Beckmann θ_i = 85°), 8 × 8 do not. Where the cone is wide against
    // the lobe the pdf steps from its plateau to 0 within about α_s: at 10⁶ samples 8 × 8
    // midpoints bias the edge cells enough to fail (Beckmann α 0.01, γ 20°, θ_i 0°: p = 0.006),
    // 24 × 24 do not (p = 0.92).
    let (theta_bins, phi_bins, sub) = match (case.is_glint(), fine) {
        (true, false) => (24, 48, 8),
        (true, true) => (24, 48, 24),
        (false, false) => (48, 96, 4),
        (false, true) => (48, 96, 12),
    };
    match &case.sampler {
        Sampler::Smooth(brdf) => chi_square_directions(
            |u| brdf.sample(wi, u).map(|s| s.wo),
            |wo| brdf.pdf(wi, wo),
            samples,
            theta_bins,
            phi_bins,
            sub,
            seed,
        ),
        Sampler::Glint(brdf) if case.cap.is_some() => chi_square_in_cap(
            |u| brdf.sample_direction(wi, [u[0], u[1], rng.uniform(), rng.uniform()]),
            |wo| brdf.sampling_pdf(wi, wo),
            DVec3::new(-wi.x, -wi.y, wi.z),
            case.cap.unwrap_or_default(),
            samples,
            (16, 32, if fine { 18 } else { 6 }),
            seed,
        ),
        Sampler::Glint(brdf) => chi_square_directions(
            |u| brdf.sample_direction(wi, [u[0], u[1], rng.uniform(), rng.uniform()]),
            |wo| brdf.sampling_pdf(wi, wo),
            samples,
            theta_bins,
            phi_bins,
            sub,
            seed,
        ),
    }
}

/// ∫ over the upper hemisphere of `f` by a midpoint rule in (t, φ) with cos θ = 1 − t², which
/// puts points where narrow lobes around the normal live (n_t × n_phi points).
pub fn hemisphere_integral(f: impl Fn(DVec3) -> f64, n_t: usize, n_phi: usize) -> f64 {
    let mut sum = 0.0;
    for i in 0..n_t {
        let t = (i as f64 + 0.5) / n_t as f64;
        let cos = 1.0 - t * t;
        let weight = 2.0 * t / n_t as f64 * std::f64::consts::TAU / n_phi as f64;
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        for j in 0..n_phi {
            let phi = (j as f64 + 0.5) / n_phi as f64 * std::f64::consts::TAU;
            sum += f(DVec3::new(sin * phi.cos(), sin * phi.sin(), cos)) * weight;
        }
    }
    sum
}
