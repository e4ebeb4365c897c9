//! glint-brdf's maps (issue 31): a roughness map of few values is exactly its levels as
//! separate materials; a dense mapped material converges to its smooth limit at the
//! footprint (the smooth model weighted by the maps); the sampler's pdf is the mixture it
//! samples (chi-square); a tint scales f̂ by its mean over the footprint, coloured flakes
//! included; maps of ones change nothing; bad maps are refused naming the texel.

use std::sync::Arc;

use glam::{DVec2, DVec3};
use glint_brdf::discrete::layer_seed;
use glint_brdf::{
    BrdfError, Bxdf, DensityMap, DiscreteBrdf, DistributionKind, Footprint, GlintParameters,
    Microfacet, QueryScratch, RoughnessMap, TintMap,
};
use glint_tests::SplitMix64;
use glint_tests::geometry::direction;
use glint_tests::sampling::chi_square_directions;

fn beckmann(alpha: f64) -> Microfacet {
    Microfacet::new(DistributionKind::Beckmann, alpha, alpha).unwrap()
}

/// A 6 × 4 map alternating α = 0.05 and 0.3 in vertical stripes two texels wide, and a
/// density falling from 1 to 0.25 down the rows.
fn striped_maps() -> (Vec<f64>, Vec<f64>) {
    let alphas = (0..24)
        .map(|k| if (k % 6) / 2 % 2 == 0 { 0.05 } else { 0.3 })
        .collect();
    let densities = (0..24).map(|k| 1.0 - 0.25 * (k / 6) as f64).collect();
    (alphas, densities)
}

fn footprints(count: usize, side: f64, seed: u64) -> Vec<Footprint> {
    let mut rng = SplitMix64::new(seed);
    (0..count)
        .map(|_| {
            let uv = DVec2::new(rng.uniform(), rng.uniform());
            Footprint::new(
                uv,
                DVec2::new(side, 0.2 * side),
                DVec2::new(-0.1 * side, side),
            )
            .unwrap()
        })
        .collect()
}

fn directions() -> Vec<(DVec3, DVec3)> {
    vec![
        (
            direction(0.3, 0.1),
            direction(0.28, 0.1 + std::f64::consts::PI),
        ),
        (direction(0.6, 1.0), direction(0.5, 4.0)),
        (direction(1.2, 2.0), direction(1.1, 5.2)),
    ]
}

/// Where the roughness map takes at most K values the material is exactly its levels: the
/// material with both maps answers, count for count and f̂ bit for bit, as the sum of two
/// separate materials of α = 0.05 and α = 0.3 whose density maps are d·[α(x) = α_k], with the
/// levels' seeds.
#[test]
fn a_roughness_map_of_two_values_is_two_materials() {
    let (alphas, densities) = striped_maps();
    let mut parameters = GlintParameters::new(beckmann(0.5));
    parameters.particles = 30_000_000;
    parameters.epsilon = 0.0;
    parameters.seed = 11;
    parameters.gamma_radians = 4f64.to_radians();
    parameters.alpha_map = Some(Arc::new(RoughnessMap::new(6, 4, &alphas).unwrap()));
    parameters.density_map = Some(Arc::new(DensityMap::new(6, 4, &densities).unwrap()));
    let mapped = DiscreteBrdf::new(parameters.clone()).unwrap();
    let separate: Vec<DiscreteBrdf> = [0.05, 0.3]
        .iter()
        .enumerate()
        .map(|(k, &alpha)| {
            let mask: Vec<f64> = alphas
                .iter()
                .zip(&densities)
                .map(|(&a, &d)| if a == alpha { d } else { 0.0 })
                .collect();
            let mut level = GlintParameters::new(beckmann(alpha));
            level.particles = parameters.particles;
            level.epsilon = 0.0;
            level.seed = layer_seed(parameters.seed, k);
            level.gamma_radians = parameters.gamma_radians;
            level.density_map = Some(Arc::new(DensityMap::new(6, 4, &mask).unwrap()));
            DiscreteBrdf::new(level).unwrap()
        })
        .collect();
    let mut scratch = QueryScratch::new();
    let mut found = 0.0;
    for footprint in footprints(200, 0.08, 3) {
        for (wi, wo) in directions() {
            let whole = mapped.at(&footprint, &mut scratch).evaluate(wi, wo);
            let parts: Vec<_> = separate
                .iter()
                .map(|m| m.at(&footprint, &mut scratch).evaluate(wi, wo))
                .collect();
            assert_eq!(whole.count, parts[0].count + parts[1].count);
            assert_eq!(
                whole.f_hat,
                parts[0].f_hat + parts[1].f_hat,
                "{footprint:?}"
            );
            found += whole.count;
        }
    }
    assert!(found > 100.0, "the queries find particles ({found})");
}

