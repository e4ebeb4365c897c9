//! Texture-space footprints and their overlap with the tree's boxes, across texture tiles.
//!
//! A [`Footprint`] is the parallelogram {c + s·dx + t·dy : s, t ∈ [−½, ½]} that ray
//! differentials give for a pixel (Sec. 3.1, "Usage in a rendering system"). The particles live
//! in the unit texture square and the texture repeats, so a particle at x is seen once for every
//! integer translate x + (i, j) inside the parallelogram: its *multiplicity* m(x). A box of the
//! tree is resolved when m is constant on it, partial otherwise.
//!
//! Per box the work is one O(1) step per texture row the footprint spans: in row j the box's
//! translates inside the footprint form an integer interval (the box lies inside the convex
//! footprint iff its four corners do), and the translates that touch it form another (the box
//! meets the footprint iff their x-ranges overlap within the row's band). So a footprint over
//! many tiles costs O(√tiles) per box, not O(tiles).

use glam::{DMat2, DVec2};

use crate::error::TreeError;

/// A texture-space parallelogram (ray-differential footprint).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footprint {
    /// The centre, reduced to [0, 1)² (the texture is periodic).
    center: DVec2,
    dx: DVec2,
    dy: DVec2,
    /// Maps x − centre to (s, t).
    to_parameters: DMat2,
    area: f64,
    /// The four corners, counter-clockwise or clockwise.
    corners: [DVec2; 4],
    /// Axis-aligned bounds of the corners.
    min: DVec2,
    max: DVec2,
}

/// The translates of a box in one texture row: those touching the footprint, and those inside.
struct RowTranslates {
    touching: std::ops::RangeInclusive<i64>,
    inside: std::ops::RangeInclusive<i64>,
}

/// The integer translates whose bounding boxes meet a box's: [`Footprint::candidate_translates`].
enum Candidates {
    None,
    /// Columns [i0, i1] and rows [j0, j1], at most four translates.
    Few([i64; 2], [i64; 2]),
    Many,
}

/// m(x) for the points of one box ([`Footprint::multiplicity_in_box`]).
pub(crate) struct BoxMultiplicity<'a> {
    footprint: &'a Footprint,
    candidates: Candidates,
}

impl BoxMultiplicity<'_> {
    /// Which of the `N` equal columns and rows of this box may hold points with m > 0, as bit
    /// masks (bit c for column or row c): a column's bit is clear only if m = 0 at every point
    /// of it (as [`Self::at`] computes m). A point x has candidate column i only if footprint
    /// min − x ≤ i ≤ footprint max − x (computed); for x between a column's bounds, monotone
    /// rounding bounds these by footprint min − its upper and footprint max − its lower
    /// bound, so translates outside those are no point's; rows alike.
    pub(crate) fn meeting_columns_and_rows<const N: usize>(
        &self,
        min: DVec2,
        size: f64,
    ) -> [u32; 2] {
        let Candidates::Few([i0, i1], [j0, j1]) = self.candidates else {
            let all = if matches!(self.candidates, Candidates::None) {
                0
            } else {
                u32::MAX
            };
            return [all; 2];
        };
        let step = size / N as f64;
        let meeting = |start: f64, low: f64, high: f64, range: [i64; 2]| {
            (0..N).fold(0u32, |mask, c| {
                let (lo, hi) = (start + c as f64 * step, start + (c + 1) as f64 * step);
                let hit =
                    (range[0]..=range[1]).any(|i| (low - hi..=high - lo).contains(&(i as f64)));
                mask | u32::from(hit) << c
            })
        };
        [
            meeting(min.x, self.footprint.min.x, self.footprint.max.x, [i0, i1]),
            meeting(min.y, self.footprint.min.y, self.footprint.max.y, [j0, j1]),
        ]
    }

    /// m(x) for a point x of the box: the same as [`Footprint::multiplicity`]. A point's
    /// candidate translates are among its box's (min − x and max − x bracket those of the box,
    /// and rounding is monotone); they are the (i, j) with footprint min − x ≤ (i, j) ≤
    /// footprint max − x, the integers of `multiplicity`'s ceil–floor ranges, so comparing
    /// replaces its four roundings.
    #[inline]
    pub(crate) fn at(&self, x: DVec2) -> u64 {
        let Candidates::Few([i0, i1], [j0, j1]) = self.candidates else {
            return match self.candidates {
                Candidates::None => 0,
                _ => self.footprint.multiplicity(x),
            };
        };
        let (lo, hi) = (self.footprint.min - x, self.footprint.max - x);
        let mut count = 0;
        for j in j0..=j1 {
            let row = j as f64;
            if row < lo.y || row > hi.y {
                continue;
            }
            for i in i0..=i1 {
                let column = i as f64;
                if column >= lo.x && column <= hi.x {
                    count += u64::from(self.footprint.contains(x + DVec2::new(column, row)));
                }
            }
        }
        count
    }
}

