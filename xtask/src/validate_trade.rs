//! `cargo xtask validate`, trade suite: what each approximation switch costs and buys.
//!
//! One material (Beckmann α = 0.1, γ = 1°) at two densities, N = 10⁸ (sparse: a few particles
//! per query) and N = 10¹¹ (dense: thousands), and a fixed set of pixel-sized queries near the
//! highlight (footprint side 10⁻³). For every setting: single-thread time per query, mean
//! nodes visited, and, where the setting keeps the particle set of the reference (ε and the
//! overlap method do; the multinomial mode and the quadrature tolerances change the draws), the
//! per-query error against the exact evaluation (ε = 0): |count − exact| / max(exact, 1), its
//! median and 99th percentile. For every setting, the dispersion index (variance/mean of the
//! counts of one conic over random footprints; 1 − q ≈ 1 for exact binomial counts) shows what
//! an approximation does to the statistics. Writes a table and a Pareto plot (time against
//! p99 error), and recommends the fastest setting within 5% p99 error and 10% of the exact
//! dispersion.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use glint_sphere::OverlapMethod;
use glint_tests::SplitMix64;
use glint_tests::counts::{beckmann_density, highlight_query, mean_and_variance};
use glint_tree::{
    CountTree, CountTreeConfig, DenseCounts, Footprint, MultinomialMode, QuadratureTolerance,
    QueryScratch,
};

use crate::plot::{Plot, Series};
use crate::validate::Check;

/// One setting of the switches.
struct Setting {
    label: String,
    epsilon: f64,
    multinomial: MultinomialMode,
    overlap: OverlapMethod,
    tolerance: f64,
    /// Whether the particle set is the reference's (so per-query errors are meaningful).
    same_particles: bool,
}

struct Measured {
    workload: &'static str,
    label: String,
    nanoseconds_per_query: f64,
    nodes: f64,
    error: Option<(f64, f64)>,
    dispersion: f64,
}

fn settings() -> Vec<Setting> {
    let mut out: Vec<Setting> = [0.0, 0.01, 0.03, 0.1, 0.3]
        .into_iter()
        .map(|epsilon| Setting {
            label: format!("ε = {epsilon}"),
            epsilon,
            multinomial: MultinomialMode::Exact,
            overlap: OverlapMethod::Planar,
            tolerance: 1e-5,
            same_particles: true,
        })
        .collect();
    out.push(Setting {
        label: "ε = 0.1, precise overlap".into(),
        epsilon: 0.1,
        multinomial: MultinomialMode::Exact,
        overlap: OverlapMethod::Precise,
        tolerance: 1e-5,
        same_particles: true,
    });
    out.push(Setting {
        label: "ε = 0.1, normal multinomial".into(),
        epsilon: 0.1,
        multinomial: MultinomialMode::Normal,
        overlap: OverlapMethod::Planar,
        tolerance: 1e-5,
        same_particles: false,
    });
    for tolerance in [1e-3, 1e-7] {
        out.push(Setting {
            label: format!("ε = 0.1, δ = {tolerance:.0e}"),
            epsilon: 0.1,
            multinomial: MultinomialMode::Exact,
            overlap: OverlapMethod::Planar,
            tolerance,
            same_particles: false,
        });
    }
    out
}

fn tree(setting: &Setting, particles: u64) -> anyhow::Result<CountTree> {
    let config = CountTreeConfig {
        particles,
        seed: 77,
        epsilon: setting.epsilon,
        // ε's own trade, on exact counts (the dense regime's is `validate_dense`).
        dense: DenseCounts::Exact,
        multinomial: setting.multinomial,
        overlap: setting.overlap,
        expected_query_area: 1e-6,
        quadrature: QuadratureTolerance {
            absolute: setting.tolerance,
            relative: setting.tolerance,
            ..QuadratureTolerance::default()
        },
        ..CountTreeConfig::default()
    };
    Ok(CountTree::new(config, beckmann_density(0.1, 0.1))?)
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    sorted[((p * (sorted.len() - 1) as f64).round() as usize).min(sorted.len() - 1)]
}