/// N = 10¹² with ε = 0.1: f̂ over a footprint inside one texel converges to the smooth limit
/// there, `smooth_at` (d·f(α) where the roughness map is exact, the levels' mixture where it
/// interpolates, times the tint), within 3% at directions off the highlight's edge; a
/// masked texel gives 0 in both.
#[test]
fn a_dense_mapped_material_converges_to_its_smooth_limit() {
    // 4 × 4: α from 0.1 to 0.4 in sixteen distinct values (K = 4 levels interpolate), density
    // 0 in one corner texel, a tint.
    let alphas: Vec<f64> = (0..16).map(|k| 0.1 + 0.02 * k as f64).collect();
    let densities: Vec<f64> = (0..16)
        .map(|k| if k == 0 { 0.0 } else { 0.5 + 0.03 * k as f64 })
        .collect();
    let tints: Vec<[f64; 3]> = (0..16).map(|k| [1.0, 0.5 + 0.02 * k as f64, 0.3]).collect();
    let mut parameters = GlintParameters::new(beckmann(0.2));
    parameters.particles = 1_000_000_000_000;
    parameters.gamma_radians = 0.5f64.to_radians();
    parameters.roughness_levels = 4;
    parameters.alpha_map = Some(Arc::new(RoughnessMap::new(4, 4, &alphas).unwrap()));
    parameters.density_map = Some(Arc::new(DensityMap::new(4, 4, &densities).unwrap()));
    parameters.tint_map = Some(Arc::new(TintMap::new(4, 4, &tints).unwrap()));
    let material = DiscreteBrdf::new(parameters).unwrap();
    let mut scratch = QueryScratch::new();
    for column in 0..4 {
        for row in 0..4 {
            let uv = DVec2::new((column as f64 + 0.5) / 4.0, 1.0 - (row as f64 + 0.5) / 4.0);
            let footprint =
                Footprint::new(uv, DVec2::new(0.02, 0.0), DVec2::new(0.0, 0.02)).unwrap();
            for (wi, wo) in directions() {
                let f_hat = material.at(&footprint, &mut scratch).eval(wi, wo);
                let smooth = material.smooth_at(wi, wo, uv);
                if column == 0 && row == 0 {
                    assert_eq!(
                        (f_hat, smooth),
                        (DVec3::ZERO, DVec3::ZERO),
                        "the masked texel"
                    );
                    continue;
                }
                for c in 0..3 {
                    let ratio = f_hat[c] / smooth[c];
                    assert!(
                        (ratio - 1.0).abs() < 0.03,
                        "texel ({column}, {row}), {wi} {wo}: f̂ {f_hat} against {smooth}"
                    );
                }
            }
        }
    }
}

