//! Placing a leaf's particles in a box wider than 64 texels under blocked tables (nearest
//! filter): what a large map's own blocked layout and a shared roughness level ask of sparse
//! leaves.
//!
//! [`super::DensityMap::place_each`] inverts the box's distribution function, column by the
//! marginal over columns, then row within the column ([`super::invert`]). Its binary
//! searches ask the mass of columns [first + 1, k) at arbitrary k, which blocked tables
//! answer from their corners plus strips of texels up to 7 columns wide along every
//! unaligned edge, and the box's first and last rows texel by texel: most of a query's time
//! under an 8192² map. The answer of either search is unique: the masses before(k) are
//! non-decreasing in k (sums of non-negative integers times positive weights), so the column
//! is the largest k with before(k) ≤ target (or < total, for the last texel with mass) however
//! it is found. Here it is found in two steps: the masses at the box's block boundaries, once
//! for all its particles (the corners, and one pass along the partial rows), then the columns
//! of one block, each column's sums read once. The row is found by walking the chosen column
//! from the box's first row, after its total. Every mass is the same integer the tables give, turned
//! into the same floating-point value, so the positions are those of
//! [`super::DensityMap::place_each`]'s searches, bit for bit (a unit test compares them).

use super::TexelSpan;
use super::blocked::BlockedPrefix;
use super::level_texels::BLOCK;

/// The widest and tallest box placed here, in texels (larger boxes take the tables' own
/// searches): its block boundaries live on the stack.
pub(super) const MAX_SIDE: usize = 1024;

/// The most block boundaries of a box's interior columns: every block's first column, the
/// interior's first and its end.
const MAX_BOUNDARIES: usize = MAX_SIDE / BLOCK + 2;

/// A box's rows as [`TexelSpan::groups`] gives them (first row, interior, last row) and the
/// masses of its columns at its block boundaries (see the module docs).
pub(super) struct LargeBox<'a> {
    table: &'a BlockedPrefix<u64>,
    columns: &'a TexelSpan,
    rows: &'a TexelSpan,
    groups: [(usize, usize, f64); 3],
    group_count: usize,
    /// Boundaries b₀ = first + 1 < b₁ < … ≤ last: the interior columns' first and each block's
    /// first column after it, and `last`.
    boundaries: [usize; MAX_BOUNDARIES],
    /// The integer sums of columns [first + 1, bₘ) over each row group.
    sums: [[u64; 3]; MAX_BOUNDARIES],
    boundary_count: usize,
    /// The first and last columns' masses, with their weights (as `invert` takes them).
    first_mass: f64,
    last_mass: f64,
}

impl<'a> LargeBox<'a> {
    /// The box of texel `columns` × `rows` under `table`, if it is at most [`MAX_SIDE`] a
    /// side.
    pub(super) fn new(
        table: &'a BlockedPrefix<u64>,
        columns: &'a TexelSpan,
        rows: &'a TexelSpan,
    ) -> Option<Self> {
        let side = |span: &TexelSpan| span.last - span.first + 1;
        if side(columns) > MAX_SIDE || side(rows) > MAX_SIDE {
            return None;
        }
        let mut groups = [(0, 0, 0.0); 3];
        let mut group_count = 0;
        for group in rows.groups() {
            groups[group_count] = group;
            group_count += 1;
        }
        let mut large = Self {
            table,
            columns,
            rows,
            groups,
            group_count,
            boundaries: [0; MAX_BOUNDARIES],
            sums: [[0; 3]; MAX_BOUNDARIES],
            boundary_count: 0,
            first_mass: 0.0,
            last_mass: 0.0,
        };
        let (first, last) = (columns.first, columns.last);
        large.first_mass = large.mass(large.column_sums(first)) * columns.first_weight;
        if last > first {
            large.last_mass = large.mass(large.column_sums(last)) * columns.last_weight;
        }
        if last > first + 1 {
            let mut at = first + 1;
            large.push_boundary(at, [0; 3]);
            while at < last {
                let next = ((at / BLOCK + 1) * BLOCK).min(last);
                let mut sums = large.sums[large.boundary_count - 1];
                for (sum, &(j0, j1, _)) in sums.iter_mut().zip(&large.groups[..group_count]) {
                    *sum += table.rect((at, next), (j0, j1));
                }
                large.push_boundary(next, sums);
                at = next;
            }
        }
        Some(large)
    }

