//! `cargo xtask validate`: the model against its definitions, at full size.
//!
//! Suites so far: **geometry** (glint-sphere), **counts** (glint-tree, in
//! `validate_counts.rs`), **BRDF** (glint-brdf, in `validate_brdf.rs`), **stability** (the
//! extremes matrix, `validate_stability.rs`) and **trade** (speed against accuracy, with a
//! Pareto plot, `validate_trade.rs`; the dense regime, `validate_dense.rs`) and **renders** (images against the smooth limit and
//! against exact evaluation, `validate_render.rs`) and **maps** (counts under density maps and
//! the roughness levels' trade, `validate_maps.rs`). Each check prints one line and adds a section to
//! `report.md`; the command fails if any check fails.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, bail};
use glint_sphere::{Classification, OverlapMethod, overlap_solid_angle};
use glint_tests::SplitMix64;
use glint_tests::geometry::{
    ClassificationAudit, ConicCase, audit_classification, direction, overlap_z_score, planar_error,
    planar_error_bound, uniform_in_cone,
};

/// Sample sizes of one run.
struct Sizes {
    membership_points: u64,
    classification_cases: u64,
    classification_samples: usize,
    monte_carlo_cases: usize,
    monte_carlo_samples: usize,
    planar_cases: usize,
}

impl Sizes {
    fn new(quick: bool) -> Self {
        if quick {
            Self {
                membership_points: 1_000_000,
                classification_cases: 1_000_000,
                classification_samples: 64,
                monte_carlo_cases: 200,
                monte_carlo_samples: 20_000,
                planar_cases: 20_000,
            }
        } else {
            Self {
                membership_points: 10_000_000,
                classification_cases: 10_000_000,
                classification_samples: 64,
                monte_carlo_cases: 2_000,
                monte_carlo_samples: 200_000,
                planar_cases: 1_000_000,
            }
        }
    }
}

/// One check's outcome.
pub(crate) struct Check {
    pub(crate) name: &'static str,
    pub(crate) passed: bool,
    pub(crate) summary: String,
}