/// The sampler at a texture position where the roughness map interpolates between levels
/// (and where it is exact) samples the mixture its pdf states: chi-square over the sphere.
#[test]
fn the_sampler_samples_the_mixture_its_pdf_states() {
    let alphas: Vec<f64> = (0..16).map(|k| 0.05 * 1.2f64.powi(k)).collect();
    let densities: Vec<f64> = (0..16).map(|k| 0.2 + 0.05 * k as f64).collect();
    let mut parameters = GlintParameters::new(beckmann(0.2));
    parameters.gamma_radians = 3f64.to_radians();
    parameters.roughness_levels = 5;
    parameters.alpha_map = Some(Arc::new(RoughnessMap::new(4, 4, &alphas).unwrap()));
    parameters.density_map = Some(Arc::new(DensityMap::new(4, 4, &densities).unwrap()));
    let material = DiscreteBrdf::new(parameters).unwrap();
    for (k, uv) in [DVec2::new(0.3, 0.6), DVec2::new(0.9, 0.1)]
        .into_iter()
        .enumerate()
    {
        for theta in [0.2, 1.0] {
            let wi = direction(theta, 0.7);
            let mut rng = SplitMix64::new(5 + k as u64);
            let outcome = chi_square_directions(
                |u| {
                    material.sample_direction_at(wi, [u[0], u[1], rng.uniform(), rng.uniform()], uv)
                },
                |wo| material.sampling_pdf_at(wi, wo, uv),
                200_000,
                24,
                48,
                8,
                31 + k as u64,
            );
            assert!(
                outcome.p_value > 1e-4,
                "uv {uv}, θ {theta}: p = {} (∫pdf {})",
                outcome.p_value,
                outcome.pdf_integral
            );
        }
    }
}

/// A tint scales f̂ by its mean over the footprint (to the 2⁻³² steps tints are stored in):
/// t where it is constant over the
/// footprint, the area-weighted mean across a tint edge, per channel on coloured flakes.
#[test]
fn a_tint_scales_f_hat_by_its_mean_over_the_footprint() {
    // Two columns: red-ish on the left half of the square, blue-ish on the right.
    let tints = [[0.9, 0.3, 0.1], [0.2, 0.4, 0.8]];
    for channels in [0, 3] {
        let mut plain = GlintParameters::new(beckmann(0.2));
        plain.particles = 100_000_000;
        plain.colour_channels = channels;
        plain.gamma_radians = 5f64.to_radians();
        let mut tinted = plain.clone();
        tinted.tint_map = Some(Arc::new(TintMap::new(2, 1, &tints).unwrap()));
        let (plain, tinted) = (
            DiscreteBrdf::new(plain).unwrap(),
            DiscreteBrdf::new(tinted).unwrap(),
        );
        let mut scratch = QueryScratch::new();
        let mut checked = 0;
        for (centre, left_share) in [(0.2, 1.0), (0.8, 0.0), (0.5, 0.5), (0.45, 0.75)] {
            let uv = DVec2::new(centre, 0.5);
            let footprint =
                Footprint::new(uv, DVec2::new(0.2, 0.0), DVec2::new(0.0, 0.05)).unwrap();
            let mean = DVec3::from_array(tints[0]) * left_share
                + DVec3::from_array(tints[1]) * (1.0 - left_share);
            for (wi, wo) in directions() {
                let a = plain.at(&footprint, &mut scratch).eval(wi, wo);
                let b = tinted.at(&footprint, &mut scratch).eval(wi, wo);
                let expected = a * mean;
                assert!(
                    (b - expected).abs().max_element() <= 1e-9 * expected.max_element(),
                    "{channels} channels, centre {centre}: {b} against {expected}"
                );
                checked += usize::from(a != DVec3::ZERO);
            }
        }
        assert!(checked > 4);
    }
}

/// Maps of ones (density, tint) and a roughness map of the material's own α change nothing:
/// counts, f̂, sampling and the smooth limit bit for bit.
#[test]
fn maps_of_ones_change_nothing() {
    let mut base = GlintParameters::new(beckmann(0.15));
    base.particles = 5_000_000;
    base.negligible_count = 1e-12;
    let mut ones = base.clone();
    ones.density_map = Some(Arc::new(DensityMap::new(3, 2, &[1.0; 6]).unwrap()));
    ones.tint_map = Some(Arc::new(TintMap::new(2, 2, &[[1.0; 3]; 4]).unwrap()));
    ones.alpha_map = Some(Arc::new(RoughnessMap::new(3, 2, &[0.15; 6]).unwrap()));
    let (base, ones) = (
        DiscreteBrdf::new(base).unwrap(),
        DiscreteBrdf::new(ones).unwrap(),
    );
    let (mut a, mut b) = (QueryScratch::new(), QueryScratch::new());
    for footprint in footprints(100, 0.01, 8) {
        for (wi, wo) in directions() {
            let (x, y) = (
                base.at(&footprint, &mut a).evaluate(wi, wo),
                ones.at(&footprint, &mut b).evaluate(wi, wo),
            );
            assert_eq!((x.count, x.f_hat, x.d_hat), (y.count, y.f_hat, y.d_hat));
            let u = [0.3, 0.8, 0.1, 0.6];
            assert_eq!(
                base.at(&footprint, &mut a).sample(wi, u),
                ones.at(&footprint, &mut b).sample(wi, u)
            );
            let uv = footprint.center();
            assert_eq!(base.smooth_at(wi, wo, uv), ones.smooth_at(wi, wo, uv));
        }
    }
}

