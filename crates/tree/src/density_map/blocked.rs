//! A roughness level's summed-area tables over blocks, its texels read from the family they
//! share ([`LevelTexels`]): the layout that keeps K levels' memory from growing K times a map
//! where α changes at every texel. A large map of its own takes the same tables over its own
//! texels ([`LevelTexels`]'s single map, 33 bits a texel): about 4.5 bytes a texel in all.
//!
//! The table holds S at the corners of whole blocks of [`BLOCK`] × [`BLOCK`] texels,
//! S(a·B, b·B) for a ≤ ⌊W/B⌋, b ≤ ⌊H/B⌋: 1/B² of an entry a texel. A rectangle's sum is
//! the sum over the whole blocks inside it, from four of those corners, plus its texels outside
//! them (the strips along its edges, under B texels wide, and all of it when it spans no whole
//! block), each read from the family: the same integers the whole table's four corners give,
//! so the same answers, bit for bit; the cost grows with the rectangle's perimeter in texels
//! instead of being O(1). Three questions a tree asks often are answered with fewer reads:
//!
//! - a box's mass by its 3 × 3 groups of texels (its edges' partial texels and its interior):
//!   the groups along the edges are scanned and the interior is the whole span's sum less
//!   them ([`BlockedPrefix::group_sums`]);
//! - whether a box is constant: one look-up where its inner whole blocks hold a change
//!   ([`BlockedPrefix::texels_constant`]);
//! - a leaf's particles' placements: a box of up to 64 × 64 texels is read once into a table
//!   of its own ([`BlockedPrefix::box_sums`], `DensityMap::place_each`); a larger one, up to
//!   1024 texels a side, is searched by its block boundaries and then one block's columns
//!   (`large_box.rs`): about nine times its height in texels a particle.
//! - a footprint's mass ([`super::DensityMap::mass_in`]): the runs of whole texels of eight
//!   rows that make a row of blocks are read together, so it reads about 8 texels per texel
//!   of the footprint's perimeter.
//!
//! A bilinear level (`bilinear.rs`) asks the same questions of the texels whose tents meet a
//! box: its mass by the box's up to 5 × 5 groups, its leaf's placements from a table of its
//! own of those texels, one more before and two after (where the tents span up to 61 texels a
//! side), its footprints' whole cells by the same bands of eight rows.
//!
//! Elsewhere (a box's constancy where it is constant, `mean_over_square`) the cost grows with
//! the box's perimeter in texels times B, where a level's own map answers in O(1).

use std::sync::Arc;

use super::level_texels::{BLOCK, BLOCK_SHIFT, LevelTexels};
use super::tables::Entry;

/// A level's summed-area table over whole blocks (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct BlockedPrefix<T> {
    texels: Arc<LevelTexels>,
    level: usize,
    /// ⌊W/B⌋ + 1 corners per row.
    stride: usize,
    /// S(a·B, b·B) at `corners[b·stride + a]`.
    corners: Vec<T>,
}

impl<T: Entry> BlockedPrefix<T> {
    /// The bytes a `width` × `height` level's table holds.
    pub(super) fn bytes(width: usize, height: usize) -> usize {
        T::BYTES * ((width >> BLOCK_SHIFT) + 1) * ((height >> BLOCK_SHIFT) + 1)
    }

    /// The table of the entries `T::of_texel` gives `level`'s texels in `texels`.
    pub(super) fn new(texels: &Arc<LevelTexels>, level: usize) -> Self {
        let (width, height) = texels.size();
        let (blocks_x, blocks_y) = (width >> BLOCK_SHIFT, height >> BLOCK_SHIFT);
        let stride = blocks_x + 1;
        let mut corners = vec![T::default(); stride * (blocks_y + 1)];
        for b in 0..blocks_y {
            // Row b + 1 of corners: row b's plus the running sum of this row of blocks.
            let mut running = T::default();
            for a in 0..blocks_x {
                let block = scan(
                    texels,
                    level,
                    (a << BLOCK_SHIFT, (a + 1) << BLOCK_SHIFT),
                    (b << BLOCK_SHIFT, (b + 1) << BLOCK_SHIFT),
                );
                running = running + block;
                corners[(b + 1) * stride + a + 1] = corners[b * stride + a + 1] + running;
            }
        }
        Self {
            texels: Arc::clone(texels),
            level,
            stride,
            corners,
        }
    }

