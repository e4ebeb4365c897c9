//! Maps that vary a glint material over its texture square (issue 31): the flakes' roughness
//! ([`RoughnessMap`]) and tint ([`TintMap`]). The particle density map is glint-tree's
//! [`DensityMap`]. Every map is W × H texels given row by row, **row 0 at the top of the
//! texture** (v from 1 − 1/H to 1), column 0 starting at u = 0, piecewise constant over its
//! texels and tiling with the square.
//!
//! **Roughness.** The law of a flake's normal depends on its position: α(x). The material
//! holds K *roughness levels* α_1 < … < α_K, each a count tree of its own whose particles
//! have density N·d(x)·w_k(x) and normals from D(α_k) ([`roughness_levels`]). Where the map
//! takes at most K distinct values, the levels are those values and w_k(x) = [α(x) = α_k]:
//! exact, every flake has the normal law of its texel. Elsewhere the levels are spaced evenly
//! in log α between the map's extremes and w_k are the hat functions of log α (a flake at α
//! between α_k and α_k+1 is a flake of one or the other, with weights linear in log α): the
//! approximation, whose error against the exact per-texel lobe `cargo xtask validate`
//! measures for K = 2…16 (`GlintParameters::roughness_levels`, default 8).
//!
//! **Tint.** A colour t(x) ∈ [0, 1]³ that scales the flakes' reflectance. A footprint's flakes
//! take the tint filtered over it: the flakes' mean tint t̄ = ∫_A d·t / ∫_A d when the material
//! has a density map of the tint's size, else t̄ = ∫_A t / area(A) ([`TintMap::mean_over`]).
//! Exact where t is constant over the footprint, and the mean a pixel converges to where it is
//! not (with a density map of another size, a footprint across a density edge and a tint edge
//! weighs the tint by area rather than by flakes). It
//! multiplies f̂ after any coloured (Dirichlet) particle areas, so `coloured` flakes keep their
//! per-flake colour under the map's tint. Without a footprint (the smooth limit) the tint is
//! t(x) at the shading point.

use std::sync::Arc;

use glam::{DVec2, DVec3};
use glint_tree::{DensityMap, DensityMapError, Footprint};

use crate::error::BrdfError;

/// The smallest and largest roughness a map may hold (the materials' range).
const ALPHA_RANGE: std::ops::RangeInclusive<f64> = 1e-4..=1.0;

/// The most roughness levels a material may have.
pub const MAX_ROUGHNESS_LEVELS: usize = 64;

/// A map of isotropic roughness α(x) ∈ [10⁻⁴, 1] (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct RoughnessMap {
    width: usize,
    height: usize,
    /// α by texel, row 0 at the top.
    values: Vec<f64>,
}

impl RoughnessMap {
    /// A map of `width` × `height` texels from α `values` given row by row, row 0 at the top.
    ///
    /// # Errors
    /// [`BrdfError::InvalidMap`] for a size that does not match the values (or no texel, or
    /// more than [`DensityMap::MAX_TEXELS`]); [`BrdfError::InvalidMapTexel`] naming the first
    /// texel whose α is not in [10⁻⁴, 1].
    pub fn new(width: usize, height: usize, values: &[f64]) -> Result<Self, BrdfError> {
        check_size("alpha_map", width, height, values.len())?;
        if let Some(k) = values.iter().position(|a| !ALPHA_RANGE.contains(a)) {
            return Err(BrdfError::InvalidMapTexel {
                map: "alpha_map",
                column: k % width,
                row: k / width,
                value: values[k],
            });
        }
        Ok(Self {
            width,
            height,
            values: values.to_vec(),
        })
    }

    /// Width and height in texels.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// α of the texel in `column` and `row` (row 0 at the top).
    #[must_use]
    pub fn texel(&self, column: usize, row: usize) -> f64 {
        self.values[row * self.width + column]
    }
}

/// A map of tints t(x) ∈ [0, 1]³ (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct TintMap {
    width: usize,
    height: usize,
    /// t by texel, row 0 at the top.
    values: Vec<[f64; 3]>,
    /// Each channel as a density map, for its integral over a footprint (`None`: all 0).
    channels: [Option<Arc<DensityMap>>; 3],
}