/// Every setting on one workload.
fn measure(
    workload_name: &'static str,
    particles: u64,
    quick: bool,
) -> anyhow::Result<Vec<Measured>> {
    let (queries, positions) = if quick { (800, 800) } else { (8000, 8000) };
    let gamma = 1f64.to_radians();
    let mut rng = SplitMix64::new(4242);
    let workload: Vec<_> = (0..queries)
        .map(|_| highlight_query(0.1, gamma, 1e-3, &mut rng))
        .collect();
    // One highlight conic over random footprint positions, for the dispersion index.
    let (_, dispersion_conic) = highlight_query(0.1, gamma, 1e-3, &mut SplitMix64::new(99));
    let footprints: Vec<Footprint> = {
        let mut rng = SplitMix64::new(5);
        (0..positions)
            .map(|_| {
                let uv = glam::DVec2::new(rng.uniform(), rng.uniform());
                Footprint::new(uv, glam::DVec2::new(1e-3, 0.0), glam::DVec2::new(0.0, 1e-3))
                    .expect("finite")
            })
            .collect()
    };
    let mut scratch = QueryScratch::new();
    let mut reference: Vec<f64> = vec![];
    let mut measured = vec![];
    for setting in settings() {
        let tree = tree(&setting, particles)?;
        // Warm the scratch space, then time the whole workload on this thread.
        let _ = tree.query(&workload[0].0, &workload[0].1, &mut scratch);
        let started = Instant::now();
        let mut counts = Vec::with_capacity(workload.len());
        let mut nodes = 0u64;
        for (footprint, conic) in &workload {
            let r = tree.query(footprint, conic, &mut scratch);
            counts.push(r.count);
            nodes += u64::from(r.nodes_visited);
        }
        let nanoseconds_per_query = started.elapsed().as_secs_f64() * 1e9 / workload.len() as f64;
        if reference.is_empty() {
            reference = counts.clone();
        }
        let error = setting.same_particles.then(|| {
            let mut errors: Vec<f64> = counts
                .iter()
                .zip(&reference)
                .map(|(c, e)| (c - e).abs() / e.max(1.0))
                .collect();
            errors.sort_by(f64::total_cmp);
            (percentile(&errors, 0.5), percentile(&errors, 0.99))
        });
        let spread: Vec<f64> = footprints
            .iter()
            .map(|f| tree.query(f, &dispersion_conic, &mut scratch).count)
            .collect();
        let (mean, variance) = mean_and_variance(&spread);
        measured.push(Measured {
            workload: workload_name,
            label: setting.label,
            nanoseconds_per_query,
            nodes: nodes as f64 / workload.len() as f64,
            error,
            dispersion: if mean > 0.0 {
                variance / mean
            } else {
                f64::NAN
            },
        });
    }
    Ok(measured)
}

/// The fastest setting of one workload within 5% p99 error and 10% of the exact dispersion.
fn recommend(measured: &[Measured]) -> String {
    let exact = &measured[0];
    let best = measured
        .iter()
        .filter(|m| {
            m.error.is_some_and(|(_, p99)| p99 <= 0.05)
                && (m.dispersion / exact.dispersion - 1.0).abs() <= 0.1
        })
        .min_by(|a, b| a.nanoseconds_per_query.total_cmp(&b.nanoseconds_per_query));
    match best {
        Some(m) => format!(
            "{}: {} ({:.2} µs per query, {:.2}× the exact time, p99 error {:.1e}, dispersion {:.3} against {:.3})",
            m.workload,
            m.label,
            m.nanoseconds_per_query / 1e3,
            m.nanoseconds_per_query / exact.nanoseconds_per_query,
            m.error.map_or(0.0, |e| e.1),
            m.dispersion,
            exact.dispersion
        ),
        None => format!(
            "{}: ε = 0 (no faster setting is within 5% p99 error and 10% dispersion)",
            exact.workload
        ),
    }
}

