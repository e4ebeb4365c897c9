//! A density map d(x) ∈ [0, 1] over the particles' unit square: the particle density at
//! texture position x is N·d(x). It is reconstructed from W × H texels by its [`MapFilter`]:
//! piecewise constant over each texel (`Nearest`, described here) or bilinear between the
//! texels' centres (`Bilinear`, `density_map/bilinear.rs`), and tiles with the
//! square. The count tree reads it in three places, each exact for the reconstructed map:
//!
//! - **Spatial splits** ([`DensityMap::quarter_probabilities`]): the four quarters of a box take
//!   probabilities proportional to their mass ∫d, as directional splits take the integrals of p
//!   over the child triangles. Where the map is constant over a box
//!   ([`DensityMap::is_constant_over`]) there is nothing to weigh and the tree splits exactly as
//!   it does without a map.
//! - **Leaves** ([`DensityMap::place`]): a particle's position is the inverse of the map's
//!   distribution function within the leaf's box (column by the marginal, then row within it),
//!   from the same two uniform numbers that place it uniformly without a map. Texels where
//!   d = 0 never receive a particle.
//! - **Expectations** ([`DensityMap::mass_in`]): ∫_A d over a footprint, for the expected count
//!   N·∫_A d·∫p and a tint's footprint mean: row by row, the texels wholly inside from the
//!   summed-area table and the texels the footprint's edges cut clipped to it, so its cost
//!   grows with the footprint's perimeter in texels.
//!
//! Masses are exact sums of integers: texel values are fixed point (multiples of 2⁻³², so
//! d = 0 is exactly 0 and a box of zero texels has mass exactly 0), held only in a summed-area
//! table of u64 (a texel's value is the table's second difference there), combined with the
//! box's partial texel weights in one final floating-point step. Whether a box is constant is
//! a count of value changes between neighbouring texels inside it, from one more summed-area
//! table: O(1) per box (see [`DensityMap::is_constant_over`]).
//!
//! - **Bounds** ([`DensityMap::max_over`]): an upper bound on d over a footprint, from a
//!   pyramid of maxima over blocks of 4 × 4 texels and up, for the negligible-query test.
//!
//! Memory: at most about 12.7 bytes per texel (8 for the summed-area table, which also holds
//! the values, 4 for the table of changes, 0.7 for the pyramid of maxima), at most
//! [`DensityMap::MAX_TEXELS`] texels. A map of 2²² texels or more (2048², where memory rather
//! than the last few percent of speed decides) keeps whichever layout holds the fewest bytes,
//! usually its own texels in 33 bits with tables over 8 × 8 blocks, about 4.5 bytes a texel
//! (`density_map/blocked.rs`, [`LevelTexels`]'s single map; its large leaves' placements in
//! `density_map/large_box.rs`): the same integers, so the same answers, bit for bit. A map
//! that is 0 over about a third or more of its square
//! (a roughness level's d·w_k, a sparse mask) keeps its tables in tiles of 64 × 64 texels and
//! stores only the tiles that hold a non-zero value, about 0.4 bytes a texel besides
//! (`density_map/tables.rs`, which derives it): the same integers, so the same answers, bit
//! for bit. The layout is chosen from the values (tiled where that saves at least a third of
//! the bytes); [`DensityMap::bytes_for_values`] counts it before building. A roughness
//! map's levels whose α changes within most tiles share one family of texels instead
//! ([`DensityMap::roughness_level`], `density_map/level_texels.rs` and `blocked.rs`): tables
//! over 8 × 8 blocks only, about 0.36 bytes a texel a level besides the family's 9.

use std::fmt;
use std::sync::Arc;

use glam::DVec2;

use crate::footprint::Footprint;

mod bilinear;
mod blocked;
mod large_box;
mod level_texels;
mod polygon;
mod tables;

use level_texels::{BLOCK, BLOCK_SHIFT};
pub use level_texels::{LevelTexels, MAX_LEVELS};
use polygon::{clip, columns_met, polygon_area, whole_columns, within};
pub use tables::MapOccupancy;
use tables::{Layout, MaxPyramid, PrefixTable, Tables};

/// Fixed-point scale of stored values: d is held as round(d·2³²).
const FIXED_ONE: f64 = 4_294_967_296.0;

// The finest level of the pyramid of maxima, `tables::FIRST_MAX_LEVEL`, has blocks of 4 × 4
// texels (the 2 × 2 level would cost 2 bytes a texel; its blocks are read from the texels
// instead, at most 16 of them).

/// Footprints whose bounding box covers more texels than this get their mass from the
/// map's mean (as the tree averages footprints over many tiles): integrating them texel by
/// texel would cost more than the query.
const MAX_INTEGRATED_TEXELS: f64 = 65_536.0;

/// How a map is reconstructed from its texels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum MapFilter {
    /// Piecewise constant: each texel's value over its whole square (the edges stair-step).
    #[default]
    Nearest,
    /// Bilinear between the texels' centres, wrapping as the map tiles: continuous, so a
    /// mask's edge ramps over one texel (`density_map/bilinear.rs`).
    Bilinear,
}

impl MapFilter {
    /// Every filter, in the order of [`MapFilter::NAMES`].
    pub const ALL: [Self; 2] = [Self::Nearest, Self::Bilinear];

    /// The filters' names in scene files, `eval`, Python and Mitsuba.
    pub const NAMES: [&'static str; 2] = ["nearest", "bilinear"];

    /// The filter called `name` (one of [`MapFilter::NAMES`]).
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::NAMES
            .iter()
            .position(|n| *n == name)
            .map(|k| Self::ALL[k])
    }

    /// Its name, as [`MapFilter::from_name`] reads it.
    #[must_use]
    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }
}

/// Why a density map was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DensityMapError {
    /// Width and height must be at least 1, with at most [`DensityMap::MAX_TEXELS`] texels.
    InvalidSize {
        /// The width given.
        width: usize,
        /// The height given.
        height: usize,
    },
    /// The values must be width × height, row by row.
    WrongLength {
        /// width × height.
        expected: usize,
        /// The number of values given.
        given: usize,
    },
    /// A texel's value is not in [0, 1].
    InvalidTexel {
        /// Its column (0 at u = 0).
        column: usize,
        /// Its row (0 at the top of the texture, v near 1).
        row: usize,
        /// The value.
        value: f64,
    },
    /// Every texel is 0: the material would have no particle at all.
    Empty,
    /// A family of levels ([`LevelTexels`]) must have 1 to [`MAX_LEVELS`] of them.
    InvalidLevels {
        /// The number of levels given.
        levels: usize,
    },
}

impl fmt::Display for DensityMapError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::InvalidSize { width, height } => write!(
                f,
                "a {width} x {height} map is invalid: it needs at least one texel and at most {} texels",
                DensityMap::MAX_TEXELS
            ),
            Self::WrongLength { expected, given } => {
                write!(f, "the map has {given} values for {expected} texels")
            }
            Self::InvalidTexel { column, row, value } => write!(
                f,
                "texel (column {column}, row {row}) is {value:?}: densities must be in [0, 1]"
            ),
            Self::Empty => write!(
                f,
                "every texel is 0 (or below 2^-33 = {:.2e}, half the map's fixed-point step, which \
                 rounds to 0): the material would hold no particle",
                0.5 / FIXED_ONE
            ),
            Self::InvalidLevels { levels } => write!(
                f,
                "a family of {levels} levels is invalid: it needs 1 to {MAX_LEVELS}"
            ),
        }
    }
}

impl std::error::Error for DensityMapError {}

/// A piecewise-constant density d(x) ∈ [0, 1] over the unit square (see the module docs).
#[derive(Clone, PartialEq)]
pub struct DensityMap {
    width: usize,
    height: usize,
    /// The summed-area tables, whole or tiled (`tables.rs`): `sums` at corner (i, j) is the
    /// sum of the fixed-point texel values q over rows < j and columns < i, row j covering
    /// v ∈ [j/H, (j + 1)/H) (row 0 at v = 0); `changes` the same sum of the texel changes
    /// g(i, j) = [q(i, j) ≠ q(i + 1, j)] + [q(i, j) ≠ q(i, j + 1)], a neighbour outside the
    /// map counting as no change; `maxima` the maxima of q over blocks of 2^L × 2^L texels,
    /// L = `tables::FIRST_MAX_LEVEL` (blocked: `BLOCK_SHIFT`), … until one block holds the
    /// map (block (i, j) covers texels [i·2^L, (i + 1)·2^L)). Smaller blocks are read from the
    /// texels. A blocked level (`blocked.rs`) keeps `sums` and `changes` at the corners of
    /// whole 8 × 8 blocks only and reads its texels from the family it shares.
    tables: Tables,
    /// How d is reconstructed from the texels.
    filter: MapFilter,
    /// The value when every texel has it.
    uniform: Option<f64>,
    /// ∫d over the unit square.
    mean: f64,
}

impl fmt::Debug for DensityMap {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("DensityMap")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("mean", &self.mean)
            .field("uniform", &self.uniform)
            .finish_non_exhaustive()
    }
}

/// Texels [first, last] along one axis of `n` that [lo, hi] covers with positive length,
/// with the fraction of each end texel covered (1 for interior ones).
#[derive(Clone, Copy, Debug)]
struct TexelSpan {
    first: usize,
    last: usize,
    first_weight: f64,
    last_weight: f64,
}

impl TexelSpan {
    fn new(lo: f64, hi: f64, n: usize) -> Self {
        let scale = n as f64;
        let (lo, hi) = (lo * scale, hi * scale);
        let first = (lo.floor().max(0.0) as usize).min(n - 1);
        let last = ((hi.ceil() - 1.0).max(0.0) as usize).clamp(first, n - 1);
        let (first_weight, last_weight) = if first == last {
            ((hi - lo).clamp(0.0, 1.0), (hi - lo).clamp(0.0, 1.0))
        } else {
            (
                ((first + 1) as f64 - lo).clamp(0.0, 1.0),
                (hi - last as f64).clamp(0.0, 1.0),
            )
        };
        Self {
            first,
            last,
            first_weight,
            last_weight,
        }
    }

    /// The span as up to three groups (first, interior, last) of texels [a, b) and weights.
    fn groups(&self) -> impl Iterator<Item = (usize, usize, f64)> {
        let single = self.first == self.last;
        let interior = self.first + 1 < self.last;
        [
            Some((self.first, self.first + 1, self.first_weight)),
            interior.then_some((self.first + 1, self.last, 1.0)),
            (!single).then_some((self.last, self.last + 1, self.last_weight)),
        ]
        .into_iter()
        .flatten()
    }
}

impl DensityMap {
    /// The largest map: 2²⁸ texels (16384 × 16384, or 8192 × 32768), 3.4 GB of tables
    /// ([`Self::bytes_for`]). The tables' integers hold any map up to 2³¹ texels; the bound
    /// keeps one map within a material's budget (`glint_brdf::MAX_MAP_BYTES`).
    pub const MAX_TEXELS: usize = 1 << 28;