/// Bad maps are refused with the map, the texel and the value named.
#[test]
fn bad_maps_are_refused_naming_the_texel() {
    assert_eq!(
        RoughnessMap::new(2, 2, &[0.1, 0.1, 0.1, 0.0]),
        Err(BrdfError::InvalidMapTexel {
            map: "alpha_map",
            column: 1,
            row: 1,
            value: 0.0
        })
    );
    assert!(matches!(
        TintMap::new(1, 2, &[[0.5; 3], [0.5, f64::NAN, 0.5]]),
        Err(BrdfError::InvalidMapTexel {
            map: "tint_map",
            column: 0,
            row: 1,
            ..
        })
    ));
    let mut parameters = GlintParameters::new(beckmann(0.2));
    parameters.density_map = Some(Arc::new(DensityMap::new(2, 2, &[1.0; 4]).unwrap()));
    parameters.alpha_map = Some(Arc::new(RoughnessMap::new(3, 2, &[0.2; 6]).unwrap()));
    assert_eq!(
        DiscreteBrdf::new(parameters.clone()).unwrap_err(),
        BrdfError::MapSizesDiffer {
            density: (2, 2),
            alpha: (3, 2)
        }
    );
    parameters.density_map = None;
    parameters.roughness_levels = 0;
    assert_eq!(
        DiscreteBrdf::new(parameters).unwrap_err(),
        BrdfError::InvalidRoughnessLevels { levels: 0 }
    );
    let message = RoughnessMap::new(1, 1, &[2.0]).unwrap_err().to_string();
    assert!(
        message.contains("alpha_map") && message.contains("column 0, row 0"),
        "{message}"
    );
}

/// One roughness level cannot interpolate a map of several α: a clear error naming
/// `roughness_levels` (it divided by `levels − 1` and panicked); a map of one α builds at one
/// level.
#[test]
fn one_roughness_level_is_refused_for_a_map_of_several_values() {
    let mut parameters = GlintParameters::new(beckmann(0.2));
    parameters.roughness_levels = 1;
    parameters.alpha_map = Some(Arc::new(RoughnessMap::new(2, 1, &[0.1, 0.3]).unwrap()));
    let error = DiscreteBrdf::new(parameters.clone()).unwrap_err();
    assert_eq!(error, BrdfError::TooFewRoughnessLevels { distinct: 2 });
    assert!(error.to_string().contains("roughness_levels"), "{error}");
    parameters.alpha_map = Some(Arc::new(RoughnessMap::new(2, 1, &[0.3, 0.3]).unwrap()));
    assert_eq!(
        DiscreteBrdf::new(parameters).unwrap().level_trees().count(),
        1
    );
}

/// Interpolated levels run from the map's least α to its greatest exactly: a map reaching
/// α = 1 builds (exp∘ln overshot it to 1.0000000000000018, refused as out of range), and
/// the levels' α are the map's extremes at both ends.
#[test]
fn interpolated_levels_keep_the_maps_extremes() {
    for (least, greatest) in [(1e-4_f64, 1.0_f64), (0.013, 0.97), (0.3, 0.7)] {
        let values: Vec<f64> = (0..64)
            .map(|k| least * (greatest / least).powf(k as f64 / 63.0))
            .map(|a: f64| a.clamp(least, greatest))
            .collect();
        for levels in [2, 5, 8, 64 - 1] {
            let mut parameters = GlintParameters::new(beckmann(0.2));
            parameters.roughness_levels = levels;
            parameters.alpha_map = Some(Arc::new(RoughnessMap::new(8, 8, &values).unwrap()));
            let brdf = DiscreteBrdf::new(parameters).unwrap();
            let alphas: Vec<f64> = brdf.level_trees().map(|(a, _)| a.unwrap()).collect();
            assert_eq!(alphas.len(), levels);
            assert_eq!(alphas[0], least);
            assert_eq!(alphas[levels - 1], greatest);
            assert!(alphas.windows(2).all(|w| w[0] < w[1]), "{alphas:?}");
        }
    }
}

