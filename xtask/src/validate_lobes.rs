//! `cargo xtask validate`, trade suite, the dense regime over the lobe's shapes: the default's
//! mean count against exact counts' on a grid of Beckmann α from 10⁻⁴ to 1, γ from 0.01° to
//! 60° and the mirror configuration at θ = 0°, 60° and 85°, N chosen so that a footprint of
//! side 10⁻³ expects about 300 particles (clamped to [10⁶, 2⁵²]), so that every query is
//! dense and exact counts stay affordable.
//!
//! Where the lobe is narrow against the cone (α ≪ γ), at grazing angles and for wide cones the
//! lattice's slope squares may not resolve the lobe, and the tree answers; the check catches
//! a regime that loses flakes or counts too many anywhere on the grid: the default's mean over
//! the positions within 1% plus four standard errors of the difference of the exact counts'.

use std::fmt::Write as _;

use glam::{DVec2, DVec3};
use glint_sphere::SphericalConic;
use glint_tests::SplitMix64;
use glint_tests::counts::beckmann_density;
use glint_tree::{CountTree, CountTreeConfig, DenseCounts, Footprint, QueryScratch};

use crate::validate::Check;

/// The footprint's side (a pixel's, as in the dense suite).
const SIDE: f64 = 1e-3;

/// The expected count a footprint is given by the choice of N.
const TARGET_COUNT: f64 = 300.0;

pub(crate) fn lobes(quick: bool, report: &mut String) -> anyhow::Result<Check> {
    let alphas: &[f64] = if quick {
        &[1e-4, 1e-2, 1.0]
    } else {
        &[1e-4, 1e-3, 1e-2, 0.1, 0.3, 1.0]
    };
    let gammas: &[f64] = if quick {
        &[0.1, 1.0, 60.0]
    } else {
        &[0.01, 0.1, 1.0, 10.0, 60.0]
    };
    let positions = if quick { 60 } else { 150 };
    writeln!(
        report,
        "\n## Trade: the dense regime over (α, γ)\n\nBeckmann, the mirror configuration at θ, a \
         square footprint of side 10⁻³ at {positions} random positions, N such that it expects \
         about {TARGET_COUNT} particles: the default's mean count against exact counts' \
         (`dense = \"exact\"`, ε = 0) and the nodes or cells each reads per query.\n\n\
         | α | γ | θ | N | default | exact | difference | in standard errors | default's nodes | exact's nodes |\n\
         |---|---|---|---|---|---|---|---|---|---|"
    )?;
    let mut scratch = QueryScratch::new();
    let (mut failures, mut largest) = (vec![], 0.0f64);
    for &alpha in alphas {
        for &gamma in gammas {
            for theta in [0.0f64, 60.0, 85.0] {
                let t = theta.to_radians();
                let wi = DVec3::new(t.sin(), 0.0, t.cos());
                let wo = DVec3::new(-t.sin(), 0.0, t.cos());
                let conic = SphericalConic::new(wi, wo, gamma.to_radians())?;
                let tree = |particles: f64, dense: DenseCounts, epsilon: f64| {
                    let config = CountTreeConfig {
                        particles: particles as u64,
                        seed: 5,
                        epsilon,
                        dense,
                        ..CountTreeConfig::default()
                    };
                    CountTree::new(config, beckmann_density(alpha, alpha))
                };
                let square = |uv: DVec2| {
                    Footprint::new(uv, DVec2::new(SIDE, 0.0), DVec2::new(0.0, SIDE))
                        .expect("a finite square")
                };
                let probe = tree(1e9, DenseCounts::Exact, 0.0)?.expected_count(
                    &square(DVec2::splat(0.5)),
                    &conic,
                    &mut scratch,
                );
                if !(probe > 0.0) {
                    continue;
                }
                let particles = (1e9 * TARGET_COUNT / probe)
                    .clamp(1e6, 2f64.powi(52))
                    .round();
                let mut measure = |dense: DenseCounts, epsilon: f64| -> anyhow::Result<_> {
                    let tree = tree(particles, dense, epsilon)?;
                    let mut rng = SplitMix64::new(17);
                    let (mut counts, mut nodes) = (vec![], 0u64);
                    for _ in 0..positions {
                        let uv = DVec2::new(rng.uniform(), rng.uniform());
                        let result = tree.query(&square(uv), &conic, &mut scratch);
                        counts.push(result.count);
                        nodes += u64::from(result.nodes_visited);
                    }
                    Ok((counts, nodes as f64 / positions as f64))
                };
                let (default, default_nodes) = measure(DenseCounts::DEFAULT, 0.1)?;
                let (exact, exact_nodes) = measure(DenseCounts::Exact, 0.0)?;
                let (mean_default, var_default) = glint_tests::counts::mean_and_variance(&default);
                let (mean_exact, var_exact) = glint_tests::counts::mean_and_variance(&exact);
                let error = ((var_default + var_exact) / positions as f64).sqrt();
                let difference = mean_default - mean_exact;
                let relative = difference / mean_exact;
                let sigmas = difference / error;
                largest = largest.max(relative.abs());
                if !(difference.abs() <= 0.01 * mean_exact + 4.0 * error) {
                    failures.push(format!(
                        "α = {alpha}, γ = {gamma}°, θ = {theta}°: {:+.2}%",
                        100.0 * relative
                    ));
                }
                writeln!(
                    report,
                    "| {alpha} | {gamma}° | {theta}° | {particles:.3e} | {mean_default:.1} | \
                     {mean_exact:.1} | {:+.2}% | {sigmas:+.1} | {default_nodes:.0} | \
                     {exact_nodes:.0} |",
                    100.0 * relative
                )?;
            }
        }
    }
    let passed = failures.is_empty();
    writeln!(
        report,
        "\nEvery setting's mean within 1% plus four standard errors of exact counts': {passed}; \
         the largest difference {:.2}%.{}",
        100.0 * largest,
        if passed {
            String::new()
        } else {
            format!(" Outside: {}.", failures.join("; "))
        }
    )?;
    Ok(Check {
        name: "trade: the dense regime over (α, γ)",
        passed,
        summary: format!(
            "{} settings; default's mean within 1% + 4 SE of exact counts': {passed} (largest \
             difference {:.2}%){}",
            alphas.len() * gammas.len() * 3,
            100.0 * largest,
            if passed {
                String::new()
            } else {
                format!(": {}", failures.join("; "))
            }
        ),
    })
}