    /// Maps of at least this many texels (2²², 2048 × 2048) keep the layout of fewest bytes,
    /// blocked tables over their own texels included (about 4.5 bytes a texel where 12.7
    /// whole); smaller maps keep the faster whole tables unless tiles save a third.
    pub const FEWEST_BYTES_FROM_TEXELS: usize = tables::BLOCKED_FROM_TEXELS;

    /// The most heap memory, in bytes, a `width` × `height` map may hold: its tables whole,
    /// the summed-area table (8 bytes a texel), the table of value changes (4 bytes a texel)
    /// and the pyramid of maxima (about 2/3 of a byte a texel). A function of the size alone,
    /// so a material can bound its budget before it builds a map; a map whose tiled tables
    /// are smaller holds those ([`Self::bytes_for_values`]).
    #[must_use]
    pub fn bytes_for(width: usize, height: usize) -> usize {
        Layout::whole_bytes(width, height, &MaxPyramid::sizes(width, height))
    }

    /// The heap memory, in bytes, the map of `width` × `height` `values` (as for
    /// [`Self::new`], and valid) will hold: its tables whole or, where the values are 0 over
    /// enough of the map, in tiles that leave those regions out (`density_map/tables.rs`).
    /// What [`Self::heap_bytes`] of the built map says, without building it; 0 for values
    /// that are all 0 (no map is built from them).
    #[must_use]
    pub fn bytes_for_values(width: usize, height: usize, values: &[f64]) -> usize {
        Tables::bytes_for(&MapOccupancy::of_values(width, height, values))
    }

    /// [`Self::bytes_for_values`] from the tiles that the values would occupy: what a map of
    /// values marked into `occupancy` will hold.
    #[must_use]
    pub fn bytes_for_occupancy(occupancy: &MapOccupancy) -> usize {
        Tables::bytes_for(occupancy)
    }

