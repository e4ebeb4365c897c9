//! Property tests of materials with maps (issue 42): over random map shapes, texel values
//! (in range, at the edges, out of range, not finite), roughness levels and tint channels, a
//! material either builds or is refused with an error naming the map or parameter, never a
//! panic; a built one keeps its memory count, splits each texel's flakes among its roughness
//! levels exactly, answers in colour exactly when a tint is coloured, and gives finite,
//! non-negative answers.

use std::sync::Arc;

use glam::{DVec2, DVec3};
use glint_brdf::{
    BrdfError, DensityMap, DiscreteBrdf, DistributionKind, Footprint, GlintParameters, MapBytes,
    Microfacet, QueryScratch, RoughnessMap, TintMap,
};
use proptest::prelude::*;

/// A density or tint value in [0, 1]: its edges, values near the fixed-point step, any other.
fn texel() -> impl Strategy<Value = f64> {
    prop_oneof![
        6 => 0.0..=1.0f64,
        1 => Just(0.0),
        1 => Just(1.0),
        1 => prop_oneof![Just(1e-10), Just(2f64.powi(-33)), Just(2f64.powi(-32))],
    ]
}

/// A roughness texel: a few repeated values (exact levels) or a spread (interpolated ones),
/// with the range's edges.
fn roughness_texel() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => prop_oneof![Just(0.05), Just(0.2), Just(0.6)],
        4 => 1e-4..=1.0f64,
        1 => prop_oneof![Just(1e-4), Just(f64::from_bits(1e-4f64.to_bits() + 1)), Just(1.0)],
    ]
}

/// A value no map takes (out of every map's range, or not finite).
fn bad_value() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(-1e-300),
        Just(1.0 + f64::EPSILON),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(7.0),
    ]
}

/// Maps of one size: density, roughness and tint texels, any of them left out.
#[derive(Clone, Debug)]
struct Maps {
    width: usize,
    height: usize,
    density: Option<Vec<f64>>,
    alpha: Option<Vec<f64>>,
    tint: Option<Vec<[f64; 3]>>,
    levels: usize,
}

fn maps() -> impl Strategy<Value = Maps> {
    (1usize..=9, 1usize..=9)
        .prop_flat_map(|(width, height)| {
            let n = width * height;
            (
                Just((width, height)),
                proptest::option::of(proptest::collection::vec(texel(), n)),
                proptest::option::of(proptest::collection::vec(roughness_texel(), n)),
                proptest::option::of(proptest::collection::vec(
                    prop_oneof![
                        3 => [texel(), texel(), texel()],
                        1 => texel().prop_map(|t| [t; 3]),
                    ],
                    n,
                )),
                prop_oneof![8 => 1usize..=9, 1 => Just(0usize), 1 => Just(64usize), 1 => Just(65usize)],
                // One map in five gets one bad value: (which map, which texel, the value).
                proptest::option::weighted(0.2, (0usize..4, 0..n, bad_value())),
            )
        })
        .prop_map(|((width, height), density, alpha, tint, levels, bad)| {
            let mut maps = Maps {
                width,
                height,
                density,
                alpha,
                tint,
                levels,
            };
            if let Some((map, k, value)) = bad {
                match map {
                    0 => maps.density.get_or_insert_with(|| vec![1.0; width * height])[k] = value,
                    1 => maps.alpha.get_or_insert_with(|| vec![0.2; width * height])[k] = value,
                    _ => maps.tint.get_or_insert_with(|| vec![[1.0; 3]; width * height])[k]
                        [map - 1] = value,
                }
            }
            maps
        })
}

/// The material of `maps`, or the first error met building it, its map's name checked.
fn build(maps: &Maps) -> Result<DiscreteBrdf, BrdfError> {
    let distribution = Microfacet::new(DistributionKind::Beckmann, 0.2, 0.2)?;
    let mut parameters = GlintParameters::new(distribution);
    parameters.particles = 1 << 30;
    parameters.gamma_radians = 3f64.to_radians();
    parameters.roughness_levels = maps.levels;
    let (w, h) = (maps.width, maps.height);
    if let Some(values) = &maps.density {
        parameters.density_map = Some(Arc::new(DensityMap::new(w, h, values)?));
    }
    if let Some(values) = &maps.alpha {
        parameters.alpha_map = Some(Arc::new(RoughnessMap::new(w, h, values)?));
    }
    if let Some(values) = &maps.tint {
        parameters.tint_map = Some(Arc::new(TintMap::new(w, h, values)?));
    }
    DiscreteBrdf::new(parameters)
}

