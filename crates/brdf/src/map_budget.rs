//! The memory a material's maps may hold, checked before any of it is allocated.
//!
//! A material holds the maps it is given (a density map, a roughness map, a tint map) and
//! builds more from them: a density map per roughness level (d·w_k, [`crate::surface_maps`])
//! and, when the density and tint maps have one size, the tint weighted by the density (three
//! more). A density map costs at most [`DensityMap::bytes_for`] its size, about 12.7 bytes a
//! texel, and less where it is 0 over whole tiles of 64 × 64 texels, which it leaves out. A
//! roughness level's map d·w_k is 0 wherever α is not near the level's, so K levels hold
//! about two maps' worth where α varies smoothly or in regions (8 levels of a smooth 4096²
//! gradient: 2.5 maps). Where it changes at every texel they would hold up to K maps' worth
//! (a 4096² map of 97 values at 64 levels: 56 non-empty levels, 11.9 GB), and there its
//! levels share one family of texels instead (9 bytes a texel, and 0.36 a level: 0.49 GB for
//! that map, nearest or bilinear; `LevelBytes`, in `surface_maps.rs`, chooses). [`DiscreteBrdf::new`] counts what
//! the material will hold from one pass over the maps' texels (which tiles each derived map
//! would occupy, [`DensityMap::bytes_for_occupancy`]) and refuses, with
//! [`BrdfError::MapsTooLarge`], a material over [`MAX_MAP_BYTES`]: every interface (scene
//! files, `eval`, C, Python, Mitsuba) builds materials through it, so the bound is the same
//! everywhere.
//!
//! [`DiscreteBrdf::new`]: crate::DiscreteBrdf::new

use glint_tree::DensityMap;

use crate::discrete::GlintParameters;
use crate::error::BrdfError;
use crate::surface_maps::{LevelBytes, LevelWeights, WeightedTint};

/// The most memory a material's maps may hold, in bytes (4 GiB, 4.29 GB): the maps it is given
/// and the ones it builds from them. An 8192² density map takes at most 0.85 GB; a 4096²
/// roughness map whose α changes at every texel fits at any K, nearest or bilinear (its levels
/// share their texels: 0.62 GB with the map at 64 levels), and one whose α varies smoothly or
/// in regions at any K (its levels hold a few density maps' worth:
/// `roughness_levels_hold_about_two_maps_not_k`). A material reaches the bound only with maps
/// of tens of millions of texels (8192² density, tint and roughness maps at 64 levels: about
/// 150 bytes a texel, 10 GB).
pub const MAX_MAP_BYTES: u64 = 4 << 30;

/// What a material's maps hold, in bytes, counted before they are built.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MapBytes {
    /// The maps the material is given (density, roughness and tint, with the tint's own
    /// per-channel tables).
    pub given: u64,
    /// The roughness levels' density maps it builds.
    pub levels: u64,
    /// How many roughness-level maps that is (0 without a roughness map).
    pub level_maps: usize,
    /// Whether those maps share one family of texels (blocked tables, where α changes within
    /// most tiles) rather than each holding its own tables.
    pub shared_levels: bool,
    /// The roughness map's width and height, and its `roughness_levels`, when it has one.
    pub roughness: Option<(usize, usize, usize)>,
    /// The density-weighted tint's three maps it builds.
    pub weighted_tint: u64,
}

impl MapBytes {
    /// What the material built from `parameters` will hold in maps: the bytes each map's
    /// tables will hold, whole or tiled ([`DensityMap::bytes_for_occupancy`]), from one pass
    /// over the maps' texels that marks the tiles each derived map occupies (levels and
    /// channels of zeros are not built and count nothing).
    ///
    /// # Errors
    /// Those of the roughness levels' count ([`BrdfError::InvalidRoughnessLevels`],
    /// [`BrdfError::TooFewRoughnessLevels`]).
    pub fn of(parameters: &GlintParameters) -> Result<Self, BrdfError> {
        Ok(Self::with_level_weights(
            parameters,
            Self::level_weights(parameters)?.as_ref(),
        ))
    }

