//! The bilinear reconstruction of a density map ([`MapFilter::Bilinear`]).
//!
//! Texel (i, j) holds the value at its centre ((i + ½)/W, (j + ½)/H), and d interpolates the
//! four centres around a point bilinearly, wrapping across the square's edges as the map
//! tiles. Equivalently d is a sum of tents, each texel's value times T(xW − i − ½)·T(yH − j − ½)
//! with T(t) = max(0, 1 − |t|), which is how everything here is exact:
//!
//! - **Masses.** The tents are separable, so ∫ d over a box [x₀, x₁] × [y₀, y₁] is
//!   Σ_ij q_ij·a_i·b_j, a_i the integral of column i's tent over [x₀, x₁] in texel units (its
//!   cumulative is the piecewise quadratic [`tent_cumulative`]). a_i is 1 for every column whose
//!   tent lies inside the box, so the sum is the summed-area table's integer sums over a
//!   rectangle of whole tents and at most two partly covered columns (rows) at each end, each
//!   weighted once ([`TentSpan`]).
//! - **Constancy.** A bilinear patch is constant on an open set only if its four corners are
//!   equal, so d is constant over a box exactly when every texel whose tent meets the box has
//!   one value.
//! - **Placement.** Along x the box's marginal is the tent interpolation of the columns'
//!   weighted sums c_i: linear between column centres, so its cumulative is quadratic there. A
//!   binary search on the cumulative at the centres (exact integer sums of c from the box's
//!   first texel, and half of the centre's own) finds the segment, and the quadratic's root
//!   the position. Given x, the density along y interpolates the two columns around x
//!   linearly, and the same inversion places y. Every sum lies within the texels whose tents
//!   meet the box, one more before and two after, so a small box's are read once.
//! - **Footprints.** ∫_A d over a parallelogram clips it to each cell between four texel
//!   centres (where d is one bilinear patch) and integrates the patch over the clipped polygon
//!   from its moments ([`super::polygon`]).

use glam::DVec2;

use super::polygon::{clip, columns_met, polygon_moments, whole_columns, within};
use super::tables::PrefixTable;
use super::{DensityMap, FIXED_ONE, MAX_INTEGRATED_TEXELS, WholeRuns};
use crate::footprint::Footprint;

/// ∫ T(s) ds from −∞ to t for the tent T(s) = max(0, 1 − |s|).
pub(super) fn tent_cumulative(t: f64) -> f64 {
    if t <= -1.0 {
        0.0
    } else if t <= 0.0 {
        0.5 * (t + 1.0) * (t + 1.0)
    } else if t < 1.0 {
        1.0 - 0.5 * (1.0 - t) * (1.0 - t)
    } else {
        1.0
    }
}

/// The texels along one axis of `n` whose tents meet [lo, hi] (within [0, 1]), as groups of
/// consecutive texels [a, b) (a ≥ −1, b ≤ n + 1: indices outside [0, n) wrap) with the integral
/// of each texel's tent over the interval in texel units: each partly covered texel alone, the
/// whole tents as one group of weight 1.
#[derive(Clone, Copy, Debug)]
pub(super) struct TentSpan {
    groups: [(i64, i64, f64); Self::MAX_GROUPS],
    len: usize,
    /// The first and last texel whose tent meets the interval.
    pub(super) first: i64,
    pub(super) last: i64,
}

impl TentSpan {
    /// Room for a span's groups (at most five: up to two partly covered texels at each end
    /// and the whole ones between, or the up to four partly covered ones of an interval under
    /// three texels wide).
    pub(super) const MAX_GROUPS: usize = 6;

    pub(super) fn new(lo: f64, hi: f64, n: usize) -> Self {
        let (a, b) = (lo * n as f64, hi * n as f64);
        // Texel i's tent covers (i − ½, i + 3/2) in texel coordinates. (⌊a − ½⌋, not
        // ⌊a − 3/2⌋ + 1: the same in exact arithmetic, but a − 3/2 rounds for a just under ½,
        // where the inversion's segment then starts at ⌊a − ½⌋, a texel before the span.)
        let first = (a - 0.5).floor() as i64;
        let last = ((b + 0.5).ceil() as i64 - 1).max(first);
        let whole = ((a + 0.5).ceil() as i64, (b - 1.5).floor() as i64);
        let weight = |i: i64| {
            let centre = i as f64 + 0.5;
            tent_cumulative(b - centre) - tent_cumulative(a - centre)
        };
        let mut span = Self {
            groups: [(0, 0, 0.0); Self::MAX_GROUPS],
            len: 0,
            first,
            last,
        };
        let mut push = |group: (i64, i64, f64)| {
            span.groups[span.len] = group;
            span.len += 1;
        };
        if whole.0 <= whole.1 {
            for i in first..whole.0 {
                push((i, i + 1, weight(i)));
            }
            push((whole.0, whole.1 + 1, 1.0));
            for i in whole.1 + 1..=last {
                push((i, i + 1, weight(i)));
            }
        } else {
            // No whole tent: the interval is under three texels wide, and meets at most four.
            for i in first..=last {
                push((i, i + 1, weight(i)));
            }
        }
        span
    }

    pub(super) fn groups(&self) -> &[(i64, i64, f64)] {
        &self.groups[..self.len]
    }
}

impl DensityMap {
    /// Σ q over texel columns [i0, i1) × rows [j0, j1), any integers (the map repeats over
    /// the plane): one rectangle per piece within one repeat.
    fn wrapped_sum(&self, (i0, i1): (i64, i64), (j0, j1): (i64, i64)) -> u64 {
        if i0 >= i1 || j0 >= j1 {
            return 0;
        }
        let (w, h) = (self.width as i64, self.height as i64);
        if 0 <= i0 && i1 <= w && 0 <= j0 && j1 <= h {
            return self.rect_sum((i0 as usize, i1 as usize), (j0 as usize, j1 as usize));
        }
        let mut sum = 0;
        for rows in runs_within_repeats(j0..j1, self.height) {
            for columns in runs_within_repeats(i0..i1, self.width) {
                sum += self.rect_sum(columns, rows);
            }
        }
        sum
    }

