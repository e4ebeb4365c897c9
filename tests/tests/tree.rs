//! glint-tree: determinism, additivity, binomial statistics, multinomial chi-square, coherence,
//! extremes and allocation-free queries.

use std::f64::consts::PI;

use glam::{DVec2, DVec3};
use glint_sphere::SphericalConic;
use glint_tests::SplitMix64;
use glint_tests::counts::{
    beckmann_tree, conic_integral_by_sampling, correlation, count_moment_errors,
    counts_over_footprints, equal_split_chi_square, mean_and_variance, multinomial_chi_square,
    overlapping_pair_counts, queries_in_threads, whole_and_halves,
};
use glint_tests::geometry::direction;
use glint_tree::{
    CountTree, CountTreeConfig, DenseCounts, Footprint, MultinomialMode, QueryScratch,
};

fn near_specular_conic(gamma_deg: f64) -> SphericalConic {
    SphericalConic::new(
        direction(0.3, 0.2),
        direction(0.25, 0.2 + PI),
        gamma_deg.to_radians(),
    )
    .unwrap()
}

fn square(uv: DVec2, side: f64) -> Footprint {
    Footprint::new(uv, DVec2::new(side, 0.0), DVec2::new(0.0, side)).unwrap()
}

#[test]
fn same_query_is_bit_identical_in_any_thread_and_order() {
    let tree = beckmann_tree(0.2, 1_000_000, 7, 0.1, MultinomialMode::Normal);
    let conic = near_specular_conic(3.0);
    let mut rng = SplitMix64::new(3);
    let footprints: Vec<Footprint> = (0..200)
        .map(|_| square(DVec2::new(rng.uniform(), rng.uniform()), 0.003))
        .collect();
    let mut scratch = QueryScratch::new();
    let forward: Vec<_> = footprints
        .iter()
        .map(|f| tree.query(f, &conic, &mut scratch))
        .collect();
    let backward: Vec<_> = footprints
        .iter()
        .rev()
        .map(|f| tree.query(f, &conic, &mut scratch))
        .collect();
    let threaded = queries_in_threads(&tree, &conic, &footprints, 4);
    for (i, result) in forward.iter().enumerate() {
        assert_eq!(
            result.count.to_bits(),
            backward[footprints.len() - 1 - i].count.to_bits()
        );
        assert_eq!(result.count.to_bits(), threaded[i].count.to_bits());
        assert_eq!(result.nodes_visited, threaded[i].nodes_visited);
    }
    assert!(forward.iter().any(|r| r.count > 0.0));
}

