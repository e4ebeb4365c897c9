//! Checkers of the count tree: Beckmann reference densities, the expected count by independent
//! Monte Carlo, binomial moments over footprints, multinomial chi-square tests.

use std::sync::Arc;

use glam::{DVec2, DVec3};
use glint_sphere::SphericalConic;
use glint_tree::sampling::{MultinomialMode, multinomial4, multinomial4_equal};
use glint_tree::tea::TeaRng;
use glint_tree::{CountTree, CountTreeConfig, DenseCounts, Footprint, NormalDensity, QueryScratch};
use statrs::distribution::{ChiSquared, ContinuousCDF, Discrete};

use crate::SplitMix64;
use crate::geometry::{direction, uniform_in_cone};

/// The anisotropic Beckmann particle normal density p(m) = D(m)·cos θ, written here from its
/// definition (independently of glint-brdf, which glint-tree does not know):
/// D(m) = exp(−(x²/α_x² + y²/α_y²)/z²) / (π α_x α_y z⁴).
#[must_use]
pub fn beckmann_density(alpha_x: f64, alpha_y: f64) -> Arc<NormalDensity> {
    Arc::new(move |m: DVec3| {
        if m.z <= 0.0 {
            return 0.0;
        }
        let z2 = m.z * m.z;
        let exponent = (m.x * m.x / (alpha_x * alpha_x) + m.y * m.y / (alpha_y * alpha_y)) / z2;
        (-exponent).exp() / (std::f64::consts::PI * alpha_x * alpha_y * z2 * m.z)
    })
}

/// The anisotropic GGX particle normal density p(m) = D(m)·cos θ, from its definition:
/// D(m) = 1 / (π α_x α_y z⁴ (1 + (x²/α_x² + y²/α_y²)/z²)²).
#[must_use]
pub fn ggx_density(alpha_x: f64, alpha_y: f64) -> Arc<NormalDensity> {
    Arc::new(move |m: DVec3| {
        if m.z <= 0.0 {
            return 0.0;
        }
        let z2 = m.z * m.z;
        let slope2 = (m.x * m.x / (alpha_x * alpha_x) + m.y * m.y / (alpha_y * alpha_y)) / z2;
        let denominator =
            std::f64::consts::PI * alpha_x * alpha_y * z2 * z2 * (1.0 + slope2).powi(2);
        m.z / denominator
    })
}

/// ∫ over the conic of p(m) dm by Monte Carlo over reflected directions: ω_r uniform in the
/// cone of radius γ around ω_o, m the half vector of (ω_i, ω_r), kept when it is a reflecting
/// facet by definition; the half-vector map has Jacobian dm/dω_r = 1/(4 ω_i·m).
/// Returns (estimate, standard error).
#[must_use]
pub fn conic_integral_by_sampling(
    density: &NormalDensity,
    conic: &SphericalConic,
    samples: usize,
    rng: &mut SplitMix64,
) -> (f64, f64) {
    let cone_solid_angle = 4.0 * std::f64::consts::PI * (0.5 * conic.gamma()).sin().powi(2);
    let (mut sum, mut sum2) = (0.0, 0.0);
    for _ in 0..samples {
        let reflected = uniform_in_cone(conic.wo(), conic.gamma(), rng.uniform(), rng.uniform());
        let m = (conic.wi() + reflected).normalize();
        let value = if m.is_finite() && conic.contains_by_reflection(m) {
            density(m) / (4.0 * conic.wi().dot(m))
        } else {
            0.0
        };
        sum += value;
        sum2 += value * value;
    }
    let n = samples as f64;
    let mean = sum / n;
    let variance = (sum2 / n - mean * mean).max(0.0) / n;
    (cone_solid_angle * mean, cone_solid_angle * variance.sqrt())
}

/// Counts of `queries` square footprints of side `side` at random positions.
#[must_use]
pub fn counts_over_footprints(
    tree: &CountTree,
    conic: &SphericalConic,
    side: f64,
    queries: usize,
    seed: u64,
) -> Vec<f64> {
    let mut rng = SplitMix64::new(seed);
    let mut scratch = QueryScratch::new();
    (0..queries)
        .map(|_| {
            let uv = DVec2::new(rng.uniform(), rng.uniform());
            let footprint = Footprint::new(uv, DVec2::new(side, 0.0), DVec2::new(0.0, side))
                .expect("finite footprint");
            tree.query(&footprint, conic, &mut scratch).count
        })
        .collect()
}