/// α values a few ulps apart share their logarithm: they get one level holding every flake,
/// the density map kept (the hat weights were 0/0 = NaN, which the clamp to 1 turned into a
/// density of 1 everywhere).
#[test]
fn alphas_sharing_their_logarithm_get_one_level() {
    let a = 1e-4_f64;
    let next = |x: f64| f64::from_bits(x.to_bits() + 1);
    let values = [a, next(a), next(next(a)), a];
    assert_eq!(values[0].ln(), values[2].ln());
    let mut parameters = GlintParameters::new(beckmann(0.2));
    parameters.roughness_levels = 2;
    parameters.alpha_map = Some(Arc::new(RoughnessMap::new(2, 2, &values).unwrap()));
    parameters.density_map = Some(Arc::new(
        DensityMap::new(2, 2, &[0.0, 0.5, 1.0, 0.25]).unwrap(),
    ));
    let brdf = DiscreteBrdf::new(parameters).unwrap();
    let levels: Vec<_> = brdf.level_trees().collect();
    assert_eq!(levels.len(), 1);
    assert_eq!(levels[0].0, Some(a));
    let map = levels[0].1.density_map().unwrap();
    let texels = [
        map.texel(0, 0),
        map.texel(1, 0),
        map.texel(0, 1),
        map.texel(1, 1),
    ];
    assert_eq!(texels, [0.0, 0.5, 1.0, 0.25]);
}

/// Under maps the negligible-query bound uses the largest density over the footprint: it
/// stays above the expected count N·∫_A d·∫p of every level, and a footprint in a masked
/// region is skipped without a traversal.
#[test]
fn the_negligible_bound_uses_the_density_over_the_footprint() {
    let (alphas, densities) = striped_maps();
    let mut masked = densities.clone();
    masked[0] = 0.0;
    masked[1] = 0.0;
    let mut parameters = GlintParameters::new(beckmann(0.2));
    parameters.particles = 1_000_000_000;
    parameters.negligible_count = 1e-12;
    parameters.alpha_map = Some(Arc::new(RoughnessMap::new(6, 4, &alphas).unwrap()));
    parameters.density_map = Some(Arc::new(DensityMap::new(6, 4, &masked).unwrap()));
    let material = DiscreteBrdf::new(parameters).unwrap();
    let mut scratch = QueryScratch::new();
    for footprint in footprints(300, 0.01, 21) {
        for (wi, wo) in directions() {
            let bxdf = material.at(&footprint, &mut scratch);
            let (bound, expected) = (
                bxdf.expected_count_bound(wi, wo),
                bxdf.expected_count(wi, wo),
            );
            assert!(
                bound >= expected * (1.0 - 1e-9),
                "{footprint:?}: λ̄ {bound} < {expected}"
            );
        }
    }
    // Inside texel (0, 0), masked: u < 1/6, v > 3/4.
    let inside = Footprint::new(
        DVec2::new(0.08, 0.85),
        DVec2::new(0.05, 0.0),
        DVec2::new(0.0, 0.05),
    )
    .unwrap();
    let (wi, wo) = directions()[0];
    let e = material.at(&inside, &mut scratch).evaluate(wi, wo);
    assert_eq!(e.negligible, Some(0.0), "{e:?}");
    assert_eq!(e.nodes_visited, 0);
}