impl TintMap {
    /// A map of `width` × `height` texels from RGB `values` given row by row, row 0 at the top.
    ///
    /// # Errors
    /// [`BrdfError::InvalidMap`] for a size that does not match the values;
    /// [`BrdfError::InvalidMapTexel`] naming the first texel with a channel not in [0, 1].
    pub fn new(width: usize, height: usize, values: &[[f64; 3]]) -> Result<Self, BrdfError> {
        check_size("tint_map", width, height, values.len())?;
        if let Some(k) = values
            .iter()
            .position(|t| !t.iter().all(|c| (0.0..=1.0).contains(c)))
        {
            let value = *values[k]
                .iter()
                .find(|c| !(0.0..=1.0).contains(*c))
                .unwrap_or(&f64::NAN);
            return Err(BrdfError::InvalidMapTexel {
                map: "tint_map",
                column: k % width,
                row: k / width,
                value,
            });
        }
        let channel = |c: usize| {
            let texels: Vec<f64> = values.iter().map(|t| t[c]).collect();
            match DensityMap::new(width, height, &texels) {
                Ok(map) => Ok(Some(Arc::new(map))),
                Err(DensityMapError::Empty) => Ok(None),
                Err(error) => Err(BrdfError::DensityMap(error)),
            }
        };
        Ok(Self {
            width,
            height,
            values: values.to_vec(),
            channels: [channel(0)?, channel(1)?, channel(2)?],
        })
    }

    /// Width and height in texels.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// t at texture point `uv` (wrapped into the square): the tint without a footprint.
    #[must_use]
    pub fn value_at(&self, uv: DVec2) -> DVec3 {
        let uv = uv - uv.floor();
        let column = ((uv.x * self.width as f64) as usize).min(self.width - 1);
        let row_from_bottom = ((uv.y * self.height as f64) as usize).min(self.height - 1);
        DVec3::from_array(self.values[(self.height - 1 - row_from_bottom) * self.width + column])
    }

    /// t̄ = ∫_A t / area(A) over the footprint's parallelogram (each tile it covers counted):
    /// exact where t is constant over it; t at its centre for a footprint without area.
    #[must_use]
    pub fn mean_over(&self, footprint: &Footprint) -> DVec3 {
        let area = footprint.area();
        if footprint.is_degenerate() {
            return self.value_at(footprint.center());
        }
        DVec3::from_array(
            self.channels
                .each_ref()
                .map(|c| c.as_ref().map_or(0.0, |map| map.mass_in(footprint) / area)),
        )
    }
}

/// A tint weighted by a density map of its size: each channel's d·t as a density map, so that
/// a footprint's tint is the flakes' mean, ∫_A d·t / ∫_A d.
#[derive(Clone, Debug)]
pub(crate) struct WeightedTint {
    density: Arc<DensityMap>,
    /// d·t per channel (`None`: 0 everywhere).
    channels: [Option<Arc<DensityMap>>; 3],
}

impl WeightedTint {
    /// The tint `tint` weighted by `density`, when the two have the same size.
    pub(crate) fn new(
        tint: &TintMap,
        density: &Arc<DensityMap>,
    ) -> Result<Option<Self>, BrdfError> {
        if density.size() != tint.size() {
            return Ok(None);
        }
        let (width, height) = tint.size();
        let channel = |c: usize| {
            let texels: Vec<f64> = (0..width * height)
                .map(|k| density.texel(k % width, k / width) * tint.values[k][c])
                .collect();
            match DensityMap::new(width, height, &texels) {
                Ok(map) => Ok(Some(Arc::new(map))),
                Err(DensityMapError::Empty) => Ok(None),
                Err(error) => Err(BrdfError::DensityMap(error)),
            }
        };
        Ok(Some(Self {
            density: Arc::clone(density),
            channels: [channel(0)?, channel(1)?, channel(2)?],
        }))
    }

    /// ∫_A d·t / ∫_A d over the footprint; `None` where the footprint holds no density.
    pub(crate) fn mean_over(&self, footprint: &Footprint) -> Option<DVec3> {
        let mass = self.density.mass_in(footprint);
        (mass > 0.0).then(|| {
            DVec3::from_array(
                self.channels
                    .each_ref()
                    .map(|c| c.as_ref().map_or(0.0, |map| map.mass_in(footprint) / mass)),
            )
        })
    }
}