    /// ∫ d over the rectangle [min, min + size] in fixed-point texel units, bilinear.
    pub(super) fn bilinear_rect_mass(&self, min: DVec2, size: DVec2) -> f64 {
        let columns = TentSpan::new(min.x, min.x + size.x, self.width);
        let rows = TentSpan::new(min.y, min.y + size.y, self.height);
        let within = |span: &TentSpan, n: usize| span.first >= 0 && span.last < n as i64;
        if let PrefixTable::Blocked(table) = &self.tables.sums
            && within(&columns, self.width)
            && within(&rows, self.height)
        {
            // The same integers, the groups along the box's edges scanned once each.
            let unsigned = |span: &TentSpan| {
                let mut groups = [(0, 0); TentSpan::MAX_GROUPS];
                for (group, &(a, b, _)) in groups.iter_mut().zip(span.groups()) {
                    *group = (a as usize, b as usize);
                }
                groups
            };
            let (c, r) = (unsigned(&columns), unsigned(&rows));
            let sums: [[u64; TentSpan::MAX_GROUPS]; TentSpan::MAX_GROUPS] =
                table.group_sums(&c[..columns.len], &r[..rows.len]);
            return weighted_sum(&columns, &rows, |c, r| sums[r][c]);
        }
        let wrapped = |c: usize, r: usize| {
            let ((i0, i1, _), (j0, j1, _)) = (columns.groups()[c], rows.groups()[r]);
            self.wrapped_sum((i0, i1), (j0, j1))
        };
        weighted_sum(&columns, &rows, wrapped)
    }

    /// Whether the bilinear d is constant over the box [min, min + size]²: every texel whose
    /// tent meets it has one value.
    pub(super) fn bilinear_is_constant_over(&self, min: DVec2, size: f64) -> bool {
        let columns = TentSpan::new(min.x, min.x + size, self.width);
        let rows = TentSpan::new(min.y, min.y + size, self.height);
        // The spans as at most three pieces within the map each (they reach one or two texels
        // past the square's edges, which wrap).
        let pieces = |first: i64, last: i64, n: usize| {
            let n = n as i64;
            [
                (first, last.min(-1)),
                (first.max(0), last.min(n - 1)),
                (first.max(n), last),
            ]
            .into_iter()
            .filter(|(lo, hi)| lo <= hi)
            .map(move |(lo, hi)| {
                let shift = lo.div_euclid(n) * n;
                ((lo - shift) as usize, (hi - shift) as usize)
            })
        };
        let first = self.fixed(
            columns.first.rem_euclid(self.width as i64) as usize,
            rows.first.rem_euclid(self.height as i64) as usize,
        );
        pieces(rows.first, rows.last, self.height).all(|(j0, j1)| {
            pieces(columns.first, columns.last, self.width).all(|(i0, i1)| {
                self.texels_constant((i0, i1), (j0, j1)) && self.fixed(i0, j0) == first
            })
        })
    }

    /// d at `x` (wrapped into the square), bilinear, in fixed-point units.
    pub(super) fn bilinear_fixed_at(&self, x: DVec2) -> f64 {
        let x = x - x.floor();
        let (s, t) = (
            x.x * self.width as f64 - 0.5,
            x.y * self.height as f64 - 0.5,
        );
        let (i, j) = (s.floor(), t.floor());
        let (fs, ft) = (s - i, t - j);
        let q = |di: i64, dj: i64| {
            self.fixed(
                (i as i64 + di).rem_euclid(self.width as i64) as usize,
                (j as i64 + dj).rem_euclid(self.height as i64) as usize,
            ) as f64
        };
        (1.0 - ft) * ((1.0 - fs) * q(0, 0) + fs * q(1, 0))
            + ft * ((1.0 - fs) * q(0, 1) + fs * q(1, 1))
    }

    /// The positions in the box [min, min + size]² of the particles with uniform numbers
    /// `uniforms`, bilinear (see the module docs): x by the box's marginal, then y given x.
    /// The sums they read lie within the texels whose tents meet the box, one more before and
    /// two more after. Where the tents span at most 61 texels a side (a leaf's box under a
    /// texel wide, as most are) those texels, at most 64 a side, are read once into a table
    /// of the box's own and the columns' marginal is cumulated once; a larger box's
    /// inversions read the map's tables.
    /// Either way by the box's size alone, so any two tables of the same texels (whole,
    /// tiled, blocked) place the same positions.
    pub(super) fn bilinear_place_each(
        &self,
        min: DVec2,
        size: f64,
        uniforms: &[[f64; 2]],
        positions: &mut [DVec2],
    ) {
        let columns = TentSpan::new(min.x, min.x + size, self.width);
        let rows = TentSpan::new(min.y, min.y + size, self.height);
        let spans = (&columns, &rows);
        let side = (columns.last - columns.first).max(rows.last - rows.first) + 4;
        let place = match side {
            ..=16 => Self::place_in_tent_box::<272>,
            17..=32 => Self::place_in_tent_box::<1056>,
            33..=64 => Self::place_in_tent_box::<4160>,
            _ => {
                let sum = |c, r| self.wrapped_sum(c, r);
                // Σ over columns [first, c) of the columns' tent-weighted sums over the rows.
                let columns_prefix = |c: i64| {
                    rows.groups()
                        .iter()
                        .map(|&(j0, j1, w)| sum((columns.first, c), (j0, j1)) as f64 * w)
                        .sum::<f64>()
                };
                let column = |k: i64, r: i64| sum((k, k + 1), (rows.first, r));
                let place = (min, size, uniforms);
                return self.place_by_tents(spans, place, positions, columns_prefix, column);
            }
        };
        place(self, spans, min, size, uniforms, positions);
    }

