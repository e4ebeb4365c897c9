//! `cargo xtask validate`, counts suite: glint-tree's statistics at full size.

use std::f64::consts::PI;
use std::fmt::Write as _;

use glam::DVec2;
use glint_sphere::SphericalConic;
use glint_tests::SplitMix64;
use glint_tests::counts::{
    beckmann_density, conic_integral_by_sampling, correlation, equal_split_chi_square, ggx_density,
    mean_and_variance, multinomial_chi_square, overlapping_pair_counts,
};
use glint_tests::geometry::direction;
use glint_tree::{
    CountTree, CountTreeConfig, DenseCounts, Footprint, MultinomialMode, QueryScratch,
};

use crate::validate::{Check, parallel_chunks};

fn square(uv: DVec2, side: f64) -> Footprint {
    Footprint::new(uv, DVec2::new(side, 0.0), DVec2::new(0.0, side)).expect("finite footprint")
}

/// Exact-mode counts over many footprints against Binomial(N, A·∫p), ∫p by independent
/// Monte Carlo, over a grid of N, α (isotropic and anisotropic), γ and incidence.
pub(crate) fn binomial_moments(quick: bool, report: &mut String) -> anyhow::Result<Check> {
    let queries: u64 = if quick { 1500 } else { 20_000 };
    // (distribution, N, α_x, α_y, γ°, θ_i, footprint side)
    let grid: [(&str, u64, f64, f64, f64, f64, f64); 11] = [
        ("Beckmann", 1_000_000, 0.2, 0.2, 5.0, 0.3, 0.01),
        ("Beckmann", 100_000_000, 0.1, 0.1, 1.0, 0.3, 0.002),
        ("Beckmann", 10_000, 0.5, 0.5, 20.0, 0.6, 0.1),
        ("Beckmann", 1_000_000, 0.05, 0.3, 5.0, 0.4, 0.01),
        ("Beckmann", 1_000_000_000, 0.1, 0.1, 0.5, 1.2, 0.0005),
        ("Beckmann", 100_000, 0.3, 0.3, 10.0, 1.4, 0.03),
        ("Beckmann", 1_000_000, 0.01, 0.01, 2.0, 0.1, 0.01),
        ("Beckmann", 10_000_000, 0.2, 0.2, 60.0, 0.8, 0.002),
        ("GGX", 1_000_000, 0.2, 0.2, 5.0, 0.3, 0.01),
        ("GGX", 100_000_000, 0.05, 0.3, 1.0, 0.5, 0.002),
        ("GGX", 10_000, 0.5, 0.5, 20.0, 1.2, 0.1),
    ];
    writeln!(
        report,
        "## Counts are binomial (ε = 0)\n\n{queries} square footprints at random positions per \
         row; expected = N·A·∫p over the conic with ∫p by Monte Carlo over reflected directions \
         (4·10⁵ samples); z = (mean − expected)/standard error; dispersion = variance/mean \
         against 1 − q. Both errors include the one realization's own fluctuation (the tree \
         is one particle set; a texture holds only 1/A independent footprints), see \
         `count_moment_errors`. Pass: |z| < 4.5 and |dispersion − (1 − q)| < 5 sd.\n\n\
         | D | N | α_x | α_y | γ | θ_i | side | expected | mean | z | dispersion | ok |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|"
    )?;
    let mut failures = 0;
    for (index, &(distribution, particles, alpha_x, alpha_y, gamma_deg, theta_i, side)) in
        grid.iter().enumerate()
    {
        let density = if distribution == "GGX" {
            ggx_density(alpha_x, alpha_y)
        } else {
            beckmann_density(alpha_x, alpha_y)
        };
        let config = CountTreeConfig {
            particles,
            seed: 100 + index as u64,
            epsilon: 0.0,
            expected_query_area: side * side,
            dense: DenseCounts::Exact,
            ..CountTreeConfig::default()
        };
        let tree = CountTree::new(config, density.clone())?;
        let conic = SphericalConic::new(
            direction(theta_i, 0.3),
            direction(theta_i * 0.8, 0.3 + PI),
            gamma_deg.to_radians(),
        )?;
        let (integral, integral_error) = conic_integral_by_sampling(
            density.as_ref(),
            &conic,
            400_000,
            &mut SplitMix64::new(index as u64),
        );
        let counts: Vec<f64> = parallel_chunks(queries, 500, |chunk, n| {
            let mut rng = SplitMix64::new(0xC0DE ^ (chunk << 16) ^ index as u64);
            let mut scratch = QueryScratch::new();
            (0..n)
                .map(|_| {
                    tree.query(
                        &square(DVec2::new(rng.uniform(), rng.uniform()), side),
                        &conic,
                        &mut scratch,
                    )
                    .count
                })
                .collect::<Vec<_>>()
        })
        .into_iter()
        .flatten()
        .collect();
        let (mean, variance) = mean_and_variance(&counts);
        let q = side * side * integral;
        let expected = particles as f64 * q;
        let area = side * side;
        let (standard_error, dispersion_sd) =
            glint_tests::counts::count_moment_errors(expected, q, area, queries as usize);
        let standard_error = standard_error + expected * integral_error / integral;
        let z = (mean - expected) / standard_error.max(f64::MIN_POSITIVE);
        let dispersion = if mean > 0.0 { variance / mean } else { 1.0 };
        let ok = z.abs() < 4.5 && (dispersion - (1.0 - q)).abs() < 5.0 * dispersion_sd;
        if !ok {
            failures += 1;
        }
        writeln!(
            report,
            "| {distribution} | {particles:.0e} | {alpha_x} | {alpha_y} | {gamma_deg}° | {theta_i} | {side} | {expected:.4} | {mean:.4} | {z:.2} | {dispersion:.4} | {} |",
            if ok { "yes" } else { "**no**" }
        )?;
    }
    writeln!(report)?;
    Ok(Check {
        name: "binomial counts",
        passed: failures == 0,
        summary: format!("{} settings, {failures} outside bounds", grid.len()),
    })
}

