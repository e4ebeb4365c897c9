//! Where a density map keeps its tables: whole, in tiles that leave out the map's empty
//! regions, or (a large map) over blocks of its own texels.
//!
//! A map's tables are summed-area tables (of its fixed-point values q and of its value
//! changes) and a pyramid of maxima. Whole, they cost about 12.7 bytes a texel whatever the
//! values. A roughness map's levels are density maps d·w_k that are 0 wherever a texel's α is
//! not near the level's (the hat functions of log α give a texel weight on two levels at
//! most; exact levels, on one), so K levels stored whole cost K × 12.7 bytes a texel where
//! about two levels' worth of texels hold anything. Tiled, a table costs its full size only
//! over the tiles of [`TILE`] × [`TILE`] texels that hold a non-zero value.
//!
//! # A tiled summed-area table
//! With S(i, j) the table at corner (i, j) (the sum over columns < i and rows < j) and
//! (a, b) = the lower corner of the tile holding (i, j) (multiples of [`TILE`]):
//!
//! ```text
//!   S(i, j) = S(a, b)                        corners of the tiles
//!           + [S(i, b) − S(a, b)]            along the tiles' lower rows
//!           + [S(a, j) − S(a, b)]            along the tiles' left columns
//!           + L(i, j)                        within the tile: Σ q over [a, i) × [b, j)
//! ```
//!
//! an identity (the four terms telescope). The first three are tables of (W + 1)(H + 1)/T²,
//! (W + 1)(H + 1)/T and again (W + 1)(H + 1)/T entries, about 0.4 bytes a texel for both
//! summed-area tables. L is 0 over a tile whose texels are all 0: there S is the sum of the
//! first three terms. Every other tile stores S itself at its (T + 1)² corners (its far edges
//! included), so that a look-up there reads the tile's place and then one entry, and a
//! rectangle of the tile's texels reads four entries of one tile. Every entry is the same
//! integer as the whole table's: a tiled map answers exactly what the same map stored whole
//! answers, bit for bit.
//!
//! The table of value changes g(i, j) = [q(i, j) ≠ q(i + 1, j)] + [q(i, j) ≠ q(i, j + 1)] is
//! non-zero only where a texel or its right or upper neighbour is, so it stores the tiles that
//! are occupied and their left and lower neighbours. The pyramid's blocks finer than a tile
//! are stored for the occupied tiles (a block of an empty tile has maximum 0); coarser levels
//! are whole (at most 1/T² of an entry a texel).
//!
//! A roughness level may instead keep its tables over blocks of 8 × 8 texels, reading its
//! texels from a family it shares with the other levels ([`PrefixTable::Blocked`],
//! `blocked.rs`); a material chooses that for all its levels at once. A map of
//! [`BLOCKED_FROM_TEXELS`] texels or more may keep the same tables over its own texels, held
//! in 33 bits ([`Layout::Blocked`]).
//!
//! Below [`BLOCKED_FROM_TEXELS`] texels a map is tiled where that saves at least a third of its
//! bytes, and from there on it takes the layout of fewest bytes ([`Layout::choose`]); the
//! layouts' bytes are functions of the map's size and of which tiles hold a non-zero value
//! ([`MapOccupancy`]), so a material can count a map's bytes before building it.

use std::ops::{Add, Sub};
use std::sync::Arc;

use super::blocked::{BlockedPrefix, block_maxima};
use super::level_texels::{BLOCK_SHIFT, LevelTexels};

/// log₂ of a tile's side in texels.
const TILE_SHIFT: u32 = 6;

/// A tile's side in texels: 64 (4096 texels; the tables of the tiles' corners, lower rows and
/// left columns cost about 0.38 bytes a texel for both summed-area tables).
pub(super) const TILE: usize = 1 << TILE_SHIFT;

const TILE_MASK: usize = TILE - 1;

/// The place of a tile that stores nothing (its L is 0).
const EMPTY: u32 = u32::MAX;

/// An integer a summed-area table holds.
pub(super) trait Entry:
    Copy + Default + PartialEq + Add<Output = Self> + Sub<Output = Self>
{
    /// Its size in bytes.
    const BYTES: usize;

    /// The entry of texel (i, j) of a family's `level` (j from v = 0): a summed-area table of
    /// values (`u64`) holds its q, one of value changes (`u32`) its g.
    fn of_texel(texels: &LevelTexels, level: usize, i: usize, j: usize) -> Self;

    /// Σ of the entries of texels [i0, i1) of row j.
    #[inline]
    fn of_row(texels: &LevelTexels, level: usize, j: usize, (i0, i1): (usize, usize)) -> Self {
        (i0..i1).fold(Self::default(), |sum, i| {
            sum + Self::of_texel(texels, level, i, j)
        })
    }
}

