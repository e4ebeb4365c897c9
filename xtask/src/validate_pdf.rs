//! `cargo xtask validate`, trade suite: the glint sampler's pdf quadrature
//! (`GlintParameters::pdf_quadrature`), the default cubature rules against the paper's 64 QMC
//! points: time per pdf and relative error against 4096 QMC points, on directions the sampler
//! draws, for cones from narrow to wider than the sampling lobe (γ/α_s from 0.04 to 1.45, the
//! range of the scenes' materials and beyond). The check: the default is at least as accurate
//! as 64 QMC points on every material, as its documentation claims.

use std::fmt::Write as _;
use std::time::Instant;

use glint_brdf::{
    DVec3, DiscreteBrdf, DistributionKind, GlintParameters, Microfacet, PdfQuadrature, PdfRule,
};
use glint_tests::SplitMix64;

use crate::validate::Check;

/// (α, γ in degrees): γ/α_s = 0.04 (sphere_lights), 0.22, 0.44 and 0.52 (ornaments,
/// glitter_object), 0.87 (the stained glass) and 1.45.
const MATERIALS: [(f64, f64); 6] = [
    (0.1, 0.5),
    (0.2, 5.0),
    (0.1, 5.0),
    (0.1, 6.0),
    (0.01, 1.0),
    (0.03, 5.0),
];

fn material(
    alpha: f64,
    gamma_degrees: f64,
    quadrature: PdfQuadrature,
    points: usize,
) -> DiscreteBrdf {
    let mut parameters = GlintParameters::new(
        Microfacet::new(DistributionKind::Beckmann, alpha, alpha).expect("valid roughness"),
    );
    parameters.gamma_radians = gamma_degrees.to_radians();
    parameters.particles = 1000;
    parameters.pdf_quadrature = quadrature;
    parameters.pdf_points = points;
    DiscreteBrdf::new(parameters).expect("valid material")
}

/// Median and maximum of `errors` (sorted in place).
fn median_and_max(errors: &mut [f64]) -> (f64, f64) {
    errors.sort_by(f64::total_cmp);
    (errors[errors.len() / 2], errors[errors.len() - 1])
}

pub(crate) fn pdf_quadrature(quick: bool, report: &mut String) -> anyhow::Result<Check> {
    let directions = if quick { 500 } else { 5000 };
    writeln!(
        report,
        "\n### The sampling pdf's quadrature\n\nBeckmann, α_s = 2α; {directions} pairs (ω_i \
         uniform within 80° of n, ω_o drawn by the sampler); relative error against 4096 QMC \
         points; time per pdf on one thread. The default (cubature) takes 7 points for \
         γ ≤ 0.35 α_s and 32 (a polar Gauss rule) above, and the slope-space rule for cones \
         across the horizon; QMC takes its points there too.\n\n\
         Errors over the cones above the horizon (those across it are a share of the pairs, \
         last column).\n\n\
         | α | γ | γ/α_s | cubature: time | median error | max error | 64 QMC points: time | median error | max error | pairs across the horizon |\n\
         |---|---|---|---|---|---|---|---|---|---|"
    )?;
    let mut passed = true;
    for (alpha, gamma_degrees) in MATERIALS {
        let reference = material(alpha, gamma_degrees, PdfQuadrature::QuasiMonteCarlo, 4096);
        let cubature = material(alpha, gamma_degrees, PdfQuadrature::Cubature, 64);
        let qmc = material(alpha, gamma_degrees, PdfQuadrature::QuasiMonteCarlo, 64);
        let mut rng = SplitMix64::new(17);
        let mut pairs = Vec::with_capacity(directions);
        while pairs.len() < directions {
            let cos = 1.0 - rng.uniform() * (1.0 - 80f64.to_radians().cos());
            let phi = std::f64::consts::TAU * rng.uniform();
            let sin = (1.0 - cos * cos).sqrt();
            let wi = DVec3::new(sin * phi.cos(), sin * phi.sin(), cos);
            let u = [rng.uniform(), rng.uniform(), rng.uniform(), rng.uniform()];
            if let Some(wo) = reference.sample_direction(wi, u) {
                pairs.push((wi, wo, reference.sampling_pdf(wi, wo)));
            }
        }
        let sin_gamma = gamma_degrees.to_radians().sin();
        let mut row = format!(
            "| {alpha} | {gamma_degrees}° | {:.2} |",
            gamma_degrees.to_radians() / (2.0 * alpha)
        );
        let mut maxima = Vec::new();
        for brdf in [&cubature, &qmc] {
            let started = Instant::now();
            let mut errors: Vec<f64> = pairs
                .iter()
                .filter(|(_, wo, _)| wo.z >= sin_gamma)
                .map(|&(wi, wo, exact)| (brdf.sampling_pdf(wi, wo) - exact).abs() / exact)
                .collect();
            let nanoseconds = started.elapsed().as_secs_f64() * 1e9 / errors.len().max(1) as f64;
            let (median, max) = median_and_max(&mut errors);
            maxima.push(max);
            write!(row, " {nanoseconds:.0} ns | {median:.1e} | {max:.1e} |")?;
        }
        passed &= maxima[0] <= maxima[1];
        let across = pairs.iter().filter(|(_, wo, _)| wo.z < sin_gamma).count();
        writeln!(
            report,
            "{row} {:.1}% |",
            100.0 * across as f64 / directions as f64
        )?;
    }
    Ok(Check {
        name: "trade: the sampling pdf's cubature against 64 QMC points",
        passed,
        summary: format!(
            "{} materials, γ/α_s 0.04–1.45: the default's largest error is at most QMC's",
            MATERIALS.len()
        ),
    })
}