    /// The heap memory this map holds, in bytes, its own texels included where it keeps them
    /// (a large map's blocked layout) but not a roughness level's family of texels (the
    /// levels share it, [`Self::level_texels`]).
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        self.tables.heap_bytes()
    }

    /// [`Self::heap_bytes`] with the family of texels it reads, if any: what the map holds
    /// when it is the only one reading its family.
    #[must_use]
    pub fn heap_bytes_with_texels(&self) -> usize {
        self.heap_bytes() + self.level_texels().map_or(0, |texels| texels.heap_bytes())
    }

    /// The family of texels a [`Self::roughness_level`] reads, which its levels share (`None`
    /// for a map that holds its own tables and texels).
    #[must_use]
    pub fn level_texels(&self) -> Option<&Arc<LevelTexels>> {
        match &self.tables.sums {
            PrefixTable::Blocked(table) if !table.texels().is_single() => Some(table.texels()),
            _ => None,
        }
    }

    /// A map of `width` × `height` texels from `values` given row by row, **row 0 at the top of
    /// the texture** (v from 1 − 1/H to 1), column 0 starting at u = 0: the order of an image.
    ///
    /// # Errors
    /// A [`DensityMapError`] naming the size, or the first texel not in [0, 1]; a map of zeros.
    pub fn new(width: usize, height: usize, values: &[f64]) -> Result<Self, DensityMapError> {
        Self::with_filter(width, height, values, MapFilter::Nearest)
    }

    /// [`DensityMap::new`] with d reconstructed by `filter` between the texels (the tables
    /// are the same; the counts are exact for the reconstructed d).
    ///
    /// # Errors
    /// Those of [`DensityMap::new`].
    pub fn with_filter(
        width: usize,
        height: usize,
        values: &[f64],
        filter: MapFilter,
    ) -> Result<Self, DensityMapError> {
        Self::with_layout(width, height, values, filter, None)
    }

    /// [`DensityMap::with_filter`] with its tables in `layout` (`None`: the one of fewer
    /// bytes).
    fn with_layout(
        width: usize,
        height: usize,
        values: &[f64],
        filter: MapFilter,
        layout: Option<Layout>,
    ) -> Result<Self, DensityMapError> {
        let texels = width.saturating_mul(height);
        if width == 0 || height == 0 || texels > Self::MAX_TEXELS {
            return Err(DensityMapError::InvalidSize { width, height });
        }
        if values.len() != texels {
            return Err(DensityMapError::WrongLength {
                expected: texels,
                given: values.len(),
            });
        }
        if let Some(k) = values.iter().position(|value| !(0.0..=1.0).contains(value)) {
            let (row, column) = (k / width, k % width);
            let value = values[k];
            return Err(DensityMapError::InvalidTexel { column, row, value });
        }
        // Row j (from v = 0) is row H − 1 − j of the values as given.
        let q = |i: usize, j: usize| fixed_point(values[(height - 1 - j) * width + i]);
        let occupancy = MapOccupancy::of_values(width, height, values);
        let tables = Tables::new(width, height, &q, &occupancy, layout);
        Self::from_tables(width, height, tables, filter)
    }

    /// The map of `tables` (of a `width` × `height` map), its uniform value and mean read from
    /// them.
    ///
    /// # Errors
    /// [`DensityMapError::Empty`] when every texel is 0.
    fn from_tables(
        width: usize,
        height: usize,
        tables: Tables,
        filter: MapFilter,
    ) -> Result<Self, DensityMapError> {
        let total = tables.sums.at(width, height);
        if total == 0 {
            return Err(DensityMapError::Empty);
        }
        // No value changes between neighbours: every texel has the first one's value.
        let uniform = (tables.changes.at(width, height) == 0)
            .then(|| tables.sums.cell(0, 0) as f64 / FIXED_ONE);
        let mean = total as f64 / (FIXED_ONE * (width * height) as f64);
        Ok(Self {
            width,
            height,
            tables,
            filter,
            uniform,
            mean,
        })
    }

    /// Level `level` of the family `texels` (a roughness level's map d·w_k, reconstructed by
    /// `filter`), its tables over blocks and its texels read from the family
    /// (`density_map/blocked.rs`): the same fixed-point values, so the same answers bit for
    /// bit, as [`DensityMap::with_filter`] of the level's values gives, in
    /// [`Self::roughness_level_bytes`] (about 0.36 bytes a texel) besides the family's 9, where
    /// a map stored whole takes 12.7.
    ///
    /// # Errors
    /// [`DensityMapError::Empty`] when the level is 0 at every texel (or not in the family).
    pub fn roughness_level(
        texels: &Arc<LevelTexels>,
        level: usize,
        filter: MapFilter,
    ) -> Result<Self, DensityMapError> {
        if level >= texels.levels() {
            return Err(DensityMapError::Empty);
        }
        let (width, height) = texels.size();
        Self::from_tables(width, height, Tables::blocked(texels, level), filter)
    }

    /// The heap memory a `width` × `height` [`Self::roughness_level`] holds, in bytes: its
    /// summed-area tables at the corners of whole 8 × 8 blocks (12 bytes a block) and its
    /// pyramid of maxima from those blocks up (about 11 bytes a block).
    #[must_use]
    pub fn roughness_level_bytes(width: usize, height: usize) -> usize {
        Tables::blocked_bytes(width, height)
    }

    /// How d is reconstructed from the texels.
    #[must_use]
    pub fn filter(&self) -> MapFilter {
        self.filter
    }

    /// Width and height in texels.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// ∫d over the unit square: a tile holds N times this many particles on average.
    #[must_use]
    pub fn mean(&self) -> f64 {
        self.mean
    }

    /// The mean of d over the square of side `side` < 1 centred on `centre`, wrapped across
    /// the texture square's edges (as the map repeats), from the summed-area tables of at most
    /// four pieces (nearest or bilinear, as the map is filtered); continuous in `centre` and
    /// `side`.
    #[must_use]
    pub fn mean_over_square(&self, centre: DVec2, side: f64) -> f64 {
        if let Some(value) = self.uniform {
            return value;
        }
        let texels = side * side * (self.width * self.height) as f64;
        if !(texels > 0.0 && side < 1.0) {
            return if side >= 1.0 {
                self.mean
            } else {
                self.value_at(centre)
            };
        }
        // Each axis's interval, its low end wrapped into [0, 1), as at most two pieces within
        // the square.
        let pieces = |c: f64| {
            let lo = (c - 0.5 * side).rem_euclid(1.0);
            let first = (1.0 - lo).min(side);
            [(lo, first), (0.0, side - first)]
        };
        let (columns, rows) = (pieces(centre.x), pieces(centre.y));
        let mut mass = 0.0;
        for &(y, height) in &rows {
            for &(x, width) in &columns {
                if width > 0.0 && height > 0.0 {
                    mass += self.rect_mass(DVec2::new(x, y), DVec2::new(width, height));
                }
            }
        }
        mass / (FIXED_ONE * texels)
    }

    /// The value of every texel, when they are all equal (as stored: a multiple of 2⁻³²).
    #[must_use]
    pub fn uniform_value(&self) -> Option<f64> {
        self.uniform
    }

    /// The largest value (as stored).
    #[must_use]
    pub fn max(&self) -> f64 {
        self.tables.maxima.top() as f64 / FIXED_ONE
    }

    /// d of the texel in `column` and `row`, row 0 at the top as given (as stored).
    #[must_use]
    pub fn texel(&self, column: usize, row: usize) -> f64 {
        self.fixed(column, self.height - 1 - row) as f64 / FIXED_ONE
    }

    /// Every texel's d (as stored), row by row from the top as values are given: what
    /// [`Self::texel`] gives for each, in one pass. Each row of the summed-area table is read
    /// once: texel (i, j)'s q is the difference of two columns' sums up to rows j + 1 and j.
    #[must_use]
    pub fn texels(&self) -> Vec<f64> {
        let sums = &self.tables.sums;
        if let PrefixTable::Blocked(_) = sums {
            // A blocked level reads its texels directly (its corners cover whole blocks only).
            return (0..self.height)
                .flat_map(|row| (0..self.width).map(move |column| self.texel(column, row)))
                .collect();
        }
        let read_corners = |j: usize, corners: &mut [u64]| {
            for (i, corner) in corners.iter_mut().enumerate() {
                *corner = sums.at(i, j);
            }
        };
        let mut values = vec![0.0; self.width * self.height];
        let (mut below, mut above) = (vec![0; self.width + 1], vec![0; self.width + 1]);
        read_corners(0, &mut below);
        for j in 0..self.height {
            read_corners(j + 1, &mut above);
            let row = &mut values[(self.height - 1 - j) * self.width..][..self.width];
            for (i, value) in row.iter_mut().enumerate() {
                let q = (above[i + 1] - above[i]) - (below[i + 1] - below[i]);
                *value = q as f64 / FIXED_ONE;
            }
            std::mem::swap(&mut below, &mut above);
        }
        values
    }

    /// The fixed-point value q of texel (i, j), j counted from v = 0: the summed-area table's
    /// second difference.
    fn fixed(&self, i: usize, j: usize) -> u64 {
        self.tables.sums.cell(i, j)
    }

    /// The largest q over block (i, j) of 2^`level` × 2^`level` texels: the pyramid's entry, or
    /// the texels' own values for blocks finer than the pyramid's first level.
    fn block_max(&self, level: usize, i: usize, j: usize) -> Option<u64> {
        let first_level = self.tables.maxima.first_level();
        if level < first_level {
            let (columns, rows) = (i << level..(i + 1) << level, j << level..(j + 1) << level);
            let columns = columns.start..columns.end.min(self.width);
            let rows = rows.start..rows.end.min(self.height);
            return rows
                .flat_map(|j| columns.clone().map(move |i| (i, j)))
                .map(|(i, j)| self.fixed(i, j))
                .max();
        }
        self.tables.maxima.block(level - first_level, i, j)
    }

    /// An upper bound on d over the footprint's parallelogram (its bounding box, wrapped):
    /// the largest value of the few blocks of the pyramid of maxima that cover the box, so the
    /// bound is exact where the box covers whole blocks and never below the true maximum.
    #[must_use]
    pub fn max_over(&self, footprint: &Footprint) -> f64 {
        if let Some(value) = self.uniform {
            return value;
        }
        let (mut min, mut max) = footprint.bounds();
        if self.filter == MapFilter::Bilinear {
            // The texels whose tents meet the box: one more on each side.
            let texel = DVec2::new(1.0 / self.width as f64, 1.0 / self.height as f64);
            (min, max) = (min - texel, max + texel);
        }
        let spans = |lo: f64, hi: f64, n: usize| -> Option<[(usize, usize); 2]> {
            let (first, last) = ((lo * n as f64).floor(), (hi * n as f64).ceil() - 1.0);
            if !(last - first < n as f64 - 1.0) {
                return None;
            }
            let first = first.rem_euclid(n as f64) as usize;
            let last = last.rem_euclid(n as f64) as usize;
            Some(if first <= last {
                [(first, last), (first, last)]
            } else {
                [(first, n - 1), (0, last)]
            })
        };
        let (Some(columns), Some(rows)) = (
            spans(min.x, max.x, self.width),
            spans(min.y, max.y, self.height),
        ) else {
            return self.max();
        };
        let longest = columns
            .iter()
            .chain(&rows)
            .map(|(a, b)| b - a + 1)
            .max()
            .unwrap_or(1);
        // The level whose blocks are at least as wide as the longest span: at most two blocks
        // per span and axis.
        let level = (usize::BITS - (longest - 1).leading_zeros()) as usize;
        let mut largest = 0;
        for &(c0, c1) in &columns {
            for &(r0, r1) in &rows {
                for j in (r0 >> level)..=(r1 >> level) {
                    for i in (c0 >> level)..=(c1 >> level) {
                        match self.block_max(level, i, j) {
                            Some(block) => largest = largest.max(block),
                            None => return self.max(),
                        }
                    }
                }
            }
        }
        largest as f64 / FIXED_ONE
    }

    /// d at texture point `x`, wrapped into the unit square (as stored).
    #[must_use]
    pub fn value_at(&self, x: DVec2) -> f64 {
        if self.filter == MapFilter::Bilinear {
            return self.bilinear_fixed_at(x) / FIXED_ONE;
        }
        let x = x - x.floor();
        let i = ((x.x * self.width as f64) as usize).min(self.width - 1);
        let j = ((x.y * self.height as f64) as usize).min(self.height - 1);
        self.fixed(i, j) as f64 / FIXED_ONE
    }

    /// Σ of fixed-point values over texel columns [i0, i1) × rows [j0, j1).
    fn rect_sum(&self, (i0, i1): (usize, usize), (j0, j1): (usize, usize)) -> u64 {
        self.tables.sums.rect((i0, i1), (j0, j1))
    }

    /// Whether d takes one value over the box [min, min + size]² (inside the unit square): for
    /// the nearest filter, the texels it covers with positive length; bilinear, the texels whose
    /// tents meet it. O(1), from the table of value changes.
    #[must_use]
    pub fn is_constant_over(&self, min: DVec2, size: f64) -> bool {
        if self.uniform.is_some() {
            return true;
        }
        if self.filter == MapFilter::Bilinear {
            return self.bilinear_is_constant_over(min, size);
        }
        let columns = TexelSpan::new(min.x, min.x + size, self.width);
        let rows = TexelSpan::new(min.y, min.y + size, self.height);
        self.texels_constant((columns.first, columns.last), (rows.first, rows.last))
    }

    /// Whether texels c₀…c₁ × r₀…r₁ (inclusive, within the map) have one value.
    ///
    /// With c₀ < c₁ and r₀ < r₁ that is O(1): they do exactly when Σg over the texels
    /// [c₀, c₁) × [r₀, r₁) is 0 (each equals its right and upper neighbours, which chains every
    /// texel to (c₀, r₀) but the corner (c₁, r₁)) and the corner equals its left neighbour. One
    /// row (or column) reads g's right (upper) changes alone in the map's last row (column),
    /// where g has no upper (right) ones, and compares its texels elsewhere: a tree's box within
    /// one row is under a texel tall, so it spans fewer than W/H + 2 texels.
    fn texels_constant(&self, (c0, c1): (usize, usize), (r0, r1): (usize, usize)) -> bool {
        if let PrefixTable::Blocked(table) = &self.tables.changes {
            return table.texels_constant((c0, c1), (r0, r1));
        }
        let changes = |(i0, i1): (usize, usize), (j0, j1): (usize, usize)| {
            self.tables.changes.rect((i0, i1), (j0, j1))
        };
        match (c0 < c1, r0 < r1) {
            (false, false) => true,
            (true, true) => {
                changes((c0, c1), (r0, r1)) == 0 && self.fixed(c1, r1) == self.fixed(c1 - 1, r1)
            }
            (true, false) if r0 == self.height - 1 => changes((c0, c1), (r0, r0 + 1)) == 0,
            (false, true) if c0 == self.width - 1 => changes((c0, c0 + 1), (r0, r1)) == 0,
            (true, false) => (c0 + 1..=c1).all(|i| self.fixed(i, r0) == self.fixed(c0, r0)),
            (false, true) => (r0 + 1..=r1).all(|j| self.fixed(c0, j) == self.fixed(c0, r0)),
        }
    }

    /// ∫d over the box [min, min + size]² in fixed-point texel units (proportional to the
    /// mass; exactly 0 when every texel it covers is 0).
    fn box_mass(&self, min: DVec2, size: f64) -> f64 {
        self.rect_mass(min, DVec2::splat(size))
    }

    /// ∫d over the rectangle [min, min + size] within the unit square, in fixed-point texel
    /// units.
    fn rect_mass(&self, min: DVec2, size: DVec2) -> f64 {
        if self.filter == MapFilter::Bilinear {
            return self.bilinear_rect_mass(min, size);
        }
        let columns = TexelSpan::new(min.x, min.x + size.x, self.width);
        let rows = TexelSpan::new(min.y, min.y + size.y, self.height);
        let mut mass = 0.0;
        if let PrefixTable::Blocked(table) = &self.tables.sums {
            let all_whole = columns
                .groups()
                .chain(rows.groups())
                .all(|(_, _, w)| w == 1.0);
            let texels = (columns.last + 1 - columns.first) * (rows.last + 1 - rows.first);
            if all_whole && texels <= 1 << 21 {
                // Every weight is 1 and every partial sum of the groups' integers is below
                // 2⁵³ (at most 2²¹ texels of at most 2³²), so the loop below would add them
                // exactly: its result is the span's sum, one rectangle (O(1) where the box's
                // edges are those of blocks, as a power-of-two map's dyadic boxes' are).
                return table.rect(
                    (columns.first, columns.last + 1),
                    (rows.first, rows.last + 1),
                ) as f64;
            }
            // The same integers, the groups along the box's edges scanned once each.
            let span = |s: &TexelSpan| {
                let mut groups = [(0, 0); 3];
                let mut n = 0;
                for (a, b, _) in s.groups() {
                    (groups[n], n) = ((a, b), n + 1);
                }
                (groups, n)
            };
            let ((c, nc), (r, nr)) = (span(&columns), span(&rows));
            let sums: [[u64; 3]; 3] = table.group_sums(&c[..nc], &r[..nr]);
            for (r, (_, _, row_weight)) in rows.groups().enumerate() {
                for (c, (_, _, column_weight)) in columns.groups().enumerate() {
                    mass += sums[r][c] as f64 * (column_weight * row_weight);
                }
            }
            return mass;
        }
        for (j0, j1, row_weight) in rows.groups() {
            for (i0, i1, column_weight) in columns.groups() {
                mass += self.rect_sum((i0, i1), (j0, j1)) as f64 * (column_weight * row_weight);
            }
        }
        mass
    }

    /// The probabilities of the four quarters of the box [min, min + size]² (quarter j at
    /// column j mod 2, row j div 2), proportional to their masses; `None` where the map is
    /// constant over the box (then they are ¼ each, and the tree draws them as it does
    /// without a map).
    #[must_use]
    pub fn quarter_probabilities(&self, min: DVec2, size: f64) -> Option<[f64; 4]> {
        if self.is_constant_over(min, size) {
            return None;
        }
        let half = 0.5 * size;
        let masses = std::array::from_fn(|j| {
            let corner = min + DVec2::new((j & 1) as f64, (j >> 1) as f64) * half;
            self.box_mass(corner, half)
        });
        let total: f64 = masses.iter().sum();
        Some(if total > 0.0 {
            masses.map(|m: f64| m / total)
        } else {
            [0.25; 4]
        })
    }

    /// Whether [`DensityMap::mean_multiplicity`] weighs the box [min, min + size]²: it covers
    /// at most 64 texels of a nearest-filtered map (a bilinear map's boxes are not weighed,
    /// so the dense regime counts varying bilinear boxes exactly).
    #[must_use]
    pub fn can_weigh(&self, min: DVec2, size: f64) -> bool {
        if self.filter == MapFilter::Bilinear {
            return false;
        }
        let columns = TexelSpan::new(min.x, min.x + size, self.width);
        let rows = TexelSpan::new(min.y, min.y + size, self.height);
        (columns.last - columns.first + 1) * (rows.last - rows.first + 1) <= 64
    }

    /// The mean multiplicity of the particles of the box [min, min + size]² in `footprint`:
    /// ∫_box d·m / ∫_box d, m(x) the number of the footprint's translates holding x (the
    /// expected contribution of one of the box's particles, in space). Texel by texel over the
    /// box, so `None` for a box over more than 64 texels or of mass 0.
    #[must_use]
    pub fn mean_multiplicity(&self, footprint: &Footprint, min: DVec2, size: f64) -> Option<f64> {
        if !self.can_weigh(min, size) {
            return None;
        }
        let columns = TexelSpan::new(min.x, min.x + size, self.width);
        let rows = TexelSpan::new(min.y, min.y + size, self.height);
        let max = min + DVec2::splat(size);
        let (mut mass, mut weighted) = (0.0, 0.0);
        for j in rows.first..=rows.last {
            for i in columns.first..=columns.last {
                let value = self.fixed(i, j) as f64;
                if value == 0.0 {
                    continue;
                }
                let lo = DVec2::new(i as f64 / self.width as f64, j as f64 / self.height as f64)
                    .max(min);
                let hi = DVec2::new(
                    (i + 1) as f64 / self.width as f64,
                    (j + 1) as f64 / self.height as f64,
                )
                .min(max);
                let area = (hi - lo).max(DVec2::ZERO);
                mass += value * area.x * area.y;
                weighted += value * footprint.overlap_area_of_rectangle(lo, hi);
            }
        }
        (mass > 0.0).then(|| weighted / mass)
    }

    /// The position in the box [min, min + size]² of the particle with uniform numbers `u`
    /// (in [0, 1)²): u₀ picks the column by the box's marginal masses and the position within
    /// it, u₁ the row within that column and the position within it. The inverse of the
    /// map's distribution restricted to the box, so positions follow d exactly and no texel
    /// of value 0 receives one (where the box holds mass at all).
    ///
    /// Each inversion is a binary search on the masses of the first k columns (rows), exact
    /// integer sums from the summed-area table weighted by the end texels' covered fractions:
    /// O(log) in the box's width in texels, so a sparse leaf over thousands of texels of a
    /// production map costs about what one over a few texels does.
    #[must_use]
    pub fn place(&self, min: DVec2, size: f64, u: [f64; 2]) -> DVec2 {
        let mut position = [DVec2::ZERO];
        self.place_each(min, size, &[u], &mut position);
        position[0]
    }

    /// [`Self::place`] for several particles of the box [min, min + size]²: `uniforms[k]`
    /// places `positions[k]`. What depends on the box alone is made once: a blocked level's
    /// box of up to 64 × 64 texels reads its texels once into a table of its own (the same
    /// integers), where its binary searches would read strips of texels at every step; a
    /// bilinear map's box whose tents span up to 61 texels a side does so under every table
    /// (`density_map/bilinear.rs`).
    pub fn place_each(
        &self,
        min: DVec2,
        size: f64,
        uniforms: &[[f64; 2]],
        positions: &mut [DVec2],
    ) {
        if self.filter == MapFilter::Bilinear {
            return self.bilinear_place_each(min, size, uniforms, positions);
        }
        let columns = TexelSpan::new(min.x, min.x + size, self.width);
        let rows = TexelSpan::new(min.y, min.y + size, self.height);
        let spans = (&columns, &rows);
        if let PrefixTable::Blocked(table) = &self.tables.sums {
            let side = (columns.last - columns.first).max(rows.last - rows.first) + 1;
            // Tables of 17², 25², 33², 49² and 65² entries (2.3 to 33.8 KB on the stack, each
            // cleared once a leaf).
            let place = match side {
                ..=16 => Self::place_in_box::<289>,
                17..=24 => Self::place_in_box::<625>,
                25..=32 => Self::place_in_box::<1089>,
                33..=48 => Self::place_in_box::<2401>,
                49..=64 => Self::place_in_box::<4225>,
                _ => Self::place_in_large_box,
            };
            return place(self, table, spans, min, size, uniforms, positions);
        }
        let rect_sum = |c: (usize, usize), r: (usize, usize)| self.rect_sum(c, r);
        self.place_by(spans, min, size, uniforms, positions, rect_sum);
    }

    /// [`Self::place_each`] on a blocked level, its box's texels read once into a summed-area
    /// table of `N` ≥ (width + 1)·(height + 1) entries.
    fn place_in_box<const N: usize>(
        &self,
        table: &blocked::BlockedPrefix<u64>,
        (columns, rows): (&TexelSpan, &TexelSpan),
        min: DVec2,
        size: f64,
        uniforms: &[[f64; 2]],
        positions: &mut [DVec2],
    ) {
        let mut sums = [0u64; N];
        let (c0, r0) = (columns.first, rows.first);
        let stride = table.box_sums((c0, columns.last), (r0, rows.last), &mut sums);
        let rect_sum = |(i0, i1): (usize, usize), (j0, j1): (usize, usize)| {
            let at = |i: usize, j: usize| sums[(j - r0) * stride + (i - c0)];
            at(i1, j1) + at(i0, j0) - at(i1, j0) - at(i0, j1)
        };
        self.place_by((columns, rows), min, size, uniforms, positions, rect_sum);
    }

    /// [`Self::place_each`] on a blocked map's box larger than 64 texels a side: by its block
    /// boundaries, then one block's columns (`density_map/large_box.rs`), up to
    /// `large_box::MAX_SIDE` texels a side, else [`Self::place_by_table`].
    fn place_in_large_box(
        &self,
        table: &blocked::BlockedPrefix<u64>,
        (columns, rows): (&TexelSpan, &TexelSpan),
        min: DVec2,
        size: f64,
        uniforms: &[[f64; 2]],
        positions: &mut [DVec2],
    ) {
        let Some(large) = large_box::LargeBox::new(table, columns, rows) else {
            return self.place_by_table(table, (columns, rows), min, size, uniforms, positions);
        };
        for (u, position) in uniforms.iter().zip(positions) {
            let (i, t) = large.column(u[0]);
            let (j, s) = large.row(i, u[1]);
            *position = DVec2::new(
                within_texel(i, self.width, min.x, min.x + size, t),
                within_texel(j, self.height, min.y, min.y + size, s),
            );
        }
    }

    /// [`Self::place_each`] on a blocked map's box larger than 64 texels a side: its
    /// rectangles' sums from its tables (strips of texels along their unaligned edges).
    fn place_by_table(
        &self,
        table: &blocked::BlockedPrefix<u64>,
        spans: (&TexelSpan, &TexelSpan),
        min: DVec2,
        size: f64,
        uniforms: &[[f64; 2]],
        positions: &mut [DVec2],
    ) {
        let rect_sum = |c: (usize, usize), r: (usize, usize)| table.rect(c, r);
        self.place_by(spans, min, size, uniforms, positions, rect_sum);
    }

    /// [`Self::place_each`] with the box's rectangles' sums from `rect_sum`.
    fn place_by(
        &self,
        (columns, rows): (&TexelSpan, &TexelSpan),
        min: DVec2,
        size: f64,
        uniforms: &[[f64; 2]],
        positions: &mut [DVec2],
        rect_sum: impl Fn((usize, usize), (usize, usize)) -> u64,
    ) {
        // The mass of columns [a, b) over the box's rows (without the columns' weights).
        let strip = |a: usize, b: usize| {
            rows.groups()
                .map(|(j0, j1, w)| rect_sum((a, b), (j0, j1)) as f64 * w)
                .sum::<f64>()
        };
        for (u, position) in uniforms.iter().zip(positions) {
            let (i, t) = invert(columns, &strip, u[0]);
            let column = |a: usize, b: usize| rect_sum((i, i + 1), (a, b)) as f64;
            let (j, s) = invert(rows, &column, u[1]);
            *position = DVec2::new(
                within_texel(i, self.width, min.x, min.x + size, t),
                within_texel(j, self.height, min.y, min.y + size, s),
            );
        }
    }

    /// ∫_A d over the footprint's parallelogram, counting each integer translate (as the tree
    /// counts particles): exact over the texels its bounding box meets, up to 65 536 of them,
    /// else its area times the map's mean (what the tree's periodic average assumes). Row by
    /// row, the texels wholly inside add their values' sum (from the summed-area table, one
    /// look-up per run of columns), and only the texels the parallelogram's edges cut are
    /// clipped: the cost grows with the footprint's perimeter in texels, not its area.
    #[must_use]
    pub fn mass_in(&self, footprint: &Footprint) -> f64 {
        if let Some(value) = self.uniform {
            return footprint.area() * value;
        }
        if footprint.is_degenerate() {
            return 0.0;
        }
        if self.filter == MapFilter::Bilinear {
            return self.bilinear_mass_in(footprint);
        }
        let (min, max) = footprint.bounds();
        let scale = DVec2::new(self.width as f64, self.height as f64);
        let (lo, hi) = ((min * scale).floor(), (max * scale).ceil());
        let texels = (hi.x - lo.x) * (hi.y - lo.y);
        if !(texels <= MAX_INTEGRATED_TEXELS) {
            return footprint.area() * self.mean;
        }
        let corners = footprint.corners();
        let in_texels = corners.map(|c| c * scale);
        let mut cut = 0.0;
        let mut whole = WholeRuns::new(self);
        for row in lo.y as i64..hi.y as i64 {
            let (y0, y1) = (row as f64 / scale.y, (row + 1) as f64 / scale.y);
            let strip = clip(&corners, |p| p.y - y0, |p| y1 - p.y);
            if strip.len() < 3 {
                continue;
            }
            let j = row.rem_euclid(self.height as i64) as usize;
            let met = columns_met(&strip, scale.x, 0.0);
            let inside = within(
                whole_columns(&in_texels, row as f64, (row + 1) as f64),
                &met,
            );
            whole.add(j, inside.clone());
            let edges = (met.start..inside.start).chain(inside.end..met.end);
            for column in edges {
                let (x0, x1) = (column as f64 / scale.x, (column + 1) as f64 / scale.x);
                let i = column.rem_euclid(self.width as i64) as usize;
                let value = self.fixed(i, j);
                if value == 0 {
                    continue;
                }
                let piece = clip(&strip, |p| p.x - x0, |p| x1 - p.x);
                cut += cut_area(&piece, footprint, column, row, scale) * value as f64;
            }
        }
        (cut + whole.sum() as f64 / (scale.x * scale.y)) / FIXED_ONE
    }

    /// Σ q over texel row `j` and the columns `columns` (any integers: the map repeats), in
    /// fixed point: one summed-area look-up per run of columns within one repeat.
    fn row_sum(&self, j: usize, columns: std::ops::Range<i64>) -> u64 {
        self.rows_sum((j, j + 1), columns)
    }

    /// Σ q over texel rows [j0, j1) (within the map) and the columns `columns` (any
    /// integers), in fixed point: one summed-area look-up per run of columns within one repeat.
    fn rows_sum(&self, rows: (usize, usize), columns: std::ops::Range<i64>) -> u64 {
        let width = self.width as i64;
        let mut sum = 0;
        let mut column = columns.start;
        while column < columns.end {
            let i = column.rem_euclid(width);
            let run = (width - i).min(columns.end - column);
            sum += self
                .tables
                .sums
                .rect((i as usize, (i + run) as usize), rows);
            column += run;
        }
        sum
    }
}