/// Standard errors of the mean count and of the dispersion index (variance/mean) measured
/// over `queries` random footprint positions of area `area` on one particle set, when the
/// expected count is `expected` and a particle's chance to be seen is `q`.
///
/// Two sources add up: sampling positions (E(1−q)/queries for the mean, 2/queries for the
/// dispersion) and the realization itself, which the positions only resample: the texture
/// holds about 1/A independent footprints, so the set's own mean deviates by Var = N q(1−q)·A
/// ≈ E·A, and its own variance, as that of a Poisson field over 1/A cells, by a relative
/// (2 + 1/E)·A.
#[must_use]
pub fn count_moment_errors(expected: f64, q: f64, area: f64, queries: usize) -> (f64, f64) {
    let n = queries as f64;
    let mean_error = (expected * (1.0 - q) / n + expected * area).sqrt();
    let dispersion_error = (2.0 / n + (2.0 + 1.0 / expected.max(1e-12)) * area).sqrt();
    (mean_error, dispersion_error)
}

/// Mean and variance of a sample.
#[must_use]
pub fn mean_and_variance(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, variance)
}

/// A tree with Beckmann α and the given particle count, seed and ε; other settings default.
///
/// # Panics
/// If the configuration is invalid (a bug in the caller).
#[must_use]
pub fn beckmann_tree(
    alpha: f64,
    particles: u64,
    seed: u64,
    epsilon: f64,
    mode: MultinomialMode,
) -> CountTree {
    let config = CountTreeConfig {
        particles,
        seed,
        epsilon,
        multinomial: mode,
        dense: DenseCounts::Exact,
        ..CountTreeConfig::default()
    };
    CountTree::new(config, beckmann_density(alpha, alpha)).expect("valid configuration")
}

/// A chi-square goodness-of-fit test of the tree's 4-way multinomial split of `n` with
/// probabilities `p`, over `draws` independent node streams.
///
/// Under the exact multinomial, X₀ ~ Bin(n, p₀), X₁ | X₀ ~ Bin(n − X₀, p₁/(p₁+p₂+p₃)) and
/// X₂ | X₀, X₁ ~ Bin(n − X₀ − X₁, p₂/(p₂+p₃)), so the randomized probability integral
/// transforms U = F(X − 1) + V·f(X) (V uniform) of the three are independent Uniform(0, 1).
/// Their 3·draws values go into 20 equal bins; the Pearson statistic's p-value is returned.
#[must_use]
pub fn multinomial_chi_square(
    n: u64,
    p: [f64; 4],
    mode: MultinomialMode,
    draws: usize,
    seed: u32,
) -> f64 {
    split_chi_square(n, p, draws, seed, |rng| multinomial4(n, p, mode, rng))
}

/// [`multinomial_chi_square`] for the tree's spatial split, [`multinomial4_equal`] (four
/// equally likely children, drawn two bits per particle up to 384 particles in exact mode).
#[must_use]
pub fn equal_split_chi_square(n: u64, mode: MultinomialMode, draws: usize, seed: u32) -> f64 {
    split_chi_square(n, [0.25; 4], draws, seed, |rng| {
        multinomial4_equal(n, mode, rng)
    })
}

/// The test of [`multinomial_chi_square`] for any sampler `split` of `n` with probabilities `p`.
fn split_chi_square(
    n: u64,
    p: [f64; 4],
    draws: usize,
    seed: u32,
    split: impl Fn(&mut TeaRng) -> [u64; 4],
) -> f64 {
    let mut jitter = SplitMix64::new(u64::from(seed) ^ 0xC41);
    let bins = 20;
    let mut observed = vec![0.0; bins];
    for i in 0..draws {
        let mut rng = TeaRng::new([seed, i as u32, 0x5EED, 7], 0, 8);
        let x = split(&mut rng);
        assert_eq!(x.iter().sum::<u64>(), n, "a split of {n} into {x:?}");
        let mut remaining = n;
        for component in 0..3 {
            let rest: f64 = p[component..].iter().sum();
            let share = if rest > 0.0 {
                (p[component] / rest).min(1.0)
            } else {
                0.0
            };
            let u = randomized_pit(remaining, share, x[component], jitter.uniform());
            observed[((u * bins as f64) as usize).min(bins - 1)] += 1.0;
            remaining -= x[component];
        }
    }
    let expected = vec![3.0 * draws as f64 / bins as f64; bins];
    chi_square_p_value(&observed, &expected)
}