    /// [`Self::bilinear_place_each`] for a box whose texels and one more on each side span
    /// at most 64 a side: each of those columns' sums over rows from the first, in a table of
    /// `N` ≥ 64 × 65 entries read once, and the columns' tent-weighted sums over the box's
    /// rows cumulated from its first column.
    fn place_in_tent_box<const N: usize>(
        &self,
        (columns, rows): (&TentSpan, &TentSpan),
        min: DVec2,
        size: f64,
        uniforms: &[[f64; 2]],
        positions: &mut [DVec2],
    ) {
        // sums[x·(h + 1) + y]: Σ q over column c0 + x, rows [r0, r0 + y).
        let mut sums = [0u64; N];
        let (c0, r0) = (columns.first - 1, rows.first - 1);
        let (w, h) = (columns.last + 3 - c0, rows.last + 3 - r0);
        let stride = h as usize + 1;
        for y in 0..h {
            let j = (r0 + y).rem_euclid(self.height as i64) as usize;
            for x in 0..w {
                let q = self.fixed((c0 + x).rem_euclid(self.width as i64) as usize, j);
                let at = x as usize * stride + y as usize;
                sums[at + 1] = sums[at] + q;
            }
        }
        // Indices outside the table do not occur (the module docs); clamped (a negative one
        // wraps to a large one), they cannot panic.
        let (w, h) = (w as usize - 1, h as usize);
        let at =
            |i: i64, j: i64| sums[((i - c0) as usize).min(w) * stride + ((j - r0) as usize).min(h)];
        // prefix[c − first]: Σ over columns [first, c) of their weighted sums, c ≤ last + 2.
        let mut prefix = [0.0; 64];
        let mut running = 0.0;
        for c in columns.first..=columns.last + 1 {
            running += rows
                .groups()
                .iter()
                .map(|&(j0, j1, w)| (at(c, j1) - at(c, j0)) as f64 * w)
                .sum::<f64>();
            prefix[(c + 1 - columns.first) as usize] = running;
        }
        let last = (columns.last + 2 - columns.first) as usize;
        let columns_prefix = |c: i64| prefix[((c - columns.first).max(0) as usize).min(last)];
        let column = |k: i64, r: i64| at(k, r) - at(k, rows.first);
        let place = (min, size, uniforms);
        self.place_by_tents((columns, rows), place, positions, columns_prefix, column);
    }

    /// [`Self::bilinear_place_each`] with the columns' cumulative marginal from
    /// `columns_prefix` (from the box's first column) and `column(k, r)`, Σ q over column k
    /// (any integer, the map repeating) and rows [first, r) of the box's.
    fn place_by_tents(
        &self,
        (columns, rows): (&TentSpan, &TentSpan),
        (min, size, uniforms): (DVec2, f64, &[[f64; 2]]),
        positions: &mut [DVec2],
        columns_prefix: impl Fn(i64) -> f64,
        column: impl Fn(i64, i64) -> u64,
    ) {
        for (u, position) in uniforms.iter().zip(positions) {
            let x = invert_tents(
                columns,
                (min.x, min.x + size),
                self.width,
                &columns_prefix,
                u[0],
            );
            // Along y at x: the two columns around x, interpolated.
            let s = x * self.width as f64 - 0.5;
            let (k, t) = (s.floor() as i64, s - s.floor());
            let rows_prefix =
                |r: i64| (1.0 - t) * column(k, r) as f64 + t * column(k + 1, r) as f64;
            let y_range = (min.y, min.y + size);
            // The inversion reads the prefix at rows first ..= last + 2, several times each:
            // over a short span they are made once.
            let span = (rows.last + 2 - rows.first) as usize;
            let y = if span < 64 {
                let mut made = [0.0; 64];
                for (r, prefix) in (rows.first..).zip(&mut made[..=span]) {
                    *prefix = rows_prefix(r);
                }
                let prefix = |r: i64| made[((r - rows.first).max(0) as usize).min(span)];
                invert_tents(rows, y_range, self.height, prefix, u[1])
            } else {
                invert_tents(rows, y_range, self.height, rows_prefix, u[1])
            };
            *position = DVec2::new(x, y);
        }
    }

    /// ∫_A d over the footprint's parallelogram, bilinear, each integer translate counted:
    /// over the cells between four texel centres its bounding box meets, up to
    /// [`MAX_INTEGRATED_TEXELS`] of them, else its area times the map's mean. A cell wholly
    /// inside adds the mean of its four corners' values (the patch's integral over the cell),
    /// summed per row from the summed-area table; only the cells the parallelogram's edges cut
    /// are clipped.
    pub(super) fn bilinear_mass_in(&self, footprint: &Footprint) -> f64 {
        let (min, max) = footprint.bounds();
        let scale = DVec2::new(self.width as f64, self.height as f64);
        // Cells [k + ½, k + 3/2) in texel coordinates, k from ⌊x·n − ½⌋.
        let (lo, hi) = (
            (min * scale - 0.5).floor(),
            (max * scale - 0.5).floor() + 1.0,
        );
        if !((hi.x - lo.x) * (hi.y - lo.y) <= MAX_INTEGRATED_TEXELS) {
            return footprint.area() * self.mean();
        }
        let corners = footprint.corners().map(|c| c * scale);
        // The corners with the cells' origin at 0: cell k spans [k, k + 1].
        let from_cells = corners.map(|c| c - 0.5);
        // The whole cells' sums: rows `row` and `row + 1` of columns `inside` and `inside + 1`,
        // each of the four runs added to its own sum so consecutive rows' runs stay together
        // (a blocked level reads eight rows' common run at once).
        let mut whole = [(); 4].map(|()| WholeRuns::new(self));
        let (mut mass, mut error) = (0.0, 0.0);
        for row in lo.y as i64..hi.y as i64 {
            let (y0, y1) = (row as f64 + 0.5, row as f64 + 1.5);
            let strip = clip(&corners, |p| p.y - y0, |p| y1 - p.y);
            if strip.len() < 3 {
                continue;
            }
            let met = columns_met(&strip, 1.0, 0.5);
            let inside = within(
                whole_columns(&from_cells, row as f64, (row + 1) as f64),
                &met,
            );
            if !inside.is_empty() {
                let [lower, upper] =
                    [row, row + 1].map(|r| r.rem_euclid(self.height as i64) as usize);
                let shifted = inside.start + 1..inside.end + 1;
                whole[0].add(lower, inside.clone());
                whole[1].add(lower, shifted.clone());
                whole[2].add(upper, inside.clone());
                whole[3].add(upper, shifted);
            }
            let edges = (met.start..inside.start).chain(inside.end..met.end);
            mass += edges
                .map(|column| {
                    let (value, bound) = self.cell_mass_in(&strip, column, row);
                    error += bound;
                    value
                })
                .sum::<f64>();
        }
        let whole = whole.into_iter().map(WholeRuns::sum).sum::<u64>() as f64 / 4.0;
        // The cut cells' moments about their corners cancel where a piece is small against
        // the cell (each edge's term is of the order of the cell, their sum of the piece's
        // area). Their sum is kept where its error bound is within 2⁻³⁰ of the mass; else
        // (footprints under a few hundredths of a texel, or near zeros of d) the cut cells
        // are integrated again about a point of each piece ([`Self::cell_mass_about_piece`],
        // accurate and never negative), and the first sum is still kept if it is within 2⁻³⁰
        // of that: bit for bit what it was wherever it was right, and then ≥ 0 too.
        let cut = if error <= MOMENTS_ACCEPTED * (mass + whole) {
            mass
        } else {
            let mut precise = 0.0;
            for row in lo.y as i64..hi.y as i64 {
                let (y0, y1) = (row as f64 + 0.5, row as f64 + 1.5);
                let strip = clip(&corners, |p| p.y - y0, |p| y1 - p.y);
                if strip.len() < 3 {
                    continue;
                }
                let met = columns_met(&strip, 1.0, 0.5);
                let inside = within(
                    whole_columns(&from_cells, row as f64, (row + 1) as f64),
                    &met,
                );
                let edges = (met.start..inside.start).chain(inside.end..met.end);
                precise += edges
                    .map(|column| self.cell_mass_about_piece(&strip, column, row))
                    .sum::<f64>();
            }
            if (mass - precise).abs() <= MOMENTS_ACCEPTED * (precise + whole) {
                mass
            } else {
                precise
            }
        };
        (cut + whole) / (FIXED_ONE * scale.x * scale.y)
    }
}