/// ⌊x⌋ as an integer, saturating (NaN gives 0, like `x.floor() as i64`). `f64::floor` is a
/// libm call on x86-64's baseline, and box overlaps take eight of these.
#[inline]
fn floor_to_i64(x: f64) -> i64 {
    let truncated = x as i64;
    truncated.saturating_sub(i64::from(truncated as f64 > x))
}

/// ⌈x⌉ as an integer, saturating (NaN gives 0).
#[inline]
fn ceil_to_i64(x: f64) -> i64 {
    let truncated = x as i64;
    truncated.saturating_add(i64::from((truncated as f64) < x))
}

/// The number of integers in a range (0 when empty).
fn range_len(range: &std::ops::RangeInclusive<i64>) -> u64 {
    if range.is_empty() {
        0
    } else {
        (range.end() - range.start() + 1) as u64
    }
}

/// How a box of the tree meets a footprint's translates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BoxOverlap {
    /// Translates containing the whole box: the box's particles are each seen this many times.
    pub inside: u64,
    /// Translates that cut the box (0 when the box is resolved).
    pub partial: u64,
}

impl BoxOverlap {
    /// Whether no translate meets the box.
    #[inline]
    #[must_use]
    pub fn is_disjoint(&self) -> bool {
        self.inside == 0 && self.partial == 0
    }
}

impl Footprint {
    /// The largest magnitude of an edge component (texture units): the area is then at most
    /// 2·10³⁰ tiles and N times it at most 2·10⁴⁶, so no count, D̂ or area overflows (an edge of
    /// 10¹⁵⁵ overflowed the area; of 10¹⁵⁴, the count). Beyond 10¹⁵ a double resolves no more
    /// than an eighth of a tile.
    pub const MAX_EDGE: f64 = 1e15;

    /// The parallelogram centred at `uv` with edge vectors `duv_dx`, `duv_dy`.
    ///
    /// # Errors
    /// [`TreeError::NonFiniteFootprint`] if any component is NaN or infinite,
    /// [`TreeError::FootprintTooLarge`] if an edge component exceeds [`Self::MAX_EDGE`].
    pub fn new(uv: DVec2, duv_dx: DVec2, duv_dy: DVec2) -> Result<Self, TreeError> {
        if !(uv.is_finite() && duv_dx.is_finite() && duv_dy.is_finite()) {
            return Err(TreeError::NonFiniteFootprint);
        }
        let largest = duv_dx.abs().max(duv_dy.abs()).max_element();
        if largest > Self::MAX_EDGE {
            return Err(TreeError::FootprintTooLarge { component: largest });
        }
        let center = uv - uv.floor();
        let determinant = duv_dx.perp_dot(duv_dy);
        let to_parameters = if determinant != 0.0 {
            DMat2::from_cols(duv_dx, duv_dy).inverse()
        } else {
            DMat2::ZERO
        };
        let corners = [
            center - 0.5 * duv_dx - 0.5 * duv_dy,
            center + 0.5 * duv_dx - 0.5 * duv_dy,
            center + 0.5 * duv_dx + 0.5 * duv_dy,
            center - 0.5 * duv_dx + 0.5 * duv_dy,
        ];
        let min = corners.iter().fold(DVec2::INFINITY, |m, c| m.min(*c));
        let max = corners.iter().fold(DVec2::NEG_INFINITY, |m, c| m.max(*c));
        Ok(Self {
            center,
            dx: duv_dx,
            dy: duv_dy,
            to_parameters,
            area: determinant.abs(),
            corners,
            min,
            max,
        })
    }

    /// The area in texture units (tiles).
    #[must_use]
    pub fn area(&self) -> f64 {
        self.area
    }

