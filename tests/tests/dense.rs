//! The dense regime (`DenseCounts::Sampled`): the statistics of exact counts, a cost bounded
//! whatever N, determinism and continuity, and sparse materials left exactly as they were.

use glam::DVec2;
use glint_tests::SplitMix64;
use glint_tests::counts::{beckmann_density, highlight_query};
use glint_tests::dense::{
    SIDE, assert_deterministic_and_continuous, conic_and_moved, dense_statistics,
};
use glint_tree::{CountTree, CountTreeConfig, DenseCounts, DensityMap, Footprint, QueryScratch};

fn tree(particles: f64, dense: DenseCounts) -> CountTree {
    tree_with_epsilon(particles, 0.0, dense)
}

fn tree_with_epsilon(particles: f64, epsilon: f64, dense: DenseCounts) -> CountTree {
    let config = CountTreeConfig {
        particles: particles as u64,
        seed: 77,
        epsilon,
        dense,
        ..CountTreeConfig::default()
    };
    CountTree::new(config, beckmann_density(0.1, 0.1)).expect("valid configuration")
}

const SAMPLED: DenseCounts = DenseCounts::Sampled { node_scale: 1.0 };

/// At N = 10¹¹ (180 particles per footprint on this conic; nodes of ≥ 128 particles at its
/// scale are sampled) the sampled counts have the exact counts' mean, dispersion and
/// correlations, over the same positions. The two runs share the tree's coarse counts but not
/// the sampled ones, so the tolerances are about four standard errors of the difference of
/// two estimates from 1000 positions (a mean's 0.3%, a dispersion's 0.063, a correlation's
/// 0.045); `cargo xtask validate` measures the same at 8000 positions and N up to 10¹⁵
/// (docs/performance.md, "Dense glitter").
#[test]
fn sampled_counts_keep_the_exact_statistics() {
    let exact = dense_statistics(&tree(1e11, DenseCounts::Exact), 1000, 5);
    let sampled = dense_statistics(&tree(1e11, SAMPLED), 1000, 5);
    assert!(
        exact.mean > 10.0,
        "the workload is dense: mean {}",
        exact.mean
    );
    assert!(
        (sampled.mean / exact.mean - 1.0).abs() < 0.012,
        "mean {sampled:?} against {exact:?}"
    );
    assert!(
        (sampled.dispersion / exact.dispersion - 1.0).abs() < 0.25,
        "dispersion {sampled:?} against {exact:?}"
    );
    for (name, got, want) in [
        ("shifted", sampled.shifted, exact.shifted),
        ("neighbour", sampled.neighbour, exact.neighbour),
        ("conic moved", sampled.conic_moved, exact.conic_moved),
    ] {
        assert!((got - want).abs() < 0.18, "{name}: {got} against {want}");
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
    assert!(at_1e10 < 160.0, "{at_1e10} nodes at N = 10¹⁰");
}

/// Sparse materials sample nothing: at N = 10⁶, 10⁸ and 10⁹ every count of the sampled mode
/// equals the `DenseCounts::Exact` count bit for bit, with ε = 0 and with ε = 0.1, but where
/// Eq. 10 stopped a short query early before (it now waits for long queries): there the old
/// count was an expectation (fractional) and the new one counts whole particles.
#[test]
fn sparse_counts_are_the_exact_counts() {
    let mut rng = SplitMix64::new(7);
    let workload: Vec<_> = (0..300)
        .map(|_| highlight_query(0.1, 1f64.to_radians(), SIDE, &mut rng))
        .collect();
    let mut scratch = QueryScratch::new();
    for particles in [1e6, 1e8, 1e9] {
        for epsilon in [0.0, 0.1] {
            let with = |dense| tree_with_epsilon(particles, epsilon, dense);
            let (exact, sampled) = (with(DenseCounts::Exact), with(SAMPLED));
            let mut estimated = 0;
            for (footprint, conic) in &workload {
                let a = exact.query(footprint, conic, &mut scratch).count;
                let b = sampled.query(footprint, conic, &mut scratch).count;
                if a.to_bits() != b.to_bits() {
                    assert!(
                        a.fract() != 0.0 && b.fract() == 0.0,
                        "N = {particles:e}: {a} → {b}"
                    );
                    estimated += 1;
                }
            }
            assert!(
                epsilon > 0.0 && particles >= 1e9 || estimated == 0,
                "N = {particles:e}, ε = {epsilon}: {estimated} counts differ"
            );
            assert!(estimated < workload.len() / 10, "{estimated} counts differ");
        }
    }
}

/// The same query gives the same count whatever came before it (the samples are the nodes'
/// own, remembered or not), and a footprint moved by a millionth of its width changes its count
/// by a millionth or so, but where a sample point or a particle crosses its edge.
#[test]
fn sampled_counts_are_deterministic_and_continuous() {
    assert_deterministic_and_continuous(&tree(1e13, SAMPLED));
}

/// Under a density map that varies at the footprints' scale (1024² texels of 0.1 to 1, each
/// about a footprint wide), the sampled counts keep the exact counts' mean: the samples place
/// their points by the map within each box, and the mean term weighs the box's share by it.
#[test]
fn sampled_counts_follow_a_density_map() {
    let size = 1024;
    let values: Vec<f64> = (0..size * size)
        .map(|i| {
            let (x, y) = ((i % size) as f64, (i / size) as f64);
            0.55 + 0.45 * (0.37 * x).sin() * (0.23 * y + 1.0).cos()
        })
        .collect();
    let map = std::sync::Arc::new(DensityMap::new(size, size, &values).expect("a valid map"));
    let mapped = |dense: DenseCounts| {
        let config = CountTreeConfig {
            particles: 1e11 as u64,
            seed: 3,
            epsilon: 0.0,
            dense,
            ..CountTreeConfig::default()
        };
        CountTree::with_density_map(config, beckmann_density(0.1, 0.1), Some(map.clone()))
            .expect("valid configuration")
    };
    let (exact, sampled) = (mapped(DenseCounts::Exact), mapped(SAMPLED));
    let (conic, _) = conic_and_moved();
    let mut rng = SplitMix64::new(2);
    let mut scratch = QueryScratch::new();
    let (mut exact_sum, mut sampled_sum, mut differing) = (0.0, 0.0, 0);
    let positions = 400;
    for _ in 0..positions {
        let uv = DVec2::new(rng.uniform(), rng.uniform());
        // Footprints twice the side of the statistics' (about 400 particles each at
        // N = 10¹¹), so that nodes at their scale are dense enough to be sampled.
        let footprint =
            Footprint::new(uv, DVec2::new(2.0 * SIDE, 0.0), DVec2::new(0.0, 2.0 * SIDE))
                .expect("finite");
        let a = exact.query(&footprint, &conic, &mut scratch).count;
        let b = sampled.query(&footprint, &conic, &mut scratch).count;
        exact_sum += a;
        sampled_sum += b;
        differing += usize::from(a != b);
    }
    assert!(
        differing > positions / 4,
        "only {differing} counts were sampled"
    );
    // Means of about 400 per footprint over 400 positions: the difference of the two means
    // (their sampled parts independent given the tree) has a standard error below 0.4%.
    assert!(
        (sampled_sum / exact_sum - 1.0).abs() < 0.016,
        "{sampled_sum} against {exact_sum}"
    );
}
