//! The error type of glint-brdf.

use std::fmt;

/// Why a BRDF or material could not be built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BrdfError {
    /// Roughness α must be finite and in [1e-4, 1].
    InvalidRoughness {
        /// The rejected value.
        alpha: f64,
    },
    /// A Fresnel parameter is outside its range: η in [10⁻³, 10³], k in [0, 10³]
    /// ([`crate::Fresnel::MIN_ETA`], [`crate::Fresnel::MAX_ETA`], [`crate::Fresnel::MAX_K`]).
    InvalidFresnel {
        /// `"eta"` or `"k"`.
        parameter: &'static str,
        /// The rejected value.
        value: f64,
    },
    /// The cone radius γ must be in [10⁻⁶ rad, 60°] (below 10⁻⁶ rad, about 0.2 arc seconds, the
    /// conic's solid angle loses its precision).
    InvalidConeRadius {
        /// The rejected value (radians).
        gamma: f64,
    },
    /// The sampling roughness scale must be finite and ≥ 1.
    InvalidSamplingScale {
        /// The rejected value.
        scale: f64,
    },
    /// The negligible-count threshold must be finite and ≥ 0.
    InvalidNegligibleCount {
        /// The rejected value.
        count: f64,
    },
    /// The expected footprint area (Eq. 11) must be finite and > 0.
    InvalidExpectedFootprintArea {
        /// The rejected value.
        area: f64,
    },
    /// Visible-normal sampling was asked of a distribution that does not have it
    /// ([`crate::DistributionKind::samples_visible_normals`]).
    VisibleSamplingUnavailable {
        /// The distribution's name.
        distribution: &'static str,
    },
    /// The pdf's quadrature needs 1 to 4096 points.
    InvalidPdfPoints {
        /// The rejected value.
        points: usize,
    },
    /// The count tree rejected the material.
    Tree(glint_tree::TreeError),
    /// A density map (or a tint map's channel, or a roughness level's density) was refused.
    DensityMap(glint_tree::DensityMapError),
    /// A map's width × height does not match its values (or it has no texel, or too many).
    InvalidMap {
        /// `"alpha_map"` or `"tint_map"`.
        map: &'static str,
        /// The width given.
        width: usize,
        /// The height given.
        height: usize,
        /// The number of texel values given.
        values: usize,
    },
    /// A map's texel is outside the map's range: α in [10⁻⁴, 1], tint channels in [0, 1].
    InvalidMapTexel {
        /// `"alpha_map"` or `"tint_map"`.
        map: &'static str,
        /// The texel's column (0 at u = 0).
        column: usize,
        /// The texel's row (0 at the top of the texture).
        row: usize,
        /// The rejected value.
        value: f64,
    },
    /// A density map and a roughness map must have the same size (their product is taken
    /// texel by texel).
    MapSizesDiffer {
        /// The density map's width and height.
        density: (usize, usize),
        /// The roughness map's width and height.
        alpha: (usize, usize),
    },
    /// The density and roughness maps must be reconstructed alike (the levels' densities
    /// d·w_k take the roughness map's filter).
    MapFiltersDiffer {
        /// The density map's filter.
        density: glint_tree::MapFilter,
        /// The roughness map's filter.
        alpha: glint_tree::MapFilter,
    },
    /// Roughness levels must be 1 to 64.
    InvalidRoughnessLevels {
        /// The rejected value.
        levels: usize,
    },
    /// One roughness level holds one α: a roughness map of several needs at least two levels
    /// to interpolate between.
    TooFewRoughnessLevels {
        /// The roughness map's distinct values.
        distinct: usize,
    },
    /// The material's maps would hold more than [`crate::MAX_MAP_BYTES`] (see
    /// [`crate::map_budget`]); nothing beyond the maps given was allocated.
    MapsTooLarge {
        /// What they would hold.
        bytes: crate::MapBytes,
    },
}