/// A scratch remembers split counts, coloured nodes' areas and leaves' particle positions and
/// normals across queries (and trees): neighbouring and overlapping footprints, queried
/// through one scratch with four trees interleaved (two coloured) and conics taking turns (normals a descent reached
/// for one conic are tested against the others), answer exactly as each does with a fresh
/// scratch, nodes visited and areas included.
#[test]
fn remembered_counts_and_leaves_change_no_answer() {
    let coloured = CountTreeConfig {
        particles: 100_000_000,
        seed: 7,
        colour_channels: 3,
        dense: DenseCounts::Exact,
        ..CountTreeConfig::default()
    };
    let other_coloured = CountTreeConfig {
        seed: 8,
        ..coloured
    };
    let trees = [
        beckmann_tree(0.2, 100_000_000, 5, 0.0, MultinomialMode::Exact),
        CountTree::new(coloured, glint_tests::counts::beckmann_density(0.15, 0.15)).unwrap(),
        CountTree::new(
            other_coloured,
            glint_tests::counts::beckmann_density(0.15, 0.15),
        )
        .unwrap(),
        beckmann_tree(0.1, 100_000_000, 6, 0.1, MultinomialMode::Exact),
    ];
    let conics = [
        near_specular_conic(2.0),
        near_specular_conic(1.0),
        SphericalConic::new(
            direction(0.2, 1.0),
            direction(0.3, 1.0 + PI),
            1.5_f64.to_radians(),
        )
        .unwrap(),
    ];
    let mut rng = SplitMix64::new(21);
    // Clusters of footprints around a few points, as a pixel's neighbours (spread 0.03) and
    // its samples (spread 3e-4, overlapping footprints that meet the same leaves).
    let footprints: Vec<Footprint> = (0..300)
        .map(|i| {
            let cluster = i / 4;
            let centre = DVec2::new(
                0.1 + 0.2 * f64::from(cluster % 4),
                0.3 + 0.1 * f64::from(cluster % 3),
            );
            let spread = if i % 2 == 0 { 0.03 } else { 3e-4 };
            let jitter = DVec2::new(rng.uniform(), rng.uniform()) * spread;
            square(centre + jitter, 1e-3)
        })
        .collect();
    let mut shared = QueryScratch::new();
    let mut found = 0.0;
    for (i, footprint) in footprints.iter().enumerate() {
        let tree = &trees[i % 4];
        let conic = &conics[i / 2 % 3];
        let warm = tree.query(footprint, conic, &mut shared);
        let fresh = tree.query(footprint, conic, &mut QueryScratch::new());
        assert_eq!(warm, fresh, "query {i}");
        found += warm.count;
    }
    assert!(found > 0.0, "the queries find particles");
    // The two coloured trees in turn, with the same footprints and conic: their nodes have
    // the same identities, and each keeps its own areas.
    let mut coloured_found = 0.0;
    for (i, footprint) in footprints.iter().enumerate().take(100) {
        let tree = &trees[1 + i % 2];
        let warm = tree.query(footprint, &conics[0], &mut shared);
        let fresh = tree.query(footprint, &conics[0], &mut QueryScratch::new());
        assert_eq!(warm, fresh, "coloured query {i}");
        coloured_found += warm.count;
    }
    assert!(coloured_found > 0.0, "the coloured queries find particles");
}

/// Exact mode: two footprints that tile a third count exactly as many particles.
#[test]
fn exact_counts_are_additive() {
    let mut rng = SplitMix64::new(11);
    for (alpha, particles, gamma_deg) in [
        (0.2, 1_000_000, 5.0),
        (0.05, 100_000_000, 1.0),
        (0.5, 10_000, 10.0),
    ] {
        let tree = beckmann_tree(alpha, particles, 5, 0.0, MultinomialMode::Exact);
        let conic = near_specular_conic(gamma_deg);
        let mut scratch = QueryScratch::new();
        for _ in 0..40 {
            let uv = DVec2::new(rng.uniform(), rng.uniform());
            let dx = DVec2::new(0.01 + 0.02 * rng.uniform(), 0.005 * rng.uniform());
            let dy = DVec2::new(-0.004 * rng.uniform(), 0.01 + 0.02 * rng.uniform());
            let (total, parts) = whole_and_halves(&tree, &conic, (uv, dx, dy), &mut scratch);
            assert_eq!(total.fract(), 0.0, "exact counts are whole particles");
            assert_eq!(total, parts, "α {alpha}, N {particles}, uv {uv}");
        }
    }
}

/// A leaf at the depth guard holds up to 256 particles, whose normals are resolved 64 at a
/// time: splitting the tile at a non-dyadic line x = 0.3 keeps counts and particle areas
/// additive, so every particle of the crowded leaf is counted once, in the right part.
#[test]
fn crowded_leaves_count_every_particle_once() {
    let mut scratch = QueryScratch::new();
    for (particles, colour_channels) in [(250, 3), (130, 0), (64, 1)] {
        let config = CountTreeConfig {
            particles,
            max_depth: 0,
            colour_channels,
            dense: DenseCounts::Exact,
            ..CountTreeConfig::default()
        };
        let tree = CountTree::new(config, glint_tests::counts::beckmann_density(0.3, 0.3)).unwrap();
        for gamma_deg in [2.0, 30.0, 150.0] {
            let conic = near_specular_conic(gamma_deg);
            let tile = |x0: f64, x1: f64| {
                Footprint::new(
                    DVec2::new(0.5 * (x0 + x1), 0.5),
                    DVec2::new(x1 - x0, 0.0),
                    DVec2::new(0.0, 1.0),
                )
                .unwrap()
            };
            let whole = tree.query(&tile(0.0, 1.0), &conic, &mut scratch);
            let left = tree.query(&tile(0.0, 0.3), &conic, &mut scratch);
            let right = tree.query(&tile(0.3, 1.0), &conic, &mut scratch);
            assert_eq!(
                whole.count,
                left.count + right.count,
                "N {particles}, γ {gamma_deg}°"
            );
            for c in 0..3 {
                let parts = left.d_hat[c] + right.d_hat[c];
                assert!(
                    (whole.d_hat[c] - parts).abs() < 1e-12,
                    "{whole:?} {left:?} {right:?}"
                );
            }
            // The widest conic holds nearly every normal.
            if gamma_deg > 100.0 {
                assert!(whole.count >= 0.9 * particles as f64, "{whole:?}");
            }
        }
    }
}