/// How near a cut texel's area from the uv corners must be to the area about the footprint's
/// own centre ([`cut_texel_area`]) to be kept, bit for bit (2⁻³⁰ relative): where the old
/// area was accurate, masses (and the pinned outputs built on them) do not change.
const ACCURATE_ENOUGH: f64 = 1.0 / (1u64 << 30) as f64;

/// The area of `piece`, texel (`column`, `row`) cut from the footprint in uv: its shoelace
/// over the uv points where that is within [`ACCURATE_ENOUGH`] of [`cut_texel_area`], else
/// that accurate area.
fn cut_area(piece: &[DVec2], footprint: &Footprint, column: i64, row: i64, scale: DVec2) -> f64 {
    let area = polygon_area(piece);
    let accurate = cut_texel_area(footprint, column, row, scale);
    if (area - accurate).abs() <= ACCURATE_ENOUGH * accurate {
        area
    } else {
        accurate
    }
}

/// The area (in uv) of texel (`column`, `row`) (`scale` texels per uv unit) cut from the
/// footprint, accurate whatever the footprint's size or place. The corners in uv, c ± ½a ±
/// ½b, are rounded by ε of their coordinates, and the shoelace over them cancels to that
/// rounding: the 10⁻⁹ square at (0.7, 0.3) had area 0. Here the footprint is cut in
/// coordinates about its centre c (its corners ±½a ± ½b, rounded by ε of the edges' own
/// size; the texel's sides less c, rounded as the cut vertices' uv would be), and the piece's
/// area is taken about its first vertex, so the shoelace's differences are of the piece's own
/// size: the area is within a few ε of itself (plus what the texel sides' rounding moves its
/// cut edges, as any float footprint's are moved).
fn cut_texel_area(footprint: &Footprint, column: i64, row: i64, scale: DVec2) -> f64 {
    let center = footprint.center();
    let (a, b) = footprint.edges();
    let (half_a, half_b) = (0.5 * a, 0.5 * b);
    let corners = [
        -half_a - half_b,
        half_a - half_b,
        half_a + half_b,
        half_b - half_a,
    ];
    let (y0, y1) = (
        row as f64 / scale.y - center.y,
        (row + 1) as f64 / scale.y - center.y,
    );
    let (x0, x1) = (
        column as f64 / scale.x - center.x,
        (column + 1) as f64 / scale.x - center.x,
    );
    let strip = clip(&corners, |p| p.y - y0, |p| y1 - p.y);
    if strip.len() < 3 {
        return 0.0;
    }
    let mut piece = clip(&strip, |p| p.x - x0, |p| x1 - p.x);
    let Some(&first) = piece.first() else {
        return 0.0;
    };
    for point in piece.iter_mut() {
        *point -= first;
    }
    polygon_area(&piece)
}