impl fmt::Display for BrdfError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::InvalidRoughness { alpha } => {
                write!(
                    f,
                    "roughness alpha = {alpha:?} is invalid: it must be finite and in [1e-4, 1]"
                )
            }
            Self::InvalidFresnel { parameter, value } => write!(
                f,
                "Fresnel {parameter} = {value:?} is invalid: eta must be in [1e-3, 1e3] and k in [0, 1e3]"
            ),
            Self::InvalidConeRadius { gamma } => write!(
                f,
                "cone radius gamma = {gamma:?} rad is invalid: it must be in [1e-6 rad, 60 degrees]"
            ),
            Self::InvalidSamplingScale { scale } => {
                write!(
                    f,
                    "sampling roughness scale {scale:?} is invalid: it must be finite and >= 1"
                )
            }
            Self::InvalidNegligibleCount { count } => write!(
                f,
                "negligible count {count:?} is invalid: it must be finite and >= 0 (0 disables it)"
            ),
            Self::InvalidExpectedFootprintArea { area } => write!(
                f,
                "expected footprint area {area:?} is invalid: it must be finite and > 0 (texture units)"
            ),
            Self::VisibleSamplingUnavailable { distribution } => write!(
                f,
                "{distribution} has no visible-normal sampling: sample its normals from D(m)(m·n)"
            ),
            Self::InvalidPdfPoints { points } => {
                write!(f, "{points} pdf quadrature points requested: use 1 to 4096")
            }
            Self::Tree(error) => write!(f, "count tree: {error}"),
            Self::DensityMap(error) => write!(f, "density_map: {error}"),
            Self::InvalidMap {
                map,
                width,
                height,
                values,
            } => write!(
                f,
                "{map}: {values} values for {width} x {height} texels (a map needs 1 to 2^28 texels)"
            ),
            Self::InvalidMapTexel {
                map,
                column,
                row,
                value,
            } => {
                let range = if *map == "alpha_map" {
                    "[1e-4, 1]"
                } else {
                    "[0, 1]"
                };
                write!(
                    f,
                    "{map}: texel (column {column}, row {row}) is {value:?}: it must be in {range}"
                )
            }
            Self::MapSizesDiffer { density, alpha } => write!(
                f,
                "density_map is {} x {} texels and alpha_map {} x {}: they must have the same size",
                density.0, density.1, alpha.0, alpha.1
            ),
            Self::MapFiltersDiffer { density, alpha } => write!(
                f,
                "density_map is filtered \"{}\" and alpha_map \"{}\": give both one map_filter",
                density.name(),
                alpha.name()
            ),
            Self::InvalidRoughnessLevels { levels } => {
                write!(f, "{levels} roughness levels requested: use 1 to 64")
            }
            Self::TooFewRoughnessLevels { distinct } => write!(
                f,
                "roughness_levels = 1 holds one alpha, but alpha_map has {distinct} distinct \
                 values: give roughness_levels >= 2 (levels interpolated in log alpha) or a map \
                 of one value"
            ),
            Self::MapsTooLarge { bytes } => {
                let gb = |b: u64| format!("{:.2} GB", b as f64 / 1e9);
                write!(
                    f,
                    "the material's maps would hold {}: {} in the maps given",
                    gb(bytes.total()),
                    gb(bytes.given)
                )?;
                if let Some((width, height, levels)) = bytes.roughness {
                    write!(
                        f,
                        ", {} in {} level maps (alpha_map {width} x {height} texels at \
                         roughness_levels = {levels})",
                        gb(bytes.levels),
                        bytes.level_maps,
                    )?;
                }
                if bytes.weighted_tint > 0 {
                    write!(
                        f,
                        ", {} in the density-weighted tint",
                        gb(bytes.weighted_tint)
                    )?;
                }
                let advice = if bytes.levels > bytes.given + bytes.weighted_tint {
                    "lower roughness_levels or the maps' resolution"
                } else {
                    "lower the maps' resolution (a tint map costs about 100 bytes a texel with \
                     a density map of its size, a density or roughness level map up to 12.7)"
                };
                write!(
                    f,
                    "; a material may hold {}: {advice}",
                    gb(crate::MAX_MAP_BYTES)
                )
            }
        }
    }
}

impl std::error::Error for BrdfError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Tree(error) => Some(error),
            Self::DensityMap(error) => Some(error),
            _ => None,
        }
    }
}

impl From<glint_tree::TreeError> for BrdfError {
    fn from(error: glint_tree::TreeError) -> Self {
        Self::Tree(error)
    }
}

impl From<glint_tree::DensityMapError> for BrdfError {
    fn from(error: glint_tree::DensityMapError) -> Self {
        Self::DensityMap(error)
    }
}