/// ε = 0: over 3000 random footprints, the mean count matches N·area·∫p over the conic, with
/// the integral from an independent Monte Carlo over reflected directions, and the
/// variance/mean ratio is 1 − q (binomial), within 5 standard errors that include the one
/// particle set's own fluctuation (`count_moment_errors`).
#[test]
fn exact_counts_are_binomial() {
    for (alpha, particles, gamma_deg, side) in
        [(0.2, 1_000_000, 5.0, 0.01), (0.1, 100_000_000, 1.0, 0.002)]
    {
        let tree = beckmann_tree(alpha, particles, 21, 0.0, MultinomialMode::Exact);
        let conic = near_specular_conic(gamma_deg);
        let density = glint_tests::counts::beckmann_density(alpha, alpha);
        let (integral, integral_error) =
            conic_integral_by_sampling(density.as_ref(), &conic, 400_000, &mut SplitMix64::new(4));
        let area = side * side;
        let expected = particles as f64 * area * integral;
        let queries = 3000;
        let counts = counts_over_footprints(&tree, &conic, side, queries, 99);
        let (mean, variance) = mean_and_variance(&counts);
        let q = area * integral;
        let (standard_error, dispersion_error) = count_moment_errors(expected, q, area, queries);
        let standard_error = standard_error + expected * integral_error / integral;
        assert!(
            (mean - expected).abs() < 5.0 * standard_error,
            "α {alpha}: mean {mean} vs N·A·∫p = {expected} ± {standard_error}"
        );
        let dispersion = variance / mean;
        assert!(
            (dispersion - (1.0 - q)).abs() < 5.0 * dispersion_error,
            "α {alpha}: variance/mean {dispersion} ± {dispersion_error}"
        );
    }
}

/// Multinomial splits against the exact multinomial (randomized PIT chi-square, α = 1e-4 per
/// test, 2000 draws each): the exact mode passes for every n; the normal approximation passes
/// from n = 10⁴ on (below, `cargo xtask validate` reports its deviations).
#[test]
fn multinomial_splits_pass_chi_square() {
    let probabilities = [[0.25; 4], [0.1, 0.2, 0.3, 0.4], [0.7, 0.01, 0.09, 0.2]];
    for n in [1u64, 2, 5, 8, 9, 20, 100, 10_000, 1_000_000_000] {
        for (k, p) in probabilities.iter().enumerate() {
            let seed = (n as u32).wrapping_mul(31).wrapping_add(k as u32);
            let exact = multinomial_chi_square(n, *p, MultinomialMode::Exact, 2000, seed);
            assert!(
                exact > 1e-4,
                "exact multinomial n = {n}, p = {p:?}: p-value {exact}"
            );
            if n >= 10_000 {
                let normal = multinomial_chi_square(n, *p, MultinomialMode::Normal, 2000, seed);
                assert!(
                    normal > 1e-4,
                    "normal approximation n = {n}, p = {p:?}: p-value {normal}"
                );
            }
        }
    }
}