    fn push_boundary(&mut self, column: usize, sums: [u64; 3]) {
        self.boundaries[self.boundary_count] = column;
        self.sums[self.boundary_count] = sums;
        self.boundary_count += 1;
    }

    /// Column `i`'s integer sums over the row groups.
    fn column_sums(&self, i: usize) -> [u64; 3] {
        let mut sums = [0; 3];
        for (sum, &(j0, j1, _)) in sums.iter_mut().zip(&self.groups[..self.group_count]) {
            *sum = self.table.rect((i, i + 1), (j0, j1));
        }
        sums
    }

    /// Columns [c₀, c₁)'s integer sums over the row groups (at most [`BLOCK`] columns), the
    /// texels read a row at a time: the same integers as [`Self::column_sums`].
    fn block_column_sums(&self, c0: usize, c1: usize) -> [[u64; 3]; BLOCK] {
        debug_assert!(c1 - c0 <= BLOCK);
        let mut sums = [[0; 3]; BLOCK];
        for (g, &(j0, j1, _)) in self.groups[..self.group_count].iter().enumerate() {
            for j in j0..j1 {
                for (column, i) in sums.iter_mut().zip(c0..c1) {
                    column[g] += self.table.cell(i, j);
                }
            }
        }
        sums
    }

    /// The mass of columns whose integer sums over the row groups are `sums`: the expression
    /// `place_by`'s strip evaluates.
    fn mass(&self, sums: [u64; 3]) -> f64 {
        self.groups[..self.group_count]
            .iter()
            .zip(sums)
            .map(|(&(_, _, w), sum)| sum as f64 * w)
            .sum::<f64>()
    }

    /// `invert`'s before(k) from the interior columns' sums over [first + 1, k).
    fn before(&self, k: usize, interior: [u64; 3]) -> f64 {
        let (first, last) = (self.columns.first, self.columns.last);
        if k == first {
            return 0.0;
        }
        let interior = if last > first + 1 {
            self.mass(interior)
        } else {
            0.0
        };
        self.first_mass + interior + if k > last { self.last_mass } else { 0.0 }
    }