impl Entry for u64 {
    const BYTES: usize = 8;

    #[inline]
    fn of_texel(texels: &LevelTexels, level: usize, i: usize, j: usize) -> Self {
        texels.fixed(level, i, j)
    }

    #[inline]
    fn of_row(texels: &LevelTexels, level: usize, j: usize, columns: (usize, usize)) -> Self {
        texels.row_sum(level, j, columns)
    }
}

impl Entry for u32 {
    const BYTES: usize = 4;

    #[inline]
    fn of_texel(texels: &LevelTexels, level: usize, i: usize, j: usize) -> Self {
        texels.changes(level, i, j)
    }
}

/// How many tiles a table of corners [0, n] spans along an axis of n texels: the corner n
/// falls in tile n / T (a tile of no texel when T divides n, whose L is then 0).
fn tiles_along(n: usize) -> usize {
    (n >> TILE_SHIFT) + 1
}

/// Which tiles of a `width` × `height` map hold a texel whose stored value is not 0: what a
/// map's bytes depend on besides its size. Marked texel by texel, so that a material can
/// count the bytes of maps it derives (a roughness level's d·w_k) without making their
/// values first ([`super::DensityMap::bytes_for_occupancy`]).
#[derive(Clone, Debug, PartialEq)]
pub struct MapOccupancy {
    width: usize,
    height: usize,
    tiles_x: usize,
    tiles_y: usize,
    occupied: Vec<bool>,
}

impl MapOccupancy {
    /// A `width` × `height` map with no texel marked.
    #[must_use]
    pub fn new(width: usize, height: usize) -> Self {
        let (tiles_x, tiles_y) = (tiles_along(width), tiles_along(height));
        Self {
            width,
            height,
            tiles_x,
            tiles_y,
            occupied: vec![false; tiles_x * tiles_y],
        }
    }

    /// Marks the texel in `column` and `row` (row 0 at the top, as a map's values are given)
    /// when `value` is stored as non-zero.
    pub fn mark(&mut self, column: usize, row: usize, value: f64) {
        if stored_as_nonzero(value) {
            self.mark_fixed(column, self.height - 1 - row);
        }
    }

    /// Marks texel (i, j), j counted from v = 0.
    fn mark_fixed(&mut self, i: usize, j: usize) {
        self.occupied[(j >> TILE_SHIFT) * self.tiles_x + (i >> TILE_SHIFT)] = true;
    }

    /// Whether no texel is marked (no map is built from such values: they are all 0).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        !self.occupied.contains(&true)
    }

    /// The map's width and height in texels.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The tiles of a `width` × `height` map of `values` (row by row, row 0 at the top).
    pub(super) fn of_values(width: usize, height: usize, values: &[f64]) -> Self {
        let mut occupancy = Self::new(width, height);
        for (k, &value) in values.iter().enumerate() {
            occupancy.mark(k % width, k / width, value);
        }
        occupancy
    }

    /// Whether tile (x, y) holds a non-zero value (tiles off the map hold none).
    fn holds(&self, x: usize, y: usize) -> bool {
        x < self.tiles_x && y < self.tiles_y && self.occupied[y * self.tiles_x + x]
    }

    /// The tiles whose value-change entries may be non-zero: the occupied tiles and their left
    /// and lower neighbours.
    fn change_tiles(&self) -> Vec<bool> {
        let mut tiles = vec![false; self.occupied.len()];
        for y in 0..self.tiles_y {
            for x in 0..self.tiles_x {
                tiles[y * self.tiles_x + x] =
                    self.holds(x, y) || self.holds(x + 1, y) || self.holds(x, y + 1);
            }
        }
        tiles
    }

    fn count(tiles: &[bool]) -> usize {
        tiles.iter().filter(|&&t| t).count()
    }
}

/// Each tile's place among the `stored` ones, in order ([`EMPTY`] for the others).
fn places(stored: &[bool]) -> Vec<u32> {
    let mut next = 0u32;
    stored
        .iter()
        .map(|&s| {
            if s {
                next += 1;
                next - 1
            } else {
                EMPTY
            }
        })
        .collect()
}