/// The parameter an error must name.
fn named(error: &BrdfError) -> &'static str {
    match error {
        BrdfError::DensityMap(_) => "density_map",
        BrdfError::InvalidMapTexel { map, .. } | BrdfError::InvalidMap { map, .. } => map,
        BrdfError::InvalidRoughnessLevels { .. } => "roughness levels",
        BrdfError::TooFewRoughnessLevels { .. } | BrdfError::MapsTooLarge { .. } => {
            "roughness_levels"
        }
        other => panic!("unexpected error for maps: {other}"),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(160))]

    #[test]
    fn materials_with_maps_build_or_name_their_problem(maps in maps()) {
        let brdf = match build(&maps) {
            Ok(brdf) => brdf,
            Err(error) => {
                let message = error.to_string();
                prop_assert!(message.contains(named(&error)), "{message}");
                return Ok(());
            }
        };
        // The memory count before building is what the built material holds (an upper
        // bound where a level came out empty).
        let counted = MapBytes::of(brdf.parameters()).unwrap();
        prop_assert!(brdf.map_bytes() <= counted.total());
        // The levels split each texel's flakes: Σ_k d_k = d, to the maps' fixed point.
        if let Some(alpha) = &brdf.parameters().alpha_map {
            let (w, h) = alpha.size();
            let levels: Vec<_> = brdf.level_trees().collect();
            prop_assert!(levels.len() <= maps.levels);
            for k in 0..w * h {
                let (column, row) = (k % w, k / w);
                let d = brdf.parameters().density_map.as_ref().map_or(1.0, |m| m.texel(column, row));
                let sum: f64 = levels
                    .iter()
                    .map(|(_, tree)| tree.density_map().unwrap().texel(column, row))
                    .sum();
                prop_assert!((sum - d).abs() <= levels.len() as f64 * 2f64.powi(-32), "{sum} {d}");
                // Each level's α lies within the map's range.
                let range = alpha_range(alpha);
                for (level_alpha, _) in &levels {
                    let a = level_alpha.unwrap();
                    prop_assert!(range.0 <= a && a <= range.1, "{a} outside {range:?}");
                }
            }
        }
        // One number per answer exactly when nothing colours the material.
        let coloured = maps.tint.as_ref().is_some_and(|t| t.iter().any(|c| c[0] != c[1] || c[1] != c[2]));
        prop_assert_eq!(brdf.is_gray(), !coloured);
        // Finite, non-negative answers at and around the texels, with and without footprints,
        // and averaged over the square (what footprints too large to query shade).
        let mut scratch = QueryScratch::new();
        let wi = DVec3::new(0.3, 0.1, 0.95).normalize();
        for (i, wo) in [DVec3::new(-0.3, -0.1, 0.95), DVec3::new(0.0, 0.0, 1.0)].into_iter().enumerate() {
            let wo = wo.normalize();
            for uv in [DVec2::new(0.1, 0.9), DVec2::new(0.55, 0.31), DVec2::new(-3.2, 7.9)] {
                let side = [1e-3, 0.4, 3.0][i + usize::from(uv.x < 0.0)];
                let footprint = Footprint::new(uv, DVec2::new(side, 0.0), DVec2::new(0.0, side)).unwrap();
                let f = glint_brdf::Bxdf::eval(&brdf.at(&footprint, &mut scratch), wi, wo);
                let smooth = brdf.smooth_at(wi, wo, uv);
                for value in [f, smooth, brdf.smooth_mean(wi, wo)] {
                    prop_assert!(value.is_finite() && value.min_element() >= 0.0, "{value}");
                }
            }
        }
    }
}

/// The least and greatest α of a roughness map.
fn alpha_range(alpha: &RoughnessMap) -> (f64, f64) {
    let (w, h) = alpha.size();
    (0..w * h)
        .map(|k| alpha.texel(k % w, k / w))
        .fold((f64::INFINITY, 0.0), |(lo, hi), a| (lo.min(a), hi.max(a)))
}