pub(crate) fn run(quick: bool, out: &Path, only: Option<&str>) -> anyhow::Result<()> {
    let sizes = Sizes::new(quick);
    let started = Instant::now();
    let mut report = String::new();
    writeln!(
        report,
        "# glint validation report\n\nMode: {}. Suites: {}.\n",
        if quick { "quick" } else { "full" },
        only.map_or_else(
            || "geometry (glint-sphere), counts (glint-tree), BRDF (glint-brdf), stability, trade, renders, maps".to_owned(),
            |only| format!("only the checks whose name contains {only:?}"),
        )
    )?;
    // Each check with the name the progress bar shows while it runs.
    type Suite<'a> = Box<dyn FnOnce(&mut String) -> anyhow::Result<Check> + 'a>;
    let suites: Vec<(&str, Suite)> = vec![
        ("geometry: membership", Box::new(|r| membership(&sizes, r))),
        (
            "geometry: classification",
            Box::new(|r| classification(&sizes, r)),
        ),
        (
            "geometry: overlap",
            Box::new(|r| overlap_against_monte_carlo(&sizes, r)),
        ),
        (
            "geometry: planar error",
            Box::new(|r| planar_error_by_size(&sizes, r)),
        ),
        (
            "counts: binomial",
            Box::new(|r| crate::validate_counts::binomial_moments(quick, r)),
        ),
        (
            "counts: multinomial",
            Box::new(|r| crate::validate_counts::multinomial_splits(quick, r)),
        ),
        (
            "counts: additivity",
            Box::new(|r| crate::validate_counts::additivity_and_determinism(quick, r)),
        ),
        (
            "counts: coherence",
            Box::new(|r| crate::validate_counts::coherence(quick, r)),
        ),
        (
            "brdf: samplers",
            Box::new(|r| crate::validate_brdf::samplers(quick, r)),
        ),
        ("brdf: energy", Box::new(crate::validate_brdf::energy)),
        (
            "brdf: negligible queries",
            Box::new(|r| crate::validate_brdf::negligible_queries(quick, r)),
        ),
        (
            "brdf: convergence",
            Box::new(|r| crate::validate_brdf::convergence(quick, out, r)),
        ),
        (
            "stability",
            Box::new(|r| crate::validate_stability::stability(quick, r)),
        ),
        (
            "trade",
            Box::new(|r| crate::validate_trade::trade(quick, out, r)),
        ),
        (
            "trade: dense glitter",
            Box::new(|r| crate::validate_dense::dense(quick, r)),
        ),
        (
            "trade: coherence across scales",
            Box::new(|r| crate::validate_coherence::coherence(quick, r)),
        ),
        (
            "trade: the dense regime over (α, γ)",
            Box::new(|r| crate::validate_lobes::lobes(quick, r)),
        ),
        (
            "trade: pdf quadrature",
            Box::new(|r| crate::validate_pdf::pdf_quadrature(quick, r)),
        ),
        (
            "trade: pdf cost by rule",
            Box::new(|r| crate::validate_pdf::pdf_cost_by_rule(quick, r)),
        ),
        (
            "renders",
            Box::new(|r| crate::validate_render::renders(quick, r)),
        ),
        (
            "light cones",
            Box::new(|r| crate::validate_light_cones::light_cones(quick, r)),
        ),
        (
            "renders: footprints in mirrors and glossy reflectors",
            Box::new(|r| crate::validate_footprints::footprints(quick, r)),
        ),
        (
            "maps: counts",
            Box::new(|r| crate::validate_maps::counts(quick, r)),
        ),
        (
            "trade: roughness levels",
            Box::new(|r| crate::validate_maps::roughness_levels(quick, r)),
        ),
    ];
    let suites: Vec<(&str, Suite)> = suites
        .into_iter()
        .filter(|(name, _)| only.is_none_or(|only| name.contains(only)))
        .collect();
    if suites.is_empty() {
        anyhow::bail!("no check's name contains {:?}", only.unwrap_or_default());
    }
    // indicatif hides the bar when the output is not a terminal.
    let bar = indicatif::ProgressBar::new(suites.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{msg:32} [{bar:30}] {pos}/{len} checks, {elapsed}",
        )
        .expect("a valid template")
        .progress_chars("=> "),
    );
    let mut checks = Vec::new();
    for (name, suite) in suites {
        bar.set_message(name);
        checks.push(suite(&mut report)?);
        bar.inc(1);
    }
    bar.finish_and_clear();
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let path = out.join("report.md");
    std::fs::write(&path, &report).with_context(|| format!("writing {}", path.display()))?;

    println!(
        "\nglint validate ({}), {:.1} s",
        if quick { "quick" } else { "full" },
        started.elapsed().as_secs_f64()
    );
    for check in &checks {
        println!(
            "  {} {:<28} {}",
            if check.passed { "PASS" } else { "FAIL" },
            check.name,
            check.summary
        );
    }
    println!("report: {}", path.display());
    let failed = checks.iter().filter(|c| !c.passed).count();
    if failed > 0 {
        bail!("{failed} validation check(s) failed");
    }
    Ok(())
}

/// Splits `total` work items into chunks run on all cores; each chunk gets its own seeded
/// stream, so results do not depend on the thread count.
pub(crate) fn parallel_chunks<T: Send>(
    total: u64,
    chunk: u64,
    work: impl Fn(u64, u64) -> T + Sync,
) -> Vec<T> {
    let chunks = total.div_ceil(chunk);
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()) as u64;
    let mut results: Vec<(u64, T)> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                let work = &work;
                scope.spawn(move || {
                    (t..chunks)
                        .step_by(threads as usize)
                        .map(|c| (c, work(c, chunk.min(total - c * chunk))))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().expect("validation worker panicked"))
            .collect()
    });
    results.sort_by_key(|(c, _)| *c);
    results.into_iter().map(|(_, r)| r).collect()
}