/// Whether d = `value` ∈ [0, 1] is stored as a non-zero fixed-point value: round(d·2³²) ≥ 1,
/// i.e. d ≥ 2⁻³³ (the product by a power of two is exact).
pub(super) fn stored_as_nonzero(value: f64) -> bool {
    value >= 1.0 / 8_589_934_592.0
}

/// Maps of at least this many texels (2048 × 2048, 53 MB of tables whole) take the layout of
/// fewest bytes, blocked ones included; smaller maps the faster whole tables unless tiles
/// save a third (see [`Layout::choose`]).
pub(super) const BLOCKED_FROM_TEXELS: usize = 1 << 22;

/// Where a map keeps its tables.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Layout {
    /// Every table whole.
    Whole,
    /// Summed-area tables and the pyramid's fine levels in tiles (see the module docs).
    Tiled,
    /// Its own texels in 33 bits ([`LevelTexels::single`]) and tables over 8 × 8 blocks
    /// (`blocked.rs`): about 4.5 bytes a texel.
    Blocked,
}

impl Layout {
    /// The layout of a `width` × `height` map with `occupancy`, and its bytes (`pyramid`: the
    /// pyramid's block grids, finest first).
    ///
    /// Below [`BLOCKED_FROM_TEXELS`] texels: tiled where that saves at least a third of the
    /// bytes, whole otherwise. A look-up in a stored tile reads two entries (the tile's place,
    /// then the entry) instead of one, and one in an empty tile four: on a 1024² density map
    /// with a few empty tiles (0.6% fewer bytes tiled) sphere-lights queries took 1.05×
    /// (nearest) and 1.34× (bilinear) their time under whole tables, so a map is tiled only
    /// for a large saving, as a roughness level's map gives (`cargo bench -p glint-benches
    /// --bench tree -- map_1024`: `…_level` against `…_level_whole`).
    ///
    /// From [`BLOCKED_FROM_TEXELS`] texels on, memory decides: the layout of fewest bytes of
    /// the three. Blocked tables read texels where a box cuts its blocks, so a query costs
    /// about what it costs under whole tables where boxes are large and up to a few percent
    /// more on frames of boxes of a few texels (docs/performance.md, "Production-size maps").
    pub(super) fn choose(
        width: usize,
        height: usize,
        occupancy: &MapOccupancy,
        pyramid: &[(usize, usize)],
    ) -> (Self, usize) {
        let whole = Self::Whole.bytes(width, height, occupancy, pyramid);
        let tiled = Self::Tiled.bytes(width, height, occupancy, pyramid);
        if width * height >= BLOCKED_FROM_TEXELS {
            let blocked = Self::Blocked.bytes(width, height, occupancy, pyramid);
            return [
                (Self::Blocked, blocked),
                (Self::Tiled, tiled),
                (Self::Whole, whole),
            ]
            .into_iter()
            .min_by_key(|&(_, bytes)| bytes)
            .expect("three layouts");
        }
        if 3 * tiled <= 2 * whole {
            (Self::Tiled, tiled)
        } else {
            (Self::Whole, whole)
        }
    }

    /// The bytes a map's tables hold whole: both summed-area tables at every corner and the
    /// pyramid's every block.
    pub(super) fn whole_bytes(width: usize, height: usize, pyramid: &[(usize, usize)]) -> usize {
        let corners = (width + 1) * (height + 1);
        let maxima: usize = pyramid.iter().map(|(w, h)| w * h).sum();
        (u64::BYTES + u32::BYTES) * corners + u64::BYTES * maxima
    }

    /// The bytes a map's tables hold under this layout.
    pub(super) fn bytes(
        self,
        width: usize,
        height: usize,
        occupancy: &MapOccupancy,
        pyramid: &[(usize, usize)],
    ) -> usize {
        match self {
            Self::Whole => Self::whole_bytes(width, height, pyramid),
            Self::Tiled => {
                let occupied = MapOccupancy::count(&occupancy.occupied);
                let changing = MapOccupancy::count(&occupancy.change_tiles());
                let maxima: usize = pyramid
                    .iter()
                    .enumerate()
                    .map(|(k, (w, h))| match fine_blocks_per_tile(k) {
                        Some(blocks) => occupied * blocks,
                        None => w * h,
                    })
                    .sum();
                TiledPrefix::<u64>::bytes(width, height, occupied)
                    + TiledPrefix::<u32>::bytes(width, height, changing)
                    + u64::BYTES * maxima
                    + 4 * occupancy.occupied.len()
            }
            Self::Blocked => {
                LevelTexels::single_bytes_for(width, height) + Tables::blocked_bytes(width, height)
            }
        }
    }
}

