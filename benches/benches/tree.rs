//! Per-query costs of glint-tree at the paper's Table 1 settings (ε = 0.1, pixel footprints,
//! directions near the highlight), plus TEA, the multinomial split and the spatial split.

use criterion::{Criterion, criterion_group, criterion_main};
use std::sync::Arc;

use glint_benches::{TABLE1, production_density_values, table1_mapped_workload, table1_workload};
use glint_tree::sampling::{MultinomialMode, multinomial4, multinomial4_equal_by_bits};
use glint_tree::tea::{DEFAULT_ROUNDS, TeaRng, encrypt, encrypt_x4};
use glint_tree::{
    DensityMap, Footprint, LevelTexels, MapFilter, MultinomialMode as Mode, QueryScratch,
};
use std::hint::black_box;

const POOL: usize = 1024;

fn tree(c: &mut Criterion) {
    let mut group = c.benchmark_group("tree");
    for setting in &TABLE1 {
        let (tree, queries) = table1_workload(setting, POOL, 1);
        let mut scratch = QueryScratch::new();
        let mut i = 0;
        group.bench_function(format!("query_{}", setting.name), |b| {
            b.iter(|| {
                i = (i + 1) % POOL;
                let (footprint, conic) = &queries[i];
                tree.query(black_box(footprint), conic, &mut scratch)
            })
        });
    }
    // Under production-size density maps (`production_density_values`), the sphere lights'
    // setting: the query cost against `query_spheres_…` above, and a map's build time.
    let side = 1024;
    let values = production_density_values(side);
    group.bench_function("density_map_build_1024", |b| {
        b.iter(|| DensityMap::new(side, side, black_box(&values)).expect("a valid map"))
    });
    // A roughness level's map: the production map times a hat of width 2/7 across x (one of
    // eight levels over a gradient), 0 over most tiles, so its tables are tiled. Its twin
    // with 10⁻⁹ instead of 0 (no empty tile: tables whole) has nearly the same particles,
    // so the two queries' ratio is the tiled tables' cost.
    let level_values = |side: usize, floor: f64| {
        let mut values = production_density_values(side);
        for (k, value) in values.iter_mut().enumerate() {
            let x = ((k % side) as f64 + 0.5) / side as f64;
            *value = (*value * (1.0 - 7.0 * (x - 0.5).abs()).max(0.0)).max(floor);
        }
        values
    };
    let values = level_values(side, 0.0);
    group.bench_function("density_map_build_1024_level", |b| {
        b.iter(|| DensityMap::new(side, side, black_box(&values)).expect("a valid map"))
    });
    // A level of a roughness map whose α changes at every texel: the production map times
    // each texel's weight on the level (0 on three texels in four, else uniform), stored as
    // its own map (whole: every tile holds a non-zero value) and blocked over a family of
    // texels (`LevelTexels`), the same values: the two queries' ratio is the blocked tables'
    // cost, as `_level_blocked` against `_level` is over the gradient's level; the
    // `_bilinear` pairs are the same levels reconstructed bilinear.
    let noise_values = |side: usize| {
        let mut rng = glint_tests::SplitMix64::new(7);
        let mut values = production_density_values(side);
        for value in &mut values {
            let [keep, weight] = rng.uniforms::<2>();
            *value *= if keep < 0.25 { weight } else { 0.0 };
        }
        values
    };
    let blocked = |side: usize, values: &[f64], filter| {
        let family = LevelTexels::new(side, side, 1, |k| (0, [values[k], 0.0])).expect("valid");
        DensityMap::roughness_level(&Arc::new(family), 0, filter).expect("not empty")
    };
    for (side, filter, level, suffix) in [
        (1024, MapFilter::Nearest, None, ""),
        (1024, MapFilter::Bilinear, None, "_bilinear"),
        (8192, MapFilter::Nearest, None, ""),
        (1024, MapFilter::Nearest, Some(0.0), "_level"),
        (1024, MapFilter::Nearest, Some(1e-9), "_level_whole"),
        (1024, MapFilter::Nearest, Some(0.0), "_level_blocked"),
        (1024, MapFilter::Nearest, Some(-1.0), "_noise_level"),
        (1024, MapFilter::Nearest, Some(-1.0), "_noise_level_blocked"),
        (1024, MapFilter::Bilinear, Some(0.0), "_level_bilinear"),
        (
            1024,
            MapFilter::Bilinear,
            Some(0.0),
            "_level_bilinear_blocked",
        ),
        (
            1024,
            MapFilter::Bilinear,
            Some(-1.0),
            "_noise_level_bilinear",
        ),
        (
            1024,
            MapFilter::Bilinear,
            Some(-1.0),
            "_noise_level_bilinear_blocked",
        ),
    ] {
        let values = match level {
            Some(-1.0) => noise_values(side),
            Some(floor) => level_values(side, floor),
            None => production_density_values(side),
        };
        let map = if suffix.ends_with("_blocked") {
            blocked(side, &values, filter)
        } else {
            DensityMap::with_filter(side, side, &values, filter).expect("valid")
        };
        let (tree, queries) = table1_mapped_workload(&TABLE1[0], POOL, 1, Arc::new(map));
        let mut scratch = QueryScratch::new();
        let mut i = 0;
        group.bench_function(
            format!("query_{}_map_{side}{suffix}", TABLE1[0].name),
            |b| {
                b.iter(|| {
                    i = (i + 1) % POOL;
                    let (footprint, conic) = &queries[i];
                    tree.query(black_box(footprint), conic, &mut scratch)
                })
            },
        );
    }
    // ∫d over a footprint (what tint means and Eq. 10's scale ask a map): rotated
    // parallelograms 8 to 200 texels across on the 1024² production map, wrapped at random
    // positions.
    let values = production_density_values(side);
    for filter in [MapFilter::Nearest, MapFilter::Bilinear] {
        let map = DensityMap::with_filter(side, side, &values, filter).expect("valid");
        let mut rng = glint_tests::SplitMix64::new(31);
        let footprints: Vec<Footprint> = (0..POOL)
            .map(|_| {
                let [u, v, width, turn] = rng.uniforms::<4>();
                let width = (8.0 + 192.0 * width) / side as f64;
                let (sin, cos) = (std::f64::consts::FRAC_PI_2 * turn).sin_cos();
                let dx = width * glam::DVec2::new(cos, sin);
                let dy = 0.7 * width * glam::DVec2::new(-sin, cos);
                Footprint::new(glam::DVec2::new(u, v), dx, dy).expect("finite")
            })
            .collect();
        let name = match filter {
            MapFilter::Nearest => "density_map_mass_in_1024",
            MapFilter::Bilinear => "density_map_mass_in_1024_bilinear",
        };
        let mut i = 0;
        group.bench_function(name, |b| {
            b.iter(|| {
                i = (i + 1) % POOL;
                map.mass_in(black_box(&footprints[i]))
            })
        });
    }
    let key = [1, 2, 3, 4];
    let mut counter = 0u32;
    group.bench_function("tea_scalar_8_rounds", |b| {
        b.iter(|| {
            counter = counter.wrapping_add(1);
            encrypt(black_box(counter), 0, key, DEFAULT_ROUNDS)
        })
    });
    group.bench_function("tea_x4_8_rounds", |b| {
        b.iter(|| {
            counter = counter.wrapping_add(4);
            let v = wide::u32x4::splat(black_box(counter));
            encrypt_x4(v, wide::u32x4::ZERO, key, DEFAULT_ROUNDS)
        })
    });
    for (name, mode) in [("exact", Mode::Exact), ("normal", Mode::Normal)] {
        for n in [5u64, 1000, 1_000_000_000] {
            let mut k = 0u32;
            group.bench_function(format!("multinomial_{name}_n{n}"), |b| {
                b.iter(|| {
                    k = k.wrapping_add(1);
                    let mut rng = TeaRng::new([k, 2, 3, 4], 0, DEFAULT_ROUNDS);
                    multinomial4(
                        black_box(n),
                        [0.1, 0.2, 0.3, 0.4],
                        mode as MultinomialMode,
                        &mut rng,
                    )
                })
            });
        }
    }
    // The spatial split: two bits per particle up to EQUAL_SPLIT_BY_BITS, against the
    // conditional binomials it replaces there.
    for n in [128u64, 384, 512] {
        let mut k = 0u32;
        group.bench_function(format!("equal_split_bits_n{n}"), |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                let mut rng = TeaRng::new([k, 2, 3, 4], 0, DEFAULT_ROUNDS);
                multinomial4_equal_by_bits(black_box(n), &mut rng)
            })
        });
        group.bench_function(format!("equal_split_binomials_n{n}"), |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                let mut rng = TeaRng::new([k, 2, 3, 4], 0, DEFAULT_ROUNDS);
                multinomial4(black_box(n), [0.25; 4], MultinomialMode::Exact, &mut rng)
            })
        });
    }
    group.finish();
}

criterion_group!(benches, tree);
criterion_main!(benches);