    /// The roughness levels' weights that [`MapBytes::of`] counts the levels' maps from: over
    /// the density map when it has the roughness map's size (else the material is refused
    /// with `MapSizesDiffer`, and the levels are counted without it); `None` without a
    /// roughness map. [`crate::DiscreteBrdf::new`] builds the levels from the same weights.
    ///
    /// # Errors
    /// Those of [`MapBytes::of`].
    pub(crate) fn level_weights(
        parameters: &GlintParameters,
    ) -> Result<Option<LevelWeights<'_>>, BrdfError> {
        let Some(alpha) = &parameters.alpha_map else {
            return Ok(None);
        };
        let density = (parameters.density_map.as_deref()).filter(|d| d.size() == alpha.size());
        LevelWeights::new(density, alpha, parameters.roughness_levels).map(Some)
    }

    /// [`MapBytes::of`] with the roughness levels' weights already made
    /// ([`MapBytes::level_weights`]).
    pub(crate) fn with_level_weights(
        parameters: &GlintParameters,
        level_weights: Option<&LevelWeights>,
    ) -> Self {
        let mut bytes = Self::default();
        let density = parameters.density_map.as_deref();
        if let Some(density) = density {
            bytes.given += density.heap_bytes_with_texels() as u64;
        }
        if let Some(tint) = &parameters.tint_map {
            bytes.given += tint.heap_bytes() as u64;
            if let Some(density) = density
                && density.size() == tint.size()
            {
                bytes.weighted_tint = WeightedTint::occupancies(tint, density)
                    .iter()
                    .map(|channel| DensityMap::bytes_for_occupancy(channel) as u64)
                    .sum();
            }
        }
        if let (Some(alpha), Some(weights)) = (&parameters.alpha_map, level_weights) {
            let (width, height) = alpha.size();
            bytes.given += alpha.heap_bytes() as u64;
            bytes.roughness = Some((width, height, parameters.roughness_levels));
            let levels = LevelBytes::of(weights);
            bytes.level_maps = levels.maps;
            bytes.levels = levels.bytes();
            bytes.shared_levels = levels.shared();
        }
        bytes
    }

    /// The total.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.given + self.levels + self.weighted_tint
    }

    /// `Ok` when the total is within [`MAX_MAP_BYTES`].
    ///
    /// # Errors
    /// [`BrdfError::MapsTooLarge`] with this count.
    pub fn check(self) -> Result<Self, BrdfError> {
        self.check_within(MAX_MAP_BYTES)
    }

    /// [`Self::check`] against `budget` bytes.
    pub(crate) fn check_within(self, budget: u64) -> Result<Self, BrdfError> {
        if self.total() > budget {
            return Err(BrdfError::MapsTooLarge { bytes: self });
        }
        Ok(self)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use glint_tree::MapFilter;

    use super::*;
    use crate::surface_maps::{RoughnessMap, TintMap};
    use crate::{DiscreteBrdf, Microfacet};

    fn parameters() -> GlintParameters {
        GlintParameters::new(Microfacet::new(crate::DistributionKind::Beckmann, 0.1, 0.1).unwrap())
    }

    /// A material's count equals the bytes its maps really hold once built, for every kind
    /// of map and both exact and interpolated levels.
    #[test]
    fn the_count_is_what_the_built_material_holds() {
        let (width, height) = (37, 21);
        let texels = width * height;
        let alphas: Vec<f64> = (0..texels).map(|k| 0.05 + 0.01 * (k % 7) as f64).collect();
        let densities: Vec<f64> = (0..texels).map(|k| (k % 5) as f64 / 4.0).collect();
        let tints: Vec<[f64; 3]> = (0..texels)
            .map(|k| [1.0, (k % 3) as f64 / 2.0, 0.5])
            .collect();
        for levels in [3, 7, 8] {
            let material = GlintParameters {
                density_map: Some(Arc::new(
                    DensityMap::new(width, height, &densities).unwrap(),
                )),
                alpha_map: Some(Arc::new(RoughnessMap::new(width, height, &alphas).unwrap())),
                tint_map: Some(Arc::new(TintMap::new(width, height, &tints).unwrap())),
                roughness_levels: levels,
                ..parameters()
            };
            let counted = MapBytes::of(&material).unwrap();
            assert_eq!(counted.level_maps, levels.min(7));
            let built = DiscreteBrdf::new(material).unwrap();
            assert_eq!(built.map_bytes(), counted.total(), "{levels} levels");
        }
        // α changing at every texel over eight levels: the levels share one family of texels,
        // counted once.
        let (width, height) = (300, 200);
        let noisy: Vec<f64> = (0..width * height)
            .map(|k| 0.02 * 20f64.powf(((k * 7_919) % 1_009) as f64 / 1_008.0))
            .collect();
        let material = GlintParameters {
            alpha_map: Some(Arc::new(RoughnessMap::new(width, height, &noisy).unwrap())),
            roughness_levels: 8,
            ..parameters()
        };
        let counted = MapBytes::of(&material).unwrap();
        assert!(counted.shared_levels);
        assert_eq!(counted.level_maps, 8);
        let built = DiscreteBrdf::new(material).unwrap();
        assert_eq!(built.map_bytes(), counted.total());
    }

    /// A roughness map's K levels hold about what two density maps hold, not K: each texel
    /// has weight on two levels at most (one where the levels are exact), and a level's
    /// tables leave out the tiles where it is 0. Measured on a smooth gradient (α from 0.02
    /// to 0.4 across the map, 8 interpolated levels) and on a painted map of three values
    /// (exact levels; its stripes cross most tiles of two of them), both 1024².
    #[test]
    fn roughness_levels_hold_about_two_maps_not_k() {
        let side = 1024;
        let whole = DensityMap::bytes_for(side, side) as f64;
        let gradient: Vec<f64> = (0..side * side)
            .map(|k| {
                let (x, y) = (
                    (k % side) as f64 / side as f64,
                    (k / side) as f64 / side as f64,
                );
                0.02 * 20f64.powf((0.7 * x + 0.3 * y).min(1.0))
            })
            .collect();
        let painted: Vec<f64> = (0..side * side)
            .map(|k| {
                let (x, y) = (
                    (k % side) as f64 / side as f64,
                    (k / side) as f64 / side as f64,
                );
                let r = ((x - 0.5).powi(2) + (y - 0.4).powi(2)).sqrt();
                if r < 0.2 {
                    0.05
                } else if (x * 7.0 + y * 3.0).fract() < 0.3 {
                    0.3
                } else {
                    0.12
                }
            })
            .collect();
        for (name, alphas, most) in [("gradient", gradient, 3.2), ("painted", painted, 2.4)] {
            let material = GlintParameters {
                alpha_map: Some(Arc::new(RoughnessMap::new(side, side, &alphas).unwrap())),
                roughness_levels: 8,
                ..parameters()
            };
            let counted = MapBytes::of(&material).unwrap();
            let maps = counted.levels as f64 / whole;
            assert!(
                maps < most,
                "{name}: {} levels hold {maps:.2} maps",
                counted.level_maps
            );
            let built = DiscreteBrdf::new(material).unwrap();
            assert_eq!(built.map_bytes(), counted.total(), "{name}");
        }
    }

    /// A material whose maps would pass its budget is refused before anything is built,
    /// with the bytes it counted, and built when they fit: a bilinear map of 97 α values
    /// changing at every texel, at 64 levels (56 of them non-empty), under budgets one byte
    /// below and at its count. At 4096², the levels' own maps would hold 11.9 GB; filtered
    /// either way they share one family of texels (9 bytes a texel, 0.36 a level) and fit
    /// [`MAX_MAP_BYTES`] in 0.62 GB with the map itself. The message names the bytes, the
    /// levels and the map's size.
    #[test]
    fn a_material_over_the_budget_is_refused_before_building() {
        let ninety_seven = |width: usize, height: usize| {
            let alphas: Vec<f64> = (0..width * height)
                .map(|k| 0.01 + 0.3 * (k % 97) as f64 / 96.0)
                .collect();
            Arc::new(RoughnessMap::new(width, height, &alphas).unwrap())
        };
        let material = |alpha: &Arc<RoughnessMap>, filter, levels| GlintParameters {
            alpha_map: Some(Arc::new((**alpha).clone().with_filter(filter))),
            roughness_levels: levels,
            ..parameters()
        };
        let small = ninety_seven(160, 96);
        let counted = MapBytes::of(&material(&small, MapFilter::Bilinear, 64)).unwrap();
        assert!(counted.shared_levels);
        let over = DiscreteBrdf::within_map_budget(
            material(&small, MapFilter::Bilinear, 64),
            counted.total() - 1,
        );
        match over {
            Err(BrdfError::MapsTooLarge { bytes }) => assert_eq!(bytes, counted),
            Err(error) => panic!("{error}"),
            Ok(_) => panic!("a material over its budget was built"),
        }
        let fits = DiscreteBrdf::within_map_budget(
            material(&small, MapFilter::Bilinear, 64),
            counted.total(),
        )
        .unwrap();
        assert_eq!(fits.map_bytes(), counted.total());

        let (width, height) = (4096, 4096);
        let large = ninety_seven(width, height);
        let texels = (width * height) as u64;
        for filter in MapFilter::ALL {
            let bytes = MapBytes::of(&material(&large, filter, 64)).unwrap();
            // Levels between the map's 97 values that no texel's hat function reaches hold
            // nothing and count nothing; every other one occupies every tile, so its own map
            // would be whole: 56 of them, 11.9 GB.
            assert_eq!(bytes.level_maps, 56);
            assert!(56 * DensityMap::bytes_for(width, height) as u64 > 11_000_000_000);
            assert!(bytes.shared_levels, "{filter:?}");
            assert_eq!(
                bytes.levels,
                9 * texels + 56 * DensityMap::roughness_level_bytes(width, height) as u64
            );
            assert!(bytes.levels < 30 * texels, "{}", bytes.levels);
            assert!(bytes.check().is_ok());
        }
        let error = BrdfError::MapsTooLarge {
            bytes: MapBytes {
                given: 134_217_728,
                levels: 11_920_000_000,
                level_maps: 56,
                shared_levels: false,
                roughness: Some((width, height, 64)),
                weighted_tint: 0,
            },
        };
        let message = error.to_string();
        for part in [
            "roughness_levels = 64",
            "alpha_map",
            "4096 x 4096",
            "4.29 GB",
            "lower roughness_levels",
        ] {
            assert!(message.contains(part), "{message:?} lacks {part:?}");
        }
        // The advice follows what costs most: levels, or the maps given and the tint's weights.
        let tinted = BrdfError::MapsTooLarge {
            bytes: MapBytes {
                given: 2_600_000_000,
                levels: 900_000_000,
                level_maps: 2,
                shared_levels: false,
                roughness: Some((4096, 4096, 2)),
                weighted_tint: 1_300_000_000,
            },
        };
        let message = tinted.to_string();
        assert!(message.contains("a tint map costs"), "{message}");
        assert!(!error.to_string().contains("a tint map costs"));
    }
}