    /// The entry of texel (i, j), read from the family.
    #[inline]
    pub(super) fn cell(&self, i: usize, j: usize) -> T {
        T::of_texel(&self.texels, self.level, i, j)
    }

    /// The family whose texels it reads.
    pub(super) fn texels(&self) -> &Arc<LevelTexels> {
        &self.texels
    }

    /// The heap memory it holds, in bytes (the family's texels are counted once, by the
    /// material that shares them).
    pub(super) fn heap_bytes(&self) -> usize {
        T::BYTES * self.corners.len()
    }

    /// Σ over texel columns [i0, i1) × rows [j0, j1) (within the map): the whole blocks from
    /// the corners, the rest texel by texel.
    pub(super) fn rect(&self, (i0, i1): (usize, usize), (j0, j1): (usize, usize)) -> T {
        if i0 >= i1 || j0 >= j1 {
            return T::default();
        }
        let (a0, a1) = (i0.div_ceil(BLOCK), i1 >> BLOCK_SHIFT);
        let (b0, b1) = (j0.div_ceil(BLOCK), j1 >> BLOCK_SHIFT);
        let texels = |columns, rows| scan(&self.texels, self.level, columns, rows);
        if a0 >= a1 || b0 >= b1 {
            return texels((i0, i1), (j0, j1));
        }
        let corner = |a: usize, b: usize| self.corners[b * self.stride + a];
        let blocks = corner(a1, b1) + corner(a0, b0) - corner(a1, b0) - corner(a0, b1);
        let (x0, x1) = (a0 << BLOCK_SHIFT, a1 << BLOCK_SHIFT);
        let (y0, y1) = (b0 << BLOCK_SHIFT, b1 << BLOCK_SHIFT);
        blocks
            + texels((i0, i1), (j0, y0))
            + texels((i0, i1), (y1, j1))
            + texels((i0, x0), (y0, y1))
            + texels((x1, i1), (y0, y1))
    }
}

impl BlockedPrefix<u64> {
    /// The sums over the rectangles `columns[c]` × `rows[r]` (a box's groups of texels, at
    /// most `N` a side: its first column, interior and last column, or a bilinear box's
    /// partly covered texels and interior, contiguous, and the same for rows), each the
    /// integer [`Self::rect`] gives it: the largest read as the whole span's sum less the
    /// others, which are scanned. A box's groups along its edges are a texel wide, so this
    /// reads its perimeter's texels, where each group's own rectangle would read strips up to
    /// B texels wide along both sides of every edge between groups (the whole span's sum still
    /// reads the strips under B wide along its own unaligned edges).
    pub(super) fn group_sums<const N: usize>(
        &self,
        columns: &[(usize, usize)],
        rows: &[(usize, usize)],
    ) -> [[u64; N]; N] {
        let mut sums = [[0u64; N]; N];
        let area = |(c, r): (usize, usize)| (columns[c].1 - columns[c].0) * (rows[r].1 - rows[r].0);
        let pairs = || (0..rows.len()).flat_map(|r| (0..columns.len()).map(move |c| (c, r)));
        let Some(largest) = pairs().max_by_key(|&pair| area(pair)) else {
            return sums;
        };
        let span = (
            (columns[0].0, columns[columns.len() - 1].1),
            (rows[0].0, rows[rows.len() - 1].1),
        );
        let mut rest = self.rect(span.0, span.1);
        for (c, r) in pairs().filter(|&pair| pair != largest) {
            let sum = scan(&self.texels, self.level, columns[c], rows[r]);
            sums[r][c] = sum;
            rest -= sum;
        }
        sums[largest.1][largest.0] = rest;
        sums
    }
}

impl BlockedPrefix<u64> {
    /// Writes the summed-area table of texels c₀…c₁ × r₀…r₁ (inclusive) into `sums`, w + 1
    /// entries a row (w = c₁ − c₀ + 1, the stride returned) from S = 0 at (c₀, r₀), for the
    /// rectangles a leaf's particles' placements ask within its box: its texels read once,
    /// four look-ups a rectangle. `sums` holds at least (w + 1)·(h + 1) entries, zeroed.
    pub(super) fn box_sums(
        &self,
        (c0, c1): (usize, usize),
        (r0, r1): (usize, usize),
        sums: &mut [u64],
    ) -> usize {
        let stride = c1 - c0 + 2;
        for j in r0..=r1 {
            let mut running = 0;
            let row = (j - r0 + 1) * stride;
            for i in c0..=c1 {
                running += self.texels.fixed(self.level, i, j);
                sums[row + i - c0 + 1] = sums[row - stride + i - c0 + 1] + running;
            }
        }
        stride
    }
}

