//! `cargo xtask validate`, stability suite: the matrix of numerical extremes through the public API
//! of glint-brdf (and so glint-tree and glint-sphere): every combination of distribution,
//! roughness, cone radius, particle count, direction pair and footprint is evaluated, sampled
//! and given a pdf, each material with one of the Fresnel terms at the ends of the accepted
//! range (in turn). A case fails on a panic, a NaN or infinite output, a negative value, a
//! sample below the horizon, or a query that visits more nodes than the budget allows.
//! Footprints beyond the largest edge, and Fresnel indices beyond their range, must be
//! refused.

use std::fmt::Write as _;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::Instant;

use glam::{DVec2, DVec3};
use glint_brdf::{
    Bxdf, DiscreteBrdf, DistributionKind, Footprint, Fresnel, GlintParameters, Microfacet,
    QueryScratch, TreeError,
};

use crate::validate::{Check, parallel_chunks};

fn alphas(quick: bool) -> Vec<(f64, f64)> {
    if quick {
        vec![(1e-4, 1e-4), (0.3, 0.3), (1e-4, 1.0)]
    } else {
        vec![
            (1e-4, 1e-4),
            (0.01, 0.01),
            (0.3, 0.3),
            (1.0, 1.0),
            (1e-4, 1.0),
        ]
    }
}

fn gammas(quick: bool) -> Vec<f64> {
    if quick {
        vec![0.01, 1.0, 60.0]
    } else {
        vec![0.01, 0.1, 1.0, 10.0, 60.0]
    }
}

fn particle_counts(quick: bool) -> Vec<u64> {
    if quick {
        vec![1, 1_000_000_000, 1_000_000_000_000_000]
    } else {
        vec![1, 1000, 1_000_000_000, 1_000_000_000_000_000]
    }
}

/// (name, Fresnel term): none, and conductors and dielectrics at the ends of the accepted
/// range ([`Fresnel::MIN_ETA`], [`Fresnel::MAX_ETA`], [`Fresnel::MAX_K`]), and η = 1, k = 0
/// (no interface: F = 0 off grazing, where rounding once made it negative). Materials take
/// them in turn.
fn fresnels() -> Vec<(&'static str, Fresnel)> {
    let conductor = |eta: f64, k: f64| Fresnel::Conductor {
        eta: DVec3::new(eta, 1.0, eta),
        k: DVec3::new(k, 0.0, k),
    };
    vec![
        ("none", Fresnel::None),
        (
            "conductor η = 10⁻³, k = 10³",
            conductor(Fresnel::MIN_ETA, Fresnel::MAX_K),
        ),
        (
            "conductor η = k = 10³",
            conductor(Fresnel::MAX_ETA, Fresnel::MAX_K),
        ),
        (
            "conductor η = 10⁻³, k = 0",
            conductor(Fresnel::MIN_ETA, 0.0),
        ),
        ("conductor η = 1, k = 0", conductor(1.0, 0.0)),
        (
            "dielectric η = 10³",
            Fresnel::Dielectric {
                eta: Fresnel::MAX_ETA,
            },
        ),
        (
            "dielectric η = 10⁻³",
            Fresnel::Dielectric {
                eta: Fresnel::MIN_ETA,
            },
        ),
    ]
}

/// Indices just beyond the accepted range, and huge ones (10¹⁵⁴ and 10³⁰⁰ gave NaN f̂): each
/// must be refused.
fn refused_fresnels() -> Vec<Fresnel> {
    let conductor = |eta: f64, k: f64| Fresnel::Conductor {
        eta: DVec3::splat(eta),
        k: DVec3::splat(k),
    };
    vec![
        conductor(1e300, 1e300),
        conductor(1e154, 1e154),
        conductor(Fresnel::MAX_ETA * 1.001, 0.0),
        conductor(Fresnel::MIN_ETA * 0.999, 0.0),
        conductor(1.0, Fresnel::MAX_K * 1.001),
        conductor(1.0, -1e-300),
        Fresnel::Dielectric { eta: 1e300 },
        Fresnel::Dielectric { eta: 0.0 },
    ]
}

/// Footprint edges beyond [`Footprint::MAX_EDGE`] (their area, or area × N, overflowed: 10³⁰⁰
/// gave NaN f̂, 10¹⁵⁴ an infinite count): each must be refused.
const REFUSED_EDGES: [f64; 4] = [Footprint::MAX_EDGE * 1.000_001, 1e154, 1e300, f64::MAX];

/// (name, ω_i, ω_o)
fn direction_pairs() -> Vec<(&'static str, DVec3, DVec3)> {
    let grazing = |x: f64| DVec3::new(x * (1.0 - 1e-12f64).sqrt(), 0.0, 1e-6).normalize();
    let at = |theta: f64, phi: f64| {
        DVec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    };
    vec![
        ("normal, normal", DVec3::Z, DVec3::Z),
        (
            "both 1e-6 from the horizon, equal",
            grazing(1.0),
            grazing(1.0),
        ),
        ("ω_i = ω_o at 60°", at(1.047, 0.3), at(1.047, 0.3)),
        (
            "mirror pair at 60°",
            at(1.047, 0.3),
            at(1.047, 0.3 + std::f64::consts::PI),
        ),
        ("grazing, nearly antipodal", grazing(1.0), grazing(-1.0)),
        (
            "ω_o below the horizon",
            at(0.5, 0.0),
            DVec3::new(0.3, 0.0, -0.95).normalize(),
        ),
        ("NaN ω_o", at(0.5, 0.0), DVec3::new(f64::NAN, 0.0, 1.0)),
    ]
}

