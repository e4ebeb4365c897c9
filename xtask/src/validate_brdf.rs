//! `cargo xtask validate`, BRDF suite: every sampler against its pdf at full size, energy, and
//! the discrete BRDF's convergence to the smooth one as N grows.

use std::f64::consts::PI;
use std::fmt::Write as _;

use glam::DVec2;
use glint_brdf::{
    Bxdf, DiscreteBrdf, DistributionKind, Fresnel, GlintParameters, Microfacet, MicrofacetBrdf,
    NormalSampling,
};
use glint_brdf::{Footprint, QueryScratch};
use glint_tests::SplitMix64;
use glint_tests::geometry::direction;
use glint_tests::sampling::{hemisphere_integral, sampler_cases, sidak, test_sampler};

use crate::validate::Check;

/// Chi-square of every sampler (Šidák-corrected family-wise 1%).
pub(crate) fn samplers(quick: bool, report: &mut String) -> anyhow::Result<Check> {
    let cases = sampler_cases();
    let threshold = sidak(0.01, cases.len());
    let samples = if quick { 100_000 } else { 2_000_000 };
    writeln!(
        report,
        "## Samplers against their pdfs\n\n{samples} samples per case (glint: half), bins in \
         (cos θ, φ), expected counts from the pdf by a midpoint rule per cell, cells expecting \
         < 5 pooled; Šidák-corrected threshold {threshold:.1e} (family-wise 1%).\n\n\
         | sampler | p-value | ∫pdf | valid samples |\n|---|---|---|---|"
    )?;
    let mut failures = 0;
    for (i, case) in cases.iter().enumerate() {
        let n = if case.is_glint() {
            samples / 2
        } else {
            samples
        };
        let outcome = test_sampler(case, n, 91 + i as u64);
        let ok = outcome.p_value > threshold
            && outcome.pdf_integral <= 1.01
            && (outcome.pdf_integral - outcome.valid_fraction).abs() < 0.02;
        failures += usize::from(!ok);
        writeln!(
            report,
            "| {} | {:.3} | {:.4} | {:.4} |",
            case.name, outcome.p_value, outcome.pdf_integral, outcome.valid_fraction
        )?;
    }
    writeln!(report)?;
    Ok(Check {
        name: "samplers (chi-square)",
        passed: failures == 0,
        summary: format!("{} samplers, {failures} rejected", cases.len()),
    })
}

/// White furnace: the directional albedo with F = 1 never exceeds 1.
pub(crate) fn energy(report: &mut String) -> anyhow::Result<Check> {
    writeln!(
        report,
        "## Energy\n\nDirectional albedo ∫ f cos θ_o dω_o with F = 1 (quadrature: 1500 × 256 \
         points, refined towards the normal), largest over θ_i ∈ [0°, 89°].\n\n\
         | distribution | α | largest albedo | at θ_i |\n|---|---|---|---|"
    )?;
    let mut worst = 0.0_f64;
    for kind in DistributionKind::ALL {
        for alpha in [0.01, 0.1, 0.3, 0.6, 1.0] {
            let brdf = MicrofacetBrdf::new(
                Microfacet::new(kind, alpha, alpha)?,
                Fresnel::None,
                NormalSampling::Distribution,
            )?;
            let (mut largest, mut at) = (0.0, 0.0);
            for degrees in (0..90).step_by(8) {
                let wi = direction(f64::from(degrees).to_radians(), 0.0);
                let albedo = hemisphere_integral(|wo| brdf.eval(wi, wo).x * wo.z, 1500, 256);
                if albedo > largest {
                    largest = albedo;
                    at = f64::from(degrees);
                }
            }
            worst = worst.max(largest);
            writeln!(report, "| {kind:?} | {alpha} | {largest:.4} | {at}° |")?;
        }
    }
    writeln!(report)?;
    Ok(Check {
        name: "energy (white furnace)",
        passed: worst <= 1.0 + 2e-3,
        summary: format!("largest albedo {worst:.4}"),
    })
}