    /// How many unit tiles its axis-aligned bounding box touches: the texture rows times the
    /// texture columns it spans (at least 1; infinite past 2⁵³ per side).
    #[must_use]
    pub fn tiles_spanned(&self) -> f64 {
        let span = |lo: f64, hi: f64| hi.floor() - lo.floor() + 1.0;
        span(self.min.x, self.max.x) * span(self.min.y, self.max.y)
    }

    /// What testing one tree node against this footprint costs, in tests of a footprint within
    /// a few tiles: a node test walks the footprint's integer translates row by row (box
    /// overlaps, overlap areas, multiplicities), about one unit of work per tile its bounding
    /// box spans, and the first four come at the price of one. At least 1.
    #[must_use]
    pub fn node_test_cost(&self) -> f64 {
        (self.tiles_spanned() / 4.0).max(1.0)
    }

    /// Whether the parallelogram has no area (a degenerate footprint sees no particles).
    #[must_use]
    pub fn is_degenerate(&self) -> bool {
        !(self.area > 0.0) || !self.to_parameters.is_finite()
    }

    /// The centre in [0, 1)².
    #[must_use]
    pub fn center(&self) -> DVec2 {
        self.center
    }

    /// The edge vectors (dx, dy).
    #[must_use]
    pub fn edges(&self) -> (DVec2, DVec2) {
        (self.dx, self.dy)
    }

    /// Whether texture point `x` (unwrapped) lies in the parallelogram.
    #[inline]
    #[must_use]
    pub fn contains(&self, x: DVec2) -> bool {
        let st = self.to_parameters * (x - self.center);
        st.x.abs() <= 0.5 && st.y.abs() <= 0.5
    }

    /// The x-interval where the horizontal line at height `y` meets the parallelogram.
    fn row(&self, y: f64) -> Option<(f64, f64)> {
        let m = &self.to_parameters;
        let dy = y - self.center.y;
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        // s = m00·(x − cx) + m01·dy and t = m10·(x − cx) + m11·dy, each in [−½, ½].
        for (slope, offset) in [(m.x_axis.x, m.y_axis.x * dy), (m.x_axis.y, m.y_axis.y * dy)] {
            if slope == 0.0 {
                if offset.abs() > 0.5 {
                    return None;
                }
                continue;
            }
            let a = (-0.5 - offset) / slope;
            let b = (0.5 - offset) / slope;
            lo = lo.max(a.min(b));
            hi = hi.min(a.max(b));
        }
        (lo <= hi).then_some((lo + self.center.x, hi + self.center.x))
    }

    /// The x-extent of the parallelogram within the band y ∈ [y0, y1].
    fn band(&self, y0: f64, y1: f64) -> Option<(f64, f64)> {
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for y in [y0, y1] {
            if let Some((a, b)) = self.row(y) {
                lo = lo.min(a);
                hi = hi.max(b);
            }
        }
        for c in &self.corners {
            if c.y >= y0 && c.y <= y1 {
                lo = lo.min(c.x);
                hi = hi.max(c.x);
            }
        }
        (lo <= hi).then_some((lo, hi))
    }

    /// The integer rows j whose translate of [y0, y1] meets the footprint's y-range.
    fn rows_for(&self, y0: f64, y1: f64) -> std::ops::RangeInclusive<i64> {
        let first = ceil_to_i64(self.min.y - y1);
        let last = floor_to_i64(self.max.y - y0);
        first..=last
    }

    /// The four corners, in order around the parallelogram (about the centre in [0, 1)²).
    pub(crate) fn corners(&self) -> [DVec2; 4] {
        self.corners
    }

    /// The footprint's axis-aligned bounding box, (min, max) (its centre in [0, 1)²).
    #[inline]
    pub(crate) fn bounds(&self) -> (DVec2, DVec2) {
        (self.min, self.max)
    }

    /// The largest magnitude of an entry of the map from texture offsets to the parameters
    /// (s, t): about 1 / the footprint's narrowest width.
    #[inline]
    pub(crate) fn parameter_map_bound(&self) -> f64 {
        let m = &self.to_parameters;
        m.x_axis
            .abs()
            .max_element()
            .max(m.y_axis.abs().max_element())
    }