/// The spatial split (four equal quarters, two random bits per particle up to 384 particles in
/// exact mode, conditional binomials beyond) against the exact multinomial, on both sides of
/// each switch point.
#[test]
fn equal_splits_pass_chi_square() {
    for n in [
        1u64,
        2,
        5,
        8,
        9,
        31,
        32,
        33,
        64,
        100,
        127,
        128,
        129,
        1000,
        1_000_000_000,
    ] {
        let seed = (n as u32).wrapping_mul(131).wrapping_add(17);
        let exact = equal_split_chi_square(n, MultinomialMode::Exact, 2000, seed);
        assert!(exact > 1e-4, "exact equal split n = {n}: p-value {exact}");
        if n <= 8 || n >= 10_000 {
            let normal = equal_split_chi_square(n, MultinomialMode::Normal, 2000, seed);
            assert!(
                normal > 1e-4,
                "normal-mode equal split n = {n}: p-value {normal}"
            );
        }
    }
}

/// Footprints overlapping by a fraction f have counts correlated by about f (exact mode).
#[test]
fn overlapping_footprints_are_correlated_by_their_overlap() {
    let tree = beckmann_tree(0.3, 4_000_000, 3, 0.0, MultinomialMode::Exact);
    let conic = near_specular_conic(6.0);
    let side = 0.01;
    for overlap in [0.0, 0.25, 0.5, 0.75, 1.0] {
        let (a, b) = overlapping_pair_counts(&tree, &conic, side, overlap, 1500, 8);
        let correlation = correlation(&a, &b);
        // Sampling sd of a correlation ≈ (1 − ρ²)/√n ≤ 0.026; allow 4 sd.
        assert!(
            (correlation - overlap).abs() < 0.1,
            "overlap {overlap}: correlation {correlation}"
        );
    }
}

/// The node budget bounds a query's work, not only its nodes: a sliver footprint spanning T
/// tiles tests each node against about T translates, so it visits at most budget·4/T nodes
/// (it took 58 s at 10⁶ nodes of 10³ tiles), and still counts about N·A·∫p (the truncated
/// nodes add their expected shares).
#[test]
fn slivers_across_many_tiles_keep_the_work_bound() {
    let config = CountTreeConfig {
        particles: 1_000_000_000_000_000,
        epsilon: 0.0,
        dense: DenseCounts::Exact,
        ..CountTreeConfig::default()
    };
    let budget = config.node_budget;
    let tree = CountTree::new(config, glint_tests::counts::beckmann_density(0.1, 0.1)).unwrap();
    let mut scratch = QueryScratch::new();
    let conic = near_specular_conic(1.0);
    for (dx, dy) in [
        (DVec2::new(1e-6, 0.0), DVec2::new(0.0, 1000.0)),
        (DVec2::new(1000.0, 0.0), DVec2::new(0.0, 1e-6)),
        (DVec2::new(5e-7, 0.0), DVec2::new(0.7, 2000.0)),
    ] {
        let footprint = Footprint::new(DVec2::new(0.3, 0.4), dx, dy).unwrap();
        let tiles = footprint.tiles_spanned();
        let result = tree.query(&footprint, &conic, &mut scratch);
        let expected = tree.expected_count(&footprint, &conic, &mut scratch);
        assert!(
            f64::from(result.nodes_visited) * tiles <= 4.0 * f64::from(budget) + 4.0 * tiles,
            "{dx} {dy}: {} nodes over {tiles} tiles",
            result.nodes_visited
        );
        assert!(result.truncated && !result.periodic_average);
        assert!(
            (result.count - expected).abs() <= 1e-3 * expected,
            "{dx} {dy}: {} vs {expected}",
            result.count
        );
    }
}