/// The pyramid's first level: blocks of 2^`FIRST_MAX_LEVEL` texels (the pyramid's k-th level
/// has blocks of 2^(FIRST_MAX_LEVEL + k)).
pub(super) const FIRST_MAX_LEVEL: usize = 2;

/// How many blocks of the pyramid's k-th level one tile holds, for levels finer than a tile.
fn fine_blocks_per_tile(k: usize) -> Option<usize> {
    let level = FIRST_MAX_LEVEL + k;
    (level < TILE_SHIFT as usize).then(|| 1 << (2 * (TILE_SHIFT as usize - level)))
}

/// A summed-area table S(i, j) over corners i ∈ [0, W], j ∈ [0, H].
#[derive(Clone, Debug, PartialEq)]
pub(super) enum PrefixTable<T> {
    /// `values[j·(W + 1) + i]`.
    Whole { stride: usize, values: Vec<T> },
    /// The decomposition of the module docs.
    Tiled(Box<TiledPrefix<T>>),
    /// Over whole blocks, the texels read from a family of levels (`blocked.rs`).
    Blocked(Box<BlockedPrefix<T>>),
}

/// The tiled layout of a summed-area table (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct TiledPrefix<T> {
    /// W + 1.
    stride: usize,
    tiles_x: usize,
    /// S(a, b) by tile, row-major.
    corners: Vec<T>,
    /// S(i, b) − S(a, b): `along_rows[tile_row·(W + 1) + i]`.
    along_rows: Vec<T>,
    /// S(a, j) − S(a, b): `along_columns[j·tiles_x + tile_column]`.
    along_columns: Vec<T>,
    /// Each tile's place in `within` ([`EMPTY`] where its L is 0).
    directory: Vec<u32>,
    /// S itself at the corners [a, a + T] × [b, b + T] of each stored tile (its own and its
    /// far edges' (clamped to the map), so that a rectangle of the tile's texels reads its
    /// sum here alone), [`SIDE`] × [`SIDE`] entries, row-major within a tile. A look-up in a
    /// stored tile reads one entry, as the whole table does; the decomposition serves the
    /// tiles that store nothing (L = 0 there).
    within: Vec<T>,
}

/// A stored tile's corners per side: T + 1.
const SIDE: usize = TILE + 1;

impl<T: Entry> TiledPrefix<T> {
    fn bytes(width: usize, height: usize, stored: usize) -> usize {
        let (tiles_x, tiles_y) = (tiles_along(width), tiles_along(height));
        T::BYTES
            * (tiles_x * tiles_y
                + (width + 1) * tiles_y
                + (height + 1) * tiles_x
                + stored * SIDE * SIDE)
            + 4 * tiles_x * tiles_y
    }
}

impl<T: Entry> PrefixTable<T> {
    /// S(i, j).
    #[inline]
    pub(super) fn at(&self, i: usize, j: usize) -> T {
        match self {
            Self::Whole { stride, values } => values[j * stride + i],
            Self::Tiled(table) => {
                let (x, y) = (i >> TILE_SHIFT, j >> TILE_SHIFT);
                let tile = y * table.tiles_x + x;
                match table.directory[tile] {
                    EMPTY => {
                        table.corners[tile]
                            + table.along_rows[y * table.stride + i]
                            + table.along_columns[j * table.tiles_x + x]
                    }
                    stored => {
                        let within = (j & TILE_MASK) * SIDE + (i & TILE_MASK);
                        table.within[stored as usize * SIDE * SIDE + within]
                    }
                }
            }
            Self::Blocked(table) => table.rect((0, i), (0, j)),
        }
    }