/// The sum of the runs of whole texels a footprint's rows hold ([`DensityMap::mass_in`]). A
/// blocked level answers a one-row run texel by texel, so there the runs of eight consecutive
/// rows that make one row of its blocks are summed together where they share 32 columns or
/// more: those columns as one rectangle eight rows tall (its whole blocks from the table's
/// corners), each row's remainder at its ends as a run of its own. The same integers, so the
/// same sum.
struct WholeRuns<'a> {
    map: &'a DensityMap,
    /// Whether the map's tables are blocked (else each run is added as it comes).
    blocked: bool,
    /// The runs held back: consecutive rows of one row of blocks.
    band: [(usize, std::ops::Range<i64>); 8],
    len: usize,
    sum: u64,
}

impl<'a> WholeRuns<'a> {
    fn new(map: &'a DensityMap) -> Self {
        Self {
            map,
            blocked: matches!(map.tables.sums, PrefixTable::Blocked(_)),
            band: std::array::from_fn(|_| (0, 0..0)),
            len: 0,
            sum: 0,
        }
    }

    /// Adds the run `columns` of row `j`.
    fn add(&mut self, j: usize, columns: std::ops::Range<i64>) {
        if !self.blocked {
            self.sum += self.map.row_sum(j, columns);
            return;
        }
        if self.len > 0 {
            let first = self.band[0].0;
            if j != self.band[self.len - 1].0 + 1 || j >> BLOCK_SHIFT != first >> BLOCK_SHIFT {
                self.flush();
            }
        }
        self.band[self.len] = (j, columns);
        self.len += 1;
        if self.len == self.band.len() {
            self.flush();
        }
    }

    /// Adds the runs held back.
    fn flush(&mut self) {
        let runs = &self.band[..self.len];
        self.len = 0;
        let start = runs.iter().map(|(_, c)| c.start).max().unwrap_or(0);
        let end = runs.iter().map(|(_, c)| c.end).min().unwrap_or(0);
        // A band is read together only where its common run holds whole blocks to gain:
        // eight short runs cost less texel by texel than the band's strips along its ends.
        if runs.len() == self.band.len() && end - start >= 4 * BLOCK as i64 {
            let first = runs[0].0;
            self.sum += self.map.rows_sum((first, first + runs.len()), start..end);
            for (j, columns) in runs {
                self.sum += self.map.row_sum(*j, columns.start..start)
                    + self.map.row_sum(*j, end..columns.end);
            }
        } else {
            for (j, columns) in runs {
                self.sum += self.map.row_sum(*j, columns.clone());
            }
        }
    }

    /// The sum of every run added.
    fn sum(mut self) -> u64 {
        self.flush();
        self.sum
    }
}

/// The footprint of the masses' property tests: centred at `uv`, edges `size` and
/// `size`·`aspect` long, turned by `turn` of a full turn (axis-aligned if `aligned`) and
/// sheared by `skew`.
#[cfg(test)]
fn turned_footprint(
    uv: DVec2,
    size: f64,
    (aspect, turn, skew): (f64, f64, f64),
    aligned: bool,
) -> Footprint {
    let (sin, cos) = if aligned {
        (0.0, 1.0)
    } else {
        (std::f64::consts::TAU * turn).sin_cos()
    };
    let dx = size * DVec2::new(cos, sin);
    let dy = size * aspect * DVec2::new(-sin + skew * cos, cos + skew * sin);
    Footprint::new(uv, dx, dy).expect("a finite footprint")
}

/// 400 footprints 0.3 to 60 texels across (of a `width` × `height` map) at every angle,
/// every fourth axis-aligned, every fifth a sliver and every seventh with its corners on
/// texel corners, at positions over several tiles: for tests of the masses over footprints.
#[cfg(test)]
fn footprints_of_every_shape((width, height): (usize, usize), seed: u32) -> Vec<Footprint> {
    let mut rng = crate::tea::TeaRng::new([seed, 5, 5, 5], 0, 8);
    let mut uniforms = || crate::tea::unit_pair(rng.next_bits());
    let texel = DVec2::new(1.0 / width as f64, 1.0 / height as f64);
    (0..400)
        .map(|k| {
            let ([u, v], [size, turn], [aspect, thin]) = (uniforms(), uniforms(), uniforms());
            if k % 7 == 0 {
                // Whole texels: a corner at a texel corner, sides of 1 to 40 texels.
                let corner = (DVec2::new(u, v) * 3.0 - 1.0) / texel;
                let sides = (DVec2::new(size, aspect) * 40.0).ceil();
                let centre = (corner.floor() + 0.5 * sides) * texel;
                let (dx, dy) = (
                    DVec2::new(sides.x * texel.x, 0.0),
                    DVec2::new(0.0, sides.y * texel.y),
                );
                return Footprint::new(centre, dx, dy).expect("finite");
            }
            let across = (0.3 + 60.0 * size * size) / width.max(height) as f64;
            let (sin, cos) = (std::f64::consts::TAU * turn).sin_cos();
            let (sin, cos) = if k % 4 == 0 { (0.0, 1.0) } else { (sin, cos) };
            let aspect = if k % 5 == 0 {
                1e-3 * thin
            } else {
                0.2 + aspect
            };
            let dx = across * DVec2::new(cos, sin);
            let dy = aspect * across * DVec2::new(-sin, cos + 0.3 * sin);
            Footprint::new(DVec2::new(u, v) * 3.0 - 1.0, dx, dy).expect("finite")
        })
        .collect()
}

/// d in fixed point: round(d·2³²), for d in [0, 1].
fn fixed_point(value: f64) -> u64 {
    (value * FIXED_ONE).round() as u64
}

/// The position at fraction `t` across texel `k` of `n` along an axis, within the box's
/// [lo, hi] on it.
fn within_texel(k: usize, n: usize, lo: f64, hi: f64, t: f64) -> f64 {
    let a = (k as f64 / n as f64).max(lo);
    let b = ((k + 1) as f64 / n as f64).min(hi);
    (a + t * (b - a)).clamp(a, b)
}