    /// The largest column k in [first, last] whose before(k) satisfies `holds` (true up to
    /// some k, false after), found at the block boundaries and then within one block, with
    /// before(k) and before(k + 1).
    fn last_column_where(&self, holds: impl Fn(f64) -> bool) -> (usize, f64, f64) {
        let (first, last) = (self.columns.first, self.columns.last);
        let no_interior = |k: usize| self.before(k, [0; 3]);
        if self.boundary_count == 0 {
            // One or two columns: before(first) = 0 holds (the caller checked).
            return if last > first && holds(no_interior(last)) {
                (last, no_interior(last), no_interior(last + 1))
            } else {
                (first, 0.0, no_interior(first + 1))
            };
        }
        // The boundaries b₀ = first + 1, …, b_M = last: the last one where it holds.
        let at = |m: usize| self.before(self.boundaries[m], self.sums[m]);
        let (mut lo, mut hi) = (0, self.boundary_count);
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            if holds(at(mid)) {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        let Some(m) = lo.checked_sub(1) else {
            return (first, 0.0, at(0));
        };
        if m + 1 == self.boundary_count {
            return (last, at(m), self.before(last + 1, self.sums[m]));
        }
        // Within the block [bₘ, bₘ₊₁): column by column, the block's columns read together.
        let mut sums = self.sums[m];
        let (mut k, mut before) = (self.boundaries[m], at(m));
        let columns = self.block_column_sums(k, self.boundaries[m + 1] - 1);
        while k + 1 < self.boundaries[m + 1] {
            for (sum, add) in sums.iter_mut().zip(columns[k - self.boundaries[m]]) {
                *sum += add;
            }
            let next = self.before(k + 1, sums);
            if !holds(next) {
                return (k, before, next);
            }
            (k, before) = (k + 1, next);
        }
        (k, before, at(m + 1))
    }

    /// The column `invert` gives `u` over the box's columns, and the fraction within it.
    pub(super) fn column(&self, u: f64) -> (usize, f64) {
        let first = self.columns.first;
        let interior = self.sums[..self.boundary_count].last().copied();
        let total = self.before(self.columns.last + 1, interior.unwrap_or([0; 3]));
        let target = u * total;
        if !(target < total) {
            if !(0.0 < total) {
                return (first, 1.0);
            }
            return (self.last_column_where(|before| before < total).0, 1.0);
        }
        let (lo, below, above) = self.last_column_where(|before| before <= target);
        (lo, ((target - below) / (above - below)).clamp(0.0, 1.0))
    }

    /// The row `invert` gives `u` within column `i` over the box's rows, and the fraction
    /// within it: the column's total, then its rows from the first until before(k) passes the
    /// target, each the same integer sum `invert`'s masses take (no table to clear).
    pub(super) fn row(&self, i: usize, u: f64) -> (usize, f64) {
        let (first, last) = (self.rows.first, self.rows.last);
        let q = |j: usize| self.table.cell(i, j);
        let first_mass = q(first) as f64 * self.rows.first_weight;
        let last_mass = if last > first {
            q(last) as f64 * self.rows.last_weight
        } else {
            0.0
        };
        // `invert`'s before(k), from the interior rows' sum over [first + 1, min(k, last)).
        let before = |k: usize, interior: u64| {
            if k == first {
                return 0.0;
            }
            let interior = if last > first + 1 {
                interior as f64
            } else {
                0.0
            };
            first_mass + interior + if k > last { last_mass } else { 0.0 }
        };
        let interior: u64 = (first + 1..last).map(q).sum();
        let total = before(last + 1, interior);
        let target = u * total;
        // The largest k in [first, last] where `holds(before(k))`, with before(k) and
        // before(k + 1): before(first) = 0 holds.
        let last_row_where = |holds: &dyn Fn(f64) -> bool| {
            let (mut k, mut below, mut sum) = (first, 0.0, 0u64);
            while k < last {
                if k > first {
                    sum += q(k);
                }
                let next = before(k + 1, sum);
                if !holds(next) {
                    return (k, below, next);
                }
                (k, below) = (k + 1, next);
            }
            (last, below, total)
        };
        if !(target < total) {
            if !(0.0 < total) {
                return (first, 1.0);
            }
            return (last_row_where(&|before| before < total).0, 1.0);
        }
        let (lo, below, above) = last_row_where(&|before| before <= target);
        (lo, ((target - below) / (above - below)).clamp(0.0, 1.0))
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec2;

    use super::super::tables::{Layout, PrefixTable};
    use super::super::{DensityMap, MapFilter};
    use crate::tea::{TeaRng, unit_pair};

    /// Boxes from 65 texels a side up (unaligned, cut by the map's edges, over columns and
    /// rows of zeros, a single column or row of mass) place every particle where the tables'
    /// own searches place it, bit for bit, for uniforms spread over [0, 1) and at its ends.
    #[test]
    fn large_boxes_place_particles_where_the_tables_searches_do() {
        for (width, height, seed) in [(300, 257, 1), (520, 140, 2), (96, 700, 3)] {
            let mut rng = TeaRng::new([seed, 4, 4, 4], 0, 8);
            let values: Vec<f64> = (0..width * height)
                .map(|k| {
                    let (i, j) = (k % width, k / width);
                    let [a, b] = unit_pair(rng.next_bits());
                    if i % 37 < 9 || j % 53 < 5 {
                        0.0
                    } else if a < 0.3 {
                        1.0
                    } else {
                        b
                    }
                })
                .collect();
            let map = DensityMap::with_layout(
                width,
                height,
                &values,
                MapFilter::Nearest,
                Some(Layout::Blocked),
            )
            .unwrap();
            let PrefixTable::Blocked(table) = &map.tables.sums else {
                panic!("a blocked map");
            };
            let mut uniforms: Vec<[f64; 2]> = (0..64).map(|_| unit_pair(rng.next_bits())).collect();
            uniforms.extend([[0.0, 0.0], [0.0, 0.999_999_999_999], [1.0 - 1e-16, 0.5]]);
            for k in 0..300 {
                let [u, v] = unit_pair(rng.next_bits());
                let [s, _] = unit_pair(rng.next_bits());
                let smallest = 65.0 / width.min(height) as f64;
                let size = (smallest + s * (1.0 - smallest)).min(1.0);
                let min = DVec2::new(u * (1.0 - size), v * (1.0 - size));
                let mut large = vec![DVec2::ZERO; uniforms.len()];
                let mut searched = large.clone();
                map.place_each(min, size, &uniforms, &mut large);
                let spans = (
                    &super::TexelSpan::new(min.x, min.x + size, width),
                    &super::TexelSpan::new(min.y, min.y + size, height),
                );
                map.place_by_table(table, spans, min, size, &uniforms, &mut searched);
                assert_eq!(large, searched, "{width} x {height}, box {k}: {min} {size}");
            }
        }
    }
}