    /// The sum over texel columns [i0, i1) × rows [j0, j1): S(i1, j1) + S(i0, j0) − S(i1, j0)
    /// − S(i0, j1). Tiled, a rectangle within one tile reads that tile's own corners, and
    /// nothing in a tile that stores nothing.
    #[inline]
    pub(super) fn rect(&self, (i0, i1): (usize, usize), (j0, j1): (usize, usize)) -> T {
        match self {
            Self::Whole { stride, values } => {
                values[j1 * stride + i1] + values[j0 * stride + i0]
                    - values[j0 * stride + i1]
                    - values[j1 * stride + i0]
            }
            Self::Tiled(table)
                if i0 < i1
                    && j0 < j1
                    && i0 >> TILE_SHIFT == (i1 - 1) >> TILE_SHIFT
                    && j0 >> TILE_SHIFT == (j1 - 1) >> TILE_SHIFT =>
            {
                let (x, y) = (i0 >> TILE_SHIFT, j0 >> TILE_SHIFT);
                match table.directory[y * table.tiles_x + x] {
                    EMPTY => T::default(),
                    stored => {
                        let (a, b) = (x << TILE_SHIFT, y << TILE_SHIFT);
                        let tile = &table.within[stored as usize * SIDE * SIDE..][..SIDE * SIDE];
                        let s = |i: usize, j: usize| tile[(j - b) * SIDE + (i - a)];
                        s(i1, j1) + s(i0, j0) - s(i1, j0) - s(i0, j1)
                    }
                }
            }
            Self::Tiled(_) => self.at(i1, j1) + self.at(i0, j0) - self.at(i1, j0) - self.at(i0, j1),
            Self::Blocked(table) => table.rect((i0, i1), (j0, j1)),
        }
    }

    /// The entry of texel (i, j): S's second difference there.
    #[inline]
    pub(super) fn cell(&self, i: usize, j: usize) -> T {
        match self {
            Self::Blocked(table) => table.cell(i, j),
            _ => self.rect((i, i + 1), (j, j + 1)),
        }
    }

    /// The heap memory it holds, in bytes.
    pub(super) fn heap_bytes(&self) -> usize {
        match self {
            Self::Whole { values, .. } => T::BYTES * values.len(),
            Self::Tiled(table) => {
                T::BYTES
                    * (table.corners.len()
                        + table.along_rows.len()
                        + table.along_columns.len()
                        + table.within.len())
                    + 4 * table.directory.len()
            }
            Self::Blocked(table) => table.heap_bytes(),
        }
    }
}

/// Builds a [`PrefixTable`] from its rows S(·, 0), S(·, 1), …, S(·, H), given in order.
pub(super) struct PrefixBuilder<T> {
    table: PrefixTable<T>,
    /// The tiled layout's S(·, b) of the current row of tiles.
    base: Vec<T>,
    /// The next row's index j.
    row: usize,
}

impl<T: Entry> PrefixBuilder<T> {
    /// A `width` × `height` map's table, whole.
    fn whole(width: usize, height: usize) -> Self {
        Self {
            table: PrefixTable::Whole {
                stride: width + 1,
                values: Vec::with_capacity((width + 1) * (height + 1)),
            },
            base: Vec::new(),
            row: 0,
        }
    }

    /// A `width` × `height` map's table, tiled, storing L for the `stored` tiles.
    fn tiled(width: usize, height: usize, stored: &[bool]) -> Self {
        let (tiles_x, tiles_y) = (tiles_along(width), tiles_along(height));
        let directory = places(stored);
        let stored_tiles = MapOccupancy::count(stored);
        let table = TiledPrefix {
            stride: width + 1,
            tiles_x,
            corners: vec![T::default(); tiles_x * tiles_y],
            along_rows: vec![T::default(); (width + 1) * tiles_y],
            along_columns: vec![T::default(); (height + 1) * tiles_x],
            directory,
            within: vec![T::default(); stored_tiles * SIDE * SIDE],
        };
        Self {
            table: PrefixTable::Tiled(Box::new(table)),
            base: vec![T::default(); width + 1],
            row: 0,
        }
    }