/// Chi-square of multinomial splits against the exact multinomial, both modes.
pub(crate) fn multinomial_splits(quick: bool, report: &mut String) -> anyhow::Result<Check> {
    let draws = if quick { 2000 } else { 20_000 };
    let sizes = [1u64, 2, 5, 8, 9, 20, 100, 10_000, 1_000_000_000];
    let probabilities = [[0.25; 4], [0.1, 0.2, 0.3, 0.4], [0.7, 0.01, 0.09, 0.2]];
    // The spatial split's own sampler (two bits per particle up to 384 particles) at these
    // sizes besides the others.
    let equal_sizes = [9u64, 33, 100, 128, 384, 385, 10_000];
    let tests = sizes.len() * probabilities.len() + equal_sizes.len();
    // Šidák: family-wise 1% over the exact mode's tests.
    let threshold = 1.0 - 0.99_f64.powf(1.0 / tests as f64);
    writeln!(
        report,
        "## Multinomial splits against the exact multinomial\n\n{draws} splits per cell; \
         randomized probability-integral transforms of X₀, X₁|X₀, X₂|X₀,X₁ in 20 bins; p-values. \
         The exact mode must pass at Šidák-corrected α = {threshold:.1e} (family-wise 1%); the \
         normal approximation (n > 8 only; exact below) is reported.\n\n\
         | n | p | exact | normal |\n|---|---|---|---|"
    )?;
    let mut failures = 0;
    let mut normal_rejections = Vec::new();
    for &n in &sizes {
        for (k, p) in probabilities.iter().enumerate() {
            let seed = (n as u32).wrapping_mul(977).wrapping_add(k as u32);
            let exact = multinomial_chi_square(n, *p, MultinomialMode::Exact, draws, seed);
            let normal = multinomial_chi_square(n, *p, MultinomialMode::Normal, draws, seed);
            if exact < threshold {
                failures += 1;
            }
            if normal < threshold {
                normal_rejections.push(format!("n = {n}, p = {p:?}"));
            }
            writeln!(report, "| {n} | {p:?} | {exact:.3} | {normal:.3} |")?;
        }
    }
    for &n in &equal_sizes {
        let seed = (n as u32).wrapping_mul(977).wrapping_add(5);
        let exact = equal_split_chi_square(n, MultinomialMode::Exact, draws, seed);
        let normal = equal_split_chi_square(n, MultinomialMode::Normal, draws, seed);
        if exact < threshold {
            failures += 1;
        }
        if normal < threshold {
            normal_rejections.push(format!("n = {n}, spatial split"));
        }
        writeln!(
            report,
            "| {n} | spatial split (¼ each) | {exact:.3} | {normal:.3} |"
        )?;
    }
    writeln!(
        report,
        "\nNormal approximation rejected at the same level for: {}.\n",
        if normal_rejections.is_empty() {
            "none".to_owned()
        } else {
            normal_rejections.join("; ")
        }
    )?;
    Ok(Check {
        name: "multinomial chi-square",
        passed: failures == 0,
        summary: format!(
            "{tests} cells: exact {failures} rejected; normal approximation rejected in {}",
            normal_rejections.len()
        ),
    })
}