/// (name, footprint)
fn footprints() -> Vec<(&'static str, Footprint)> {
    let square = |uv: DVec2, side: f64| {
        Footprint::new(uv, DVec2::new(side, 0.0), DVec2::new(0.0, side)).expect("finite")
    };
    vec![
        ("area 1e-14", square(DVec2::new(0.3, 0.6), 1e-7)),
        ("pixel, side 1e-3", square(DVec2::new(0.71, 0.13), 1e-3)),
        ("100 texture tiles", square(DVec2::new(0.5, 0.5), 10.0)),
        (
            "degenerate (zero area)",
            Footprint::new(
                DVec2::new(0.2, 0.2),
                DVec2::new(1e-3, 0.0),
                DVec2::new(2e-3, 0.0),
            )
            .expect("finite"),
        ),
        (
            "uv 10⁶ from the origin",
            square(DVec2::new(1e6 + 0.3, -1e6 + 0.7), 1e-3),
        ),
        (
            "edges of ±10¹⁵ (the largest), area 2·10³⁰",
            Footprint::new(
                DVec2::new(0.4, 0.9),
                DVec2::new(Footprint::MAX_EDGE, -Footprint::MAX_EDGE),
                DVec2::new(Footprint::MAX_EDGE, Footprint::MAX_EDGE),
            )
            .expect("within the limit"),
        ),
    ]
}

/// What one material's cases found.
#[derive(Default)]
struct Outcome {
    cases: u64,
    failures: Vec<String>,
    max_nodes: u32,
    slowest_seconds: f64,
}

fn check_material(
    kind: DistributionKind,
    alpha: (f64, f64),
    gamma_degrees: f64,
    particles: u64,
    (fresnel_name, fresnel): (&str, Fresnel),
) -> Outcome {
    let mut outcome = Outcome::default();
    let label = format!(
        "{kind:?} α = {alpha:?}, γ = {gamma_degrees}°, N = {particles:.0e}, Fresnel {fresnel_name}",
        particles = particles as f64
    );
    let built = catch_unwind(|| -> Result<DiscreteBrdf, String> {
        let distribution = Microfacet::new(kind, alpha.0, alpha.1).map_err(|e| e.to_string())?;
        let mut parameters = GlintParameters::new(distribution);
        parameters.gamma_radians = gamma_degrees.to_radians();
        parameters.particles = particles;
        parameters.fresnel = fresnel;
        DiscreteBrdf::new(parameters).map_err(|e| e.to_string())
    });
    let brdf = match built {
        Ok(Ok(brdf)) => brdf,
        Ok(Err(e)) => {
            outcome.cases += 1;
            outcome.failures.push(format!("{label}: rejected: {e}"));
            return outcome;
        }
        Err(_) => {
            outcome.cases += 1;
            outcome
                .failures
                .push(format!("{label}: panicked while building"));
            return outcome;
        }
    };
    let budget = brdf.tree().config().node_budget;
    let mut scratch = QueryScratch::new();
    for (direction_name, wi, wo) in direction_pairs() {
        for (footprint_name, footprint) in footprints() {
            outcome.cases += 1;
            let case = format!("{label}, {direction_name}, {footprint_name}");
            let started = Instant::now();
            let result = catch_unwind(AssertUnwindSafe(|| -> Result<u32, String> {
                let bxdf = brdf.at(&footprint, &mut scratch);
                let e = bxdf.evaluate(wi, wo);
                let values = [
                    e.f_hat.x,
                    e.f_hat.y,
                    e.f_hat.z,
                    e.count,
                    bxdf.expected_count(wi, wo),
                    e.d_hat.x,
                ];
                if values.iter().any(|v| !v.is_finite() || *v < 0.0) {
                    return Err(format!("evaluate gave {e:?}"));
                }
                if e.nodes_visited > budget {
                    return Err(format!(
                        "{} nodes visited (budget {budget})",
                        e.nodes_visited
                    ));
                }
                let f = bxdf.eval(wi, wo);
                if !f.is_finite() || f.min_element() < 0.0 {
                    return Err(format!("eval gave {f}"));
                }
                let pdf = bxdf.pdf(wi, wo);
                if !pdf.is_finite() || pdf < 0.0 {
                    return Err(format!("pdf gave {pdf}"));
                }
                for u in [
                    [0.0, 0.0, 0.0, 0.0],
                    [0.5, 0.25, 0.75, 0.125],
                    [0.999_999, 0.999_999, 0.999_999, 0.999_999],
                ] {
                    if let Some(s) = bxdf.sample(wi, u) {
                        let ok = s.wo.is_finite()
                            && s.wo.z > 0.0
                            && (s.wo.length() - 1.0).abs() < 1e-9
                            && s.pdf.is_finite()
                            && s.pdf > 0.0
                            && s.weight.is_finite()
                            && s.weight.min_element() >= 0.0;
                        if !ok {
                            return Err(format!("sample gave {s:?}"));
                        }
                    }
                }
                Ok(e.nodes_visited)
            }));
            outcome.slowest_seconds = outcome.slowest_seconds.max(started.elapsed().as_secs_f64());
            match result {
                Ok(Ok(nodes)) => outcome.max_nodes = outcome.max_nodes.max(nodes),
                Ok(Err(problem)) => outcome.failures.push(format!("{case}: {problem}")),
                Err(_) => outcome.failures.push(format!("{case}: panicked")),
            }
        }
    }
    outcome
}