/// Relative RMS difference of f̂ from the smooth BRDF against the 1/√(expected count) law, and
/// the mean over footprints against the smooth BRDF, as N grows.
pub(crate) fn convergence(
    quick: bool,
    out: &std::path::Path,
    report: &mut String,
) -> anyhow::Result<Check> {
    let queries: u32 = if quick { 400 } else { 4000 };
    let distribution = Microfacet::new(DistributionKind::Beckmann, 0.2, 0.2)?;
    let (wi, wo) = (direction(0.4, 0.0), direction(0.3, PI + 0.2));
    writeln!(
        report,
        "## Convergence to the smooth BRDF\n\nBeckmann α = 0.2, γ = 2°, ε = 0.1, θ_i = 23°, \
         θ_o = 17° (near specular); {queries} footprints of side 10⁻³ per N. The relative RMS \
         difference of f̂ from f should follow 1/√(expected count) (Poisson) until it meets the \
         difference between f and its average over the cone (f̂ converges to the latter), and \
         the mean ratio should be 1 (pass: within 3% + 5 standard errors, with the Poisson \
         error 1/√(queries·expected) as the floor of the standard error).\n\n\
         | N | expected count | relative RMS | 1/√(expected) | mean f̂ / f | nodes per query |\n\
         |---|---|---|---|---|---|"
    )?;
    let mut failures = 0;
    let mut scratch = QueryScratch::new();
    let (mut measured, mut law) = (vec![], vec![]);
    for exponent in [3, 5, 7, 9, 11, 13, 15] {
        let mut parameters = GlintParameters::new(distribution);
        parameters.particles = 10u64.pow(exponent);
        parameters.gamma_radians = 2f64.to_radians();
        let brdf = DiscreteBrdf::new(parameters)?;
        let mut rng = SplitMix64::new(u64::from(exponent));
        let (mut sum, mut sum2, mut expected, mut nodes, mut smooth) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for _ in 0..queries {
            let f = Footprint::new(
                DVec2::new(rng.uniform(), rng.uniform()),
                DVec2::new(1e-3, 0.0),
                DVec2::new(0.0, 1e-3),
            )?;
            let bxdf = brdf.at(&f, &mut scratch);
            let e = bxdf.evaluate(wi, wo);
            smooth = brdf.smooth().eval(wi, wo).x;
            let ratio = e.f_hat.x / smooth;
            sum += ratio;
            sum2 += ratio * ratio;
            expected += bxdf.expected_count(wi, wo);
            nodes += f64::from(e.nodes_visited);
        }
        let n = f64::from(queries);
        let mean = sum / n;
        let rms = (sum2 / n - 2.0 * mean + 1.0).max(0.0).sqrt();
        let expected = expected / n;
        // With few particles the sample may hold none: the Poisson error of the mean ratio,
        // 1/√(queries·expected), is the floor of its standard error.
        let standard_error = ((sum2 / n - mean * mean).max(0.0) / n)
            .sqrt()
            .max(1.0 / (n * expected).sqrt());
        let ok = (mean - 1.0).abs() < 0.03 + 5.0 * standard_error;
        failures += usize::from(!ok);
        writeln!(
            report,
            "| 10^{exponent} | {expected:.3e} | {rms:.3e} | {:.3e} | {mean:.4} | {:.0} |",
            1.0 / expected.sqrt(),
            nodes / n
        )?;
        let _ = smooth;
        measured.push((expected, rms));
        law.push((expected, 1.0 / expected.sqrt()));
    }
    let plot = crate::plot::Plot {
        title: "Convergence: relative RMS of f̂ against f".into(),
        x_label: "expected particles per footprint".into(),
        y_label: "relative RMS difference".into(),
        log_x: true,
        log_y: true,
        series: vec![
            crate::plot::Series {
                name: "measured (N = 10³ … 10¹⁵)".into(),
                colour: "#c03",
                points: measured,
                line: true,
                labels: vec![],
            },
            crate::plot::Series {
                name: "1/√(expected count)".into(),
                colour: "#1f5fbf",
                points: law,
                line: true,
                labels: vec![],
            },
        ],
    };
    std::fs::create_dir_all(out)?;
    std::fs::write(out.join("convergence.svg"), plot.svg())?;
    writeln!(report, "\nPlot: `convergence.svg`.")?;
    writeln!(report)?;
    Ok(Check {
        name: "convergence to smooth",
        passed: failures == 0,
        summary: format!("7 particle counts, {failures} means off"),
    })
}

/// Queries skipped as negligible, traversed anyway: their particles against Σλ̄, from near
/// the highlight of a sparse material to the far tails of a dense one (glint-brdf's
/// "Negligible queries"; `glint_tests::counts::skipped_query_particles`).
pub(crate) fn negligible_queries(quick: bool, report: &mut String) -> anyhow::Result<Check> {
    writeln!(
        report,
        "## Negligible queries\n\nRandom queries (Beckmann α = 0.1, γ = 6°, footprints of side \
         10⁻³, ε = 0) with `negligible_count` = ½; every skipped query is traversed anyway. \
         Pass: the particles found stay within Σλ̄ + 4√Σλ̄ + 4 (a count of mean ≤ Σλ̄ exceeds it \
         with probability ~1e-4), and queries not skipped match the traversal bit for bit.\n\n\
         | N | directions | queries | skipped | Σλ̄ (bound) | particles found |\n\
         |---|---|---|---|---|---|"
    )?;
    let scale = if quick { 1 } else { 5 };
    let mut passed = true;
    let mut summary = Vec::new();
    for (particles, near_highlight, queries) in [
        (2e6, true, 4000 * scale),
        (1e12, false, 1000 * scale),
        (1e15, false, if quick { 0 } else { 500 }),
    ] {
        if queries == 0 {
            continue;
        }
        let check =
            glint_tests::counts::skipped_query_particles(particles, near_highlight, queries, 31);
        passed &= check.mismatched == 0 && check.within_bound();
        writeln!(
            report,
            "| {particles:e} | {} | {queries} | {} | {:.1} | {} |",
            if near_highlight {
                "near the highlight"
            } else {
                "uniform"
            },
            check.skipped,
            check.bound_sum,
            check.found
        )?;
        summary.push(format!(
            "N={particles:e}: {} vs Σλ̄ {:.1}",
            check.found, check.bound_sum
        ));
    }
    writeln!(report)?;
    Ok(Check {
        name: "negligible queries",
        passed,
        summary: summary.join(", "),
    })
}
