//! # glint-benches: the case pools the criterion benchmarks run on
//!
//! Invariant: **benchmarks measure the public APIs on fixed, seeded inputs**, so figures from
//! two runs (or two machines) time the same work. `cargo xtask bench` runs them and writes the
//! summary table that `docs/performance.md` quotes.
#![deny(missing_docs)]

use glint_sphere::{Classification, SphericalConic, SphericalTriangle};
use glint_tests::SplitMix64;
use glint_tests::counts::{beckmann_density, highlight_query};
use glint_tests::geometry::ConicCase;
use std::sync::Arc;

use glint_tree::{
    CountTree, CountTreeConfig, DenseCounts, DensityMap, Footprint, expected_conic_solid_angle,
};

/// `n` random cases of every kind the validation draws (extremes included).
#[must_use]
pub fn mixed_cases(n: usize, seed: u64) -> Vec<ConicCase> {
    let mut rng = SplitMix64::new(seed);
    (0..n)
        .map(|_| ConicCase::from_uniforms(&rng.uniforms()))
        .collect()
}

/// `n` cases the count tree meets in practice: a conic and a subdivided octant triangle at
/// depth 2..=8 (edges of 0.4 to 0.006 rad), reached by descending towards the conic, so that
/// the answers mix disjoint, inside and partial.
#[must_use]
pub fn tree_cases(n: usize, seed: u64) -> Vec<(SphericalConic, SphericalTriangle)> {
    let mut rng = SplitMix64::new(seed);
    let mut cases = Vec::with_capacity(n);
    while cases.len() < n {
        let conic = ConicCase::from_uniforms(&rng.uniforms()).conic;
        let depth = 2 + (rng.uniform() * 7.0) as usize;
        let mut triangle =
            SphericalTriangle::upper_hemisphere_octants()[(rng.uniform() * 4.0) as usize];
        for _ in 0..depth {
            let children = triangle.subdivide();
            // Prefer a child that is not disjoint, as the tree's traversal does.
            let start = (rng.uniform() * 4.0) as usize;
            triangle = (0..4)
                .map(|k| children[(start + k) % 4])
                .find(|c| conic.classify(c) != Classification::Disjoint)
                .unwrap_or(children[start]);
        }
        cases.push((conic, triangle));
    }
    cases
}

/// `n` tree cases whose classification is partial: the inputs of an overlap computation.
#[must_use]
pub fn partial_tree_cases(n: usize, seed: u64) -> Vec<(SphericalConic, SphericalTriangle)> {
    let mut out = Vec::with_capacity(n);
    let mut round = seed;
    while out.len() < n {
        out.extend(
            tree_cases(n, round)
                .into_iter()
                .filter(|(c, t)| c.classify(t) == Classification::Partial),
        );
        round += 1;
    }
    out.truncate(n);
    out
}

/// A material setting of the paper's Table 1 (Beckmann, ε = 0.1).
#[derive(Clone, Copy, Debug)]
pub struct Table1Setting {
    /// A short name for tables and benchmark ids.
    pub name: &'static str,
    /// N.
    pub particles: u64,
    /// γ in degrees.
    pub gamma_degrees: f64,
    /// Beckmann α.
    pub alpha: f64,
}

/// The settings of the paper's scenes: sphere lights (N = 10⁶, γ = 6°, α = 0.1), N = 10⁹ at
/// γ = 0.5°, the stained glass floor (N = 10⁸, γ = 1°, α = 0.01) and the ornaments' range
/// (N = 4·10⁵ … 9·10⁶, γ = 5°, α = 0.1–0.4).
pub const TABLE1: [Table1Setting; 6] = [
    Table1Setting {
        name: "spheres_1e6_6deg_a0.1",
        particles: 1_000_000,
        gamma_degrees: 6.0,
        alpha: 0.1,
    },
    Table1Setting {
        name: "dense_1e9_0.5deg_a0.1",
        particles: 1_000_000_000,
        gamma_degrees: 0.5,
        alpha: 0.1,
    },
    Table1Setting {
        name: "glass_1e8_1deg_a0.01",
        particles: 100_000_000,
        gamma_degrees: 1.0,
        alpha: 0.01,
    },
    Table1Setting {
        name: "ornament_4e5_5deg_a0.2",
        particles: 400_000,
        gamma_degrees: 5.0,
        alpha: 0.2,
    },
    Table1Setting {
        name: "ornament_9e6_5deg_a0.4",
        particles: 9_000_000,
        gamma_degrees: 5.0,
        alpha: 0.4,
    },
    Table1Setting {
        name: "ornament_8e5_5deg_a0.1",
        particles: 800_000,
        gamma_degrees: 5.0,
        alpha: 0.1,
    },
];

/// The side of a 1080p pixel's footprint on a texture spanning the frame: ~10⁻³.
pub const PIXEL_FOOTPRINT_SIDE: f64 = 1e-3;

