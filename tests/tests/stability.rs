//! Value stability of the particle set, in the style of rand_distr's value-stability tests.
//!
//! The particles are never stored: they are a function of the material (N, D, seed, the
//! expected query statistics of Eq. 11) through the count tree's seeded draws. A change to the
//! tree's streams, split choice, splits, leaves or normal descent changes every glint pattern
//! a user has rendered. These pins make such a change visible and deliberate: a commit that
//! changes the particle set updates [`PINNED`] in the same commit (the failure message prints
//! the new table) and says why in CHANGELOG.md.
//!
//! The queries cover both split kinds (footprints smaller and larger than Eq. 11 plans for),
//! leaves (a few hundred particles in the footprint, and sparse materials), exact evaluation
//! and ε > 0, the normal approximation of the multinomial, coloured particles (per-channel
//! Dirichlet areas, Fig. 8), a hyperbolic conic, footprints that wrap: across the unit
//! square's edge, far from the origin, and over several tiles, and the dense modes: sampled
//! nodes, and the lattice regime alone and in its band with the tree.

use glam::{DVec2, DVec3};
use glint_brdf::{
    DenseCounts, DiscreteBrdf, DistributionKind, Footprint, Fresnel, GlintParameters, Microfacet,
    MultinomialMode, QueryScratch,
};
use glint_tests::geometry::direction;

/// One pinned query.
#[derive(Clone, Copy)]
struct Case {
    /// What the case covers.
    name: &'static str,
    material: fn() -> GlintParameters,
    uv: [f64; 2],
    duv_dx: [f64; 2],
    duv_dy: [f64; 2],
    /// (θ, φ) of ω_i and ω_o.
    wi: (f64, f64),
    wo: (f64, f64),
}

/// The pins' base material: the paper's ε = 0.1 and exact counts, as the pins were taken
/// with (the library's default dense mode is now the lattice; it and the sampled mode have
/// cases of their own).
fn beckmann(alpha: f64) -> GlintParameters {
    GlintParameters {
        epsilon: 0.1,
        dense: DenseCounts::Exact,
        ..GlintParameters::new(Microfacet::new(DistributionKind::Beckmann, alpha, alpha).unwrap())
    }
}