    /// How the box [min, min + size]² meets the footprint's integer translates.
    #[must_use]
    pub fn overlap_box(&self, min: DVec2, size: f64) -> BoxOverlap {
        let max = min + DVec2::splat(size);
        match self.candidate_translates(min, max) {
            // The commonest answer in a query: a child box beside a small footprint.
            Candidates::None => {
                return BoxOverlap {
                    inside: 0,
                    partial: 0,
                };
            }
            Candidates::Few(columns, rows) => {
                return self.overlap_box_by_translates(min, size, columns, rows);
            }
            Candidates::Many => {}
        }
        let (mut inside, mut touching) = (0u64, 0u64);
        for j in self.rows_for(min.y, max.y) {
            let Some(row) = self.row_translates(min, max, j) else {
                continue;
            };
            touching += range_len(&row.touching);
            inside += range_len(&row.inside);
        }
        BoxOverlap {
            inside,
            partial: touching.saturating_sub(inside),
        }
    }

    /// The footprint's narrowest width: its area over its longer edge (the distance between
    /// the two lines parallel to that edge).
    #[must_use]
    pub fn narrowest_width(&self) -> f64 {
        let longest = self.dx.length().max(self.dy.length());
        if longest > 0.0 {
            self.area / longest
        } else {
            0.0
        }
    }

    /// The integer translates (i, j) of [min, max] whose bounding boxes meet the footprint's:
    /// none, at most four (a footprint below a tile, the common case), or more.
    fn candidate_translates(&self, min: DVec2, max: DVec2) -> Candidates {
        let columns = [
            ceil_to_i64(self.min.x - max.x),
            floor_to_i64(self.max.x - min.x),
        ];
        let rows = [
            ceil_to_i64(self.min.y - max.y),
            floor_to_i64(self.max.y - min.y),
        ];
        if columns[1] < columns[0] || rows[1] < rows[0] {
            return Candidates::None;
        }
        // Counted in f64: saturated bounds of absurd footprints must not overflow.
        let span = |[lo, hi]: [i64; 2]| hi as f64 - lo as f64 + 1.0;
        if span(columns) * span(rows) <= 4.0 {
            Candidates::Few(columns, rows)
        } else {
            Candidates::Many
        }
    }

    /// [`Footprint::overlap_box`] for the common case of a few candidate translates (columns
    /// i0..=i1 and rows j0..=j1): each is classified by the separating-axis test in the
    /// footprint's (s, t) parameters (the box's extent along s and t from its corner and edge
    /// images) and along x and y.
    fn overlap_box_by_translates(
        &self,
        min: DVec2,
        size: f64,
        [i0, i1]: [i64; 2],
        [j0, j1]: [i64; 2],
    ) -> BoxOverlap {
        let m = &self.to_parameters;
        let edge_x = m.x_axis * size;
        let edge_y = m.y_axis * size;
        let spread_lo = edge_x.min(DVec2::ZERO) + edge_y.min(DVec2::ZERO);
        let spread_hi = edge_x.max(DVec2::ZERO) + edge_y.max(DVec2::ZERO);
        let mut overlap = BoxOverlap {
            inside: 0,
            partial: 0,
        };
        for j in j0..=j1 {
            for i in i0..=i1 {
                let corner = min + DVec2::new(i as f64, j as f64);
                let st = *m * (corner - self.center);
                let (lo, hi) = (st + spread_lo, st + spread_hi);
                if lo.x >= -0.5 && hi.x <= 0.5 && lo.y >= -0.5 && hi.y <= 0.5 {
                    overlap.inside += 1;
                } else if !(lo.x > 0.5 || hi.x < -0.5 || lo.y > 0.5 || hi.y < -0.5) {
                    overlap.partial += 1;
                }
            }
        }
        overlap
    }

    /// In texture row j, the translates i of the box [min, max] that touch the footprint and
    /// those that lie inside it (the box is inside the convex footprint iff its four corners
    /// are; it touches it iff their x-ranges overlap within the row's band).
    fn row_translates(&self, min: DVec2, max: DVec2, j: i64) -> Option<RowTranslates> {
        let (y0, y1) = (min.y + j as f64, max.y + j as f64);
        let (band_lo, band_hi) = self.band(y0, y1)?;
        let touching = ceil_to_i64(band_lo - max.x)..=floor_to_i64(band_hi - min.x);
        if touching.is_empty() {
            return None;
        }
        let inside = match (self.row(y0), self.row(y1)) {
            (Some((a0, b0)), Some((a1, b1))) => {
                ceil_to_i64(a0.max(a1) - min.x)..=floor_to_i64(b0.min(b1) - max.x)
            }
            // No translate is inside when a box edge's row misses the footprint.
            #[allow(clippy::reversed_empty_ranges)]
            _ => 1..=0,
        };
        Some(RowTranslates { touching, inside })
    }