    /// Appends S(·, j) for the next j.
    fn push_row(&mut self, row: &[T]) {
        let j = self.row;
        self.row += 1;
        let table = match &mut self.table {
            PrefixTable::Whole { values, .. } => {
                values.extend_from_slice(row);
                return;
            }
            PrefixTable::Tiled(table) => table,
            PrefixTable::Blocked(_) => unreachable!("a blocked table is built whole at once"),
        };
        let width = row.len() - 1;
        // The row of L entries this row gives to the tiles of row `y`, `local` rows above
        // their lower edge b (the tiles above a row j = b hold it as their upper edge, T).
        let fill =
            |table: &mut TiledPrefix<T>, base: &[T], y: usize, local: usize| {
                for x in 0..table.tiles_x {
                    let stored = table.directory[y * table.tiles_x + x];
                    let first = x << TILE_SHIFT;
                    // Corners past the map's right edge hold the sums up to it.
                    let columns = (first..=first + TILE).map(|i| i.min(width));
                    if stored == EMPTY {
                        debug_assert!(columns.clone().all(|i| {
                            row[i] + base[first] - row[first] - base[i] == T::default()
                        }));
                        continue;
                    }
                    let start = stored as usize * SIDE * SIDE + local * SIDE;
                    for (r, i) in columns.enumerate() {
                        table.within[start + r] = row[i];
                    }
                }
            };
        let y = j >> TILE_SHIFT;
        if j & TILE_MASK == 0 {
            if y > 0 {
                fill(table, &self.base, y - 1, TILE);
            }
            self.base.copy_from_slice(row);
            for x in 0..table.tiles_x {
                table.corners[y * table.tiles_x + x] = row[x << TILE_SHIFT];
            }
            for (i, &s) in row.iter().enumerate() {
                table.along_rows[y * table.stride + i] = s - row[i & !TILE_MASK];
            }
        }
        let base = &self.base;
        for x in 0..table.tiles_x {
            table.along_columns[j * table.tiles_x + x] =
                row[x << TILE_SHIFT] - base[x << TILE_SHIFT];
        }
        fill(table, base, y, j & TILE_MASK);
    }

    fn finish(self) -> PrefixTable<T> {
        self.table
    }
}

/// The maxima of q over blocks of 2^L × 2^L texels, L = [`FIRST_MAX_LEVEL`], … until one block
/// holds the map. Under the tiled layout the levels finer than a tile are stored for the
/// occupied tiles only.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct MaxPyramid {
    /// L of its first level's blocks, 2^L × 2^L texels ([`FIRST_MAX_LEVEL`], or
    /// [`BLOCK_SHIFT`] for a blocked level's): finer blocks are read from the texels.
    first_level: usize,
    levels: Vec<MaxLevel>,
    /// Under the tiled layout: each tile's place among the occupied ones ([`EMPTY`] for the
    /// others), and the tiles per row.
    tiles: Option<(Vec<u32>, usize)>,
}

#[derive(Clone, Debug, PartialEq)]
struct MaxLevel {
    /// Blocks per row.
    width: usize,
    /// Whole: `maxima[j·width + i]`; by tile (levels finer than a tile, under the tiled
    /// layout): each occupied tile's blocks, row-major within it.
    maxima: Vec<u64>,
}

impl MaxPyramid {
    /// The block grids' sizes, finest first, for a `width` × `height` map.
    pub(super) fn sizes(width: usize, height: usize) -> Vec<(usize, usize)> {
        Self::sizes_from(FIRST_MAX_LEVEL, width, height)
    }

    /// The block grids' sizes, from blocks of 2^`first_level` texels.
    fn sizes_from(first_level: usize, width: usize, height: usize) -> Vec<(usize, usize)> {
        let first = (
            width.div_ceil(1 << first_level),
            height.div_ceil(1 << first_level),
        );
        std::iter::successors(Some(first), |&(w, h)| {
            (w > 1 || h > 1).then(|| (w.div_ceil(2), h.div_ceil(2)))
        })
        .collect()
    }

    /// Every level whole, from the first one's `first_level` (a grid of `sizes[0]`): each
    /// level's blocks the maxima of four of the level below.
    fn grids(first_level: Vec<u64>, sizes: &[(usize, usize)]) -> Vec<(usize, Vec<u64>)> {
        let mut grids: Vec<(usize, Vec<u64>)> = vec![(sizes[0].0, first_level)];
        for &(next_w, next_h) in &sizes[1..] {
            let mut maxima = vec![0u64; next_w * next_h];
            let (below_w, below) = grids.last().expect("the first level");
            for (k, &value) in below.iter().enumerate() {
                let (i, j) = (k % below_w, k / below_w);
                let block = &mut maxima[(j / 2) * next_w + i / 2];
                *block = (*block).max(value);
            }
            grids.push((next_w, maxima));
        }
        grids
    }

    /// The pyramid of a blocked level (`blocked.rs`), whole, from blocks of 2^[`BLOCK_SHIFT`].
    fn blocked(texels: &LevelTexels, level: usize) -> Self {
        let (width, height) = texels.size();
        let first_level = BLOCK_SHIFT as usize;
        let sizes = Self::sizes_from(first_level, width, height);
        let levels = Self::grids(block_maxima(texels, level), &sizes)
            .into_iter()
            .map(|(width, maxima)| MaxLevel { width, maxima })
            .collect();
        Self {
            first_level,
            levels,
            tiles: None,
        }
    }