/// F(k − 1) + v·f(k) for Bin(n, p): uniform on (0, 1) when k ~ Bin(n, p) and v ~ U(0, 1).
///
/// The binomial CDF comes from statrs while n·p·(1−p) ≤ 10⁶; beyond, statrs' incomplete beta
/// function fails (it returns values outside [0, 1] near the mean at n = 10⁹), and the normal
/// distribution with continuity correction stands in: its error, about the skewness
/// (1 − 2p)/(6√(npq)) < 2e-4, is far below what 10⁴ draws resolve.
fn randomized_pit(n: u64, p: f64, k: u64, v: f64) -> f64 {
    if n == 0 || p <= 0.0 || p >= 1.0 {
        return v;
    }
    let variance = n as f64 * p * (1.0 - p);
    if variance > 1e6 {
        let normal =
            statrs::distribution::Normal::new(n as f64 * p, variance.sqrt()).expect("valid normal");
        let below = normal.cdf(k as f64 - 0.5);
        let through = normal.cdf(k as f64 + 0.5);
        return (below + v * (through - below)).clamp(0.0, 1.0);
    }
    let binomial = statrs::distribution::Binomial::new(p, n).expect("valid binomial");
    let below = if k == 0 {
        0.0
    } else {
        statrs::distribution::DiscreteCDF::cdf(&binomial, k - 1)
    };
    (below + v * binomial.pmf(k)).clamp(0.0, 1.0)
}

/// Pearson's chi-square p-value after pooling cells with expected count below 5.
#[must_use]
pub fn chi_square_p_value(observed: &[f64], expected: &[f64]) -> f64 {
    let mut pooled_observed = Vec::new();
    let mut pooled_expected = Vec::new();
    let (mut carry_observed, mut carry_expected) = (0.0, 0.0);
    for (&o, &e) in observed.iter().zip(expected) {
        carry_observed += o;
        carry_expected += e;
        if carry_expected >= 5.0 {
            pooled_observed.push(carry_observed);
            pooled_expected.push(carry_expected);
            carry_observed = 0.0;
            carry_expected = 0.0;
        }
    }
    if let (Some(lo), Some(le)) = (pooled_observed.last_mut(), pooled_expected.last_mut()) {
        *lo += carry_observed;
        *le += carry_expected;
    }
    if pooled_expected.len() < 2 {
        return 1.0;
    }
    let statistic: f64 = pooled_observed
        .iter()
        .zip(&pooled_expected)
        .map(|(o, e)| (o - e) * (o - e) / e)
        .sum();
    let freedom = (pooled_expected.len() - 1) as f64;
    1.0 - ChiSquared::new(freedom)
        .expect("positive degrees of freedom")
        .cdf(statistic)
}

/// A normal drawn from the isotropic Beckmann density p(m) = D(m)·cos θ: tan²θ = −α²·ln(1 − u₀),
/// φ = 2π·u₁ (the standard inversion of the distribution's CDF in θ).
#[must_use]
pub fn sample_beckmann(alpha: f64, u0: f64, u1: f64) -> DVec3 {
    let tan2 = -alpha * alpha * (1.0 - u0).ln();
    let cos_theta = 1.0 / (1.0 + tan2).sqrt();
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = 2.0 * std::f64::consts::PI * u1;
    DVec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta)
}

/// A query "near the highlight": ω_i within 60° of the normal, a facet normal m drawn from
/// p(m), and ω_o the mirror reflection of ω_i about m (retried until above the horizon), with
/// a square footprint of side `side` at a random position.
#[must_use]
pub fn highlight_query(
    alpha: f64,
    gamma: f64,
    side: f64,
    rng: &mut SplitMix64,
) -> (Footprint, SphericalConic) {
    loop {
        let cos_i = 0.5 + 0.5 * rng.uniform();
        let phi = 2.0 * std::f64::consts::PI * rng.uniform();
        let sin_i = (1.0 - cos_i * cos_i).sqrt();
        let wi = DVec3::new(sin_i * phi.cos(), sin_i * phi.sin(), cos_i);
        let m = sample_beckmann(alpha, rng.uniform(), rng.uniform());
        let wo = 2.0 * wi.dot(m) * m - wi;
        if wo.z <= 1e-3 || wi.dot(m) <= 0.0 {
            continue;
        }
        let uv = DVec2::new(rng.uniform(), rng.uniform());
        let footprint =
            Footprint::new(uv, DVec2::new(side, 0.0), DVec2::new(0.0, side)).expect("finite");
        let conic = SphericalConic::new(wi, wo, gamma).expect("valid conic");
        return (footprint, conic);
    }
}