/// The largest error of the cut cells' moments about their corners, relative to the mass, at
/// which [`DensityMap::bilinear_mass_in`] keeps their sum (bounded, or measured against the
/// integral about each piece).
const MOMENTS_ACCEPTED: f64 = 1.0 / (1u64 << 30) as f64;

impl DensityMap {
    /// The four corners' values of cell (`column`, `row`), q00, q10, q01, q11 (texels
    /// `column`, `column + 1` × rows `row`, `row + 1`, wrapped), in fixed point.
    fn cell_corners(&self, column: i64, row: i64) -> [f64; 4] {
        let q = |di: i64, dj: i64| {
            self.fixed(
                (column + di).rem_euclid(self.width as i64) as usize,
                (row + dj).rem_euclid(self.height as i64) as usize,
            ) as f64
        };
        [q(0, 0), q(1, 0), q(0, 1), q(1, 1)]
    }

    /// ∫ of the bilinear patch of cell (`column`, `row`) (between the centres of texels
    /// `column`, `column + 1` and rows `row`, `row + 1`) over the convex polygon `strip` (in
    /// texel units, within the cell's row), in fixed point times texels², from the piece's
    /// moments about the cell's corner; and a bound on that value's rounding error.
    ///
    /// The piece's points lie in the cell, s, t ∈ [0, 1] up to rounding, so each edge's term
    /// of ∫1, ∫s, ∫t, ∫st ([`polygon_moments`], after its divisions) is at most 1 in size and
    /// is rounded a few times; its sum of n terms adds n roundings of partial sums at most n:
    /// each moment is within about (n + 8)·n·ε ≤ 4n²ε of its value (n ≥ 3), and weighing
    /// them by the patch's coefficients adds ε of each product. The bound, 8n²ε times the
    /// coefficients' sizes, covers both. It is of the cell's order while the value is of the
    /// piece's area: for a piece of side h the relative error reaches ε/h², hence the
    /// negative masses of tiny footprints near a zero of d (−8·10⁻²⁰ for the 10⁻⁹ square on
    /// the zero of the map [[1, 0]], whose mass is 5·10⁻²⁸).
    fn cell_mass_in(&self, strip: &[DVec2], column: i64, row: i64) -> (f64, f64) {
        let (x0, x1) = (column as f64 + 0.5, column as f64 + 1.5);
        let mut piece = clip(strip, |p| p.x - x0, |p| x1 - p.x);
        if piece.len() < 3 {
            return (0.0, 0.0);
        }
        let [q00, q10, q01, q11] = self.cell_corners(column, row);
        if q00 == 0.0 && q10 == 0.0 && q01 == 0.0 && q11 == 0.0 {
            return (0.0, 0.0);
        }
        // The patch in the cell's own coordinates s = x − x0, t = y − y0:
        // q00 + (q10 − q00)s + (q01 − q00)t + (q00 − q10 − q01 + q11)st.
        let y0 = row as f64 + 0.5;
        for point in piece.iter_mut() {
            *point -= DVec2::new(x0, y0);
        }
        let [area, sx, sy, sxy] = polygon_moments(&piece);
        let coefficients = [q00, q10 - q00, q01 - q00, q00 - q10 - q01 + q11];
        let value = coefficients[0] * area
            + coefficients[1] * sx
            + coefficients[2] * sy
            + coefficients[3] * sxy;
        let n = piece.len() as f64;
        let size: f64 = coefficients.iter().map(|c| c.abs()).sum();
        (value, 8.0 * n * n * f64::EPSILON * size)
    }