/// The texel k of `span` where the cumulative mass passes the fraction `u` of the span's total,
/// and the fraction of k's own mass below that point; `mass(a, b)` is the mass of texels
/// [a, b), which `span`'s end weights scale at its ends. The cumulative mass of texels
/// [first, k) is non-decreasing in k (each of its three terms is), so a binary search finds the
/// texel, and it never lands on one of mass 0; where rounding runs past the total, it takes
/// the last texel with mass.
fn invert(span: &TexelSpan, mass: &dyn Fn(usize, usize) -> f64, u: f64) -> (usize, f64) {
    let (first, last) = (span.first, span.last);
    let first_mass = mass(first, first + 1) * span.first_weight;
    let last_mass = if last > first {
        mass(last, last + 1) * span.last_weight
    } else {
        0.0
    };
    // The mass of texels [first, k), k in [first, last + 1].
    let before = |k: usize| -> f64 {
        if k == first {
            return 0.0;
        }
        let interior = if last > first + 1 {
            mass(first + 1, k.clamp(first + 1, last))
        } else {
            0.0
        };
        first_mass + interior + if k > last { last_mass } else { 0.0 }
    };
    let total = before(last + 1);
    let target = u * total;
    if !(target < total) {
        // The last texel with mass: the largest k with before(k) < total.
        let (mut lo, mut hi) = (first, last + 1);
        if !(before(lo) < total) {
            return (first, 1.0);
        }
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            if before(mid) < total {
                lo = mid
            } else {
                hi = mid
            }
        }
        return (lo, 1.0);
    }
    // before(lo) ≤ target < before(hi) throughout.
    let (mut lo, mut hi) = (first, last + 1);
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if before(mid) <= target {
            lo = mid
        } else {
            hi = mid
        }
    }
    let (below, above) = (before(lo), before(lo + 1));
    (lo, ((target - below) / (above - below)).clamp(0.0, 1.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tea::{TeaRng, unit_pair};

    /// Values with zeros over most of the map: a patchy region in one corner, a diagonal band
    /// and a few isolated texels (so tiles are empty, full, and touched by one texel).
    fn mostly_zero(width: usize, height: usize, seed: u32) -> Vec<f64> {
        let mut rng = TeaRng::new([seed, 3, 2, 1], 0, 8);
        let levels = [0.125, 0.25, 1.0, 0.6];
        (0..width * height)
            .map(|k| {
                let block = (k % width) / 3 + (k / width) / 2;
                let patchy = levels[(block + usize::from(rng.next_bits().is_multiple_of(5))) % 4];
                let (i, j) = (k % width, k / width);
                let region = i < width / 3 + 1 && j < height / 2 + 1;
                let band = i + 2 * j == width;
                let isolated = k % 4099 == 17;
                if region || band || isolated {
                    patchy
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// The bytes counted before a map is built are what its tables hold, in both layouts, for
    /// sizes with odd sides, single rows and columns, powers of two and several tiles; a map
    /// takes the tiled layout only where it saves at least a third of the bytes, and never
    /// holds more than [`DensityMap::bytes_for`].
    #[test]
    fn the_bytes_counted_before_building_are_the_tables() {
        let sizes = [
            (1, 1),
            (1, 7),
            (9, 1),
            (5, 3),
            (16, 16),
            (33, 17),
            (64, 1),
            (64, 64),
            (130, 67),
            (200, 129),
        ];
        for (width, height) in sizes {
            let full: Vec<f64> = (0..width * height)
                .map(|k| (k % 3 + 1) as f64 / 3.0)
                .collect();
            for values in [full, mostly_zero(width, height, 4)] {
                let occupancy = MapOccupancy::of_values(width, height, &values);
                let pyramid = MaxPyramid::sizes(width, height);
                let [whole, tiled, _] =
                    [Layout::Whole, Layout::Tiled, Layout::Blocked].map(|layout| {
                        let map = DensityMap::with_layout(
                            width,
                            height,
                            &values,
                            MapFilter::Nearest,
                            Some(layout),
                        )
                        .unwrap();
                        let counted = layout.bytes(width, height, &occupancy, &pyramid);
                        assert_eq!(map.heap_bytes(), counted, "{width} x {height} {layout:?}");
                        counted
                    });
                let chosen = DensityMap::new(width, height, &values).unwrap();
                let saves_a_third = 3 * tiled <= 2 * whole;
                assert_eq!(
                    chosen.heap_bytes(),
                    if saves_a_third { tiled } else { whole }
                );
                let predicted = DensityMap::bytes_for_values(width, height, &values);
                assert_eq!(chosen.heap_bytes(), predicted, "{width} x {height}");
                let mut marked = MapOccupancy::new(width, height);
                for (k, &value) in values.iter().enumerate() {
                    marked.mark(k % width, k / width, value);
                }
                assert_eq!(DensityMap::bytes_for_occupancy(&marked), predicted);
                assert!(predicted <= DensityMap::bytes_for(width, height));
            }
        }
        // About 12.7 bytes a texel for a large map stored whole, as the module docs say.
        let per_texel = DensityMap::bytes_for(8192, 8192) as f64 / (8192.0 * 8192.0);
        assert!((12.6..12.7).contains(&per_texel), "{per_texel}");
    }

    /// Maps of 2²² texels and more take the layout of fewest bytes: blocked (about 4.5 bytes
    /// a texel, as the module docs say) where every tile holds a value, tiled where most tiles
    /// are empty; a map of one texel fewer keeps the whole tables.
    #[test]
    fn large_maps_take_the_layout_of_fewest_bytes() {
        let occupancy = |width: usize, height: usize, sparse: bool| {
            let mut occupancy = MapOccupancy::new(width, height);
            for j in (0..height).step_by(if sparse { 64 * 8 } else { 1 }) {
                for i in (0..width).step_by(if sparse { 64 * 8 } else { 1 }) {
                    occupancy.mark(i, j, 0.5);
                }
            }
            occupancy
        };
        let choose = |width, height, sparse| {
            let pyramid = MaxPyramid::sizes(width, height);
            Layout::choose(width, height, &occupancy(width, height, sparse), &pyramid)
        };
        let (layout, bytes) = choose(2048, 2048, false);
        assert_eq!(layout, Layout::Blocked);
        let per_texel = bytes as f64 / (2048.0 * 2048.0);
        assert!((4.4..4.6).contains(&per_texel), "{per_texel}");
        assert_eq!(choose(2048, 2048, true).0, Layout::Tiled);
        assert_eq!(choose(2047, 2048, false).0, Layout::Whole);
        assert_eq!(
            DensityMap::bytes_for_occupancy(&occupancy(2048, 2048, false)),
            bytes
        );
    }

    /// Asserts that maps `a` and `b` answer `count` random boxes and footprints alike, bit for
    /// bit: constancy, quarter probabilities, placements, mean multiplicities, bounds,
    /// footprint masses and values.
    pub(super) fn assert_same_answers(
        a: &DensityMap,
        b: &DensityMap,
        rng: &mut TeaRng,
        count: usize,
        what: &str,
    ) {
        for k in 0..count {
            let [u, v] = unit_pair(rng.next_bits());
            let [c, d] = unit_pair(rng.next_bits());
            let size = [0.003, 0.02, 0.1, 0.4, 1.0][k % 5] * (0.5 + c);
            let min = DVec2::new(u * (1.0 - size).max(0.0), v * (1.0 - size).max(0.0));
            let size = size.min(1.0);
            let footprint = Footprint::new(
                DVec2::new(u, v),
                DVec2::new(size * (0.2 + c), size * (d - 0.5)),
                DVec2::new(size * (0.3 * c - 0.1), size * (0.2 + d)),
            )
            .unwrap();
            let answers = |map: &DensityMap| {
                (
                    map.is_constant_over(min, size),
                    map.quarter_probabilities(min, size),
                    map.place(min, size, [c, d]),
                    map.mean_multiplicity(&footprint, min, size),
                    map.max_over(&footprint),
                    map.mass_in(&footprint),
                    map.value_at(DVec2::new(c, d)),
                )
            };
            assert_eq!(answers(a), answers(b), "{what}: box {min} {size}");
        }
    }

    /// A map stored in tiles answers every question exactly as the same map stored whole: the
    /// tables' entries at every corner and block, and the masses, constancy, placements,
    /// bounds and footprint integrals of random boxes and footprints (bit for bit), under
    /// both filters.
    #[test]
    fn tiled_tables_answer_what_whole_tables_answer() {
        for (width, height, seed) in [(130, 67, 1), (64, 128, 2), (257, 191, 3), (20, 300, 4)] {
            let values = mostly_zero(width, height, seed);
            for filter in MapFilter::ALL {
                let build = |layout| {
                    DensityMap::with_layout(width, height, &values, filter, Some(layout)).unwrap()
                };
                let (whole, tiled) = (build(Layout::Whole), build(Layout::Tiled));
                // Empty tiles are left out of the larger maps.
                if width * height > 30_000 {
                    assert!(
                        tiled.heap_bytes() < whole.heap_bytes(),
                        "{width} x {height}"
                    );
                }
                assert_eq!((whole.mean, whole.uniform), (tiled.mean, tiled.uniform));
                for j in 0..=height {
                    for i in 0..=width {
                        assert_eq!(whole.tables.sums.at(i, j), tiled.tables.sums.at(i, j));
                        assert_eq!(whole.tables.changes.at(i, j), tiled.tables.changes.at(i, j));
                        if i < width && j < height {
                            let value = fixed_point(values[(height - 1 - j) * width + i]);
                            assert_eq!(tiled.tables.sums.cell(i, j), value, "texel ({i}, {j})");
                            assert_eq!(whole.tables.sums.cell(i, j), value, "texel ({i}, {j})");
                        }
                    }
                }
                for (k, (w, h)) in MaxPyramid::sizes(width, height).into_iter().enumerate() {
                    for j in 0..h {
                        for i in 0..w {
                            let block = |map: &DensityMap| map.tables.maxima.block(k, i, j);
                            assert_eq!(block(&whole), block(&tiled), "level {k} ({i}, {j})");
                        }
                    }
                }
                assert_eq!(whole.max(), tiled.max());
                let mut rng = TeaRng::new([seed, 5, 6, 7], 0, 8);
                // Rectangles within a tile, across tiles, along the map's edges.
                for _ in 0..20_000 {
                    let [a, b] = unit_pair(rng.next_bits());
                    let [c, d] = unit_pair(rng.next_bits());
                    let span = |u: f64, v: f64, n: usize| {
                        let first = (u * n as f64) as usize;
                        let length = ((v * v * v) * (n - first) as f64) as usize;
                        (first, (first + length).min(n))
                    };
                    let (columns, rows) = (span(a, c, width), span(b, d, height));
                    assert_eq!(
                        whole.tables.sums.rect(columns, rows),
                        tiled.tables.sums.rect(columns, rows)
                    );
                    assert_eq!(
                        whole.tables.changes.rect(columns, rows),
                        tiled.tables.changes.rect(columns, rows)
                    );
                }
                assert_same_answers(&whole, &tiled, &mut rng, 2000, &format!("{filter:?}"));
            }
        }
    }

    /// A map of `width` × `height` with a few repeated values (so some boxes are constant),
    /// zeros included.
    fn patchy(width: usize, height: usize, seed: u32) -> (DensityMap, Vec<f64>) {
        let mut rng = TeaRng::new([seed, 1, 2, 3], 0, 8);
        let levels = [0.0, 0.25, 1.0, 0.6];
        let values: Vec<f64> = (0..width * height)
            .map(|k| {
                let block = (k % width) / 3 + (k / width) / 2;
                levels[(block + usize::from(rng.next_bits().is_multiple_of(5))) % 4]
            })
            .collect();
        (DensityMap::new(width, height, &values).unwrap(), values)
    }

    /// d at texel (column i, row j counted from v = 0), from the values as given (top row
    /// first).
    fn texel(values: &[f64], width: usize, height: usize, i: usize, j: usize) -> f64 {
        values[(height - 1 - j) * width + i]
    }

    /// ∫d over [x0, x1] × [y0, y1] (inside the square) texel by texel, from the values as
    /// given.
    fn brute_mass(values: &[f64], (w, h): (usize, usize), x: [f64; 2], y: [f64; 2]) -> f64 {
        let mut mass = 0.0;
        for j in 0..h {
            for i in 0..w {
                let ox =
                    (x[1].min((i + 1) as f64 / w as f64) - x[0].max(i as f64 / w as f64)).max(0.0);
                let oy =
                    (y[1].min((j + 1) as f64 / h as f64) - y[0].max(j as f64 / h as f64)).max(0.0);
                mass += texel(values, w, h, i, j) * ox * oy;
            }
        }
        mass
    }

    #[test]
    fn quarter_probabilities_and_constancy_match_the_texels() {
        // Maps much wider than tall (and the reverse) have boxes within one row (column)
        // away from the last one, which compare their texels.
        for (w, h, seed) in [
            (8, 8, 1),
            (7, 5, 2),
            (37, 23, 3),
            (1, 9, 4),
            (64, 1, 5),
            (128, 4, 6),
            (3, 70, 7),
        ] {
            let (map, values) = patchy(w, h, seed);
            for level in 0..8u32 {
                let size = 0.5f64.powi(level as i32);
                let boxes = 1usize << level;
                for bx in 0..boxes.min(16) {
                    for by in 0..boxes.min(16) {
                        let min = DVec2::new(bx as f64, by as f64) * size;
                        // Constancy: every texel the box covers with positive area alike.
                        let mut seen = Vec::new();
                        for j in 0..h {
                            for i in 0..w {
                                let ox = ((min.x + size).min((i + 1) as f64 / w as f64)
                                    - min.x.max(i as f64 / w as f64))
                                    > 0.0;
                                let oy = ((min.y + size).min((j + 1) as f64 / h as f64)
                                    - min.y.max(j as f64 / h as f64))
                                    > 0.0;
                                if ox && oy {
                                    seen.push(texel(&values, w, h, i, j));
                                }
                            }
                        }
                        let constant = seen.iter().all(|&v| v == seen[0]);
                        assert_eq!(
                            map.is_constant_over(min, size),
                            constant,
                            "{w}x{h} {min} {size}"
                        );
                        let Some(p) = map.quarter_probabilities(min, size) else {
                            continue;
                        };
                        let half = 0.5 * size;
                        let masses: Vec<f64> = (0..4)
                            .map(|q| {
                                let c = min + DVec2::new((q & 1) as f64, (q >> 1) as f64) * half;
                                brute_mass(&values, (w, h), [c.x, c.x + half], [c.y, c.y + half])
                            })
                            .collect();
                        let total: f64 = masses.iter().sum();
                        for q in 0..4 {
                            assert!(
                                (p[q] - masses[q] / total).abs() < 1e-9,
                                "{w}x{h} {min}: {p:?} {masses:?}"
                            );
                            assert_eq!(
                                p[q] == 0.0,
                                masses[q] == 0.0,
                                "zero masses are exactly zero"
                            );
                        }
                    }
                }
            }
        }
    }

    /// Positions placed in a box follow d restricted to the box: the share landing in each
    /// texel matches its mass (chi-square-like bound), and none lands where d = 0.
    #[test]
    fn placed_positions_follow_the_map() {
        let (map, values) = patchy(7, 5, 9);
        let (w, h) = (7, 5);
        let mut rng = TeaRng::new([4, 4, 4, 4], 0, 8);
        for (min, size) in [
            (DVec2::ZERO, 1.0),
            (DVec2::new(0.25, 0.5), 0.25),
            (DVec2::new(0.5, 0.0), 0.5),
        ] {
            let mut hits = vec![0.0; w * h];
            let samples = 40_000;
            for _ in 0..samples {
                let p = map.place(min, size, unit_pair(rng.next_bits()));
                assert!(p.x >= min.x && p.x <= min.x + size && p.y >= min.y && p.y <= min.y + size);
                let (i, j) = (
                    ((p.x * w as f64) as usize).min(w - 1),
                    ((p.y * h as f64) as usize).min(h - 1),
                );
                assert!(
                    texel(&values, w, h, i, j) > 0.0,
                    "a particle at {p} where d = 0"
                );
                hits[j * w + i] += 1.0;
            }
            let total = brute_mass(
                &values,
                (w, h),
                [min.x, min.x + size],
                [min.y, min.y + size],
            );
            for j in 0..h {
                for i in 0..w {
                    let cell = [
                        [
                            (i as f64 / w as f64).max(min.x),
                            ((i + 1) as f64 / w as f64).min(min.x + size),
                        ],
                        [
                            (j as f64 / h as f64).max(min.y),
                            ((j + 1) as f64 / h as f64).min(min.y + size),
                        ],
                    ];
                    if cell[0][1] <= cell[0][0] || cell[1][1] <= cell[1][0] {
                        continue;
                    }
                    let expected =
                        samples as f64 * brute_mass(&values, (w, h), cell[0], cell[1]) / total;
                    let observed = hits[j * w + i];
                    assert!(
                        (observed - expected).abs() <= 5.0 * expected.sqrt() + 1.0,
                        "texel ({i}, {j}) of box {min} {size}: {observed} against {expected}"
                    );
                }
            }
        }
    }

    /// The binary searches place a particle where the plain inversion puts it: walking the
    /// box's texel columns (then the chosen column's rows) and accumulating their masses from
    /// the values as stored, on boxes across texel edges, within one texel and over the whole
    /// map, with u at texel boundaries included.
    #[test]
    fn placement_is_the_inverse_of_the_walked_masses() {
        for (w, h, seed) in [(7, 5, 9), (37, 23, 3), (1, 9, 4), (64, 1, 5), (128, 4, 6)] {
            let (map, _) = patchy(w, h, seed);
            let stored = |i: usize, j: usize| map.texel(i, h - 1 - j);
            let mut rng = TeaRng::new([seed, 5, 5, 5], 0, 8);
            for k in 0..400 {
                let size = 0.5f64.powi(k % 9);
                let [a, b] = unit_pair(rng.next_bits());
                let min = (DVec2::new(a, b) * (1.0 - size) / size).floor() * size;
                let u = if k % 5 == 0 {
                    [0.0, (k % 3) as f64 / 3.0]
                } else {
                    unit_pair(rng.next_bits())
                };
                let covered = |lo: f64, hi: f64, t: usize, n: usize| {
                    ((hi.min((t + 1) as f64 / n as f64) - lo.max(t as f64 / n as f64)) * n as f64)
                        .max(0.0)
                };
                let walk = |masses: &[(usize, f64)], target: f64| {
                    let total: f64 = masses.iter().map(|m| m.1).sum();
                    let target = target * total;
                    let mut before = 0.0;
                    for &(t, m) in masses {
                        if m > 0.0 && before + m > target {
                            return (t, (target - before) / m);
                        }
                        before += m;
                    }
                    let last = masses.iter().rev().find(|m| m.1 > 0.0).unwrap();
                    (last.0, 1.0)
                };
                let column_masses: Vec<(usize, f64)> = (0..w)
                    .map(|i| {
                        let mass: f64 = (0..h)
                            .map(|j| stored(i, j) * covered(min.y, min.y + size, j, h))
                            .sum();
                        (i, mass * covered(min.x, min.x + size, i, w))
                    })
                    .filter(|&(i, _)| covered(min.x, min.x + size, i, w) > 0.0)
                    .collect();
                if column_masses.iter().all(|m| m.1 == 0.0) {
                    continue;
                }
                let (i, t) = walk(&column_masses, u[0]);
                let row_masses: Vec<(usize, f64)> = (0..h)
                    .filter(|&j| covered(min.y, min.y + size, j, h) > 0.0)
                    .map(|j| (j, stored(i, j) * covered(min.y, min.y + size, j, h)))
                    .collect();
                let (j, s) = walk(&row_masses, u[1]);
                let at = |t: usize, n: usize, lo: f64, f: f64| {
                    let a = (t as f64 / n as f64).max(lo);
                    let b = ((t + 1) as f64 / n as f64).min(lo + size);
                    a + f * (b - a)
                };
                let expected = DVec2::new(at(i, w, min.x, t), at(j, h, min.y, s));
                let placed = map.place(min, size, u);
                assert!(
                    (placed - expected).abs().max_element() < 1e-12,
                    "{w}x{h} box {min} {size}, u {u:?}: {placed} against {expected}"
                );
            }
        }
    }

    /// ∫_A d over parallelograms, wrapped across tiles, against a fine midpoint rule over the
    /// parallelogram's own parameters.
    #[test]
    fn mass_in_a_footprint_is_the_integral_over_the_parallelogram() {
        let (map, _) = patchy(11, 6, 3);
        let mut rng = TeaRng::new([8, 1, 8, 1], 0, 8);
        for _ in 0..40 {
            let [a, b] = unit_pair(rng.next_bits());
            let [c, d] = unit_pair(rng.next_bits());
            let uv = DVec2::new(a, b);
            let dx = DVec2::new(0.02 + 0.5 * c, 0.1 * d - 0.05);
            let dy = DVec2::new(0.2 * a - 0.1, 0.03 + 0.4 * d);
            let footprint = Footprint::new(uv, dx, dy).unwrap();
            let n = 600;
            let mut sum = 0.0;
            for s in 0..n {
                for t in 0..n {
                    let (s, t) = (
                        (s as f64 + 0.5) / n as f64 - 0.5,
                        (t as f64 + 0.5) / n as f64 - 0.5,
                    );
                    sum += map.value_at(uv + s * dx + t * dy);
                }
            }
            let reference = sum / (n * n) as f64 * footprint.area();
            let exact = map.mass_in(&footprint);
            assert!(
                (exact - reference).abs() < 0.01 * footprint.area(),
                "{uv} {dx} {dy}: {exact} against {reference}"
            );
        }
    }

    /// The mean over a square is the integral of the map over it (a fine midpoint rule of the
    /// repeating map) over its area, for nearest and bilinear maps, squares across the
    /// texture square's edges included; a square narrower than a texel (down to 0) nears the
    /// value at its centre.
    #[test]
    fn the_mean_over_a_square_is_the_integral_over_its_area() {
        let (nearest, _) = patchy(11, 6, 3);
        let values = nearest.texels();
        let bilinear = DensityMap::with_filter(11, 6, &values, MapFilter::Bilinear).unwrap();
        let mut rng = TeaRng::new([3, 1, 4, 1], 0, 8);
        for map in [&nearest, &bilinear] {
            for _ in 0..40 {
                let [a, b] = unit_pair(rng.next_bits());
                let [c, _] = unit_pair(rng.next_bits());
                let side = 0.01 + 0.5 * c;
                // Centres over the square and past its edges.
                let centre = DVec2::new(a, b) * 1.4 - 0.2;
                let min = centre - 0.5 * side;
                let n = 400;
                let mut sum = 0.0;
                for i in 0..n {
                    for j in 0..n {
                        let t = (DVec2::new(f64::from(i), f64::from(j)) + 0.5) / f64::from(n);
                        sum += map.value_at(min + side * t);
                    }
                }
                let reference = sum / f64::from(n * n);
                let mean = map.mean_over_square(centre, side);
                assert!(
                    (mean - reference).abs() < 0.01,
                    "{centre} {side}: {mean} against {reference}"
                );
            }
            let corner = DVec2::new(0.31, 0.62);
            assert!((map.mean_over_square(corner, 1e-9) - map.value_at(corner)).abs() < 1e-3);
            assert_eq!(map.mean_over_square(corner, 0.0), map.value_at(corner));
        }
    }

    /// Every texel's value in one pass is the texel's own, for maps stored whole and tiled.
    #[test]
    fn texels_are_each_texels_value() {
        let (patchy_map, _) = patchy(37, 23, 4);
        // 0 outside one corner, stored whole and tiled (most of its 64 × 64 tiles empty).
        let (w, h) = (300, 200);
        let values: Vec<f64> = (0..w * h)
            .map(|k| {
                if k % w < 70 && k / w < 90 {
                    ((k * 7) % 11) as f64 / 10.0
                } else {
                    0.0
                }
            })
            .collect();
        let build = |layout| {
            DensityMap::with_layout(w, h, &values, MapFilter::Nearest, Some(layout)).unwrap()
        };
        let (whole, tiled) = (build(Layout::Whole), build(Layout::Tiled));
        assert!(matches!(tiled.tables.sums, tables::PrefixTable::Tiled(_)));
        for map in [&patchy_map, &whole, &tiled] {
            let texels = map.texels();
            for row in 0..map.height {
                for column in 0..map.width {
                    assert_eq!(texels[row * map.width + column], map.texel(column, row));
                }
            }
        }
    }

    /// The mass row by row (whole texels from the summed-area table, only the cut ones
    /// clipped) is the sum of every texel of the bounding box clipped to the parallelogram:
    /// footprints 0.3 to 60 texels across at every angle, thin ones, wrapped across the
    /// square's edges and over several tiles, and footprints whose corners are texel corners.
    #[test]
    fn whole_texels_add_what_clipping_them_adds() {
        let every_texel_clipped = |map: &DensityMap, footprint: &Footprint| {
            let (min, max) = footprint.bounds();
            let scale = DVec2::new(map.width as f64, map.height as f64);
            let (lo, hi) = ((min * scale).floor(), (max * scale).ceil());
            let corners = footprint.corners();
            let mut mass = 0.0;
            for row in lo.y as i64..hi.y as i64 {
                for column in lo.x as i64..hi.x as i64 {
                    let (x0, y0) = (column as f64 / scale.x, row as f64 / scale.y);
                    let (x1, y1) = ((column + 1) as f64 / scale.x, (row + 1) as f64 / scale.y);
                    let strip = clip(&corners, |p| p.y - y0, |p| y1 - p.y);
                    let piece = clip(&strip, |p| p.x - x0, |p| x1 - p.x);
                    let (i, j) = (
                        column.rem_euclid(map.width as i64) as usize,
                        row.rem_euclid(map.height as i64) as usize,
                    );
                    let area = cut_area(&piece, footprint, column, row, scale);
                    mass += area * map.fixed(i, j) as f64;
                }
            }
            mass / FIXED_ONE
        };
        for (w, h, seed) in [(11, 6, 1), (64, 48, 2), (5, 40, 3)] {
            let (map, _) = patchy(w, h, seed);
            for footprint in footprints_of_every_shape((w, h), seed) {
                let fast = map.mass_in(&footprint);
                let reference = every_texel_clipped(&map, &footprint);
                assert!(
                    (fast - reference).abs() <= 1e-12 * reference.max(footprint.area()),
                    "{w}x{h} {footprint:?}: {fast} against {reference}"
                );
            }
        }
    }

    /// The map [[1, 0.5]], nearest: a square of side s at (0.7, 0.3) lies in the 0.5 texel and
    /// holds s²/2. The cut texel's area was a shoelace over its corners in uv, which cancel to
    /// their rounding: 17% low for s = 10⁻⁸, 0 for 10⁻⁹ and 10⁻¹⁰. Now within 10⁻⁹ of s²/2
    /// for sides 10⁻⁴ to 10⁻¹².
    #[test]
    fn a_tiny_square_at_0_7_0_3_on_a_one_half_nearest_map_holds_half_its_area() {
        let map = DensityMap::with_filter(2, 1, &[1.0, 0.5], MapFilter::Nearest).unwrap();
        for k in 4..=12 {
            let side = 10f64.powi(-k);
            let footprint =
                Footprint::new(DVec2::new(0.7, 0.3), DVec2::X * side, DVec2::Y * side).unwrap();
            let (got, exact) = (map.mass_in(&footprint), 0.5 * side * side);
            assert!(
                (got - exact).abs() <= 1e-9 * exact,
                "side 1e-{k}: {got:e} against {exact:e}"
            );
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::test_runner::Config {
            cases: 1000,
            rng_seed: proptest::test_runner::RngSeed::Fixed(0x6e65_6172),
            failure_persistence: None,
            ..proptest::test_runner::Config::default()
        })]

        /// Over random nearest maps (zeros common), footprints 10⁻¹² to 10⁻¹ across at any
        /// angle, shape and place (on texel corners, on edges, anywhere, over several tiles):
        /// the mass is finite and ≥ 0, and where the footprint lies inside one texel (its
        /// corners' texel coordinates, about its centre, all within that texel's), it is the
        /// texel's value times the footprint's area to 10⁻⁹.
        #[test]
        fn nearest_masses_are_never_negative_and_inside_a_texel_are_value_times_area(
            (w, h) in (1usize..=8, 1usize..=8),
            values in proptest::collection::vec(
                proptest::prop_oneof![
                    2 => proptest::strategy::Just(0.0),
                    1 => proptest::strategy::Just(1.0),
                    3 => 0.0..=1.0f64,
                ],
                64,
            ),
            place in 0usize..3,
            (cell, nudge) in ((-8i64..24, -8i64..24), (-1.0..=1.0f64, -1.0..=1.0f64)),
            (exponent, aspect, turn, skew) in
                (-12.0..=-1.0f64, 0.05..=1.0f64, 0.0..1.0f64, -0.4..=0.4f64),
            aligned in proptest::bool::weighted(0.3),
        ) {
            let mut values = values[..w * h].to_vec();
            if values.iter().all(|&v| v == 0.0) {
                values[0] = 1.0;
            }
            let map = DensityMap::with_filter(w, h, &values, MapFilter::Nearest).unwrap();
            let texel = DVec2::new(1.0 / w as f64, 1.0 / h as f64);
            let size = 10f64.powf(exponent);
            let at = DVec2::new(cell.0 as f64, cell.1 as f64);
            let uv = match place {
                0 => at * texel,
                1 => (at + DVec2::new(0.5, 0.0)) * texel,
                _ => at / 8.0 + DVec2::new(0.3, 0.7) * texel,
            } + DVec2::new(nudge.0, nudge.1) * size;
            let footprint = turned_footprint(uv, size, (aspect, turn, skew), aligned);
            let (dx, dy) = footprint.edges();
            let mass = map.mass_in(&footprint);
            proptest::prop_assert!(mass.is_finite() && mass >= 0.0, "{mass:e} at {uv} {dx} {dy}");
            // The footprint is inside texel (i, j) when its extent about the centre stays
            // within the centre's distances to the texel's sides (with a margin of rounding).
            let scale = DVec2::new(w as f64, h as f64);
            let center = footprint.center();
            let in_texels = center * scale;
            let texel_at = in_texels.floor();
            let half = 0.5 * ((dx * scale).abs() + (dy * scale).abs());
            let (below, above) = (in_texels - texel_at, texel_at + 1.0 - in_texels);
            let margin = 4.0 * f64::EPSILON * (in_texels.abs() + 1.0);
            if (half + margin).cmplt(below).all() && (half + margin).cmplt(above).all() {
                let (i, j) = (texel_at.x as usize % w, texel_at.y as usize % h);
                let exact = map.fixed(i, j) as f64 / FIXED_ONE * footprint.area();
                proptest::prop_assert!(
                    (mass - exact).abs() <= 1e-9 * exact,
                    "{w}x{h} at {uv} {dx} {dy}: {mass:e} against {exact:e}"
                );
            }
        }
    }

    /// The bound over a footprint is at least every value inside it and at most the largest
    /// texel its bounding box (wrapped) touches.
    #[test]
    fn the_maximum_over_a_footprint_bounds_its_values() {
        for (w, h, seed) in [(11, 6, 1), (64, 64, 2), (5, 40, 3)] {
            let (map, _) = patchy(w, h, seed);
            let mut rng = TeaRng::new([seed, 9, 9, 9], 0, 8);
            for k in 0..300 {
                let [a, b] = unit_pair(rng.next_bits());
                let [c, d] = unit_pair(rng.next_bits());
                let scale = [0.002, 0.03, 0.3, 2.0][k % 4];
                let uv = DVec2::new(a, b);
                let dx = DVec2::new(scale * (0.2 + c), scale * (d - 0.5));
                let dy = DVec2::new(scale * (0.3 * c - 0.1), scale * (0.2 + d));
                let footprint = Footprint::new(uv, dx, dy).unwrap();
                let bound = map.max_over(&footprint);
                let mut inside = 0.0f64;
                for s in 0..40 {
                    for t in 0..40 {
                        let (s, t) = (f64::from(s) / 39.0 - 0.5, f64::from(t) / 39.0 - 0.5);
                        inside = inside.max(map.value_at(uv + s * dx + t * dy));
                    }
                }
                let (min, max) = footprint.bounds();
                // The blocks covering the box reach less than twice its longest side beyond it.
                let (i0, i1) = (
                    (min.x * w as f64).floor() as i64,
                    (max.x * w as f64).ceil() as i64,
                );
                let (j0, j1) = (
                    (min.y * h as f64).floor() as i64,
                    (max.y * h as f64).ceil() as i64,
                );
                let reach = 2 * (i1 - i0).max(j1 - j0);
                let mut near = 0.0f64;
                for j in j0 - reach..j1 + reach {
                    for i in i0 - reach..i1 + reach {
                        let (i, j) = (
                            i.rem_euclid(w as i64) as usize,
                            j.rem_euclid(h as i64) as usize,
                        );
                        near = near.max(map.texel(i, h - 1 - j));
                    }
                }
                assert!(bound >= inside, "{w}x{h} {footprint:?}: {bound} < {inside}");
                assert!(
                    bound <= near,
                    "{w}x{h} {footprint:?}: {bound} above the texels near it ({near})"
                );
            }
        }
    }

    /// The map-weighted mean multiplicity of a box's particles against a midpoint rule over
    /// the box, for footprints across texel edges and tiles.
    #[test]
    fn mean_multiplicity_is_the_weighted_mean_over_the_box() {
        let (map, _) = patchy(11, 6, 4);
        let mut rng = TeaRng::new([2, 7, 1, 8], 0, 8);
        let mut checked = 0;
        for k in 0..200 {
            let [a, b] = unit_pair(rng.next_bits());
            let [c, d] = unit_pair(rng.next_bits());
            let level = 1 + k % 4;
            let size = 0.5f64.powi(level as i32);
            let min = (DVec2::new(c, d) / size).floor() * size;
            let scale = [0.05, 0.3, 1.2][k % 3];
            let footprint = Footprint::new(
                DVec2::new(a, b),
                DVec2::new(scale, 0.1 * scale),
                DVec2::new(-0.2 * scale, 0.8 * scale),
            )
            .unwrap();
            let Some(weighted) = map.mean_multiplicity(&footprint, min, size) else {
                continue;
            };
            let n = 400;
            let (mut mass, mut sum) = (0.0, 0.0);
            for i in 0..n {
                for j in 0..n {
                    let x = min
                        + size
                            * DVec2::new((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
                    let d = map.value_at(x);
                    mass += d;
                    sum += d * footprint.multiplicity(x) as f64;
                }
            }
            let reference = sum / mass;
            assert!(
                (weighted - reference).abs() < 0.02 * reference.max(1.0),
                "box {min} {size}, {footprint:?}: {weighted} against {reference}"
            );
            checked += 1;
        }
        assert!(checked > 50);
    }

    #[test]
    fn invalid_maps_are_refused_naming_the_texel() {
        assert_eq!(
            DensityMap::new(2, 2, &[0.0, 1.0, 1.5, 0.0]),
            Err(DensityMapError::InvalidTexel {
                column: 0,
                row: 1,
                value: 1.5
            })
        );
        assert!(matches!(
            DensityMap::new(2, 1, &[f64::NAN, 0.0]),
            Err(DensityMapError::InvalidTexel {
                column: 0,
                row: 0,
                ..
            })
        ));
        assert_eq!(
            DensityMap::new(2, 2, &[0.0; 4]),
            Err(DensityMapError::Empty)
        );
        assert_eq!(
            DensityMap::new(0, 3, &[]),
            Err(DensityMapError::InvalidSize {
                width: 0,
                height: 3
            })
        );
        // Sizes up to 2^28 texels are valid (8192 x 8192 and 16384 x 16384: only the values'
        // count is wrong here), larger ones are not.
        for (width, height) in [(8192, 8192), (16384, 16384)] {
            assert!(matches!(
                DensityMap::new(width, height, &[1.0]),
                Err(DensityMapError::WrongLength { .. })
            ));
        }
        assert_eq!(
            DensityMap::new(16384, 16385, &[1.0]),
            Err(DensityMapError::InvalidSize {
                width: 16384,
                height: 16385
            })
        );
        assert_eq!(
            DensityMap::new(2, 2, &[1.0; 3]),
            Err(DensityMapError::WrongLength {
                expected: 4,
                given: 3
            })
        );
        assert_eq!(
            DensityMap::new(3, 2, &[1.0; 6]).unwrap().uniform_value(),
            Some(1.0)
        );
    }
}
