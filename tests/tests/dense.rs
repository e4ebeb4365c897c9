//! The dense regime (`DenseCounts::Sampled`): the statistics of exact counts, a cost bounded
//! whatever N, determinism and continuity, and sparse materials left exactly as they were.

use glam::DVec2;
use glint_tests::SplitMix64;
use glint_tests::counts::{beckmann_density, highlight_query};
use glint_tests::dense::{SIDE, conic_and_moved, dense_statistics};
use glint_tree::{CountTree, CountTreeConfig, DenseCounts, DensityMap, Footprint, QueryScratch};

fn tree(particles: f64, dense: DenseCounts) -> CountTree {
    let config = CountTreeConfig {
        particles: particles as u64,
        seed: 77,
        epsilon: 0.0,
        dense,
        ..CountTreeConfig::default()
    };
    CountTree::new(config, beckmann_density(0.1, 0.1)).expect("valid configuration")
}

const SAMPLED: DenseCounts = DenseCounts::Sampled { node_scale: 2.0 };

/// At N = 10¹⁰ (18 particles per footprint on this conic; nodes of ≥ 128 particles at its
/// scale are sampled) the sampled counts have the exact counts' mean, dispersion and
/// correlations, over the same positions. Tolerances: about 4 standard errors of 1000
/// positions (a correlation's is about 0.03, a dispersion's 0.045); `cargo xtask validate`
/// measures the same at 8000 positions and N up to 10¹⁵ (docs/performance.md).
#[test]
fn sampled_counts_keep_the_exact_statistics() {
    let exact = dense_statistics(&tree(1e10, DenseCounts::Exact), 1000, 5);
    let sampled = dense_statistics(&tree(1e10, SAMPLED), 1000, 5);
    assert!(
        exact.mean > 10.0,
        "the workload is dense: mean {}",
        exact.mean
    );
    assert!(
        (sampled.mean / exact.mean - 1.0).abs() < 0.02,
        "mean {sampled:?} against {exact:?}"
    );
    assert!(
        (sampled.dispersion / exact.dispersion - 1.0).abs() < 0.2,
        "dispersion {sampled:?} against {exact:?}"
    );
    for (name, got, want) in [
        ("shifted", sampled.shifted, exact.shifted),
        ("neighbour", sampled.neighbour, exact.neighbour),
        ("conic moved", sampled.conic_moved, exact.conic_moved),
    ] {
        assert!((got - want).abs() < 0.12, "{name}: {got} against {want}");
    }
}

/// Nodes visited per highlight query stop growing with N once nodes at the query's scale are
/// sampled: from N = 10¹⁰ to 10¹⁵ the mean stays within 15% of its value at 10¹⁰ (exact
/// counts: 206 nodes at 10¹⁰, 1980 at 10¹², the node budget beyond).
#[test]
fn sampled_query_cost_is_bounded_whatever_n() {
    let mut rng = SplitMix64::new(4242);
    let workload: Vec<_> = (0..150)
        .map(|_| highlight_query(0.1, 1f64.to_radians(), SIDE, &mut rng))
        .collect();
    let mut scratch = QueryScratch::new();
    let mut mean_nodes = |particles: f64| {
        let tree = tree(particles, SAMPLED);
        let total: u64 = workload
            .iter()
            .map(|(footprint, conic)| {
                u64::from(tree.query(footprint, conic, &mut scratch).nodes_visited)
            })
            .sum();
        total as f64 / workload.len() as f64
    };
    let at_1e10 = mean_nodes(1e10);
    for particles in [1e12, 1e14, 1e15] {
        let nodes = mean_nodes(particles);
        assert!(
            nodes < 1.15 * at_1e10,
            "N = {particles:e}: {nodes} nodes against {at_1e10}"
        );
    }
    assert!(at_1e10 < 150.0, "{at_1e10} nodes at N = 10¹⁰");
}

/// Sparse materials sample nothing: at N = 10⁶ and 10⁸ every count equals the exact count,
/// bit for bit.
#[test]
fn sparse_counts_are_the_exact_counts() {
    let mut rng = SplitMix64::new(7);
    let workload: Vec<_> = (0..300)
        .map(|_| highlight_query(0.1, 1f64.to_radians(), SIDE, &mut rng))
        .collect();
    let mut scratch = QueryScratch::new();
    for particles in [1e6, 1e8] {
        let (exact, sampled) = (
            tree(particles, DenseCounts::Exact),
            tree(particles, SAMPLED),
        );
        for (footprint, conic) in &workload {
            let a = exact.query(footprint, conic, &mut scratch).count;
            let b = sampled.query(footprint, conic, &mut scratch).count;
            assert_eq!(a.to_bits(), b.to_bits(), "N = {particles:e}");
        }
    }
}