fn membership(sizes: &Sizes, report: &mut String) -> anyhow::Result<Check> {
    let mismatches: u64 = parallel_chunks(sizes.membership_points, 100_000, |chunk, n| {
        let mut rng = SplitMix64::new(0x4d45_4d42 ^ chunk);
        let mut mismatches = 0;
        for _ in 0..n {
            let case = ConicCase::from_uniforms(&rng.uniforms());
            let conic = case.conic;
            let uniform = direction(
                (2.0 * rng.uniform() - 1.0).acos(),
                rng.uniform() * std::f64::consts::TAU,
            );
            let reflected = uniform_in_cone(
                conic.wo(),
                1.2 * conic.gamma(),
                rng.uniform(),
                rng.uniform(),
            );
            let near = (conic.wi() + reflected).normalize();
            for m in [uniform, near] {
                if m.is_finite() && conic.contains(m) != conic.contains_by_reflection(m) {
                    mismatches += 1;
                }
            }
        }
        mismatches
    })
    .into_iter()
    .sum();
    let points = 2 * sizes.membership_points;
    writeln!(
        report,
        "## Conic membership against the reflection definition (Eq. 7, 8)\n\n\
         {points} directions (half uniform on S², half reflections of ω_i into a cone 1.2γ \
         around ω_o), over random conics at the numerical extremes: {mismatches} \
         disagreements.\n"
    )?;
    Ok(Check {
        name: "conic membership",
        passed: mismatches == 0,
        summary: format!("{mismatches} disagreements in {points} directions"),
    })
}

fn classification(sizes: &Sizes, report: &mut String) -> anyhow::Result<Check> {
    let samples = sizes.classification_samples;
    let mut audit = ClassificationAudit::default();
    for part in parallel_chunks(sizes.classification_cases, 50_000, |chunk, n| {
        let mut rng = SplitMix64::new(0x434c_4153 ^ (chunk << 20));
        let mut audit = ClassificationAudit::default();
        for _ in 0..n {
            let case = ConicCase::from_uniforms(&rng.uniforms());
            audit_classification(&case, samples, &mut rng, &mut audit);
        }
        audit
    }) {
        audit.merge(&part);
    }
    let [disjoint, inside, conic_inside, partial] = audit.answers;
    writeln!(
        report,
        "## Triangle–conic classification by brute force\n\n\
         {cases} random cases, each checked with {samples} points of the triangle (vertices, \
         edges, interior) and {samples} points of the conic.\n\n\
         | answer | count | wrong |\n|---|---|---|\n\
         | disjoint | {disjoint} | {wd} |\n| triangle inside conic | {inside} | {wi} |\n\
         | conic inside triangle | {conic_inside} | {wc} |\n| partial | {partial} | — |\n\n\
         Partial answers whose samples saw no overlap (an upper bound on needless splits; \
         samples can miss a small overlap): {pd}.\n",
        cases = audit.cases,
        wd = audit.wrong_disjoint,
        wi = audit.wrong_triangle_inside,
        wc = audit.wrong_conic_inside,
        pd = audit.partial_but_looked_disjoint,
    )?;
    Ok(Check {
        name: "classification",
        passed: audit.is_clean(),
        summary: format!(
            "{} cases: {} wrong disjoint, {} wrong inside, {} wrong conic-inside",
            audit.cases,
            audit.wrong_disjoint,
            audit.wrong_triangle_inside,
            audit.wrong_conic_inside
        ),
    })
}

