//! glint-tree under a density map (issue 31): the particle density N·d(x) over the square.
//! Counts are binomial with mean N·∫_A d·∫p on checkerboard and gradient maps, over footprints
//! straddling texel edges and tiles; texels where d = 0 hold nothing; exact counts stay
//! additive; a map of ones is no map, bit for bit; overlapping queries agree in any order.

use std::sync::Arc;

use glam::DVec2;
use glint_tests::SplitMix64;
use glint_tests::counts::{beckmann_density, queries_in_threads, whole_and_halves};
use glint_tests::maps::{
    count_cases, disc, filtered_square_mass, mapped_count_sums, square_mass, test_conic, test_maps,
};
use glint_tree::{
    CountTree, CountTreeConfig, DenseCounts, DensityMap, Footprint, MapFilter, QueryScratch,
};

fn tree(particles: u64, epsilon: f64, seed: u64, map: Option<DensityMap>) -> CountTree {
    let config = CountTreeConfig {
        particles,
        seed,
        epsilon,
        dense: DenseCounts::Exact,
        ..CountTreeConfig::default()
    };
    CountTree::with_density_map(config, beckmann_density(0.2, 0.2), map.map(Arc::new)).unwrap()
}

/// Over 2000 footprints of side 1.3 texels at random positions (straddling texel edges and,
/// near the square's edges, tiles), on 20 particle sets (seeds) of 100 footprints each, Σ
/// counts matches Σ N·∫_A d·∫p within 5 standard errors, separately over the footprints of
/// mean density above and below ½ (so particles in the wrong texels show): the binomial
/// spread, plus each set's own fluctuation over the footprints it shares
/// (`count_moment_errors`' realization term), plus the error of the independent Monte Carlo
/// ∫p. With ε = 0, Σ (count − mean)² also matches Σ mean(1 − q), the binomial variance.
/// The maps are fine against the particles' leaves in the sparse case (10⁴ particles on
/// 64 × 64 texels: leaves span 4 × 4 texels and place their particles by the map).
#[test]
fn counts_follow_the_map_binomially() {
    let cases = count_cases();
    for (name, w, h, values, particles, gamma) in cases {
        for epsilon in [0.0, 0.1] {
            let sums = mapped_count_sums(
                (w, h, &values),
                MapFilter::Nearest,
                particles,
                gamma,
                epsilon,
                (20, 100),
            );
            for (half, sums) in ["dense", "light"].iter().zip(sums) {
                if sums.means == 0.0 {
                    continue;
                }
                assert!(
                    sums.z().abs() < 5.0,
                    "{name}, ε {epsilon}, {half} footprints: Σ counts {} against Σ N·∫d·∫p {} ± {}",
                    sums.counts,
                    sums.means,
                    sums.error
                );
                if epsilon == 0.0 {
                    assert!(
                        (sums.dispersion() - 1.0).abs() < 0.25,
                        "{name}, {half}: Σ(count − mean)² / Σ mean(1 − q) = {}",
                        sums.dispersion()
                    );
                }
            }
        }
    }
}

/// Under the bilinear reconstruction of the disc (a mask) and the sparse checkerboard (leaves
/// over many texels), counts are binomial with mean N·∫_A d·∫p for the reconstructed d (∫_A d
/// from the texels' tents, independently of the map's tables), and footprints where the
/// reconstruction is 0 (all four centres around them 0, inside the disc's zeros) hold
/// nothing. (`cargo xtask validate` runs every count case under both filters.)
#[test]
fn counts_follow_the_bilinear_map_binomially() {
    let cases = count_cases()
        .into_iter()
        .filter(|case| ["disc", "sparse checkerboard"].contains(&case.0));
    for (name, w, h, values, particles, gamma) in cases {
        let sums = mapped_count_sums(
            (w, h, &values),
            MapFilter::Bilinear,
            particles,
            gamma,
            0.0,
            (20, 100),
        );
        for (half, sums) in ["dense", "light"].iter().zip(sums) {
            if sums.means == 0.0 {
                continue;
            }
            assert!(
                sums.z().abs() < 5.0,
                "{name}, bilinear, {half} footprints: Σ counts {} against Σ N·∫d·∫p {} ± {}",
                sums.counts,
                sums.means,
                sums.error
            );
            assert!(
                (sums.dispersion() - 1.0).abs() < 0.25,
                "{name}, bilinear, {half}: Σ(count − mean)² / Σ mean(1 − q) = {}",
                sums.dispersion()
            );
            assert_eq!(
                sums.masked_count, 0.0,
                "{name}, bilinear: particles where d = 0"
            );
        }
    }
}