/// Materials for the pdf's cost by rule: (label, kind, α_x, α_y, γ in degrees).
const COST_MATERIALS: [(&str, DistributionKind, f64, f64, f64); 5] = [
    ("stained_glass", DistributionKind::Beckmann, 0.01, 0.01, 1.0),
    ("glitter_object", DistributionKind::Beckmann, 0.1, 0.1, 6.0),
    ("ornaments", DistributionKind::Beckmann, 0.2, 0.2, 5.0),
    (
        "ornaments, anisotropic",
        DistributionKind::Beckmann,
        0.1,
        0.4,
        5.0,
    ),
    ("GGX, wide cone", DistributionKind::Ggx, 0.02, 0.02, 10.0),
];

/// What the sampler's pdf costs per call in each of its regimes ([`PdfRule`]), on directions
/// the sampler draws for incidence from the normal to 87°: the share of calls each rule takes
/// and its time per call, one thread. The check: every sampled direction has a positive, finite
/// pdf.
pub(crate) fn pdf_cost_by_rule(quick: bool, report: &mut String) -> anyhow::Result<Check> {
    let directions = if quick { 2000 } else { 20_000 };
    let repeats = if quick { 3 } else { 10 };
    writeln!(
        report,
        "\n### The sampling pdf's cost by rule\n\n{directions} pairs per material (cos θ_i \
         uniform in [0.05, 1], ω_o drawn by the sampler, default cubature); time per pdf on one \
         thread, the best of {repeats} passes over each rule's pairs. Rules: 7 points \
         (γ ≤ 0.35·α_s·cos θ_i), 32-point polar Gauss (γ ≤ 2·α_s·cos θ_i), the slope-space \
         rule along an ellipse's chords (wider cones above the horizon), and the same cut by the \
         horizon (cones across it).\n\n\
         | material | α | γ | rule | share of pairs | time per pdf |\n|---|---|---|---|---|---|"
    )?;
    let rules = [
        (PdfRule::SevenPoint, "7 points"),
        (PdfRule::PolarGauss, "32-point polar Gauss"),
        (PdfRule::SlopeSpace, "slope space"),
        (PdfRule::AcrossTheHorizon, "slope space, across the horizon"),
    ];
    let mut bad = 0usize;
    for (label, kind, alpha_x, alpha_y, gamma_degrees) in COST_MATERIALS {
        let mut parameters =
            GlintParameters::new(Microfacet::new(kind, alpha_x, alpha_y).expect("valid roughness"));
        parameters.gamma_radians = gamma_degrees.to_radians();
        parameters.particles = 1000;
        let brdf = DiscreteBrdf::new(parameters).expect("valid material");
        let mut rng = SplitMix64::new(23);
        let mut pairs = Vec::with_capacity(directions);
        while pairs.len() < directions {
            let cos = 0.05 + 0.95 * rng.uniform();
            let phi = std::f64::consts::TAU * rng.uniform();
            let sin = (1.0 - cos * cos).sqrt();
            let wi = DVec3::new(sin * phi.cos(), sin * phi.sin(), cos);
            let u = [rng.uniform(), rng.uniform(), rng.uniform(), rng.uniform()];
            if let Some(wo) = brdf.sample_direction(wi, u) {
                pairs.push((wi, wo));
            }
        }
        for (rule, rule_name) in rules {
            let chosen: Vec<(DVec3, DVec3)> = pairs
                .iter()
                .copied()
                .filter(|&(wi, wo)| brdf.sampling_pdf_rule(wi, wo) == rule)
                .collect();
            if chosen.is_empty() {
                continue;
            }
            bad += chosen
                .iter()
                .filter(|&&(wi, wo)| {
                    let pdf = brdf.sampling_pdf(wi, wo);
                    !(pdf > 0.0 && pdf.is_finite())
                })
                .count();
            let mut best = f64::INFINITY;
            for _ in 0..repeats {
                let started = Instant::now();
                for &(wi, wo) in &chosen {
                    std::hint::black_box(brdf.sampling_pdf(std::hint::black_box(wi), wo));
                }
                best = best.min(started.elapsed().as_secs_f64() / chosen.len() as f64);
            }
            let alpha = if alpha_x == alpha_y {
                format!("{alpha_x}")
            } else {
                format!("({alpha_x}, {alpha_y})")
            };
            writeln!(
                report,
                "| {label} ({kind:?}) | {alpha} | {gamma_degrees}° | {rule_name} | {:.1}% | {} |",
                100.0 * chosen.len() as f64 / pairs.len() as f64,
                if best < 1e-6 {
                    format!("{:.0} ns", best * 1e9)
                } else {
                    format!("{:.2} µs", best * 1e6)
                }
            )?;
        }
    }
    Ok(Check {
        name: "trade: the sampling pdf's cost by rule",
        passed: bad == 0,
        summary: format!(
            "{} materials; sampled directions with a pdf that is not positive and finite: {bad}",
            COST_MATERIALS.len()
        ),
    })
}