/// The tree of a setting (ε = 0.1, Eq. 11 tuned to pixel footprints and the setting's γ) and
/// `n` queries near the highlight. Table 1 measures the tree's query (Alg. 1), so the setting
/// answers with the tree whatever the query expects (`DenseCounts::Sampled`, the mode the
/// default lattice regime leaves its sparse queries to).
#[must_use]
pub fn table1_workload(
    setting: &Table1Setting,
    n: usize,
    seed: u64,
) -> (CountTree, Vec<(Footprint, SphericalConic)>) {
    let gamma = setting.gamma_degrees.to_radians();
    let config = CountTreeConfig {
        particles: setting.particles,
        seed,
        epsilon: 0.1,
        expected_query_area: PIXEL_FOOTPRINT_SIDE * PIXEL_FOOTPRINT_SIDE,
        expected_query_solid_angle: expected_conic_solid_angle(gamma),
        dense: DenseCounts::Sampled {
            node_scale: DenseCounts::DEFAULT_NODE_SCALE,
        },
        ..CountTreeConfig::default()
    };
    let tree = CountTree::new(config, beckmann_density(setting.alpha, setting.alpha))
        .expect("valid setting");
    let mut rng = SplitMix64::new(seed ^ 0x7AB1E1);
    let queries = (0..n)
        .map(|_| highlight_query(setting.alpha, gamma, PIXEL_FOOTPRINT_SIDE, &mut rng))
        .collect();
    (tree, queries)
}

/// The values (row 0 at the top) of a `side` × `side` production-like density map: a soft
/// radial fall-off from 1 to 0.3 over the square, cut by a band of zeros (a masked stripe, a
/// hard edge every 1/8 of the square) and with a fine texel-level grain, so that few boxes
/// are constant and every mass is a real sum.
#[must_use]
pub fn production_density_values(side: usize) -> Vec<f64> {
    let mut values = Vec::with_capacity(side * side);
    for row in 0..side {
        for column in 0..side {
            let (x, y) = (
                (column as f64 + 0.5) / side as f64,
                (row as f64 + 0.5) / side as f64,
            );
            let masked = ((8.0 * (x + y)) as usize).is_multiple_of(5);
            let fall_off = 1.0 - 0.7 * ((x - 0.5).powi(2) + (y - 0.5).powi(2)).sqrt() / 0.71;
            let grain = ((column * 7 + row * 13) % 16) as f64 / 160.0;
            values.push(if masked {
                0.0
            } else {
                (fall_off - grain).clamp(0.0, 1.0)
            });
        }
    }
    values
}

/// A setting's Table 1 workload ([`table1_workload`]) with the particles under `map`: the same
/// tree configuration and queries.
#[must_use]
pub fn table1_mapped_workload(
    setting: &Table1Setting,
    n: usize,
    seed: u64,
    map: Arc<DensityMap>,
) -> (CountTree, Vec<(Footprint, SphericalConic)>) {
    let (tree, queries) = table1_workload(setting, n, seed);
    let mapped = CountTree::with_density_map(
        *tree.config(),
        beckmann_density(setting.alpha, setting.alpha),
        Some(map),
    )
    .expect("valid setting");
    (mapped, queries)
}

/// Mean tree nodes visited (and meeting the query) and particles found per query over a
/// setting's workload.
#[must_use]
pub fn table1_statistics(setting: &Table1Setting, n: usize, seed: u64) -> Table1Statistics {
    let (tree, queries) = table1_workload(setting, n, seed);
    let mut scratch = glint_tree::QueryScratch::new();
    let mut sums = Table1Statistics::default();
    for (footprint, conic) in &queries {
        let result = tree.query(footprint, conic, &mut scratch);
        sums.nodes_visited += f64::from(result.nodes_visited);
        sums.nodes_overlapping += f64::from(result.nodes_overlapping);
        sums.particles_found += result.count;
    }
    let n = n as f64;
    Table1Statistics {
        nodes_visited: sums.nodes_visited / n,
        nodes_overlapping: sums.nodes_overlapping / n,
        particles_found: sums.particles_found / n,
    }
}

/// Means per query over a Table 1 workload.
#[derive(Clone, Copy, Debug, Default)]
pub struct Table1Statistics {
    /// Nodes visited (tested against the query).
    pub nodes_visited: f64,
    /// Visited nodes that meet the query.
    pub nodes_overlapping: f64,
    /// Particles found.
    pub particles_found: f64,
}

/// The glint material of a Table 1 setting and `n` (ω_i, ω_o, footprint) near the highlight.
#[must_use]
pub fn table1_brdf_workload(
    setting: &Table1Setting,
    n: usize,
    seed: u64,
) -> (
    glint_brdf::DiscreteBrdf,
    Vec<(glam::DVec3, glam::DVec3, Footprint)>,
) {
    let distribution = glint_brdf::Microfacet::new(
        glint_brdf::DistributionKind::Beckmann,
        setting.alpha,
        setting.alpha,
    )
    .expect("valid roughness");
    let mut parameters = glint_brdf::GlintParameters::new(distribution);
    parameters.particles = setting.particles;
    parameters.gamma_radians = setting.gamma_degrees.to_radians();
    parameters.seed = seed;
    parameters.expected_footprint_area = PIXEL_FOOTPRINT_SIDE * PIXEL_FOOTPRINT_SIDE;
    let brdf = glint_brdf::DiscreteBrdf::new(parameters).expect("valid setting");
    let (_, queries) = table1_workload(setting, n, seed);
    let queries = queries
        .into_iter()
        .map(|(f, c)| (c.wi(), c.wo(), f))
        .collect();
    (brdf, queries)
}