    /// The bytes a blocked level's pyramid holds.
    fn blocked_bytes(width: usize, height: usize) -> usize {
        let blocks: usize = Self::sizes_from(BLOCK_SHIFT as usize, width, height)
            .iter()
            .map(|(w, h)| w * h)
            .sum();
        u64::BYTES * blocks
    }

    /// L of the first level's blocks (2^L × 2^L texels).
    pub(super) fn first_level(&self) -> usize {
        self.first_level
    }

    /// The pyramid of a `width` × `height` map whose first level's maxima (blocks of
    /// 2^[`FIRST_MAX_LEVEL`] texels, row-major) are `first_level`, in `layout`.
    fn new(
        first_level: Vec<u64>,
        width: usize,
        height: usize,
        layout: Layout,
        occupancy: &MapOccupancy,
    ) -> Self {
        // Every level whole first, each from the one below.
        let grids = Self::grids(first_level, &Self::sizes(width, height));
        let tiles =
            (layout == Layout::Tiled).then(|| (places(&occupancy.occupied), occupancy.tiles_x));
        let levels = grids
            .into_iter()
            .enumerate()
            .map(
                |(k, (width, maxima))| match (&tiles, fine_blocks_per_tile(k)) {
                    (Some((places, tiles_x)), Some(blocks)) => MaxLevel {
                        width,
                        maxima: Self::by_tile(&maxima, width, k, places, *tiles_x, blocks),
                    },
                    _ => MaxLevel { width, maxima },
                },
            )
            .collect();
        Self {
            first_level: FIRST_MAX_LEVEL,
            levels,
            tiles,
        }
    }

    /// The k-th level's `maxima` (a `width` × `height` grid), regrouped by occupied tile.
    fn by_tile(
        maxima: &[u64],
        width: usize,
        k: usize,
        places: &[u32],
        tiles_x: usize,
        blocks: usize,
    ) -> Vec<u64> {
        let shift = TILE_SHIFT as usize - FIRST_MAX_LEVEL - k;
        let side = 1 << shift;
        let stored = places.iter().filter(|&&p| p != EMPTY).count();
        let mut by_tile = vec![0u64; stored * blocks];
        for (k, &value) in maxima.iter().enumerate() {
            let (i, j) = (k % width, k / width);
            let place = places[(j >> shift) * tiles_x + (i >> shift)];
            if place == EMPTY {
                debug_assert_eq!(value, 0);
                continue;
            }
            by_tile[place as usize * blocks + (j & (side - 1)) * side + (i & (side - 1))] = value;
        }
        by_tile
    }

    /// The largest q over block (i, j) of the pyramid's k-th level; `None` past its levels.
    pub(super) fn block(&self, k: usize, i: usize, j: usize) -> Option<u64> {
        let level = self.levels.get(k)?;
        let (Some((places, tiles_x)), Some(_)) = (&self.tiles, fine_blocks_per_tile(k)) else {
            return Some(level.maxima[j * level.width + i]);
        };
        let shift = TILE_SHIFT as usize - FIRST_MAX_LEVEL - k;
        let side = 1 << shift;
        Some(match places[(j >> shift) * tiles_x + (i >> shift)] {
            EMPTY => 0,
            place => {
                level.maxima
                    [place as usize * side * side + (j & (side - 1)) * side + (i & (side - 1))]
            }
        })
    }

    /// The largest q of the map.
    pub(super) fn top(&self) -> u64 {
        let last = self.levels.len() - 1;
        self.block(last, 0, 0).unwrap_or(0)
    }

    /// The heap memory it holds, in bytes (the tile places counted with the summed-area
    /// tables' directories, which they equal in size).
    pub(super) fn heap_bytes(&self) -> usize {
        let places = self.tiles.as_ref().map_or(0, |(p, _)| 4 * p.len());
        u64::BYTES * self.levels.iter().map(|l| l.maxima.len()).sum::<usize>() + places
    }
}

/// A map's tables.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Tables {
    /// Σ q over columns < i and rows < j.
    pub(super) sums: PrefixTable<u64>,
    /// Σ g over columns < i and rows < j.
    pub(super) changes: PrefixTable<u32>,
    pub(super) maxima: MaxPyramid,
}