/// Counts of `pairs` pairs of square footprints of side `side`, the second shifted along u so
/// that the two overlap by the fraction `overlap`, at random positions.
#[must_use]
pub fn overlapping_pair_counts(
    tree: &CountTree,
    conic: &SphericalConic,
    side: f64,
    overlap: f64,
    pairs: usize,
    seed: u64,
) -> (Vec<f64>, Vec<f64>) {
    let mut rng = SplitMix64::new(seed);
    let mut scratch = QueryScratch::new();
    let square = |uv: DVec2| {
        Footprint::new(uv, DVec2::new(side, 0.0), DVec2::new(0.0, side)).expect("finite")
    };
    (0..pairs)
        .map(|_| {
            let uv = DVec2::new(rng.uniform(), rng.uniform());
            let shifted = uv + DVec2::new((1.0 - overlap) * side, 0.0);
            (
                tree.query(&square(uv), conic, &mut scratch).count,
                tree.query(&square(shifted), conic, &mut scratch).count,
            )
        })
        .unzip()
}

/// Pearson's correlation of two equally long samples.
#[must_use]
pub fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let (mean_a, var_a) = mean_and_variance(a);
    let (mean_b, var_b) = mean_and_variance(b);
    let covariance = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - mean_a) * (y - mean_b))
        .sum::<f64>()
        / (a.len() as f64 - 1.0);
    covariance / (var_a * var_b).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both densities integrate to 1 over the hemisphere (midpoint rule in (cos θ, φ) on a
    /// 2000 × 400 grid, refined near the pole where they concentrate).
    #[test]
    fn densities_integrate_to_one() {
        for density in [
            beckmann_density(0.3, 0.3),
            beckmann_density(0.1, 0.4),
            ggx_density(0.3, 0.3),
            ggx_density(0.2, 0.5),
        ] {
            let (n_theta, n_phi) = (2000, 400);
            let mut sum = 0.0;
            for i in 0..n_theta {
                // θ² uniform: cells concentrate near the normal.
                let (t0, t1) = (
                    f64::from(i) / f64::from(n_theta),
                    f64::from(i + 1) / f64::from(n_theta),
                );
                let half_pi = std::f64::consts::FRAC_PI_2;
                let (theta0, theta1) = (half_pi * t0 * t0, half_pi * t1 * t1);
                let theta = 0.5 * (theta0 + theta1);
                let solid = theta1.cos() - theta0.cos();
                for j in 0..n_phi {
                    let phi = 2.0 * std::f64::consts::PI * (f64::from(j) + 0.5) / f64::from(n_phi);
                    let m = DVec3::new(
                        theta.sin() * phi.cos(),
                        theta.sin() * phi.sin(),
                        theta.cos(),
                    );
                    sum += density(m) * (-solid) * 2.0 * std::f64::consts::PI / f64::from(n_phi);
                }
            }
            assert!((sum - 1.0).abs() < 2e-3, "∫p = {sum}");
        }
    }
}

/// What queries skipped as negligible would have found: the totals over the skipped ones of
/// `queries` random queries (Beckmann α = 0.1, γ = 6°, footprints of side 10⁻³, ε = 0,
/// `negligible_count` = ½), each skipped query traversed anyway. Near the highlight ω_o is
/// the mirror direction about a normal from the model widened 2.5 times; elsewhere ω_o is
/// uniform in direction. Queries not skipped near the highlight must equal the traversal
/// (the answer says how many did not).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SkippedQueries {
    /// Queries skipped.
    pub skipped: usize,
    /// Σλ̄ over them: the bound on the particles they hold, in expectation.
    pub bound_sum: f64,
    /// The particles the skipped queries held (found by traversing them).
    pub found: f64,
    /// Queries not skipped whose answer differed from the traversal's.
    pub mismatched: usize,
}

impl SkippedQueries {
    /// Whether `found` is within a one-sided Poisson bound of Σλ̄ (a count with mean at most
    /// Σλ̄ exceeds Σλ̄ + 4√Σλ̄ + 4 with probability below about 1e-4).
    #[must_use]
    pub fn within_bound(&self) -> bool {
        self.found <= self.bound_sum + 4.0 * self.bound_sum.sqrt() + 4.0
    }
}