/// Exact additivity over split footprints and bit-identical repeats.
pub(crate) fn additivity_and_determinism(
    quick: bool,
    report: &mut String,
) -> anyhow::Result<Check> {
    let cases = if quick { 300 } else { 5000 };
    let config = CountTreeConfig {
        particles: 50_000_000,
        seed: 9,
        epsilon: 0.0,
        dense: DenseCounts::Exact,
        ..CountTreeConfig::default()
    };
    let tree = CountTree::new(config, beckmann_density(0.15, 0.15))?;
    let conic = SphericalConic::new(direction(0.4, 0.0), direction(0.35, PI), 2f64.to_radians())?;
    let mut rng = SplitMix64::new(77);
    let mut scratch = QueryScratch::new();
    let (mut violations, mut repeats_differing, mut particles) = (0, 0, 0.0);
    for _ in 0..cases {
        let uv = DVec2::new(rng.uniform(), rng.uniform()) * 1e3;
        let dx = DVec2::new(0.002 + 0.01 * rng.uniform(), 0.004 * (rng.uniform() - 0.5));
        let dy = DVec2::new(0.004 * (rng.uniform() - 0.5), 0.002 + 0.01 * rng.uniform());
        let whole = Footprint::new(uv, dx, dy)?;
        let total = tree.query(&whole, &conic, &mut scratch);
        let again = tree.query(&whole, &conic, &mut scratch);
        let parts = tree
            .query(
                &Footprint::new(uv - 0.25 * dy, dx, 0.5 * dy)?,
                &conic,
                &mut scratch,
            )
            .count
            + tree
                .query(
                    &Footprint::new(uv + 0.25 * dy, dx, 0.5 * dy)?,
                    &conic,
                    &mut scratch,
                )
                .count;
        particles += total.count;
        if total.count != parts || total.count.fract() != 0.0 {
            violations += 1;
        }
        if total != again {
            repeats_differing += 1;
        }
    }
    writeln!(
        report,
        "## Exact additivity and determinism\n\n{cases} footprints (uv up to 10³) split in two \
         halves, N = 5·10⁷, ε = 0: {violations} whose halves do not sum exactly to the whole \
         ({particles} particles in all); {repeats_differing} repeated queries not bit-identical.\n"
    )?;
    Ok(Check {
        name: "additivity, determinism",
        passed: violations == 0 && repeats_differing == 0,
        summary: format!(
            "{cases} splits: {violations} not additive, {repeats_differing} not repeatable"
        ),
    })
}

/// Correlation of counts of footprints overlapping by a fraction f.
pub(crate) fn coherence(quick: bool, report: &mut String) -> anyhow::Result<Check> {
    let pairs = if quick { 1500 } else { 20_000 };
    let config = CountTreeConfig {
        particles: 4_000_000,
        seed: 3,
        epsilon: 0.0,
        dense: DenseCounts::Exact,
        ..CountTreeConfig::default()
    };
    let tree = CountTree::new(config, beckmann_density(0.3, 0.3))?;
    let conic = SphericalConic::new(
        direction(0.3, 0.2),
        direction(0.25, 0.2 + PI),
        6f64.to_radians(),
    )?;
    let side = 0.01;
    writeln!(
        report,
        "## Coherence\n\n{pairs} pairs of footprints (side {side}) shifted so that they overlap by \
         f; correlation of their exact counts (expected: f; sampling sd ≤ 1/√pairs).\n\n\
         | f | correlation |\n|---|---|"
    )?;
    let mut worst = 0.0_f64;
    for overlap in [0.0, 0.25, 0.5, 0.75, 1.0] {
        let (a, b) = overlapping_pair_counts(&tree, &conic, side, overlap, pairs, 8);
        let correlation = correlation(&a, &b);
        worst = worst.max((correlation - overlap).abs());
        writeln!(report, "| {overlap} | {correlation:.3} |")?;
    }
    writeln!(report)?;
    let bound = 5.0 / (pairs as f64).sqrt();
    Ok(Check {
        name: "coherence",
        passed: worst < bound,
        summary: format!("largest |correlation − f| = {worst:.3} (bound {bound:.3})"),
    })
}