impl Tables {
    /// The tables of the fixed-point values `q(i, j)` of a `width` × `height` map (j from
    /// v = 0), in the layout [`Layout::choose`] gives unless `layout` says which.
    pub(super) fn new(
        width: usize,
        height: usize,
        q: &dyn Fn(usize, usize) -> u64,
        occupancy: &MapOccupancy,
        layout: Option<Layout>,
    ) -> Self {
        let layout = layout.unwrap_or_else(|| {
            Layout::choose(width, height, occupancy, &MaxPyramid::sizes(width, height)).0
        });
        let (mut sums, mut changes) = match layout {
            Layout::Blocked => {
                return Self::blocked(&Arc::new(LevelTexels::single(width, height, q)), 0);
            }
            Layout::Whole => (
                PrefixBuilder::whole(width, height),
                PrefixBuilder::whole(width, height),
            ),
            Layout::Tiled => (
                PrefixBuilder::tiled(width, height, &occupancy.occupied),
                PrefixBuilder::tiled(width, height, &occupancy.change_tiles()),
            ),
        };
        // S(·, j) of both tables, a row at a time: S(i + 1, j + 1) = S(i + 1, j) + Σ_{i′ ≤ i} of
        // row j.
        let mut sum_row = vec![0u64; width + 1];
        let mut change_row = vec![0u32; width + 1];
        // The pyramid's first level, from the same rows.
        let first_width = width.div_ceil(1 << FIRST_MAX_LEVEL);
        let mut first_level = vec![0u64; first_width * height.div_ceil(1 << FIRST_MAX_LEVEL)];
        sums.push_row(&sum_row);
        changes.push_row(&change_row);
        let (mut row, mut above) = (Vec::with_capacity(width), Vec::with_capacity(width));
        row.extend((0..width).map(|i| q(i, 0)));
        for j in 0..height {
            above.clear();
            if j + 1 < height {
                above.extend((0..width).map(|i| q(i, j + 1)));
            }
            let (mut row_sum, mut row_changes) = (0u64, 0u32);
            let blocks = &mut first_level[(j >> FIRST_MAX_LEVEL) * first_width..];
            for i in 0..width {
                let value = row[i];
                let block = &mut blocks[i >> FIRST_MAX_LEVEL];
                *block = (*block).max(value);
                row_sum += value;
                row_changes += u32::from(i + 1 < width && row[i + 1] != value)
                    + u32::from(j + 1 < height && above[i] != value);
                sum_row[i + 1] += row_sum;
                change_row[i + 1] += row_changes;
            }
            sums.push_row(&sum_row);
            changes.push_row(&change_row);
            std::mem::swap(&mut row, &mut above);
        }
        Self {
            sums: sums.finish(),
            changes: changes.finish(),
            maxima: MaxPyramid::new(first_level, width, height, layout, occupancy),
        }
    }

    /// The tables of `level` of the family `texels`, blocked (`blocked.rs`); of a map's own
    /// texels where the family is [`LevelTexels::single`].
    pub(super) fn blocked(texels: &Arc<LevelTexels>, level: usize) -> Self {
        Self {
            sums: PrefixTable::Blocked(Box::new(BlockedPrefix::new(texels, level))),
            changes: PrefixTable::Blocked(Box::new(BlockedPrefix::new(texels, level))),
            maxima: MaxPyramid::blocked(texels, level),
        }
    }

    /// The bytes a blocked level's tables hold (its family's texels not counted).
    pub(super) fn blocked_bytes(width: usize, height: usize) -> usize {
        BlockedPrefix::<u64>::bytes(width, height)
            + BlockedPrefix::<u32>::bytes(width, height)
            + MaxPyramid::blocked_bytes(width, height)
    }

    /// The heap memory they hold, in bytes, a map's own texels ([`LevelTexels::single`])
    /// included, not a family of levels it shares.
    pub(super) fn heap_bytes(&self) -> usize {
        let own_texels = match &self.sums {
            PrefixTable::Blocked(table) if table.texels().is_single() => {
                table.texels().heap_bytes()
            }
            _ => 0,
        };
        own_texels + self.sums.heap_bytes() + self.changes.heap_bytes() + self.maxima.heap_bytes()
    }

    /// The bytes the tables of a map with `occupancy` will hold (0 for a map of zeros, which
    /// is not built).
    pub(super) fn bytes_for(occupancy: &MapOccupancy) -> usize {
        if occupancy.is_empty() {
            return 0;
        }
        let (width, height) = occupancy.size();
        Layout::choose(width, height, occupancy, &MaxPyramid::sizes(width, height)).1
    }
}