/// Runs the check of [`SkippedQueries`] for a material of `particles` particles.
#[must_use]
pub fn skipped_query_particles(
    particles: f64,
    near_highlight: bool,
    queries: usize,
    seed: u64,
) -> SkippedQueries {
    use glint_brdf::{DiscreteBrdf, DistributionKind, GlintParameters, Microfacet};
    let d = Microfacet::new(DistributionKind::Beckmann, 0.1, 0.1).expect("valid roughness");
    let mut parameters = GlintParameters::new(d);
    parameters.particles = particles as u64;
    parameters.gamma_radians = 6f64.to_radians();
    parameters.epsilon = 0.0;
    let exact = DiscreteBrdf::new(parameters.clone()).expect("valid material");
    parameters.negligible_count = 0.5;
    let skipping = DiscreteBrdf::new(parameters).expect("valid material");
    let mut scratch = QueryScratch::new();
    let mut rng = SplitMix64::new(seed);
    let mut out = SkippedQueries::default();
    let random_direction = |theta_max: f64, rng: &mut SplitMix64| {
        let theta = rng.uniform() * theta_max;
        direction(theta, 2.0 * std::f64::consts::PI * rng.uniform())
    };
    for _ in 0..queries {
        let wi = random_direction(1.2, &mut rng);
        let wo = if near_highlight {
            let m = d.scaled(2.5).sample_normal([rng.uniform(), rng.uniform()]);
            2.0 * wi.dot(m) * m - wi
        } else {
            random_direction(1.5, &mut rng)
        };
        let footprint = Footprint::new(
            DVec2::new(rng.uniform(), rng.uniform()),
            DVec2::new(1e-3, 0.0),
            DVec2::new(0.0, 1e-3),
        )
        .expect("finite footprint");
        let lean = skipping.at(&footprint, &mut scratch).evaluate(wi, wo);
        match lean.negligible {
            Some(bound) => {
                let skipped_answer_is_empty = lean.count == 0.0
                    && lean.nodes_visited == 0
                    && lean.f_hat == DVec3::ZERO
                    && bound < 0.5;
                out.mismatched += usize::from(!skipped_answer_is_empty);
                out.skipped += 1;
                out.bound_sum += bound;
                out.found += exact.at(&footprint, &mut scratch).evaluate(wi, wo).count;
            }
            None if near_highlight => {
                let full = exact.at(&footprint, &mut scratch).evaluate(wi, wo);
                out.mismatched += usize::from(lean != full);
            }
            None => {}
        }
    }
    out
}

/// The answers to `footprints` against `conic`, queried in `threads` threads, each with a
/// scratch of its own, in input order.
///
/// # Panics
/// If a thread panics.
#[must_use]
pub fn queries_in_threads(
    tree: &CountTree,
    conic: &SphericalConic,
    footprints: &[Footprint],
    threads: usize,
) -> Vec<glint_tree::QueryResult> {
    std::thread::scope(|scope| {
        let handles: Vec<_> = footprints
            .chunks(footprints.len().div_ceil(threads.max(1)).max(1))
            .map(|chunk| {
                scope.spawn(move || {
                    let mut scratch = QueryScratch::new();
                    chunk
                        .iter()
                        .map(|f| tree.query(f, conic, &mut scratch))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().expect("a query thread panicked"))
            .collect()
    })
}

/// The counts of a footprint (`uv`, `dx`, `dy`) and of its two halves split along `dx`:
/// (whole, left + right). At ε = 0 they are equal (counts are additive over a split).
#[must_use]
pub fn whole_and_halves(
    tree: &CountTree,
    conic: &SphericalConic,
    (uv, dx, dy): (DVec2, DVec2, DVec2),
    scratch: &mut QueryScratch,
) -> (f64, f64) {
    let footprint = |uv, dx| Footprint::new(uv, dx, dy).expect("a finite footprint");
    let whole = tree.query(&footprint(uv, dx), conic, scratch).count;
    let left = tree
        .query(&footprint(uv - 0.25 * dx, 0.5 * dx), conic, scratch)
        .count;
    let right = tree
        .query(&footprint(uv + 0.25 * dx, 0.5 * dx), conic, scratch)
        .count;
    (whole, left + right)
}