fn overlap_against_monte_carlo(sizes: &Sizes, report: &mut String) -> anyhow::Result<Check> {
    let mut rng = SplitMix64::new(0x4f56_4c50);
    let mut worst_z = 0.0_f64;
    let mut failures = 0;
    let mut checked = 0;
    while checked < sizes.monte_carlo_cases {
        let case = ConicCase::from_uniforms(&rng.uniforms());
        if case.conic.classify(&case.triangle) != Classification::Partial {
            continue;
        }
        let precise = overlap_solid_angle(&case.triangle, &case.conic, OverlapMethod::Precise);
        let z = overlap_z_score(&case, precise, sizes.monte_carlo_samples, &mut rng);
        worst_z = worst_z.max(z);
        if z > 5.0 {
            failures += 1;
        }
        checked += 1;
    }
    writeln!(
        report,
        "## Precise overlap against Monte Carlo\n\n\
         {checked} partial cases, {samples} points each (uniform on the planar triangle, weighted by \
         the gnomonic Jacobian, membership by the reflection definition). Largest deviation: \
         {worst_z:.2} standard errors; {failures} beyond 5 (family-wise false-alarm rate \
         ≈ {rate:.1e}).\n",
        samples = sizes.monte_carlo_samples,
        rate = checked as f64 * 5.7e-7,
    )?;
    Ok(Check {
        name: "overlap vs Monte Carlo",
        passed: failures == 0,
        summary: format!("{checked} cases, worst {worst_z:.2} standard errors"),
    })
}

fn planar_error_by_size(sizes: &Sizes, report: &mut String) -> anyhow::Result<Check> {
    // Bins of the longest edge (radians), by decade.
    let edges = [1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.6];
    let mut errors: Vec<Vec<f64>> = vec![Vec::new(); edges.len() - 1];
    let mut worst_ratio = 0.0_f64;
    let mut beyond_bound = 0;
    let mut rng = SplitMix64::new(0x504c_414e);
    let mut checked = 0;
    while checked < sizes.planar_cases {
        let case = ConicCase::from_uniforms(&rng.uniforms());
        if case.conic.classify(&case.triangle) != Classification::Partial {
            continue;
        }
        let edge = case.triangle.longest_edge();
        let error = planar_error(&case);
        worst_ratio = worst_ratio.max(error / (edge * edge));
        if error > planar_error_bound(&case.triangle) + 1e-9 {
            beyond_bound += 1;
        }
        if let Some(bin) = edges.windows(2).position(|w| edge >= w[0] && edge < w[1]) {
            errors[bin].push(error);
        }
        checked += 1;
    }
    writeln!(
        report,
        "## Planar overlap approximation against the precise reference\n\n\
         Error = |planar − precise| / Ω(T) over {checked} partial cases, by the triangle's longest \
         edge. The count tree uses overlaps only on nodes small enough for the error criterion \
         (Eq. 10), typically a few degrees (0.05 rad) and below.\n\n\
         | longest edge (rad) | cases | median error | 99th percentile | max error |\n|---|---|---|---|---|"
    )?;
    for (bin, list) in errors.iter_mut().enumerate() {
        list.sort_by(f64::total_cmp);
        let quantile = |q: f64| {
            list.get(((list.len() as f64 - 1.0) * q).round() as usize)
                .copied()
                .unwrap_or(f64::NAN)
        };
        writeln!(
            report,
            "| {:.0e} – {:.0e} | {} | {:.2e} | {:.2e} | {:.2e} |",
            edges[bin],
            edges[bin + 1],
            list.len(),
            quantile(0.5),
            quantile(0.99),
            quantile(1.0)
        )?;
    }
    writeln!(
        report,
        "\nLargest error / (longest edge)²: {worst_ratio:.3}. Cases beyond the rigorous bound set \
         by the Jacobian's variation over the triangle (`planar_error_bound`, + 1e-9 for \
         rounding): {beyond_bound}.\n"
    )?;
    Ok(Check {
        name: "planar overlap error",
        passed: beyond_bound == 0,
        summary: format!(
            "{checked} cases, {beyond_bound} beyond the Jacobian bound, max error/edge² = {worst_ratio:.3}"
        ),
    })
}