impl BlockedPrefix<u32> {
    /// Whether texels c₀…c₁ × r₀…r₁ (inclusive) have one value. The whole blocks inside whose
    /// right and upper neighbours are inside too answer at once where they hold a change;
    /// where they hold none they and those neighbours share one value, and only the texels
    /// outside them are compared with it (a texel a time, stopping at the first that
    /// differs): about the box's perimeter times B texels, and one look-up for a box of
    /// white noise.
    pub(super) fn texels_constant(
        &self,
        (c0, c1): (usize, usize),
        (r0, r1): (usize, usize),
    ) -> bool {
        let corner = |a: usize, b: usize| self.corners[b * self.stride + a];
        let blocks_changes = |(a0, a1): (usize, usize), (b0, b1): (usize, usize)| {
            corner(a1, b1) + corner(a0, b0) - corner(a1, b0) - corner(a0, b1)
        };
        // A box made of whole blocks with no change among them nor towards their right and
        // upper neighbours is constant at once (one look-up, as a power-of-two map's dyadic
        // boxes of 8 texels and more are).
        let whole =
            |lo: usize, hi: usize| lo.is_multiple_of(BLOCK) && (hi + 1).is_multiple_of(BLOCK);
        if whole(c0, c1)
            && whole(r0, r1)
            && blocks_changes(
                (c0 >> BLOCK_SHIFT, (c1 + 1) >> BLOCK_SHIFT),
                (r0 >> BLOCK_SHIFT, (r1 + 1) >> BLOCK_SHIFT),
            ) == 0
        {
            return true;
        }
        let (a0, a1) = (c0.div_ceil(BLOCK), c1 >> BLOCK_SHIFT);
        let (b0, b1) = (r0.div_ceil(BLOCK), r1 >> BLOCK_SHIFT);
        let q = |i: usize, j: usize| self.texels.fixed(self.level, i, j);
        let inner = if a0 < a1 && b0 < b1 {
            if blocks_changes((a0, a1), (b0, b1)) > 0 {
                return false;
            }
            (
                a0 << BLOCK_SHIFT..a1 << BLOCK_SHIFT,
                b0 << BLOCK_SHIFT..b1 << BLOCK_SHIFT,
            )
        } else {
            (0..0, 0..0)
        };
        let value = q(c0, r0);
        let row_is =
            |j: usize, columns: (usize, usize)| self.texels.row_is(self.level, j, columns, value);
        (r0..=r1).all(|j| {
            if inner.1.contains(&j) {
                row_is(j, (c0, inner.0.start)) && row_is(j, (inner.0.end, c1 + 1))
            } else {
                row_is(j, (c0, c1 + 1))
            }
        })
    }
}

/// Σ of `level`'s entries over texel columns [i0, i1) × rows [j0, j1), texel by texel.
fn scan<T: Entry>(
    texels: &LevelTexels,
    level: usize,
    (i0, i1): (usize, usize),
    (j0, j1): (usize, usize),
) -> T {
    (j0..j1).fold(T::default(), |sum, j| {
        sum + T::of_row(texels, level, j, (i0, i1))
    })
}

/// The maxima of `level`'s q over blocks of [`BLOCK`] × [`BLOCK`] texels (those the map's
/// edges cut included), row-major: the first level of its pyramid of maxima.
pub(super) fn block_maxima(texels: &LevelTexels, level: usize) -> Vec<u64> {
    let (width, height) = texels.size();
    let blocks_x = width.div_ceil(BLOCK);
    let mut maxima = vec![0u64; blocks_x * height.div_ceil(BLOCK)];
    for j in 0..height {
        let row = &mut maxima[(j >> BLOCK_SHIFT) * blocks_x..][..blocks_x];
        for i in 0..width {
            let block = &mut row[i >> BLOCK_SHIFT];
            *block = (*block).max(texels.fixed(level, i, j));
        }
    }
    maxima
}

#[cfg(test)]
mod tests {
    use glam::DVec2;

    use super::super::tables::{Layout, MaxPyramid};
    use super::super::tests::assert_same_answers;
    use super::super::{DensityMap, DensityMapError, MapFilter, fixed_point};
    use super::*;
    use crate::tea::{TeaRng, unit_pair};