/// The numerical extremes (α, γ, N, directions, footprints) through the public API: finite, non-negative, bounded.
#[test]
fn extreme_parameters_give_finite_bounded_answers() {
    let mut scratch = QueryScratch::new();
    for particles in [1u64, 2, 1000, 1_000_000_000, 1_000_000_000_000_000] {
        for epsilon in [0.0, 0.1] {
            let config = CountTreeConfig {
                particles,
                epsilon,
                multinomial: MultinomialMode::Normal,
                node_budget: 20_000,
                dense: DenseCounts::Exact,
                ..CountTreeConfig::default()
            };
            let tree =
                CountTree::new(config, glint_tests::counts::beckmann_density(0.1, 0.1)).unwrap();
            for (uv, side) in [
                (DVec2::new(0.5, 0.5), 1e-14),
                (DVec2::new(1e6 + 0.3, -1e6 + 0.2), 1e-3),
                (DVec2::new(0.1, 0.9), 1.0),
                (DVec2::new(0.7, 0.2), 100.0),
            ] {
                for conic in [
                    near_specular_conic(0.01),
                    near_specular_conic(60.0),
                    SphericalConic::new(
                        direction(PI / 2.0 - 1e-6, 0.0),
                        direction(PI / 2.0 - 1e-6, PI),
                        0.02,
                    )
                    .unwrap(),
                    SphericalConic::new(DVec3::Z, DVec3::Z, 0.01).unwrap(),
                ] {
                    let footprint = square(uv, side);
                    let result = tree.query(&footprint, &conic, &mut scratch);
                    let multiplicity_bound = (side + 1.0).ceil().powi(2);
                    assert!(result.count.is_finite() && result.count >= 0.0);
                    assert!(result.count <= particles as f64 * multiplicity_bound);
                    assert!(result.d_hat.iter().all(|d| d.is_finite() && *d >= 0.0));
                    // The budget is strict.
                    assert!(
                        result.nodes_visited <= 20_000,
                        "{} nodes",
                        result.nodes_visited
                    );
                    // The root meets every footprint; only nodes meeting the query are split,
                    // each into at most four tested children.
                    let (visited, overlapping) = (result.nodes_visited, result.nodes_overlapping);
                    assert!(1 <= overlapping && overlapping <= visited);
                    assert!(visited <= 1 + 4 * overlapping, "{visited} {overlapping}");
                }
            }
        }
    }
    // Degenerate (zero-area) footprints see nothing.
    let tree = beckmann_tree(0.1, 1_000_000, 1, 0.0, MultinomialMode::Exact);
    let line = Footprint::new(
        DVec2::new(0.3, 0.3),
        DVec2::new(0.01, 0.01),
        DVec2::new(0.02, 0.02),
    )
    .unwrap();
    assert_eq!(
        tree.query(&line, &near_specular_conic(5.0), &mut scratch)
            .count,
        0.0
    );
}

/// Once the scratch space has grown, a query allocates nothing.
#[test]
fn queries_do_not_allocate() {
    let tree = beckmann_tree(0.1, 1_000_000, 1, 0.1, MultinomialMode::Normal);
    let conic = near_specular_conic(6.0);
    let mut scratch = QueryScratch::new();
    let mut rng = SplitMix64::new(5);
    let footprints: Vec<Footprint> = (0..500)
        .map(|_| square(DVec2::new(rng.uniform(), rng.uniform()), 0.001))
        .collect();
    for f in &footprints {
        let _ = tree.query(f, &conic, &mut scratch);
    }
    let before = crate::counting_allocator::allocations();
    for f in &footprints {
        let _ = tree.query(f, &conic, &mut scratch);
    }
    assert_eq!(crate::counting_allocator::allocations() - before, 0);
}

/// With particle areas (Dirichlet, Sec. 3.4), D̂ per channel has the same mean as count/N, and
/// channels differ per footprint.
#[test]
fn particle_areas_have_the_mean_of_counts() {
    let config = CountTreeConfig {
        particles: 200_000,
        seed: 4,
        epsilon: 0.0,
        colour_channels: 3,
        dense: DenseCounts::Exact,
        ..CountTreeConfig::default()
    };
    let tree = CountTree::new(config, glint_tests::counts::beckmann_density(0.3, 0.3)).unwrap();
    let conic = near_specular_conic(8.0);
    let mut scratch = QueryScratch::new();
    let mut rng = SplitMix64::new(6);
    let (mut sum_counts, mut sum_areas) = (0.0, [0.0; 3]);
    let mut differing = 0;
    for _ in 0..1500 {
        let f = square(DVec2::new(rng.uniform(), rng.uniform()), 0.02);
        let r = tree.query(&f, &conic, &mut scratch);
        sum_counts += r.count / 200_000.0;
        for (sum, d) in sum_areas.iter_mut().zip(r.d_hat) {
            *sum += d;
        }
        if r.count > 0.0 && r.d_hat[0] != r.d_hat[1] {
            differing += 1;
        }
    }
    for (channel, sum) in sum_areas.iter().enumerate() {
        // Areas of k particles: mean k/N, relative sd ~ 1/√k per query; the sums agree to ~2%.
        assert!(
            (sum / sum_counts - 1.0).abs() < 0.05,
            "channel {channel}: {sum} vs {sum_counts}"
        );
    }
    assert!(differing > 100);
}