pub(crate) fn trade(quick: bool, out: &Path, report: &mut String) -> anyhow::Result<Check> {
    let sparse = measure("sparse, N = 10⁸", 100_000_000, quick)?;
    let dense = measure("dense, N = 10¹¹", 100_000_000_000, quick)?;
    let queries = if quick { 800 } else { 8000 };
    writeln!(
        report,
        "\n## Trade: speed against accuracy\n\nBeckmann α = 0.1, γ = 1°; {queries} pixel-sized \
         queries near the highlight (side 10⁻³), one thread. Error: |count − exact| / \
         max(exact, 1) per query against ε = 0 (only where the setting keeps the particle set: \
         the multinomial mode and the quadrature tolerance δ = δ_abs = δ_rel change the draws). \
         Dispersion: variance/mean of one conic's counts over {queries} footprints (≈ 1 − q for \
         exact binomial counts; an approximation that replaces counts by expectations lowers it). \
         Plot: `trade.svg`.\n\n\
         | workload | setting | time per query | nodes | median error | p99 error | dispersion |\n\
         |---|---|---|---|---|---|---|"
    )?;
    for m in sparse.iter().chain(&dense) {
        let (median, p99) = m.error.map_or(("–".into(), "–".into()), |(a, b)| {
            (format!("{a:.2e}"), format!("{b:.2e}"))
        });
        writeln!(
            report,
            "| {} | {} | {:.2} µs | {:.1} | {median} | {p99} | {:.3} |",
            m.workload,
            m.label,
            m.nanoseconds_per_query / 1e3,
            m.nodes,
            m.dispersion
        )?;
    }
    let recommendations = [recommend(&sparse), recommend(&dense)];
    writeln!(
        report,
        "\nRecommended (the fastest setting within 5% p99 error and 10% of the exact dispersion):\n"
    )?;
    for r in &recommendations {
        writeln!(report, "- {r}")?;
    }
    std::fs::create_dir_all(out)?;
    std::fs::write(out.join("trade.svg"), pareto_svg(&sparse, &dense))?;
    let exact_is_exact = [&sparse, &dense].iter().all(|m| {
        m[0].error
            .is_some_and(|(median, p99)| median == 0.0 && p99 == 0.0)
    });
    let finite = sparse
        .iter()
        .chain(&dense)
        .all(|m| m.nanoseconds_per_query.is_finite() && m.nodes.is_finite());
    Ok(Check {
        name: "trade: speed against accuracy",
        passed: exact_is_exact && finite,
        summary: format!(
            "{} settings on 2 workloads (table and trade.svg)",
            sparse.len()
        ),
    })
}

/// Time per query against p99 error (log scale, errors floored at 1e-6 so that exact settings
/// show), one labelled point per setting that keeps the particle set, per workload.
fn pareto_svg(sparse: &[Measured], dense: &[Measured]) -> String {
    let series = |measured: &[Measured], name: &str, colour: &'static str| {
        let kept: Vec<&Measured> = measured.iter().filter(|m| m.error.is_some()).collect();
        Series {
            name: name.into(),
            colour,
            points: kept
                .iter()
                .map(|m| {
                    (
                        m.nanoseconds_per_query / 1e3,
                        m.error.map_or(0.0, |e| e.1).max(1e-6),
                    )
                })
                .collect(),
            line: false,
            labels: kept.iter().map(|m| m.label.clone()).collect(),
        }
    };
    Plot {
        title: "Trade: time per query against p99 error (vs ε = 0)".into(),
        x_label: "time per query (µs)".into(),
        y_label: "p99 relative error (floored at 1e-6)".into(),
        log_x: true,
        log_y: true,
        series: vec![
            series(sparse, "N = 10⁸ (sparse)", "#1f5fbf"),
            series(dense, "N = 10¹¹ (dense)", "#c03"),
        ],
    }
    .svg()
}