    /// A family of `levels` over `width` × `height` texels (given row by row, from the top):
    /// white noise over the lower level in most of the map, one level over a region and a
    /// band of another (so some boxes are constant), values 0, ¼, 1 and random ones.
    fn family(width: usize, height: usize, levels: usize, seed: u32) -> Vec<(usize, [f64; 2])> {
        let mut rng = TeaRng::new([seed, 9, 8, 7], 0, 8);
        let mut value = || match rng.next_bits() % 5 {
            0 => 0.0,
            1 => 0.25,
            2 => 1.0,
            _ => unit_pair(rng.next_bits())[0],
        };
        (0..width * height)
            .map(|k| {
                let (i, j) = (k % width, k / width);
                if i < width / 3 && j < height / 2 {
                    (0, [0.6, 0.0])
                } else if i + j == width {
                    (levels - 1, [1.0, 0.0])
                } else {
                    let lower = (k * 7 + k / 3) % levels.max(2).saturating_sub(1);
                    (lower, [value(), value()])
                }
            })
            .collect()
    }

    /// Asserts that `blocked` (the map of `values` reconstructed nearest and bilinear, blocked)
    /// answers every question exactly as the same values stored whole: the tables at every
    /// corner, texel and block of the pyramid, random rectangles, and the masses, constancy,
    /// placements, bounds and footprint integrals of random boxes, footprints and a tree's
    /// dyadic boxes, bit for bit.
    fn assert_blocked_answers_as_whole(
        (width, height): (usize, usize),
        values: &[f64],
        blocked: &[DensityMap; 2],
        rng: &mut TeaRng,
        what: &str,
    ) {
        let whole = MapFilter::ALL.map(|filter| {
            DensityMap::with_layout(width, height, values, filter, Some(Layout::Whole)).unwrap()
        });
        for (whole, blocked) in whole.iter().zip(blocked.iter()) {
            assert_eq!((whole.mean, whole.uniform), (blocked.mean, blocked.uniform));
            assert_eq!(whole.max(), blocked.max());
            assert_eq!(whole.texels(), blocked.texels());
        }
        let [whole, bilinear_whole] = &whole;
        let [blocked, bilinear_blocked] = blocked;
        for j in 0..=height {
            for i in 0..=width {
                assert_eq!(whole.tables.sums.at(i, j), blocked.tables.sums.at(i, j));
                assert_eq!(
                    whole.tables.changes.at(i, j),
                    blocked.tables.changes.at(i, j)
                );
                if i < width && j < height {
                    let value = fixed_point(values[(height - 1 - j) * width + i]);
                    assert_eq!(blocked.tables.sums.cell(i, j), value, "{what}");
                }
            }
        }
        for (level, (w, h)) in MaxPyramid::sizes(width, height).into_iter().enumerate() {
            for j in 0..h {
                for i in 0..w {
                    let level = level + super::super::tables::FIRST_MAX_LEVEL;
                    assert_eq!(
                        whole.block_max(level, i, j),
                        blocked.block_max(level, i, j),
                        "{what}: block ({i}, {j}) of level {level}"
                    );
                }
            }
        }
        for _ in 0..5000 {
            let [a, b] = unit_pair(rng.next_bits());
            let [c, d] = unit_pair(rng.next_bits());
            let span = |u: f64, v: f64, n: usize| {
                let first = (u * n as f64) as usize;
                let length = ((v * v) * (n - first + 1) as f64) as usize;
                (first, (first + length).min(n))
            };
            let (columns, rows) = (span(a, c, width), span(b, d, height));
            assert_eq!(
                whole.tables.sums.rect(columns, rows),
                blocked.tables.sums.rect(columns, rows),
                "{what}: {columns:?} x {rows:?}"
            );
            assert_eq!(
                whole.tables.changes.rect(columns, rows),
                blocked.tables.changes.rect(columns, rows)
            );
        }
        assert_same_answers(whole, blocked, rng, 1000, what);
        let bilinear = format!("{what}, bilinear");
        assert_same_answers(bilinear_whole, bilinear_blocked, rng, 1000, &bilinear);
        // A tree's boxes: dyadic squares, whole blocks on a map whose sides are powers of two
        // (the one-look-up paths of constancy and mass).
        for (whole, blocked) in [(whole, blocked), (bilinear_whole, bilinear_blocked)] {
            for depth in 0..7u32 {
                let side = 1.0 / f64::from(1u32 << depth);
                for k in 0..(1u32 << (2 * depth)).min(256) {
                    let cell = DVec2::new(f64::from(k % (1 << depth)), f64::from(k >> depth));
                    let min = cell * side;
                    assert_eq!(
                        (
                            whole.is_constant_over(min, side),
                            whole.quarter_probabilities(min, side)
                        ),
                        (
                            blocked.is_constant_over(min, side),
                            blocked.quarter_probabilities(min, side)
                        ),
                        "{what}, box {min} {side}"
                    );
                }
            }
        }
    }