/// The independent bilinear mass of a footprint agrees with the map's own (tables, tents and
/// clipping) on squares across texel edges and tiles: the reference of the count check above
/// is right.
#[test]
fn the_bilinear_reference_mass_is_the_maps_own() {
    let mut rng = SplitMix64::new(3);
    for (name, w, h, values) in test_maps() {
        let map = DensityMap::with_filter(w, h, &values, MapFilter::Bilinear).unwrap();
        for _ in 0..50 {
            let centre = DVec2::new(rng.uniform(), rng.uniform());
            let side = (0.2 + 2.0 * rng.uniform()) / w.max(h) as f64;
            let footprint =
                Footprint::new(centre, DVec2::new(side, 0.0), DVec2::new(0.0, side)).unwrap();
            let reference =
                filtered_square_mass(&values, (w, h), MapFilter::Bilinear, centre, side);
            let own = map.mass_in(&footprint);
            assert!(
                (own - reference).abs() < 1e-9 * side * side + 1e-15,
                "{name} at {centre}, side {side}: {own} against {reference}"
            );
        }
    }
}

/// Texels where d = 0 hold no particle: every footprint inside the disc map's zeros counts 0
/// even with a cone that takes nearly every normal, while the ones hold N·∫d of them; also
/// with 3000 particles on 64 × 64 texels, whose leaves straddle the disc's edge.
#[test]
fn masked_texels_hold_no_particle() {
    masked_texels_hold_none_of(1_000_000, 16, 16, &disc(16));
    masked_texels_hold_none_of(3000, 64, 64, &disc(64));
}

/// The disc map of `w` × `h` texels with `particles` particles.
fn masked_texels_hold_none_of(particles: u64, w: usize, h: usize, values: &[f64]) {
    let map = DensityMap::new(w, h, values).unwrap();
    let tree = tree(particles, 0.0, 5, Some(map.clone()));
    let wide = test_conic(170.0);
    let mut scratch = QueryScratch::new();
    let mut rng = SplitMix64::new(8);
    let mut zero_footprints = 0;
    for _ in 0..3000 {
        let centre = DVec2::new(rng.uniform(), rng.uniform());
        let side = 0.01 + 0.05 * rng.uniform();
        if square_mass(values, (w, h), centre, side) > 0.0 {
            continue;
        }
        zero_footprints += 1;
        let footprint =
            Footprint::new(centre, DVec2::new(side, 0.0), DVec2::new(0.0, side)).unwrap();
        let result = tree.query(&footprint, &wide, &mut scratch);
        assert_eq!(result.count, 0.0, "{centre} side {side}: {result:?}");
    }
    assert!(
        zero_footprints > 300,
        "{zero_footprints} footprints in the mask"
    );
    let tile = Footprint::new(DVec2::splat(0.5), DVec2::X, DVec2::Y).unwrap();
    let all = tree.query(&tile, &wide, &mut scratch).count;
    let expected = (particles as f64 * map.mean()).round();
    assert!(
        all <= expected && all > 0.95 * expected,
        "{all} of {expected}"
    );
}