/// Checks a map's size against its values' count.
fn check_size(
    map: &'static str,
    width: usize,
    height: usize,
    values: usize,
) -> Result<(), BrdfError> {
    let texels = width.saturating_mul(height);
    if width == 0 || height == 0 || texels > DensityMap::MAX_TEXELS || texels != values {
        return Err(BrdfError::InvalidMap {
            map,
            width,
            height,
            values,
        });
    }
    Ok(())
}

/// One roughness level of a material: its α and its particles' density map d·w_k (`None`: the
/// material's own density map, for a material without a roughness map).
#[derive(Clone, Debug)]
pub(crate) struct RoughnessLevel {
    pub(crate) alpha: Option<f64>,
    pub(crate) density: Option<Arc<DensityMap>>,
}

/// The roughness levels of a material with density map `density` and roughness map `alpha`,
/// at most `levels` of them (see the module docs); levels whose density is 0 everywhere are
/// left out. Without a roughness map, one level: the material's α and its density map.
///
/// # Errors
/// [`BrdfError::MapSizesDiffer`] when both maps are given with different sizes;
/// [`BrdfError::InvalidRoughnessLevels`] unless 1 ≤ `levels` ≤ [`MAX_ROUGHNESS_LEVELS`].
pub(crate) fn roughness_levels(
    density: Option<&Arc<DensityMap>>,
    alpha: Option<&RoughnessMap>,
    levels: usize,
) -> Result<Vec<RoughnessLevel>, BrdfError> {
    if !(1..=MAX_ROUGHNESS_LEVELS).contains(&levels) {
        return Err(BrdfError::InvalidRoughnessLevels { levels });
    }
    let Some(alpha) = alpha else {
        return Ok(vec![RoughnessLevel {
            alpha: None,
            density: density.cloned(),
        }]);
    };
    let (width, height) = alpha.size();
    if let Some(density) = density
        && density.size() != (width, height)
    {
        return Err(BrdfError::MapSizesDiffer {
            density: density.size(),
            alpha: (width, height),
        });
    }
    let d = |k: usize| density.map_or(1.0, |map| map.texel(k % width, k / width));
    let mut distinct: Vec<f64> = alpha.values.clone();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup();
    // The levels, and each texel's weights on them (two adjacent levels at most).
    let exact = distinct.len() <= levels;
    let level_alphas: Vec<f64> = if exact {
        distinct.clone()
    } else {
        let (low, high) = (distinct[0].ln(), distinct[distinct.len() - 1].ln());
        (0..levels)
            .map(|k| (low + (high - low) * k as f64 / (levels - 1) as f64).exp())
            .collect()
    };
    let weights = |a: f64| -> [(usize, f64); 2] {
        if exact {
            let k = level_alphas.partition_point(|&l| l < a);
            return [(k, 1.0), (k, 0.0)];
        }
        let (low, high) = (level_alphas[0].ln(), level_alphas[levels - 1].ln());
        let position =
            ((a.ln() - low) / (high - low) * (levels - 1) as f64).clamp(0.0, (levels - 1) as f64);
        let k = (position.floor() as usize).min(levels - 2);
        let f = position - k as f64;
        [(k, 1.0 - f), (k + 1, f)]
    };
    let mut level_values = vec![vec![0.0; width * height]; level_alphas.len()];
    for (k, &a) in alpha.values.iter().enumerate() {
        for (level, w) in weights(a) {
            level_values[level][k] += d(k) * w;
        }
    }
    let mut result = Vec::new();
    for (a, values) in level_alphas.into_iter().zip(level_values) {
        let values: Vec<f64> = values.into_iter().map(|v| v.min(1.0)).collect();
        match DensityMap::new(width, height, &values) {
            Ok(map) => result.push(RoughnessLevel {
                alpha: Some(a),
                density: Some(Arc::new(map)),
            }),
            Err(DensityMapError::Empty) => {}
            Err(error) => return Err(BrdfError::DensityMap(error)),
        }
    }
    if result.is_empty() {
        return Err(BrdfError::DensityMap(DensityMapError::Empty));
    }
    Ok(result)
}