/// The top-level cache changes nothing: the same answers, bit for bit, with 0 to 8 levels.
#[test]
fn top_level_cache_is_invisible() {
    let conic = near_specular_conic(4.0);
    let mut rng = SplitMix64::new(12);
    let footprints: Vec<Footprint> = (0..100)
        .map(|_| square(DVec2::new(rng.uniform(), rng.uniform()), 0.004))
        .collect();
    let answers = |levels: u32, epsilon: f64| {
        let config = CountTreeConfig {
            particles: 20_000_000,
            seed: 2,
            epsilon,
            colour_channels: 3,
            cached_levels: levels,
            dense: DenseCounts::Exact,
            ..CountTreeConfig::default()
        };
        let tree =
            CountTree::new(config, glint_tests::counts::beckmann_density(0.15, 0.25)).unwrap();
        let mut scratch = QueryScratch::new();
        footprints
            .iter()
            .map(|f| tree.query(f, &conic, &mut scratch))
            .collect::<Vec<_>>()
    };
    for epsilon in [0.0, 0.1] {
        let reference = answers(0, epsilon);
        for levels in [1, 6, 8] {
            assert_eq!(
                answers(levels, epsilon),
                reference,
                "{levels} cached levels, ε = {epsilon}"
            );
        }
    }
    let too_deep = CountTreeConfig {
        cached_levels: 9,
        dense: DenseCounts::Exact,
        ..CountTreeConfig::default()
    };
    assert!(CountTree::new(too_deep, glint_tests::counts::beckmann_density(0.1, 0.1)).is_err());
}

/// The tree's own expected count N·A·∫p (its quadrature) agrees with the independent Monte
/// Carlo integral over reflected directions within 1% plus 5 standard errors.
#[test]
fn expected_count_matches_independent_integral() {
    let mut scratch = QueryScratch::new();
    for (alpha, gamma_deg, theta) in [(0.2, 5.0, 0.3), (0.05, 1.0, 0.8), (0.5, 30.0, 1.3)] {
        let tree = beckmann_tree(alpha, 1_000_000, 1, 0.1, MultinomialMode::Exact);
        let conic = SphericalConic::new(
            direction(theta, 0.1),
            direction(0.9 * theta, 0.1 + PI),
            f64::to_radians(gamma_deg),
        )
        .unwrap();
        let footprint = square(DVec2::new(0.2, 0.3), 0.01);
        let expected = tree.expected_count(&footprint, &conic, &mut scratch);
        let density = glint_tests::counts::beckmann_density(alpha, alpha);
        let (integral, error) =
            conic_integral_by_sampling(density.as_ref(), &conic, 400_000, &mut SplitMix64::new(3));
        let reference = 1_000_000.0 * footprint.area() * integral;
        let tolerance = 0.01 * reference + 5.0 * 1_000_000.0 * footprint.area() * error;
        assert!(
            (expected - reference).abs() < tolerance,
            "α {alpha}: {expected} vs {reference} ± {tolerance}"
        );
    }
}