/// With a density map of the tint's size, a footprint's tint is the flakes' mean,
/// ∫_A d·t / ∫_A d: across a mask edge that is also a tint edge, only the dense side's tint.
#[test]
fn the_tint_is_the_flakes_mean_under_a_density_map() {
    let tints = [[0.9, 0.3, 0.1], [0.2, 0.4, 0.8]];
    let mut plain = GlintParameters::new(beckmann(0.2));
    plain.particles = 100_000_000;
    plain.gamma_radians = 5f64.to_radians();
    plain.density_map = Some(Arc::new(DensityMap::new(2, 1, &[1.0, 0.0]).unwrap()));
    let mut tinted = plain.clone();
    tinted.tint_map = Some(Arc::new(TintMap::new(2, 1, &tints).unwrap()));
    let (plain, tinted) = (
        DiscreteBrdf::new(plain).unwrap(),
        DiscreteBrdf::new(tinted).unwrap(),
    );
    let mut scratch = QueryScratch::new();
    let footprint = Footprint::new(
        DVec2::new(0.5, 0.5),
        DVec2::new(0.2, 0.0),
        DVec2::new(0.0, 0.05),
    )
    .unwrap();
    let mut checked = 0;
    for (wi, wo) in directions() {
        let a = plain.at(&footprint, &mut scratch).eval(wi, wo);
        let b = tinted.at(&footprint, &mut scratch).eval(wi, wo);
        let expected = a * DVec3::from_array(tints[0]);
        assert!(
            (b - expected).abs().max_element() <= 1e-9 * expected.max_element(),
            "{b} against {expected}"
        );
        checked += usize::from(a != DVec3::ZERO);
    }
    assert!(checked > 0);
}

/// Under `map_filter` bilinear the roughness levels' densities d·w_k are interpolated like
/// the density: at every point they sum to the bilinear density (the levels' weights sum to 1
/// at every texel), each is continuous across texel edges, and a density map and a roughness
/// map filtered differently are refused naming both filters.
#[test]
fn bilinear_roughness_levels_sum_to_the_bilinear_density() {
    use glint_brdf::MapFilter;
    let (alphas, densities) = striped_maps();
    // Exact levels (two values) and interpolated ones (a third α between them, K = 2).
    let mut three = alphas.clone();
    three[7] = 0.12;
    for (alphas, levels) in [(alphas, 8), (three, 2)] {
        let density =
            Arc::new(DensityMap::with_filter(6, 4, &densities, MapFilter::Bilinear).unwrap());
        let alpha = RoughnessMap::new(6, 4, &alphas)
            .unwrap()
            .with_filter(MapFilter::Bilinear);
        let material = DiscreteBrdf::new(GlintParameters {
            density_map: Some(Arc::clone(&density)),
            alpha_map: Some(Arc::new(alpha.clone())),
            roughness_levels: levels,
            ..GlintParameters::new(beckmann(0.1))
        })
        .unwrap();
        let level_maps: Vec<DensityMap> = material
            .level_trees()
            .map(|(_, tree)| tree.density_map().expect("a level map").clone())
            .collect();
        assert!(level_maps.len() >= 2);
        assert!(level_maps.iter().all(|m| m.filter() == MapFilter::Bilinear));
        let mut rng = SplitMix64::new(5);
        for _ in 0..500 {
            let x = DVec2::new(rng.uniform(), rng.uniform());
            let sum: f64 = level_maps.iter().map(|m| m.value_at(x)).sum();
            // Each level is rounded to 2^-32 on its own.
            assert!((sum - density.value_at(x)).abs() < 1e-8, "at {x}: {sum}");
            let step = DVec2::new(1e-9, 1e-9);
            for m in &level_maps {
                assert!((m.value_at(x) - m.value_at(x + step)).abs() < 1e-6);
            }
        }
        let nearest = Arc::new(DensityMap::new(6, 4, &densities).unwrap());
        let error = DiscreteBrdf::new(GlintParameters {
            density_map: Some(nearest),
            alpha_map: Some(Arc::new(alpha)),
            ..GlintParameters::new(beckmann(0.1))
        })
        .unwrap_err();
        assert!(
            matches!(error, BrdfError::MapFiltersDiffer { .. }),
            "{error}"
        );
        let message = error.to_string();
        assert!(
            message.contains("\"nearest\"") && message.contains("\"bilinear\""),
            "{message}"
        );
    }
}