/// The same query gives the same count whatever came before it (the samples are the nodes'
/// own, remembered or not), and a footprint moved by a millionth of its width changes its count
/// by a millionth or so, but where a sample point or a particle crosses its edge.
#[test]
fn sampled_counts_are_deterministic_and_continuous() {
    let tree = tree(1e13, SAMPLED);
    let (conic, moved) = conic_and_moved();
    let mut rng = SplitMix64::new(11);
    let square = |uv: DVec2| {
        Footprint::new(uv, DVec2::new(SIDE, 0.0), DVec2::new(0.0, SIDE)).expect("finite")
    };
    let positions: Vec<DVec2> = (0..200)
        .map(|_| DVec2::new(rng.uniform(), rng.uniform()))
        .collect();
    let mut scratch = QueryScratch::new();
    let first: Vec<f64> = positions
        .iter()
        .map(|&uv| tree.query(&square(uv), &conic, &mut scratch).count)
        .collect();
    // Other queries in between, then the same ones in reverse with a fresh scratch.
    for &uv in &positions {
        let _ = tree.query(&square(uv + DVec2::splat(0.3)), &moved, &mut scratch);
    }
    let mut fresh = QueryScratch::new();
    for (uv, count) in positions.iter().zip(&first).rev() {
        let again = tree.query(&square(*uv), &conic, &mut fresh).count;
        assert_eq!(again.to_bits(), count.to_bits());
    }
    // The mean term moves continuously with the footprint's share of each sampled node; the
    // sampled points (√w each, w = n/32) and the exact particles only where one crosses an edge.
    let (mut moved_total, mut total) = (0.0, 0.0);
    for (uv, count) in positions.iter().zip(&first) {
        let nudged = tree
            .query(
                &square(*uv + DVec2::new(1e-6 * SIDE, 0.0)),
                &conic,
                &mut scratch,
            )
            .count;
        assert!((nudged - count).abs() <= 0.05 * count, "{count} → {nudged}");
        moved_total += (nudged - count).abs();
        total += count;
    }
    assert!(
        moved_total < 1e-3 * total,
        "a move of 10⁻⁶ width changed the counts by {moved_total} of {total}"
    );
}

/// Under a density map the sampled counts keep the map's mean: a map that is zero on its left
/// half and one on its right gives footprints on the right half the uniform material's mean,
/// and those on the left none.
#[test]
fn sampled_counts_follow_a_density_map() {
    let map = DensityMap::new(2, 1, &[0.0, 1.0]).expect("a valid map");
    let config = CountTreeConfig {
        particles: 1e12 as u64,
        seed: 3,
        epsilon: 0.0,
        dense: SAMPLED,
        ..CountTreeConfig::default()
    };
    let mapped = CountTree::with_density_map(
        config,
        beckmann_density(0.1, 0.1),
        Some(std::sync::Arc::new(map)),
    )
    .expect("valid configuration");
    let uniform = CountTree::new(config, beckmann_density(0.1, 0.1)).expect("valid configuration");
    let (conic, _) = conic_and_moved();
    let mut rng = SplitMix64::new(2);
    let mut scratch = QueryScratch::new();
    let (mut left, mut right, mut reference) = (0.0, 0.0, 0.0);
    let positions = 300;
    for _ in 0..positions {
        let v = rng.uniform();
        let [a, b] = [0.05 + 0.4 * rng.uniform(), 0.55 + 0.4 * rng.uniform()];
        let square = |u: f64| {
            Footprint::new(
                DVec2::new(u, v),
                DVec2::new(SIDE, 0.0),
                DVec2::new(0.0, SIDE),
            )
            .expect("finite")
        };
        left += mapped.query(&square(a), &conic, &mut scratch).count;
        right += mapped.query(&square(b), &conic, &mut scratch).count;
        reference += uniform.query(&square(b), &conic, &mut scratch).count;
    }
    assert_eq!(left, 0.0);
    // Both means ≈ 1800 per footprint: standard error about 0.1% each.
    assert!(
        (right / reference - 1.0).abs() < 0.01,
        "{right} against {reference}"
    );
}