    /// [`Self::cell_mass_in`]'s integral, accurate for a piece of any size: about a point r
    /// of the piece (its vertices' mean, kept in the cell) the patch is
    /// d(r + u) = d(r) + g·u + k·u_s·u_t, so its integral is d(r)·A + g·(∫u) + k·∫u_s·u_t,
    /// the moments of the piece's points less r. Those differences are exact (Sterbenz: r
    /// lies among the points), or within ε of the piece's size where it straddles 0, so the
    /// moments' terms are of the piece's own size; d(r) and g come from r's distances to the
    /// cell's four sides (again exact where small), so the result is within a few ε of the
    /// terms d(r)·A and |g|·h·A (h the piece's size), whatever its size or place. (The
    /// vertices where the clips cut are themselves rounded by ε of their texel coordinates:
    /// that moves the footprint by as much, as any float footprint is, and is not
    /// cancellation.) d ≥ 0 over the cell (the corners' convex combination), so the integral
    /// is ≥ 0: a value below 0 is rounding, and 0 is nearer to the integral than it, so the
    /// clamp needs no bound.
    fn cell_mass_about_piece(&self, strip: &[DVec2], column: i64, row: i64) -> f64 {
        let (x0, x1) = (column as f64 + 0.5, column as f64 + 1.5);
        let piece = clip(strip, |p| p.x - x0, |p| x1 - p.x);
        if piece.len() < 3 {
            return 0.0;
        }
        let [q00, q10, q01, q11] = self.cell_corners(column, row);
        if q00 == 0.0 && q10 == 0.0 && q01 == 0.0 && q11 == 0.0 {
            return 0.0;
        }
        let (y0, y1) = (row as f64 + 0.5, row as f64 + 1.5);
        let mean = piece.iter().copied().sum::<DVec2>() / piece.len() as f64;
        let r = mean.clamp(DVec2::new(x0, y0), DVec2::new(x1, y1));
        let mut about = piece;
        for point in about.iter_mut() {
            *point -= r;
        }
        let [area, mu_s, mu_t, mu_st] = polygon_moments(&about);
        // The bilinear weights of r: its distances to the cell's far and near sides.
        let (s0, s1) = ((x1 - r.x).max(0.0), (r.x - x0).max(0.0));
        let (t0, t1) = ((y1 - r.y).max(0.0), (r.y - y0).max(0.0));
        let at_r = t0 * (s0 * q00 + s1 * q10) + t1 * (s0 * q01 + s1 * q11);
        let slope_s = t0 * (q10 - q00) + t1 * (q11 - q01);
        let slope_t = s0 * (q01 - q00) + s1 * (q11 - q10);
        let twist = q00 - q10 - q01 + q11;
        (at_r * area + slope_s * mu_s + slope_t * mu_t + twist * mu_st).max(0.0)
    }
}

/// The integers `range` as runs of indices within one repeat of a period `n` (the map's
/// width or height), in order: [a, b) with a < b ≤ n, each wrapped into [0, n).
fn runs_within_repeats(
    range: std::ops::Range<i64>,
    n: usize,
) -> impl Iterator<Item = (usize, usize)> {
    let n = n as i64;
    let mut start = range.start;
    std::iter::from_fn(move || {
        (start < range.end).then(|| {
            let i = start.rem_euclid(n);
            let run = (n - i).min(range.end - start);
            start += run;
            (i as usize, (i + run) as usize)
        })
    })
}

/// Σ over the pairs of the spans' groups of the integer `sum(c, r)` (column group c, row
/// group r) times the groups' weights, rows outer and columns inner: the order every bilinear
/// mass adds them in, so its float sum is the same whichever table gives the integers.
fn weighted_sum(columns: &TentSpan, rows: &TentSpan, sum: impl Fn(usize, usize) -> u64) -> f64 {
    let mut mass = 0.0;
    for (r, &(_, _, row_weight)) in rows.groups().iter().enumerate() {
        for (c, &(_, _, column_weight)) in columns.groups().iter().enumerate() {
            mass += sum(c, r) as f64 * (column_weight * row_weight);
        }
    }
    mass
}