    /// The number of integer translates x + (i, j) inside the footprint: the multiplicity m(x).
    #[must_use]
    pub fn multiplicity(&self, x: DVec2) -> u64 {
        // The translates whose bounding box holds x: with at most four (a footprint below a
        // tile, the leaves' common case), test each; otherwise count row by row.
        match self.candidate_translates(x, x) {
            Candidates::None => return 0,
            Candidates::Few([i0, i1], [j0, j1]) => {
                let mut count = 0;
                for j in j0..=j1 {
                    for i in i0..=i1 {
                        count += u64::from(self.contains(x + DVec2::new(i as f64, j as f64)));
                    }
                }
                return count;
            }
            Candidates::Many => {}
        }
        let mut count = 0u64;
        for j in self.rows_for(x.y, x.y) {
            if let Some((a, b)) = self.row(x.y + j as f64) {
                let first = ceil_to_i64(a - x.x);
                let last = floor_to_i64(b - x.x);
                if last >= first {
                    count += (last - first + 1) as u64;
                }
            }
        }
        count
    }

    /// The multiplicities of points of the box [min, min + size]², with the box's candidate
    /// translates found once (a leaf of the tree needs m(x) for each of its particles).
    pub(crate) fn multiplicity_in_box(&self, min: DVec2, size: f64) -> BoxMultiplicity<'_> {
        BoxMultiplicity {
            footprint: self,
            candidates: self.candidate_translates(min, min + DVec2::splat(size)),
        }
    }

    /// ∫ over the box of m(x) dx: the summed area of the box's overlaps with all translates.
    /// Translates containing the box add its area; the O(perimeter) others are clipped
    /// (Sutherland–Hodgman, box by parallelogram).
    #[must_use]
    pub fn overlap_area(&self, min: DVec2, size: f64) -> f64 {
        self.overlap_area_within(min, min + DVec2::splat(size), DVec2::splat(size))
    }

    /// ∫ m(x) dx over the rectangle [min, max] (inside the unit square): its area in the
    /// footprint counted once per integer translate that covers it, as
    /// [`Footprint::overlap_area`] for a box.
    pub(crate) fn overlap_area_of_rectangle(&self, min: DVec2, max: DVec2) -> f64 {
        self.overlap_area_within(min, max, max - min)
    }

    /// [`Footprint::overlap_area_of_rectangle`] of [min, max], whose sides are `size`.
    fn overlap_area_within(&self, min: DVec2, max: DVec2, size: DVec2) -> f64 {
        let mut area = 0.0;
        for j in self.rows_for(min.y, max.y) {
            let Some(row) = self.row_translates(min, max, j) else {
                continue;
            };
            area += range_len(&row.inside) as f64 * size.x * size.y;
            for i in row.touching {
                if row.inside.contains(&i) {
                    continue;
                }
                let offset = DVec2::new(i as f64, j as f64);
                area += self.clipped_area(min + offset, max + offset);
            }
        }
        area
    }

    /// The area of box [lo, hi] ∩ parallelogram.
    fn clipped_area(&self, lo: DVec2, hi: DVec2) -> f64 {
        let mut polygon = [DVec2::ZERO; 8];
        polygon[..4].copy_from_slice(&[lo, DVec2::new(hi.x, lo.y), hi, DVec2::new(lo.x, hi.y)]);
        let mut len = 4;
        let m = &self.to_parameters;
        // The four half-planes ±s ≤ ½, ±t ≤ ½.
        let rows = [m.row(0), m.row(1)];
        for row in rows {
            for sign in [1.0, -1.0] {
                let value = |p: DVec2| 0.5 - sign * row.dot(p - self.center);
                let mut out = [DVec2::ZERO; 8];
                let mut out_len = 0;
                for k in 0..len {
                    let (p, q) = (polygon[k], polygon[(k + 1) % len]);
                    let (vp, vq) = (value(p), value(q));
                    if vp >= 0.0 {
                        out[out_len] = p;
                        out_len += 1;
                    }
                    if (vp >= 0.0) != (vq >= 0.0) {
                        out[out_len] = p + (vp / (vp - vq)) * (q - p);
                        out_len += 1;
                    }
                }
                polygon = out;
                len = out_len;
                if len == 0 {
                    return 0.0;
                }
            }
        }
        let mut twice_area = 0.0;
        for k in 0..len {
            twice_area += polygon[k].perp_dot(polygon[(k + 1) % len]);
        }
        0.5 * twice_area.abs()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integer_floor_and_ceil_match_the_float_ones() {
        let values = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.5,
            -2.5,
            1e-300,
            -1e-300,
            4503599627370495.5,
            -4503599627370495.5,
            9.3e18,
            -9.3e18,
            1e300,
            -1e300,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        for x in values {
            assert_eq!(floor_to_i64(x), x.floor() as i64, "floor {x}");
            assert_eq!(ceil_to_i64(x), x.ceil() as i64, "ceil {x}");
        }
    }

    fn brute_multiplicity(f: &Footprint, x: DVec2) -> u64 {
        let mut count = 0;
        for j in -40..=40 {
            for i in -40..=40 {
                if f.contains(x + DVec2::new(f64::from(i), f64::from(j))) {
                    count += 1;
                }
            }
        }
        count
    }

    /// Small (the leaves' case, one at a texture corner), a few tiles, and many tiles.
    fn sample_footprints() -> [Footprint; 4] {
        let footprint = |c: [f64; 2], dx: [f64; 2], dy: [f64; 2]| {
            Footprint::new(DVec2::from(c), DVec2::from(dx), DVec2::from(dy)).unwrap()
        };
        [
            footprint([0.3, 0.4], [0.001, 0.0002], [-0.0003, 0.002]),
            footprint([0.999, 0.0005], [0.003, 0.001], [0.0005, 0.004]),
            footprint([0.99, 0.01], [0.3, 0.1], [0.05, 0.4]),
            footprint([5.5, -3.2], [7.3, 2.1], [-1.7, 6.2]),
        ]
    }

    /// A reproducible source of uniforms in [0, 1).
    fn uniforms(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state = crate::node::mix64(state.wrapping_add(0x9E37_79B9_7F4A_7C15));
            (state >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    #[test]
    fn multiplicity_matches_brute_force() {
        let mut uniform = uniforms(1);
        for f in &sample_footprints() {
            for _ in 0..2000 {
                let x = DVec2::new(uniform(), uniform());
                assert_eq!(f.multiplicity(x), brute_multiplicity(f, x), "{f:?} {x}");
            }
        }
    }

    #[test]
    fn a_box_gives_its_points_their_own_multiplicity() {
        // Boxes from the unit square to 2⁻²⁰, their corners among the points.
        let footprints = sample_footprints();
        let mut uniform = uniforms(7);
        let mut nonzero = 0;
        for f in &footprints {
            for level in [0, 3, 8, 12, 20] {
                let size = 0.5_f64.powi(level);
                for _ in 0..400 {
                    // A box near the footprint's centre half the time.
                    let near = f.center() + DVec2::new(uniform() - 0.5, uniform() - 0.5) * 0.01;
                    let anywhere = DVec2::new(uniform(), uniform());
                    let corner = if uniform() < 0.5 { near } else { anywhere };
                    let min = (corner / size)
                        .floor()
                        .clamp(DVec2::ZERO, DVec2::splat(1.0 / size - 1.0))
                        * size;
                    let in_box = f.multiplicity_in_box(min, size);
                    for k in 0..8 {
                        let (u, v) = match k {
                            0 => (0.0, 0.0),
                            1 => (1.0 - f64::EPSILON, 1.0 - f64::EPSILON),
                            _ => (uniform(), uniform()),
                        };
                        let x = min + size * DVec2::new(u, v);
                        let m = f.multiplicity(x);
                        assert_eq!(in_box.at(x), m, "{f:?} box {min} {size} at {x}");
                        nonzero += usize::from(m > 0);
                    }
                }
            }
        }
        assert!(nonzero > 2000, "{nonzero} points with m > 0");
    }

    #[test]
    fn columns_and_rows_without_points_in_the_footprint_are_told() {
        // Points placed as leaves place them (a column's and a row's lower corner plus a
        // fraction of their width): where m > 0, their column's and row's bits are set.
        let mut uniform = uniforms(11);
        let (mut positive, mut culled) = (0, 0);
        for f in &sample_footprints() {
            for level in [0, 3, 8, 10, 12, 20] {
                let size = 0.5_f64.powi(level);
                for _ in 0..300 {
                    let near = f.center() + DVec2::new(uniform() - 0.5, uniform() - 0.5) * 0.004;
                    let corner = if uniform() < 0.7 {
                        near
                    } else {
                        DVec2::new(uniform(), uniform())
                    };
                    let min = (corner / size)
                        .floor()
                        .clamp(DVec2::ZERO, DVec2::splat(1.0 / size - 1.0))
                        * size;
                    let in_box = f.multiplicity_in_box(min, size);
                    let [columns, rows] = in_box.meeting_columns_and_rows::<4>(min, size);
                    culled += 8 - (columns.count_ones() + rows.count_ones()).min(8);
                    let step = size / 4.0;
                    for _ in 0..16 {
                        let (c, r) = ((uniform() * 4.0) as usize, (uniform() * 4.0) as usize);
                        let (u, v) = if uniform() < 0.2 {
                            (0.0, 1.0 - f64::EPSILON)
                        } else {
                            (uniform(), uniform())
                        };
                        let x =
                            min + DVec2::new(c as f64, r as f64) * step + step * DVec2::new(u, v);
                        if in_box.at(x) > 0 {
                            positive += 1;
                            assert!(
                                columns >> c & rows >> r & 1 == 1,
                                "{f:?} box {min} {size} at {x}"
                            );
                        }
                    }
                }
            }
        }
        assert!(
            positive > 1000 && culled > 1000,
            "{positive} points in, {culled} culled"
        );
    }

    #[test]
    fn box_overlap_brackets_the_multiplicity() {
        let f = Footprint::new(
            DVec2::new(0.2, 0.7),
            DVec2::new(2.3, 0.4),
            DVec2::new(-0.6, 1.9),
        )
        .unwrap();
        for level in 0..6 {
            let size = 0.5_f64.powi(level);
            let cells = 1 << level;
            for cy in 0..cells {
                for cx in 0..cells {
                    let min = DVec2::new(f64::from(cx), f64::from(cy)) * size;
                    let overlap = f.overlap_box(min, size);
                    for (sx, sy) in [(0.1, 0.1), (0.9, 0.2), (0.5, 0.5), (0.2, 0.95)] {
                        let m = f.multiplicity(min + DVec2::new(sx, sy) * size);
                        assert!(m >= overlap.inside && m <= overlap.inside + overlap.partial);
                    }
                    let area = f.overlap_area(min, size);
                    let box_area = size * size;
                    assert!(area >= overlap.inside as f64 * box_area * (1.0 - 1e-12));
                    assert!(
                        area <= (overlap.inside + overlap.partial) as f64
                            * box_area
                            * (1.0 + 1e-12)
                    );
                    if overlap.partial == 0 {
                        assert!((area - overlap.inside as f64 * box_area).abs() < 1e-12);
                    }
                }
            }
        }
        // Over the whole tile, ∫ m = the footprint's area.
        assert!((f.overlap_area(DVec2::ZERO, 1.0) - f.area()).abs() < 1e-12 * f.area());
    }

    #[test]
    fn degenerate_and_invalid_footprints() {
        let zero = Footprint::new(
            DVec2::new(0.5, 0.5),
            DVec2::new(0.1, 0.0),
            DVec2::new(0.2, 0.0),
        )
        .unwrap();
        assert!(zero.is_degenerate());
        assert!(Footprint::new(DVec2::new(f64::NAN, 0.5), DVec2::X, DVec2::Y).is_err());
        let far = Footprint::new(
            DVec2::new(1e6 + 0.25, -1e6 + 0.5),
            DVec2::new(1e-3, 0.0),
            DVec2::new(0.0, 1e-3),
        )
        .unwrap();
        assert!((far.center() - DVec2::new(0.25, 0.5)).length() < 1e-9);
    }
}
