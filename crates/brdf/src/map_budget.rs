//! The memory a material's maps may hold, checked before any of it is allocated.
//!
//! A material holds the maps it is given (a density map, a roughness map, a tint map) and
//! builds more from them: a density map per roughness level (d·w_k, [`crate::surface_maps`])
//! and, when the density and tint maps have one size, the tint weighted by the density (three
//! more). Each density map costs [`DensityMap::bytes_for`] its size, about 12.7 bytes a
//! texel, so a 4096² roughness map at 64 levels would need 13.6 GB. [`DiscreteBrdf::new`] counts what
//! the material will hold from the maps' sizes alone and refuses, with
//! [`BrdfError::MapsTooLarge`], a material over [`MAX_MAP_BYTES`]: every interface (scene
//! files, `eval`, C, Python, Mitsuba) builds materials through it, so the bound is the same
//! everywhere.
//!
//! [`DiscreteBrdf::new`]: crate::DiscreteBrdf::new

use glint_tree::DensityMap;

use crate::discrete::GlintParameters;
use crate::error::BrdfError;
use crate::surface_maps::level_alphas;

/// The most memory a material's maps may hold, in bytes (4 GiB, 4.29 GB): the maps it is given
/// and the ones it builds from them. An 8192² density map takes 0.85 GB; a 4096² roughness map
/// fits at up to 19 levels (4.17 GB), 18 with a density map of its size; an 8192² one at 4.
pub const MAX_MAP_BYTES: u64 = 4 << 30;

/// What a material's maps hold, in bytes, counted from their sizes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MapBytes {
    /// The maps the material is given (density, roughness and tint, with the tint's own
    /// per-channel tables).
    pub given: u64,
    /// The roughness levels' density maps it builds.
    pub levels: u64,
    /// How many roughness-level maps that is (0 without a roughness map).
    pub level_maps: usize,
    /// The roughness map's width and height, and its `roughness_levels`, when it has one.
    pub roughness: Option<(usize, usize, usize)>,
    /// The density-weighted tint's three maps it builds.
    pub weighted_tint: u64,
}

impl MapBytes {
    /// What the material built from `parameters` will hold in maps (an upper bound: levels
    /// that turn out empty are not built). Costs a sort of the roughness map's values.
    ///
    /// # Errors
    /// Those of the roughness levels' count ([`BrdfError::InvalidRoughnessLevels`],
    /// [`BrdfError::TooFewRoughnessLevels`]).
    pub fn of(parameters: &GlintParameters) -> Result<Self, BrdfError> {
        let mut bytes = Self::default();
        if let Some(density) = &parameters.density_map {
            bytes.given += density.heap_bytes() as u64;
        }
        if let Some(tint) = &parameters.tint_map {
            bytes.given += tint.heap_bytes() as u64;
            if let Some(density) = &parameters.density_map
                && density.size() == tint.size()
            {
                let (width, height) = tint.size();
                bytes.weighted_tint = 3 * DensityMap::bytes_for(width, height) as u64;
            }
        }
        if let Some(alpha) = &parameters.alpha_map {
            let (width, height) = alpha.size();
            bytes.given += alpha.heap_bytes() as u64;
            bytes.roughness = Some((width, height, parameters.roughness_levels));
            bytes.level_maps = level_alphas(alpha, parameters.roughness_levels)?.0.len();
            bytes.levels = bytes.level_maps as u64 * DensityMap::bytes_for(width, height) as u64;
        }
        Ok(bytes)
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
        if self.total() > MAX_MAP_BYTES {
            return Err(BrdfError::MapsTooLarge { bytes: self });
        }
        Ok(self)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

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
    }

    /// A roughness map whose levels would pass the budget is refused before anything is
    /// built, naming the bytes, the levels and the map's size; fewer levels pass.
    #[test]
    fn a_material_over_the_budget_is_refused_before_building() {
        // 4096² texels of 97 values: each level map needs 213 MB, 64 of them 13.6 GB.
        let (width, height) = (4096, 4096);
        let alphas: Vec<f64> = (0..width * height)
            .map(|k| 0.01 + 0.3 * (k % 97) as f64 / 96.0)
            .collect();
        let alpha = Arc::new(RoughnessMap::new(width, height, &alphas).unwrap());
        let material = |levels| GlintParameters {
            alpha_map: Some(Arc::clone(&alpha)),
            roughness_levels: levels,
            ..parameters()
        };
        let error = DiscreteBrdf::new(material(64)).unwrap_err();
        let BrdfError::MapsTooLarge { bytes } = error else {
            panic!("{error}");
        };
        assert_eq!(bytes.level_maps, 64);
        assert!(bytes.total() > 13_000_000_000, "{}", bytes.total());
        let message = error.to_string();
        for part in [
            "roughness_levels = 64",
            "alpha_map",
            "4096 x 4096",
            "4.29 GB",
        ] {
            assert!(message.contains(part), "{message:?} lacks {part:?}");
        }
        // The advice follows what costs most: levels, or the maps given and the tint's weights.
        let tinted = BrdfError::MapsTooLarge {
            bytes: MapBytes {
                given: 2_600_000_000,
                levels: 900_000_000,
                level_maps: 2,
                roughness: Some((4096, 4096, 2)),
                weighted_tint: 1_300_000_000,
            },
        };
        let message = tinted.to_string();
        assert!(message.contains("a tint map costs"), "{message}");
        assert!(!error.to_string().contains("a tint map costs"));
        // Without a density map 19 levels (4.17 GB) fit and 20 (4.39 GB) do not.
        assert!(MapBytes::of(&material(19)).unwrap().check().is_ok());
        assert!(MapBytes::of(&material(20)).unwrap().check().is_err());
    }
}