fn cases() -> Vec<Case> {
    let near = |theta: f64| ((theta, 0.3), (theta * 0.9, 0.3 + std::f64::consts::PI));
    let (wi, wo) = near(0.4);
    // The first case: the paper's defaults and a 0.03 footprint (also the lattice's band case).
    let paper_query = Case {
        name: "the paper's defaults (N = 10⁶, γ = 1°, ε = 0.1), a 0.03 footprint",
        material: || beckmann(0.1),
        uv: [0.3, 0.6],
        duv_dx: [3e-2, 0.0],
        duv_dy: [0.0, 3e-2],
        wi,
        wo,
    };
    // A pixel-sized footprint near the highlight, for the dense materials.
    let dense_query = Case {
        name: "",
        material: || dense_material(1e12, LATTICE),
        uv: [0.37, 0.81],
        duv_dx: [1e-3, 0.0],
        duv_dy: [0.0, 1e-3],
        wi,
        wo,
    };
    vec![
        paper_query,
        Case {
            name: "exact (ε = 0), a large footprint: spatial splits first, leaves at the end",
            material: || GlintParameters {
                epsilon: 0.0,
                ..beckmann(0.2)
            },
            uv: [0.71, 0.13],
            duv_dx: [2e-2, 3e-3],
            duv_dy: [-4e-3, 1.5e-2],
            wi,
            wo,
        },
        Case {
            name: "N = 10¹², a footprint far below the expected area: directional splits",
            material: || GlintParameters {
                particles: 1_000_000_000_000,
                expected_footprint_area: 1e-4,
                ..beckmann(0.05)
            },
            uv: [0.52, 0.48],
            duv_dx: [1e-5, 0.0],
            duv_dy: [0.0, 2e-5],
            wi: (0.2, 1.0),
            wo: (0.18, 1.0 + std::f64::consts::PI),
        },
        Case {
            name: "sparse (N = 10⁴, ε = 0): single leaves, GGX",
            material: || GlintParameters {
                particles: 10_000,
                epsilon: 0.0,
                dense: DenseCounts::Exact,
                gamma_radians: 8f64.to_radians(),
                ..GlintParameters::new(Microfacet::new(DistributionKind::Ggx, 0.3, 0.3).unwrap())
            },
            uv: [0.25, 0.25],
            duv_dx: [0.05, 0.0],
            duv_dy: [0.0, 0.05],
            wi: (0.5, 0.0),
            wo: (0.5, 3.0),
        },
        Case {
            name: "normal approximation of the multinomial, anisotropic, seed 11",
            material: || GlintParameters {
                multinomial: MultinomialMode::Normal,
                seed: 11,
                particles: 100_000_000,
                epsilon: 0.1,
                dense: DenseCounts::Exact,
                ..GlintParameters::new(
                    Microfacet::new(DistributionKind::Beckmann, 0.05, 0.2).unwrap(),
                )
            },
            uv: [0.9, 0.05],
            duv_dx: [3e-3, 0.0],
            duv_dy: [0.0, 3e-3],
            wi: (0.6, 0.5),
            wo: (0.55, 0.5 + std::f64::consts::PI),
        },
        Case {
            name: "coloured particles (Dirichlet areas per channel) with a conductor",
            material: || GlintParameters {
                colour_channels: 3,
                particles: 20_000_000,
                fresnel: Fresnel::Conductor {
                    eta: DVec3::new(0.2, 0.9, 1.1),
                    k: DVec3::new(3.9, 2.4, 2.2),
                },
                ..beckmann(0.15)
            },
            uv: [0.4, 0.8],
            duv_dx: [4e-3, 1e-3],
            duv_dy: [-1e-3, 4e-3],
            wi,
            wo,
        },
        Case {
            name: "a footprint across the unit square's corner (wraps in u and v), N = 10⁸",
            material: || GlintParameters {
                particles: 100_000_000,
                ..beckmann(0.1)
            },
            uv: [0.9995, 0.0002],
            duv_dx: [3e-3, 0.0],
            duv_dy: [0.0, 3e-3],
            wi,
            wo,
        },
        Case {
            name: "far from the origin (u = 10⁴ + 0.3, v = −7.4), N = 10⁸",
            material: || GlintParameters {
                particles: 100_000_000,
                ..beckmann(0.1)
            },
            uv: [10_000.3, -7.4],
            duv_dx: [3e-3, 0.0],
            duv_dy: [0.0, 3e-3],
            wi,
            wo,
        },
        Case {
            name: "over several tiles (a 3.2 × 2.1 footprint), N = 10⁴",
            material: || GlintParameters {
                particles: 10_000,
                ..beckmann(0.3)
            },
            uv: [0.5, 0.5],
            duv_dx: [3.2, 0.0],
            duv_dy: [0.0, 2.1],
            wi: (0.3, 0.0),
            wo: (0.3, 3.1),
        },
        Case {
            name: "a hyperbolic conic (ω_i and ω_o near opposite grazing), wide γ",
            material: || GlintParameters {
                gamma_radians: 30f64.to_radians(),
                ..beckmann(0.5)
            },
            uv: [0.2, 0.3],
            duv_dx: [2e-3, 0.0],
            duv_dy: [0.0, 2e-3],
            wi: (1.45, 0.0),
            wo: (1.45, std::f64::consts::PI - 0.05),
        },
        Case {
            name: "dense nodes sampled (ε = 0.1, node scale 1), N = 10¹²",
            material: || dense_material(1e12, DenseCounts::Sampled { node_scale: 1.0 }),
            ..dense_query
        },
        // The lattice regime's draws are a function of the material and the query's lattice,
        // as the particles are of the tree: pinned alike.
        Case {
            name: "the lattice alone (the defaults: ε = 0.1, dense = lattice), N = 10¹²",
            ..dense_query
        },
        Case {
            name: "the lattice's band with the tree (the defaults), N = 10⁶, a 0.03 footprint",
            material: || dense_material(1e6, LATTICE),
            ..paper_query
        },
    ]
}

