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
//! measures for K = 2…16 (`GlintParameters::roughness_levels`, default 8). A roughness map
//! built [`RoughnessMap::with_filter`] bilinear reconstructs each level's density d·w_k
//! bilinearly from its texel values: the levels' shares of the flakes, and so the law of a
//! flake's roughness, vary continuously across texels, exact for that reconstruction (the
//! density map must then be bilinear too).
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
use glint_tree::{DensityMap, DensityMapError, Footprint, LevelTexels, MapFilter, MapOccupancy};

use crate::error::BrdfError;

/// The smallest and largest roughness a map may hold (the materials' range).
const ALPHA_RANGE: std::ops::RangeInclusive<f64> = 1e-4..=1.0;

/// The most roughness levels a material may have.
pub const MAX_ROUGHNESS_LEVELS: usize = 64;

// A material's levels may share one family of texels, which holds at most as many.
const _: () = assert!(MAX_ROUGHNESS_LEVELS <= glint_tree::density_map::MAX_LEVELS);

/// A map of isotropic roughness α(x) ∈ [10⁻⁴, 1] (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct RoughnessMap {
    width: usize,
    height: usize,
    /// α by texel, row 0 at the top.
    values: Vec<f64>,
    /// How the roughness levels' densities are reconstructed between texels.
    filter: MapFilter,
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
            filter: MapFilter::Nearest,
        })
    }

    /// The map with its roughness levels' densities d·w_k reconstructed by `filter` between
    /// the texels (bilinear: each level's share of the flakes, and so the flakes' roughness,
    /// varies continuously; see the module docs).
    #[must_use]
    pub fn with_filter(mut self, filter: MapFilter) -> Self {
        self.filter = filter;
        self
    }

    /// How the roughness levels' densities are reconstructed between texels.
    #[must_use]
    pub fn filter(&self) -> MapFilter {
        self.filter
    }

    /// Width and height in texels.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The heap memory it holds, in bytes (8 a texel).
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        std::mem::size_of_val(self.values.as_slice())
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

    /// The heap memory it holds, in bytes: its texels (24 a texel) and each non-zero channel's
    /// density map ([`DensityMap::bytes_for`]).
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        std::mem::size_of_val(self.values.as_slice()) + channel_bytes(&self.channels)
    }

    /// Whether every texel is grey (r = g = b), so that the tint scales every channel alike.
    #[must_use]
    pub fn is_gray(&self) -> bool {
        self.values.iter().all(|t| t[0] == t[1] && t[1] == t[2])
    }

    /// t at texture point `uv` (wrapped into the square): the tint without a footprint.
    #[must_use]
    pub fn value_at(&self, uv: DVec2) -> DVec3 {
        let uv = uv - uv.floor();
        let column = ((uv.x * self.width as f64) as usize).min(self.width - 1);
        let row_from_bottom = ((uv.y * self.height as f64) as usize).min(self.height - 1);
        DVec3::from_array(self.values[(self.height - 1 - row_from_bottom) * self.width + column])
    }

    /// ∫t over the square: the mean tint.
    #[must_use]
    pub fn mean(&self) -> DVec3 {
        DVec3::from_array(
            self.channels
                .each_ref()
                .map(|c| c.as_ref().map_or(0.0, |map| map.mean())),
        )
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
        let d = density.texels();
        let channel = |c: usize| {
            let texels: Vec<f64> = (0..width * height)
                .map(|k| d[k] * tint.values[k][c])
                .collect();
            match DensityMap::with_filter(width, height, &texels, density.filter()) {
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

    /// Which tiles each channel's map d·t would occupy, for a density map of the tint's size.
    pub(crate) fn occupancies(tint: &TintMap, density: &DensityMap) -> [MapOccupancy; 3] {
        let (width, height) = tint.size();
        let d = density.texels();
        std::array::from_fn(|c| {
            let mut occupancy = MapOccupancy::new(width, height);
            for (k, (d, t)) in d.iter().zip(&tint.values).enumerate() {
                occupancy.mark(k % width, k / width, d * t[c]);
            }
            occupancy
        })
    }

    /// The heap memory of its channels' maps, in bytes (the density map is the material's).
    pub(crate) fn heap_bytes(&self) -> usize {
        channel_bytes(&self.channels)
    }

    /// ∫d·t / ∫d over the square: the flakes' mean tint.
    pub(crate) fn mean(&self) -> DVec3 {
        let mass = self.density.mean();
        DVec3::from_array(
            self.channels
                .each_ref()
                .map(|c| c.as_ref().map_or(0.0, |map| map.mean() / mass)),
        )
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

/// The heap memory of a tint's per-channel density maps.
fn channel_bytes(channels: &[Option<Arc<DensityMap>>; 3]) -> usize {
    channels.iter().flatten().map(|map| map.heap_bytes()).sum()
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

/// The α of each roughness level for roughness map `alpha` and at most `levels` levels (see
/// the module docs), and whether they are exact (the map's own distinct values). Interpolated
/// levels run from the map's least to its greatest α, both exactly, evenly in log α between.
///
/// # Errors
/// [`BrdfError::InvalidRoughnessLevels`] unless 1 ≤ `levels` ≤ [`MAX_ROUGHNESS_LEVELS`];
/// [`BrdfError::TooFewRoughnessLevels`] for one level and a map of more than one α (the hat
/// functions need two levels to interpolate between).
pub(crate) fn level_alphas(
    alpha: &RoughnessMap,
    levels: usize,
) -> Result<(Vec<f64>, bool), BrdfError> {
    if !(1..=MAX_ROUGHNESS_LEVELS).contains(&levels) {
        return Err(BrdfError::InvalidRoughnessLevels { levels });
    }
    // The map's distinct values while there are at most `levels` + 1 of them (kept sorted),
    // and its extremes: one pass, no copy of the map.
    let mut distinct: Vec<f64> = Vec::with_capacity(levels + 1);
    let (mut least, mut greatest) = (f64::INFINITY, f64::NEG_INFINITY);
    for &a in &alpha.values {
        (least, greatest) = (least.min(a), greatest.max(a));
        if distinct.len() <= levels
            && let Err(at) = distinct.binary_search_by(|x| x.total_cmp(&a))
        {
            distinct.insert(at, a);
        }
    }
    if distinct.len() <= levels {
        return Ok((distinct, true));
    }
    if levels == 1 {
        return Err(BrdfError::TooFewRoughnessLevels {
            distinct: distinct.len(),
        });
    }
    let (low, high) = (least.ln(), greatest.ln());
    if !(high > low) {
        // Values a few ulps apart near 10⁻⁴ share their logarithm: one level holds them all.
        return Ok((vec![least], false));
    }
    let interpolated = (0..levels)
        .map(|k| match k {
            0 => least,
            k if k == levels - 1 => greatest,
            k => (low + (high - low) * k as f64 / (levels - 1) as f64)
                .exp()
                .clamp(least, greatest),
        })
        .collect();
    Ok((interpolated, false))
}

/// The share w_k(x) of each roughness level in each texel's flakes (see the module docs), with
/// the density d(x) they multiply: the values of the levels' density maps d·w_k.
pub(crate) struct LevelWeights<'a> {
    /// d of each texel (`None`: 1 everywhere).
    density: Option<Vec<f64>>,
    alpha: &'a RoughnessMap,
    /// The levels' α.
    pub(crate) alphas: Vec<f64>,
    /// Whether the levels are the map's own values (w_k(x) = [α(x) = α_k]).
    exact: bool,
    /// Interpolated levels: each texel's position in [0, K − 1] between them (log α).
    positions: Vec<f64>,
}

impl<'a> LevelWeights<'a> {
    /// The weights of roughness map `alpha`'s levels, at most `levels` of them, over density
    /// map `density` (the size and filter of `alpha`; checked by the caller).
    ///
    /// # Errors
    /// Those of [`level_alphas`].
    pub(crate) fn new(
        density: Option<&'a DensityMap>,
        alpha: &'a RoughnessMap,
        levels: usize,
    ) -> Result<Self, BrdfError> {
        let (alphas, exact) = level_alphas(alpha, levels)?;
        let last = alphas.len() - 1;
        let positions: Vec<f64> = if exact || last == 0 {
            Vec::new()
        } else {
            let (low, high) = (alphas[0].ln(), alphas[last].ln());
            alpha
                .values
                .iter()
                .map(|a| ((a.ln() - low) / (high - low) * last as f64).clamp(0.0, last as f64))
                .collect()
        };
        Ok(Self {
            density: density.map(DensityMap::texels),
            alpha,
            alphas,
            exact,
            positions,
        })
    }

    /// Texel k's levels with their weights: 1 on its own α where exact, else the hat
    /// functions of log α centred on the levels (non-zero on the two levels around its
    /// position, at most). A second entry of weight 0 stands for none.
    fn weights(&self, k: usize) -> [(usize, f64); 2] {
        let last = self.alphas.len() - 1;
        if self.exact {
            let a = self.alpha.values[k];
            let level = self
                .alphas
                .binary_search_by(|x| x.total_cmp(&a))
                .expect("exact levels hold every value of the map");
            return [(level, 1.0), (level, 0.0)];
        }
        if last == 0 {
            return [(0, 1.0), (0, 0.0)];
        }
        let position = self.positions[k];
        let below = (position.floor() as usize).min(last - 1);
        let above = position - below as f64;
        [(below, 1.0 - above), (below + 1, above)]
    }

    /// w of texel k on `level`: [`Self::weights`]' entry for it, else 0.
    fn weight(&self, k: usize, level: usize) -> f64 {
        if self.exact {
            return f64::from(u8::from(self.alpha.values[k] == self.alphas[level]));
        }
        let last = self.alphas.len() - 1;
        if last == 0 {
            return 1.0;
        }
        // A hat is 0 a level or more from its centre, exactly as the two weights below give
        // it (at |position − level| = 1 they give it weight 0): most texels stop here.
        if (self.positions[k] - level as f64).abs() >= 1.0 {
            return 0.0;
        }
        match self.weights(k) {
            [(below, w), _] if below == level => w,
            [_, (above, w)] if above == level => w,
            _ => 0.0,
        }
    }

    /// d·w of texel k on `level` (d·w ≤ 1, both are; the clamp only absorbs rounding).
    fn value(&self, k: usize, level: usize) -> f64 {
        self.value_of(k, self.weight(k, level))
    }

    /// d·w of texel k for its weight `w`.
    fn value_of(&self, k: usize, w: f64) -> f64 {
        let d = self.density.as_ref().map_or(1.0, |d| d[k]);
        (d * w).clamp(0.0, 1.0)
    }

    /// The values of `level`'s density map, row by row as a map's values are given.
    pub(crate) fn values(&self, level: usize) -> Vec<f64> {
        (0..self.alpha.values.len())
            .map(|k| self.value(k, level))
            .collect()
    }

    /// Every texel's lower level and its values on that level and the next (the levels'
    /// values, two at a time): the family a material's levels share where each stored as its
    /// own map would hold far more ([`LevelBytes::shared`]).
    ///
    /// # Errors
    /// [`BrdfError::DensityMap`] should the family be refused (its size and values are those
    /// of maps already checked).
    fn family(&self) -> Result<LevelTexels, BrdfError> {
        let (width, height) = self.alpha.size();
        LevelTexels::new(width, height, self.alphas.len(), |k| {
            let [(lower, w), (_, w_next)] = self.weights(k);
            (lower, [self.value_of(k, w), self.value_of(k, w_next)])
        })
        .map_err(BrdfError::DensityMap)
    }

    /// Which tiles each level's density map would occupy, in one pass over the texels.
    pub(crate) fn occupancies(&self) -> Vec<MapOccupancy> {
        let (width, height) = self.alpha.size();
        let mut occupancies = vec![MapOccupancy::new(width, height); self.alphas.len()];
        for k in 0..self.alpha.values.len() {
            for (level, w) in self.weights(k) {
                if w > 0.0 {
                    occupancies[level].mark(k % width, k / width, self.value_of(k, w));
                }
            }
        }
        occupancies
    }
}

/// What a roughness map's levels hold, counted before they are built, in either of the two
/// ways a material keeps them: each level as its own density map (tiled where it is 0 over
/// whole tiles), or all of them blocked over one family of texels ([`LevelTexels`]: 9 bytes a
/// texel, and [`DensityMap::roughness_level_bytes`] a level, about 0.36 bytes a texel).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct LevelBytes {
    /// How many levels hold a non-zero value (the others are not built).
    pub(crate) maps: usize,
    /// Their bytes, each its own density map.
    own: u64,
    /// Their bytes, blocked over one family.
    shared: u64,
    /// Texels a level.
    texels: usize,
}

impl LevelBytes {
    /// The bytes of the levels of `weights`, from one pass over the texels.
    pub(crate) fn of(weights: &LevelWeights) -> Self {
        let occupancies = weights.occupancies();
        let nonempty = || occupancies.iter().filter(|o| !o.is_empty());
        let (width, height) = weights.alpha.size();
        let maps = nonempty().count();
        let own = nonempty()
            .map(|o| DensityMap::bytes_for_occupancy(o) as u64)
            .sum();
        let shared = (LevelTexels::bytes_for(width, height)
            + maps * DensityMap::roughness_level_bytes(width, height)) as u64;
        Self {
            maps,
            own,
            shared,
            texels: width * height,
        }
    }

    /// Whether the levels share one family of texels: where that holds at most a quarter of
    /// the bytes of the levels' own maps, as where α changes within most tiles over several
    /// levels (white noise over 8 levels: 11.8 bytes a texel against 102). A shared level
    /// reads its texels where a box cuts its 8 × 8 blocks and compares texels to tell whether
    /// a box under a block is constant, so those questions cost more than under its own map,
    /// while a leaf's box of up to 64 × 64 texels is read once, so placements cost less.
    /// Queries on one level's 1024² map took 0.84–1.00× the time of its own map's (bilinear:
    /// 0.92× for white noise, 1.33× for a gradient's level); a glitter_pattern frame (a
    /// 256 × 128 map of two α, tiny boxes) 1.065× the instructions (docs/performance.md). So
    /// where the levels' own tiled maps hold less than 4× the family's bytes (α smooth or in
    /// regions: about two maps' worth) they are kept. From
    /// [`DensityMap::FEWEST_BYTES_FROM_TEXELS`] texels a level on, memory decides, as it
    /// does for each level's own map (which may then be blocked itself): the levels share
    /// wherever that holds fewer bytes.
    pub(crate) fn shared(&self) -> bool {
        if self.texels >= DensityMap::FEWEST_BYTES_FROM_TEXELS {
            self.shared < self.own
        } else {
            4 * self.shared <= self.own
        }
    }

    /// The bytes the levels hold, kept as [`Self::shared`] says.
    pub(crate) fn bytes(&self) -> u64 {
        if self.shared() { self.shared } else { self.own }
    }
}

/// The roughness levels of a material with density map `density` and the roughness map's
/// level `weights` (`MapBytes::level_weights`: at most `levels` of them, see the module docs);
/// levels whose density is 0 everywhere are left out. Without a roughness map, one level: the
/// material's α and its density map. The levels' density maps are built one at a time (one
/// map's texels at once besides them), or, `shared` ([`LevelBytes::shared`]), blocked over one
/// family of texels that they all read.
///
/// # Errors
/// [`BrdfError::MapSizesDiffer`] when both maps are given with different sizes; those of
/// [`level_alphas`].
pub(crate) fn roughness_levels(
    density: Option<&Arc<DensityMap>>,
    weights: Option<LevelWeights>,
    levels: usize,
    shared: bool,
) -> Result<Vec<RoughnessLevel>, BrdfError> {
    if !(1..=MAX_ROUGHNESS_LEVELS).contains(&levels) {
        return Err(BrdfError::InvalidRoughnessLevels { levels });
    }
    let Some(weights) = weights else {
        return Ok(vec![RoughnessLevel {
            alpha: None,
            density: density.cloned(),
        }]);
    };
    let alpha = weights.alpha;
    let (width, height) = alpha.size();
    if let Some(density) = density
        && density.size() != (width, height)
    {
        return Err(BrdfError::MapSizesDiffer {
            density: density.size(),
            alpha: (width, height),
        });
    }
    if let Some(density) = density
        && density.filter() != alpha.filter()
    {
        return Err(BrdfError::MapFiltersDiffer {
            density: density.filter(),
            alpha: alpha.filter(),
        });
    }
    let family = shared.then(|| weights.family().map(Arc::new)).transpose()?;
    let mut result = Vec::new();
    for (level, &level_alpha) in weights.alphas.iter().enumerate() {
        let map = match &family {
            Some(family) => DensityMap::roughness_level(family, level, alpha.filter()),
            None => DensityMap::with_filter(width, height, &weights.values(level), alpha.filter()),
        };
        match map {
            Ok(map) => result.push(RoughnessLevel {
                alpha: Some(level_alpha),
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Levels that share one family of texels are the levels' own maps: for noisy α over a
    /// density map with zeros, interpolated (8 and 2 levels) and exact (3 values), filtered
    /// nearest and bilinear, every level's texels and its answers on random boxes and
    /// footprints are bit for bit those of the level's map built from its values.
    /// Below `DensityMap::FEWEST_BYTES_FROM_TEXELS` texels the levels share their texels only
    /// for a fourfold saving (a shared level answers small boxes slower than its own whole
    /// map); from there on, where it saves anything (the levels' own maps are blocked then).
    #[test]
    fn large_levels_share_wherever_that_holds_fewer_bytes() {
        let large = DensityMap::FEWEST_BYTES_FROM_TEXELS;
        let bytes = |texels, own, shared| LevelBytes {
            maps: 4,
            own,
            shared,
            texels,
        };
        assert!(!bytes(large - 1, 300, 100).shared());
        assert!(bytes(large - 1, 400, 100).shared());
        assert!(bytes(large, 300, 100).shared());
        assert!(!bytes(large, 100, 100).shared());
        assert_eq!(bytes(large, 300, 100).bytes(), 100);
        assert_eq!(bytes(large - 1, 300, 100).bytes(), 300);
    }

    #[test]
    fn shared_levels_are_the_levels_own_maps() {
        let (width, height) = (67, 45);
        let texels = width * height;
        let mut state = 12_345u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let noisy: Vec<f64> = (0..texels).map(|_| 0.02 * 20f64.powf(next())).collect();
        let three: Vec<f64> = (0..texels).map(|k| [0.05, 0.1, 0.2][k * k % 3]).collect();
        let density: Vec<f64> = (0..texels)
            .map(|k| if k % 7 == 0 { 0.0 } else { next() })
            .collect();
        let cases = [(&noisy, 8), (&noisy, 2), (&three, 8)];
        for ((alphas, levels), filter) in cases
            .into_iter()
            .flat_map(|case| [MapFilter::Nearest, MapFilter::Bilinear].map(|filter| (case, filter)))
        {
            let density =
                Arc::new(DensityMap::with_filter(width, height, &density, filter).unwrap());
            let alpha = RoughnessMap::new(width, height, alphas)
                .unwrap()
                .with_filter(filter);
            let build = |shared| {
                let weights = LevelWeights::new(Some(&density), &alpha, levels).unwrap();
                roughness_levels(Some(&density), Some(weights), levels, shared).unwrap()
            };
            let (own, shared) = (build(false), build(true));
            assert_eq!(own.len(), shared.len());
            for (own, shared) in own.iter().zip(&shared) {
                assert_eq!(own.alpha, shared.alpha);
                let (own, shared) = (
                    own.density.as_ref().unwrap(),
                    shared.density.as_ref().unwrap(),
                );
                assert!(own.level_texels().is_none() && shared.level_texels().is_some());
                assert_eq!(own.texels(), shared.texels());
                assert_eq!(
                    (own.mean(), own.uniform_value(), own.max()),
                    (shared.mean(), shared.uniform_value(), shared.max())
                );
                for _ in 0..300 {
                    let [a, b, c, d] = [next(), next(), next(), next()];
                    let size = 0.5 * c * c;
                    let min = DVec2::new(a * (1.0 - size), b * (1.0 - size));
                    let footprint = Footprint::new(
                        DVec2::new(a, b),
                        DVec2::new(size, 0.3 * size * (d - 0.5)),
                        DVec2::new(0.2 * size * d, 0.8 * size),
                    )
                    .unwrap();
                    let answers = |map: &DensityMap| {
                        (
                            map.is_constant_over(min, size),
                            map.quarter_probabilities(min, size),
                            map.place(min, size, [c, d]),
                            map.max_over(&footprint),
                            map.mass_in(&footprint),
                        )
                    };
                    assert_eq!(answers(own), answers(shared), "box {min} {size}");
                }
            }
        }
    }
}