    /// The sizes the blocked tables are checked at: sides under a block, odd, powers of two.
    const SIZES: [(usize, usize); 6] =
        [(130, 67), (64, 128), (257, 191), (20, 300), (5, 3), (9, 8)];

    /// Each level of a family, blocked, answers every question exactly as the map of that
    /// level's values stored whole (`assert_blocked_answers_as_whole`), in its stated bytes;
    /// a level of zeros is refused as [`DensityMapError::Empty`] as the map of its values is.
    #[test]
    fn blocked_levels_answer_what_their_own_maps_answer() {
        for ((width, height), (levels, seed)) in
            SIZES
                .into_iter()
                .zip([(6, 1), (3, 2), (8, 3), (2, 4), (3, 5), (64, 6)])
        {
            let texels = family(width, height, levels, seed);
            let shared = Arc::new(
                LevelTexels::new(width, height, levels, |k| texels[k]).expect("a valid family"),
            );
            for level in 0..levels {
                let values: Vec<f64> = texels
                    .iter()
                    .map(|&(lower, [a, b])| match level {
                        l if l == lower => a,
                        l if l == lower + 1 => b,
                        _ => 0.0,
                    })
                    .collect();
                let own = DensityMap::with_layout(width, height, &values, MapFilter::Nearest, None);
                let blocked = MapFilter::ALL
                    .map(|filter| DensityMap::roughness_level(&shared, level, filter));
                let blocked = match (own, blocked) {
                    (Ok(_), [Ok(nearest), Ok(bilinear)]) => [nearest, bilinear],
                    (Err(DensityMapError::Empty), [Err(DensityMapError::Empty), _]) => continue,
                    (own, blocked) => panic!("level {level}: {own:?} against {blocked:?}"),
                };
                assert_eq!(
                    blocked[0].heap_bytes(),
                    DensityMap::roughness_level_bytes(width, height)
                );
                assert!(blocked[0].level_texels().is_some());
                let mut rng = TeaRng::new([seed, level as u32, 6, 7], 0, 8);
                let what = format!("level {level}");
                assert_blocked_answers_as_whole(
                    (width, height),
                    &values,
                    &blocked,
                    &mut rng,
                    &what,
                );
            }
        }
    }

    /// A map of its own stored blocked (its texels in 33 bits, `LevelTexels::single`; what
    /// maps of 2²² texels and more take) answers every question exactly as the same map
    /// stored whole (`assert_blocked_answers_as_whole`), d = 1 (q = 2³², the 33rd bit)
    /// included, and holds the bytes [`Layout::Blocked`] counts, its texels with it.
    #[test]
    fn blocked_maps_of_their_own_answer_what_whole_tables_answer() {
        for (seed, (width, height)) in (1..).zip(SIZES) {
            let values: Vec<f64> = family(width, height, 2, seed)
                .into_iter()
                .map(|(_, [a, _])| a)
                .collect();
            assert!(values.contains(&1.0) && values.contains(&0.0));
            let blocked = MapFilter::ALL.map(|filter| {
                DensityMap::with_layout(width, height, &values, filter, Some(Layout::Blocked))
                    .unwrap()
            });
            let occupancy = super::super::MapOccupancy::of_values(width, height, &values);
            let pyramid = MaxPyramid::sizes(width, height);
            assert_eq!(
                blocked[0].heap_bytes(),
                Layout::Blocked.bytes(width, height, &occupancy, &pyramid)
            );
            assert!(blocked[0].level_texels().is_none());
            assert_eq!(blocked[0].heap_bytes_with_texels(), blocked[0].heap_bytes());
            let mut rng = TeaRng::new([seed, 11, 6, 7], 0, 8);
            let what = format!("{width} x {height}");
            assert_blocked_answers_as_whole((width, height), &values, &blocked, &mut rng, &what);
        }
    }
}