/// ε = 0 under every map: a footprint split in two along a line at any slope counts exactly
/// what the whole does.
#[test]
fn exact_counts_under_a_map_are_additive() {
    let conic = test_conic(5.0);
    for (name, w, h, values) in test_maps() {
        let tree = tree(
            50_000_000,
            0.0,
            9,
            Some(DensityMap::new(w, h, &values).unwrap()),
        );
        let mut scratch = QueryScratch::new();
        let mut rng = SplitMix64::new(21);
        let mut found = 0.0;
        for _ in 0..60 {
            let uv = DVec2::new(rng.uniform(), rng.uniform());
            let dx = DVec2::new(0.01 + 0.05 * rng.uniform(), 0.01 * rng.uniform());
            let dy = DVec2::new(-0.01 * rng.uniform(), 0.01 + 0.05 * rng.uniform());
            let (total, parts) = whole_and_halves(&tree, &conic, (uv, dx, dy), &mut scratch);
            assert_eq!(total.fract(), 0.0);
            assert_eq!(total, parts, "{name}: uv {uv}");
            found += total;
        }
        assert!(found > 0.0, "{name}: the queries find particles");
    }
}

/// A map of ones (of any size) is no map: the same counts, D̂, nodes visited, in exact and
/// approximate evaluation, coloured or not, over small footprints, footprints across tiles and
/// whole tiles. A constant map of c < 1 is the uniform material of round(N·c) particles.
#[test]
fn a_map_of_ones_is_no_map_bit_for_bit() {
    let mut rng = SplitMix64::new(2);
    for (epsilon, channels) in [(0.0, 0), (0.1, 0), (0.1, 3)] {
        let config = CountTreeConfig {
            particles: 300_000,
            seed: 4,
            epsilon,
            colour_channels: channels,
            dense: DenseCounts::Exact,
            ..CountTreeConfig::default()
        };
        let density = beckmann_density(0.3, 0.3);
        let plain = CountTree::new(config, density.clone()).unwrap();
        let ones = DensityMap::new(5, 3, &[1.0; 15]).unwrap();
        let mapped = CountTree::with_density_map(config, density, Some(Arc::new(ones))).unwrap();
        let (mut a, mut b) = (QueryScratch::new(), QueryScratch::new());
        for k in 0..300 {
            let side = [0.003, 0.05, 1.3][k % 3];
            let uv = DVec2::new(rng.uniform(), rng.uniform());
            let footprint = Footprint::new(
                uv,
                DVec2::new(side, 0.1 * side),
                DVec2::new(-0.2 * side, side),
            )
            .unwrap();
            let conic = test_conic(2.0 + 10.0 * rng.uniform());
            assert_eq!(
                plain.query(&footprint, &conic, &mut a),
                mapped.query(&footprint, &conic, &mut b),
                "ε {epsilon}, {channels} channels, {footprint:?}"
            );
        }
    }
}

/// Under a map, one query's particles are every other query's: overlapping footprints queried
/// through one scratch in any order, and through fresh scratches, give the same answers bit
/// for bit, and so do four threads.
#[test]
fn mapped_queries_are_the_same_in_any_order_and_thread() {
    let (_, w, h, values) = test_maps().remove(1);
    let tree = tree(
        10_000_000,
        0.1,
        6,
        Some(DensityMap::new(w, h, &values).unwrap()),
    );
    let conic = test_conic(3.0);
    let mut rng = SplitMix64::new(12);
    let footprints: Vec<Footprint> = (0..400)
        .map(|_| {
            let uv = DVec2::new(rng.uniform(), rng.uniform());
            Footprint::new(uv, DVec2::new(0.02, 0.003), DVec2::new(0.001, 0.02)).unwrap()
        })
        .collect();
    let mut scratch = QueryScratch::new();
    let forward: Vec<_> = footprints
        .iter()
        .map(|f| tree.query(f, &conic, &mut scratch))
        .collect();
    let fresh: Vec<_> = footprints
        .iter()
        .rev()
        .map(|f| tree.query(f, &conic, &mut QueryScratch::new()))
        .collect();
    let threaded = queries_in_threads(&tree, &conic, &footprints, 4);
    for (i, result) in forward.iter().enumerate() {
        assert_eq!(*result, fresh[footprints.len() - 1 - i]);
        assert_eq!(*result, threaded[i]);
    }
    assert!(forward.iter().any(|r| r.count > 0.0));
}