/// The position in [lo, hi] (within [0, 1]) where the cumulative of a tent-interpolated
/// sequence over `n` texels passes the fraction `u` of its integral over [lo, hi];
/// `prefix(c)` is the sequence summed over texels [first, c) (the first texel whose tent
/// meets the interval; c from there to the last one's index + 2, the sequence repeating with
/// period n), non-decreasing; `span` is `TentSpan::new(lo, hi, n)`. See the module docs.
fn invert_tents(
    span: &TentSpan,
    (lo, hi): (f64, f64),
    n: usize,
    prefix: impl Fn(i64) -> f64,
    u: f64,
) -> f64 {
    let (a, b) = (lo * n as f64, hi * n as f64);
    let value = |i: i64| prefix(i + 1) - prefix(i);
    // The low partly covered texels' tents before a: their share left of the interval.
    let before_a: f64 = (span.first..=span.last)
        .take_while(|&i| (i as f64 + 0.5) - 1.0 < a)
        .map(|i| value(i) * tent_cumulative(a - i as f64 - 0.5))
        .sum();
    let start = prefix(span.first);
    // The mass of [a, centre of texel k], for centres within (a, b): the texels before k whole,
    // half of k's own, less the share of the first tents left of a.
    let at_centre = |k: i64| 0.5 * (prefix(k) + prefix(k + 1)) - start - before_a;
    let total: f64 = span
        .groups()
        .iter()
        .map(|&(i0, i1, w)| (prefix(i1) - prefix(i0)) * w)
        .sum();
    let target = u * total;
    if !(target < total) {
        return hi;
    }
    // The texel centres k + ½ strictly inside (a, b); breakpoint m is a for m = 0, the
    // centres for m = 1 ..= centres, b after them.
    let first_centre = (a - 0.5).floor() as i64 + 1;
    let last_centre = ((b - 0.5).ceil() as i64 - 1).max(first_centre - 1);
    let centres = last_centre - first_centre + 1;
    let breakpoint = |m: i64| -> (f64, f64) {
        if m == 0 {
            (a, 0.0)
        } else if m > centres {
            (b, total)
        } else {
            let k = first_centre + m - 1;
            (k as f64 + 0.5, at_centre(k))
        }
    };
    // The last breakpoint at or below the target: cumulative(lo_m) ≤ target < cumulative(hi_m).
    let (mut lo_m, mut hi_m) = (0_i64, centres + 1);
    while hi_m - lo_m > 1 {
        let mid = lo_m + (hi_m - lo_m) / 2;
        if breakpoint(mid).1 <= target {
            lo_m = mid;
        } else {
            hi_m = mid;
        }
    }
    let ((start, below), (end, _)) = (breakpoint(lo_m), breakpoint(lo_m + 1));
    // Within the segment the density is linear between the centres k and k + 1 around it.
    let k = ((start - 0.5).floor() as i64).max(span.first);
    let (c0, c1) = (value(k), value(k + 1));
    let (ts, te) = (start - k as f64 - 0.5, end - k as f64 - 0.5);
    let slope = c1 - c0;
    // Solve c0·(t − ts) + slope·(t² − ts²)/2 = target − below for t in [ts, te].
    let rest = (target - below).max(0.0) + c0 * ts + 0.5 * slope * ts * ts;
    let root = c0 * c0 + 2.0 * slope * rest;
    let t = if rest > 0.0 {
        2.0 * rest / (c0 + root.max(0.0).sqrt())
    } else {
        ts
    };
    let position = (k as f64 + 0.5 + t.clamp(ts, te)) / n as f64;
    position.clamp(lo, hi)
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::tea::{TeaRng, unit_pair};
    use crate::{LevelTexels, MapFilter};

    /// A `width` × `height` bilinear map of a few repeated values, zeros included (so some
    /// regions are constant and some vanish).
    fn patchy(width: usize, height: usize, seed: u32) -> DensityMap {
        let mut rng = TeaRng::new([seed, 3, 2, 1], 0, 8);
        let levels = [0.0, 0.25, 1.0, 0.6];
        let values: Vec<f64> = (0..width * height)
            .map(|k| {
                let block = (k % width) / 3 + (k / width) / 2;
                levels[(block + usize::from(rng.next_bits().is_multiple_of(5))) % 4]
            })
            .collect();
        DensityMap::with_filter(width, height, &values, MapFilter::Bilinear).unwrap()
    }

    /// ∫ d over [x0, x1] × [y0, y1] by a midpoint rule of n × n points on the bilinear d.
    fn midpoint_mass(map: &DensityMap, x: [f64; 2], y: [f64; 2], n: usize) -> f64 {
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                let p = DVec2::new(
                    x[0] + (x[1] - x[0]) * (i as f64 + 0.5) / n as f64,
                    y[0] + (y[1] - y[0]) * (j as f64 + 0.5) / n as f64,
                );
                sum += map.value_at(p);
            }
        }
        sum * (x[1] - x[0]) * (y[1] - y[0]) / (n * n) as f64
    }

    const MAPS: [(usize, usize, u32); 6] = [
        (7, 5, 1),
        (16, 16, 2),
        (1, 9, 3),
        (12, 1, 4),
        (37, 23, 5),
        (97, 71, 6),
    ];

    /// d interpolates the texels: at a texel's centre it is the texel's value, it is
    /// continuous across texel edges and across the square's edges (the map tiles), and
    /// halfway between two centres it is their mean.
    #[test]
    fn d_interpolates_the_texels_and_tiles() {
        for (w, h, seed) in MAPS {
            let map = patchy(w, h, seed);
            for j in 0..h {
                for i in 0..w {
                    let centre =
                        DVec2::new((i as f64 + 0.5) / w as f64, (j as f64 + 0.5) / h as f64);
                    let texel = map.texel(i, h - 1 - j);
                    assert!((map.value_at(centre) - texel).abs() < 1e-12);
                    let right = map.texel((i + 1) % w, h - 1 - j);
                    let halfway = centre + DVec2::new(0.5 / w as f64, 0.0);
                    assert!((map.value_at(halfway) - 0.5 * (texel + right)).abs() < 1e-12);
                }
            }
            for t in [0.013, 0.5, 0.77] {
                for (a, b) in [
                    (DVec2::new(1e-12, t), DVec2::new(1.0 - 1e-12, t)),
                    (DVec2::new(t, 1e-12), DVec2::new(t, 1.0 - 1e-12)),
                ] {
                    assert!(
                        (map.value_at(a) - map.value_at(b)).abs() < 1e-9,
                        "{w}x{h} at {a}"
                    );
                }
            }
        }
    }

    /// Box masses (the quarter probabilities' ratios and zeros), constancy and the bound over
    /// a footprint, against the definitions: a fine midpoint rule, and the texels whose tents
    /// meet the box listed one by one.
    #[test]
    fn masses_constancy_and_bounds_follow_the_definitions() {
        for (w, h, seed) in MAPS {
            let map = patchy(w, h, seed);
            for level in 0..6 {
                let size = 0.5f64.powi(level);
                let boxes = 1usize << level;
                for bx in 0..boxes.min(6) {
                    for by in 0..boxes.min(6) {
                        let min = DVec2::new(bx as f64, by as f64) * size;
                        let mass = map.bilinear_rect_mass(min, DVec2::splat(size))
                            / (FIXED_ONE * (w * h) as f64);
                        let reference =
                            midpoint_mass(&map, [min.x, min.x + size], [min.y, min.y + size], 160);
                        assert!(
                            (mass - reference).abs() < 2e-4 * size * size + 1e-12,
                            "{w}x{h} box {min} {size}: {mass} against {reference}"
                        );
                        // The texels whose tents (centre ± one texel) meet the box.
                        let meets = |centre: f64, lo: f64, texel: f64| {
                            (lo..lo + size).contains(&centre)
                                || (centre - lo).abs().min((centre - lo - size).abs())
                                    < texel - 1e-12
                        };
                        let mut seen = Vec::new();
                        for j in -1..=h as i64 {
                            for i in -1..=w as i64 {
                                let (cx, cy) =
                                    ((i as f64 + 0.5) / w as f64, (j as f64 + 0.5) / h as f64);
                                if meets(cx, min.x, 1.0 / w as f64)
                                    && meets(cy, min.y, 1.0 / h as f64)
                                {
                                    let i = i.rem_euclid(w as i64) as usize;
                                    let j = j.rem_euclid(h as i64) as usize;
                                    seen.push(map.texel(i, h - 1 - j));
                                }
                            }
                        }
                        let constant = seen.iter().all(|&v| v == seen[0]);
                        assert_eq!(
                            map.is_constant_over(min, size),
                            constant,
                            "{w}x{h} {min} {size}"
                        );
                        if let Some(p) = map.quarter_probabilities(min, size) {
                            let half = 0.5 * size;
                            for (q, &pq) in p.iter().enumerate() {
                                let c = min + DVec2::new((q & 1) as f64, (q >> 1) as f64) * half;
                                let quarter = map.bilinear_rect_mass(c, DVec2::splat(half));
                                assert_eq!(pq == 0.0, quarter == 0.0);
                                let reference =
                                    midpoint_mass(&map, [c.x, c.x + half], [c.y, c.y + half], 100);
                                assert!(
                                    (pq * mass - reference).abs() < 1e-4 * size * size,
                                    "{w}x{h} {c}"
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    /// A placed particle is the inverse of the distribution restricted to the box: the mass
    /// left of its x is u₀ of the box's, and along y at its x, the mass below it is u₁ of the
    /// column's (both by midpoint rules on the bilinear d); none lands where d = 0.
    #[test]
    fn placement_inverts_the_distribution() {
        for (w, h, seed) in MAPS {
            let map = patchy(w, h, seed);
            let mut rng = TeaRng::new([seed, 7, 7, 7], 0, 8);
            for k in 0..150 {
                let size = 0.5f64.powi(k % 6);
                let [a, b] = unit_pair(rng.next_bits());
                let min = (DVec2::new(a, b) * (1.0 - size) / size).floor() * size;
                let (x, y) = ([min.x, min.x + size], [min.y, min.y + size]);
                let total = midpoint_mass(&map, x, y, 300);
                if total < 1e-9 * size * size {
                    continue;
                }
                let u = unit_pair(rng.next_bits());
                let p = map.place(min, size, u);
                assert!(
                    map.value_at(p) > 0.0,
                    "{w}x{h}: a particle at {p} where d = 0"
                );
                let left = midpoint_mass(&map, [x[0], p.x], y, 300);
                assert!(
                    (left / total - u[0]).abs() < 2e-3,
                    "{w}x{h} box {min} {size}: x {p}"
                );
                let n = 4000;
                let along = |to: f64| -> f64 {
                    (0..n)
                        .map(|i| {
                            map.value_at(DVec2::new(
                                p.x,
                                y[0] + (to - y[0]) * (i as f64 + 0.5) / n as f64,
                            ))
                        })
                        .sum::<f64>()
                        * (to - y[0])
                        / n as f64
                };
                let column = along(y[1]);
                if column > 1e-9 {
                    assert!(
                        (along(p.y) / column - u[1]).abs() < 2e-3,
                        "{w}x{h} box {min} {size}: y {p}"
                    );
                }
            }
        }
    }

    /// Boxes whose low edge lies a rounding below a texel's centre (a = x·n just under ½,
    /// where a − 3/2 rounds to −1) place inside the box under whole and blocked tables, small
    /// and large boxes alike: the inversion's first segment starts at ⌊a − ½⌋, which the span
    /// includes (it started a texel later, and a large box's sums then read a reversed range
    /// and panicked).
    #[test]
    fn boxes_at_a_rounding_below_a_centre_place_inside() {
        for (width, height) in [(1, 200), (49, 3), (98, 98), (1, 5)] {
            let values: Vec<f64> = (0..width * height)
                .map(|k| [0.2, 1.0, 0.5][k % 3])
                .collect();
            let own = DensityMap::with_filter(width, height, &values, MapFilter::Bilinear).unwrap();
            let family = LevelTexels::new(width, height, 1, |k| (0, [values[k], 0.0])).unwrap();
            let blocked =
                DensityMap::roughness_level(&Arc::new(family), 0, MapFilter::Bilinear).unwrap();
            for lo in [0.499_999_999_999_999_94, 0.499_999_999_999_999_9] {
                let x = lo / width as f64;
                for size in [0.01, 0.5] {
                    let min = DVec2::new(x, lo / height as f64);
                    for u in [[0.0, 0.0], [0.0, 0.5], [0.3, 0.9]] {
                        let p = own.place(min, size, u);
                        assert_eq!(p, blocked.place(min, size, u));
                        let inside = |v: f64, lo: f64| lo <= v && v <= lo + size;
                        assert!(
                            inside(p.x, min.x) && inside(p.y, min.y),
                            "{p} in {min} {size}"
                        );
                    }
                }
            }
        }
    }

    /// The mass row by row (whole cells from the summed-area table, only the cut ones
    /// clipped) is the sum of every cell of the bounding box clipped to the parallelogram:
    /// footprints 0.3 to 60 texels across at every angle, thin ones, wrapped across the
    /// square's edges and over several tiles, and footprints whose corners are texel corners.
    #[test]
    fn whole_cells_add_what_clipping_them_adds() {
        let every_cell_clipped = |map: &DensityMap, footprint: &Footprint| {
            let (min, max) = footprint.bounds();
            let scale = DVec2::new(map.width as f64, map.height as f64);
            let (lo, hi) = (
                (min * scale - 0.5).floor(),
                (max * scale - 0.5).floor() + 1.0,
            );
            let corners = footprint.corners().map(|c| c * scale);
            let mut mass = 0.0;
            for row in lo.y as i64..hi.y as i64 {
                let (y0, y1) = (row as f64 + 0.5, row as f64 + 1.5);
                let strip = clip(&corners, |p| p.y - y0, |p| y1 - p.y);
                for column in lo.x as i64..hi.x as i64 {
                    if strip.len() >= 3 {
                        mass += map.cell_mass_in(&strip, column, row).0;
                    }
                }
            }
            mass / (FIXED_ONE * scale.x * scale.y)
        };
        for (w, h, seed) in [(11, 6, 1), (64, 48, 2), (5, 40, 3)] {
            let map = patchy(w, h, seed);
            for footprint in crate::density_map::footprints_of_every_shape((w, h), seed) {
                let fast = map.mass_in(&footprint);
                let reference = every_cell_clipped(&map, &footprint);
                assert!(
                    (fast - reference).abs() <= 1e-12 * reference.max(footprint.area()),
                    "{w}x{h} {footprint:?}: {fast} against {reference}"
                );
            }
        }
    }

    /// The map [[1, 0]], bilinear: about the zero texel's centre (u = ¾) d is 2|u − ¾|, so a
    /// square of side s there holds s³/2. Its mass was a difference of the cut cells' moments
    /// about their corners, which cancel: −8.3·10⁻²⁰ for s = 10⁻⁹ (the expected count
    /// −8.3·10⁻¹⁴ of issue 64), about −s²/12 from s = 10⁻⁸ down. Now within 10⁻⁹ of s³/2 for
    /// sides 2⁻² to 2⁻⁴⁰ (whose corners are exact), and within the corners' own rounding for
    /// 10⁻⁹.
    #[test]
    fn a_tiny_footprint_on_the_zero_texel_of_a_one_zero_map_has_positive_mass() {
        let map = DensityMap::with_filter(2, 1, &[1.0, 0.0], MapFilter::Bilinear).unwrap();
        let mass = |side: f64| {
            let footprint =
                Footprint::new(DVec2::new(0.75, 0.5), DVec2::X * side, DVec2::Y * side).unwrap();
            map.mass_in(&footprint)
        };
        for k in 2..=40 {
            let side = 0.5f64.powi(k);
            let (got, exact) = (mass(side), 0.5 * side * side * side);
            assert!(
                (got - exact).abs() <= 1e-9 * exact,
                "side 2^-{k}: {got:e} against {exact:e}"
            );
        }
        // 0.75 ± 5·10⁻¹⁰ rounds by up to 2⁻⁵⁴, 10⁻⁷ of the half side: s³/2 within 10⁻⁶.
        let got = mass(1e-9);
        assert!(
            got > 0.0 && (got - 5e-28).abs() <= 1e-6 * 5e-28,
            "side 1e-9: {got:e} against 5e-28"
        );
    }

    /// d at uv + `offset` (uv units) by its definition, Σ q·T·T over the nine texels about the
    /// cell corner K nearest to uv, with each tent's weight from the point's offset from K
    /// (1 − |p|, p or −p): a reference exact to the offsets' own size near any zero of d.
    fn tents_about(map: &DensityMap, uv: DVec2, offset: DVec2) -> f64 {
        let (w, h) = map.size();
        let lattice = uv * DVec2::new(w as f64, h as f64) - 0.5;
        let k = lattice.round();
        let p = (lattice - k) + offset * DVec2::new(w as f64, h as f64);
        let weights = |p: f64| [(-p).max(0.0), (1.0 - p.abs()).max(0.0), p.max(0.0)];
        let (wx, wy) = (weights(p.x), weights(p.y));
        let mut value = 0.0;
        for (b, wy) in wy.iter().enumerate() {
            for (a, wx) in wx.iter().enumerate() {
                let i = (k.x as i64 + a as i64 - 1).rem_euclid(w as i64) as usize;
                let j = (k.y as i64 + b as i64 - 1).rem_euclid(h as i64) as usize;
                value += map.texel(i, h - 1 - j) * wx * wy;
            }
        }
        value
    }

    proptest::proptest! {
        #![proptest_config(proptest::test_runner::Config {
            cases: 600,
            rng_seed: proptest::test_runner::RngSeed::Fixed(0x6269_6c69),
            failure_persistence: None,
            ..proptest::test_runner::Config::default()
        })]

        /// Over random bilinear maps (zeros common), footprints of 10⁻¹² to 10⁻¹ at any angle,
        /// shape and place (on texel centres, where isolated zeros of d are, on the cells'
        /// edges, anywhere, over several tiles): the mass is finite and ≥ 0, and where the
        /// footprint is under 0.05 texel, it is a 160 × 160 midpoint rule of the bilinear
        /// surface ([`tents_about`]) to 10⁻³ (the rule's error at d's kinks is ~1/160²), give
        /// or take what rounding the footprint's corners in texel units (by ε of their size)
        /// moves: 32ε·|x|·perimeter·max d.
        #[test]
        fn bilinear_masses_are_never_negative_and_tiny_ones_are_the_integral(
            (w, h) in (1usize..=8, 1usize..=8),
            values in proptest::collection::vec(
                proptest::prop_oneof![
                    3 => proptest::strategy::Just(0.0),
                    1 => proptest::strategy::Just(1.0),
                    2 => 0.0..=1.0f64,
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
            let map = DensityMap::with_filter(w, h, &values, MapFilter::Bilinear).unwrap();
            let texel = DVec2::new(1.0 / w as f64, 1.0 / h as f64);
            let size = 10f64.powf(exponent);
            let at = DVec2::new(cell.0 as f64, cell.1 as f64);
            let uv = match place {
                0 => (at + 0.5) * texel,
                1 => at * texel,
                _ => at / 8.0 + DVec2::new(0.3, 0.7) * texel,
            } + DVec2::new(nudge.0, nudge.1) * size;
            let footprint = crate::density_map::turned_footprint(uv, size, (aspect, turn, skew), aligned);
            let (dx, dy) = footprint.edges();
            let mass = map.mass_in(&footprint);
            proptest::prop_assert!(mass.is_finite() && mass >= 0.0, "{mass:e} at {uv} {dx} {dy}");
            let scale = DVec2::new(w as f64, h as f64);
            let extent = (dx * scale).abs() + (dy * scale).abs();
            if extent.max_element() < 0.05 {
                let n = 160;
                let (mut sum, mut largest) = (0.0, 0.0f64);
                for i in 0..n {
                    for j in 0..n {
                        let [s, t] = [i, j].map(|k| (k as f64 + 0.5) / n as f64 - 0.5);
                        let d = tents_about(&map, uv, s * dx + t * dy);
                        sum += d;
                        largest = largest.max(d);
                    }
                }
                let reference = sum / (n * n) as f64 * footprint.area();
                // d's largest value over the footprint: the samples' and a step's slope more.
                let largest = largest + extent.max_element() / n as f64 * 4.0;
                let coordinates = ((uv * scale).abs() + extent).max_element() + 1.0;
                let perimeter = 2.0 * (dx.length() + dy.length());
                let moved = 32.0 * f64::EPSILON * coordinates / scale.min_element();
                let rounding = moved * perimeter * largest;
                proptest::prop_assert!(
                    (mass - reference).abs() <= 1e-3 * reference + rounding,
                    "{w}x{h} at {uv} {dx} {dy}: {mass:e} against {reference:e} (± {rounding:e})"
                );
            }
        }
    }

    /// ∫_A d over parallelograms (across texel edges and tiles) against a midpoint rule over
    /// the parallelogram's own parameters.
    #[test]
    fn mass_in_a_footprint_is_the_integral_over_the_parallelogram() {
        let map = patchy(11, 6, 3);
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
                (exact - reference).abs() < 1e-4 * footprint.area(),
                "{uv} {dx} {dy}: {exact} against {reference}"
            );
            let bound = map.max_over(&footprint);
            for s in 0..20 {
                for t in 0..20 {
                    let x = uv + (s as f64 / 19.0 - 0.5) * dx + (t as f64 / 19.0 - 0.5) * dy;
                    assert!(map.value_at(x) <= bound + 1e-12);
                }
            }
        }
    }
}