pub(crate) fn stability(quick: bool, report: &mut String) -> anyhow::Result<Check> {
    let mut materials = vec![];
    for kind in DistributionKind::ALL {
        for alpha in alphas(quick) {
            for gamma in gammas(quick) {
                for particles in particle_counts(quick) {
                    materials.push((kind, alpha, gamma, particles));
                }
            }
        }
    }
    let fresnel_terms = fresnels();
    let outcomes = parallel_chunks(materials.len() as u64, 1, |chunk, _| {
        let (kind, alpha, gamma, particles) = materials[chunk as usize];
        let fresnel = fresnel_terms[chunk as usize % fresnel_terms.len()];
        check_material(kind, alpha, gamma, particles, fresnel)
    });
    let mut refusals = Outcome::default();
    for edge in REFUSED_EDGES {
        refusals.cases += 1;
        let footprint = Footprint::new(DVec2::new(0.3, 0.4), DVec2::new(edge, 0.0), DVec2::Y);
        if footprint != Err(TreeError::FootprintTooLarge { component: edge }) {
            refusals
                .failures
                .push(format!("a footprint edge of {edge:e} gave {footprint:?}"));
        }
    }
    for fresnel in refused_fresnels() {
        refusals.cases += 1;
        if fresnel.validated().is_ok() {
            refusals.failures.push(format!("{fresnel:?} was accepted"));
        }
    }
    let outcomes: Vec<Outcome> = outcomes.into_iter().chain([refusals]).collect();
    let cases: u64 = outcomes.iter().map(|o| o.cases).sum();
    let failures: Vec<&String> = outcomes.iter().flat_map(|o| &o.failures).collect();
    let max_nodes = outcomes.iter().map(|o| o.max_nodes).max().unwrap_or(0);
    let slowest = outcomes
        .iter()
        .map(|o| o.slowest_seconds)
        .fold(0.0, f64::max);
    writeln!(
        report,
        "\n## Stability: the extremes matrix\n\nEvery combination below through glint-brdf's \
         public API (the footprint-bound BxDF's `evaluate`, `expected_count`, `eval`, `pdf`, and `sample` at three uniform quadruples). A case \
         fails on a panic, a NaN or infinite output, a negative value, a sample below the \
         horizon or not unit, or more nodes than the budget.\n\n\
         | dimension | values |\n|---|---|\n\
         | distribution | Beckmann, GGX |\n\
         | α (α_x, α_y) | {} |\n\
         | γ | {} |\n\
         | N | {} |\n\
         | (ω_i, ω_o) | {} |\n\
         | footprint | {} |\n\
         | Fresnel (one per material, in turn) | {} |\n\n\
         Refused, as they must be: footprint edges of {} (their area or count overflows), \
         and {} Fresnel terms beyond the accepted range (η in [10⁻³, 10³], k in [0, 10³]).\n\n\
         {cases} cases, {} failures; at most {max_nodes} nodes visited in one query; the \
         slowest case took {:.1} ms.\n",
        alphas(quick)
            .iter()
            .map(|a| format!("{a:?}"))
            .collect::<Vec<_>>()
            .join(", "),
        gammas(quick)
            .iter()
            .map(|g| format!("{g}°"))
            .collect::<Vec<_>>()
            .join(", "),
        particle_counts(quick)
            .iter()
            .map(|n| format!("{:.0e}", *n as f64))
            .collect::<Vec<_>>()
            .join(", "),
        direction_pairs()
            .iter()
            .map(|d| d.0)
            .collect::<Vec<_>>()
            .join("; "),
        footprints()
            .iter()
            .map(|f| f.0)
            .collect::<Vec<_>>()
            .join("; "),
        fresnel_terms
            .iter()
            .map(|f| f.0)
            .collect::<Vec<_>>()
            .join("; "),
        REFUSED_EDGES
            .iter()
            .map(|e| format!("{e:e}"))
            .collect::<Vec<_>>()
            .join(", "),
        refused_fresnels().len(),
        failures.len(),
        slowest * 1e3
    )?;
    for failure in failures.iter().take(20) {
        writeln!(report, "- {failure}")?;
    }
    Ok(Check {
        name: "stability: extremes matrix",
        passed: failures.is_empty(),
        summary: format!(
            "{cases} cases, {} failures, max {max_nodes} nodes",
            failures.len()
        ),
    })
}