/// The lattice regime (the library's default), named so that its pins stay its own.
const LATTICE: DenseCounts = DenseCounts::Lattice { node_scale: 1.0 };

/// The library's defaults (Beckmann α = 0.1, γ = 1°, ε = 0.1) with N = `particles` and the
/// dense mode `dense`.
fn dense_material(particles: f64, dense: DenseCounts) -> GlintParameters {
    GlintParameters {
        particles: particles as u64,
        dense,
        ..GlintParameters::new(Microfacet::new(DistributionKind::Beckmann, 0.1, 0.1).unwrap())
    }
}

/// count, then f̂ per channel, for each case in order.
const PINNED: [(f64, [f64; 3]); 13] = [
    (
        6.0,
        [7.506622317930054, 7.506622317930054, 7.506622317930054],
    ),
    (
        1.0,
        [3.608953037466372, 3.608953037466372, 3.608953037466372],
    ),
    (
        5.860206449311248,
        [31.184783112743887, 31.184783112743887, 31.184783112743887],
    ),
    (1.0, [0.73669126463349, 0.73669126463349, 0.73669126463349]),
    (
        12.0,
        [16.62282795059876, 16.62282795059876, 16.62282795059876],
    ),
    (
        1.0,
        [1.1924294414262966, 6.47675373462966, 5.736890864765939],
    ),
    (
        7.0,
        [8.757726037585062, 8.757726037585062, 8.757726037585062],
    ),
    (
        5.0,
        [6.255518598275043, 6.255518598275043, 6.255518598275043],
    ),
    (
        60.13332058908939,
        [0.9788450163872295, 0.9788450163872295, 0.9788450163872295],
    ),
    (
        1.0,
        [1.044527871544571, 1.044527871544571, 1.044527871544571],
    ),
    (
        7899.8929813218565,
        [8.895226944427447, 8.895226944427447, 8.895226944427447],
    ),
    (
        7933.168873987843,
        [8.932695378207777, 8.932695378207777, 8.932695378207777],
    ),
    (
        9.440415916772247,
        [11.810939468564111, 11.810939468564111, 11.810939468564111],
    ),
];

#[test]
fn particle_set_is_pinned() {
    let cases = cases();
    assert_eq!(cases.len(), PINNED.len());
    let mut scratch = QueryScratch::new();
    let mut measured = Vec::new();
    for case in &cases {
        let material = DiscreteBrdf::new((case.material)()).unwrap();
        let footprint = Footprint::new(
            DVec2::from_array(case.uv),
            DVec2::from_array(case.duv_dx),
            DVec2::from_array(case.duv_dy),
        )
        .unwrap();
        let (wi, wo) = (
            direction(case.wi.0, case.wi.1),
            direction(case.wo.0, case.wo.1),
        );
        let e = material.at(&footprint, &mut scratch).evaluate(wi, wo);
        measured.push((e.count, e.f_hat.to_array()));
    }
    let table: String = measured
        .iter()
        .map(|(count, f)| format!("    ({count:?}, [{:?}, {:?}, {:?}]),\n", f[0], f[1], f[2]))
        .collect();
    for ((case, (count, f_hat)), (pinned_count, pinned_f_hat)) in
        cases.iter().zip(&measured).zip(PINNED)
    {
        // Counts are exact; f̂ is pinned to 12 digits (it goes through exp and erf).
        let f_matches = f_hat
            .iter()
            .zip(pinned_f_hat)
            .all(|(a, b)| (a - b).abs() <= 1e-12 * b.abs());
        assert!(
            *count == pinned_count && f_matches,
            "the particle set changed at \"{}\": count {count} (pinned {pinned_count}), \
             f̂ {f_hat:?} (pinned {pinned_f_hat:?}).\nIf the change is deliberate, pin the new \
             values in the same commit and say why in CHANGELOG.md:\n{table}",
            case.name
        );
    }
    // The pins are not vacuous: every case finds particles.
    let found = measured.iter().filter(|(count, _)| *count > 0.0).count();
    assert!(
        found == cases.len(),
        "only {found} of {} cases find particles:\n{table}",
        cases.len()
    );
}