/// With ε > 0, a footprint over many tiles costs no more than one over a few: every tile holds
/// the same particles, so whole tiles count in aggregate (the expected total sets Eq. 10's
/// scale), and the answer is that expectation to within ε.
#[test]
fn many_tiles_cost_no_more_than_a_few() {
    let tree = beckmann_tree(0.1, 1_000_000_000, 1, 0.1, MultinomialMode::Exact);
    let conic = near_specular_conic(1.0);
    let mut scratch = QueryScratch::new();
    let nodes = |side: f64, scratch: &mut QueryScratch| {
        let f = square(DVec2::new(0.3, 0.6), side);
        let r = tree.query(&f, &conic, scratch);
        let expected = tree.expected_count(&f, &conic, scratch);
        assert!(
            (r.count - expected).abs() <= 0.1 * expected,
            "side {side}: {} vs {expected}",
            r.count
        );
        r.nodes_visited
    };
    let few = nodes(2.0, &mut scratch);
    for side in [10.0, 100.0, 1000.0] {
        assert!(nodes(side, &mut scratch) <= few.max(16), "side {side}");
    }
}

/// Footprints over many tiles (`ManyTiles`): beyond the limits the count is the area times one
/// tile's count, at the cost of one tile's query, and close to the exact count of the
/// particles' multiplicities. Measured here just above each default limit, exact (ε = 0)
/// against averaged, on a material whose tile holds 17 318 particles in the conic: relative
/// errors 1.6e-6 (the square) and 4.7e-5 (the strip).
#[test]
fn many_tile_footprints_are_averaged_within_their_measured_error() {
    use glint_tree::{CountTreeConfig, ManyTiles};
    let config = CountTreeConfig {
        particles: 1_000_000,
        epsilon: 0.0,
        dense: DenseCounts::Exact,
        ..CountTreeConfig::default()
    };
    let density = glint_tests::counts::beckmann_density(0.2, 0.2);
    let averaged = CountTree::new(config, density.clone()).unwrap();
    let exact = CountTree::new(
        CountTreeConfig {
            many_tiles: ManyTiles::EXACT,
            // The reference must not be truncated: the work budget gives footprints spanning
            // T tiles budget·4/T nodes, and these span hundreds.
            node_budget: u32::MAX,
            ..config
        },
        density,
    )
    .unwrap();
    let conic = near_specular_conic(3.0);
    let mut scratch = QueryScratch::new();
    let tile = averaged.query(&square(DVec2::splat(0.5), 1.0), &conic, &mut scratch);
    assert!(tile.count > 1000.0, "{}", tile.count);
    let (angle_cos, angle_sin) = (0.3f64.cos(), 0.3f64.sin());
    let cases = [
        // A rotated 17.3 × 17.1 square: area 296 tiles, above 256.
        (
            DVec2::new(17.3 * angle_cos, 17.3 * angle_sin),
            DVec2::new(-17.1 * angle_sin, 17.1 * angle_cos),
            1e-4,
        ),
        // A strip 4100 tiles long and 0.02 wide at an irrational slope: 82 tiles of area,
        // spanning more than 4096.
        (
            DVec2::new(4100.0, 4100.0 / 7f64.sqrt() / 100.0),
            DVec2::new(0.0, 0.02),
            0.02,
        ),
    ];
    for (dx, dy, tolerance) in cases {
        let footprint = Footprint::new(DVec2::new(0.37, 0.61), dx, dy).unwrap();
        assert!(ManyTiles::default().averages(&footprint));
        let a = averaged.query(&footprint, &conic, &mut scratch);
        let e = exact.query(&footprint, &conic, &mut scratch);
        assert!(a.periodic_average && !e.periodic_average);
        assert_eq!(a.count, tile.count * footprint.area());
        assert_eq!(a.nodes_visited, tile.nodes_visited);
        let error = (a.count - e.count).abs() / e.count;
        assert!(
            error < tolerance,
            "{dx} {dy}: averaged {} exact {} ({error:.2e})",
            a.count,
            e.count
        );
    }
    // Below both limits nothing changes.
    let small = Footprint::new(
        DVec2::new(0.37, 0.61),
        DVec2::new(3.2, 0.4),
        DVec2::new(0.1, 2.1),
    )
    .unwrap();
    let a = averaged.query(&small, &conic, &mut scratch);
    assert!(!a.periodic_average);
    assert_eq!(a.count, exact.query(&small, &conic, &mut scratch).count);
}
