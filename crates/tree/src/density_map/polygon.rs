//! Convex polygons in the plane: clipping to a strip and exact moments, for a density map's
//! integrals over a footprint's parallelogram.

use glam::DVec2;

/// A convex polygon of at most [`Polygon::CAPACITY`] vertices, held in place (clipping runs
/// once per texel a footprint's edges cut, where a heap allocation cost more than the cut).
#[derive(Clone, Copy, Debug)]
pub(super) struct Polygon {
    points: [DVec2; Polygon::CAPACITY],
    len: usize,
}

impl Polygon {
    /// A cut keeps the k vertices on its inner side and adds one per change of side, at most
    /// 2·min(k, n − k) of them, so an n-gon leaves at most ⌊3n/2⌋ vertices whatever rounding
    /// does to the sides (2 changes and n + 1 vertices in exact arithmetic): a parallelogram
    /// cut by two strips (four cuts) leaves at most 6, 9, then 13.
    const CAPACITY: usize = 16;

    fn push(&mut self, point: DVec2) {
        debug_assert!(
            self.len < Self::CAPACITY,
            "four cuts leave at most 13 vertices"
        );
        if self.len < Self::CAPACITY {
            self.points[self.len] = point;
            self.len += 1;
        }
    }
}

impl std::ops::Deref for Polygon {
    type Target = [DVec2];

    fn deref(&self) -> &[DVec2] {
        &self.points[..self.len]
    }
}

impl std::ops::DerefMut for Polygon {
    fn deref_mut(&mut self) -> &mut [DVec2] {
        &mut self.points[..self.len]
    }
}

/// The convex polygon `points` cut to where both `inside_a` and `inside_b` are ≥ 0
/// (Sutherland–Hodgman, each an affine function of the point); `points` is a parallelogram
/// or a polygon cut from one by an earlier clip (see [`Polygon`]).
pub(super) fn clip(
    points: &[DVec2],
    inside_a: impl Fn(DVec2) -> f64,
    inside_b: impl Fn(DVec2) -> f64,
) -> Polygon {
    let once = |points: &[DVec2], inside: &dyn Fn(DVec2) -> f64| {
        let mut out = Polygon {
            points: [DVec2::ZERO; Polygon::CAPACITY],
            len: 0,
        };
        for (k, &p) in points.iter().enumerate() {
            let q = points[(k + 1) % points.len()];
            let (fp, fq) = (inside(p), inside(q));
            if fp >= 0.0 {
                out.push(p);
            }
            if (fp >= 0.0) != (fq >= 0.0) {
                out.push(p + (q - p) * (fp / (fp - fq)));
            }
        }
        out
    };
    let first = once(points, &inside_a);
    if first.len < 3 {
        return first;
    }
    once(&first, &inside_b)
}

/// The part of `columns` within `met`, empty at `met`'s start if none (the columns a row's
/// strip meets, which the whole ones and the cut ones then split between them).
pub(super) fn within(
    columns: std::ops::Range<i64>,
    met: &std::ops::Range<i64>,
) -> std::ops::Range<i64> {
    let start = columns.start.max(met.start).min(met.end);
    start..columns.end.min(met.end).max(start)
}

/// Where the horizontal line at height `y` crosses the convex polygon `points`: its
/// (leftmost, rightmost) x, or `None` if the line misses the polygon.
pub(super) fn chord_at(points: &[DVec2], y: f64) -> Option<(f64, f64)> {
    let mut chord: Option<(f64, f64)> = None;
    let mut include = |x: f64| {
        chord = Some(chord.map_or((x, x), |(left, right)| (left.min(x), right.max(x))));
    };
    for (k, &p) in points.iter().enumerate() {
        let q = points[(k + 1) % points.len()];
        if y < p.y.min(q.y) || y > p.y.max(q.y) {
            continue;
        }
        if p.y == q.y {
            include(p.x);
            include(q.x);
        } else {
            include(p.x + (q.x - p.x) * ((y - p.y) / (q.y - p.y)));
        }
    }
    chord
}

/// The columns c that the polygon `points` meets, from its leftmost to its rightmost point,
/// where column c spans [(c + `offset`) / `columns_per_unit`, (c + 1 + `offset`) /
/// `columns_per_unit`] in the polygon's units.
pub(super) fn columns_met(
    points: &[DVec2],
    columns_per_unit: f64,
    offset: f64,
) -> std::ops::Range<i64> {
    let (left, right) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, r), p| {
            (l.min(p.x), r.max(p.x))
        });
    let column = |x: f64| x * columns_per_unit - offset;
    column(left).floor() as i64..column(right).ceil() as i64
}

/// The columns c (texel [c, c + 1) along x, in the units of `points`) whose whole texel
/// [c, c + 1) × [y0, y1] lies in the convex polygon `points`, as c0..c1 (empty if none).
/// A rectangle lies in a convex polygon exactly when its four corners do, and the corners on
/// a horizontal line lie in it when they lie within its chord there.
pub(super) fn whole_columns(points: &[DVec2], y0: f64, y1: f64) -> std::ops::Range<i64> {
    match (chord_at(points, y0), chord_at(points, y1)) {
        (Some((left0, right0)), Some((left1, right1))) => {
            let (left, right) = (left0.max(left1), right0.min(right1));
            let first = left.ceil() as i64;
            let end = right.floor() as i64;
            first..end.max(first)
        }
        _ => 0..0,
    }
}

/// The area of a simple polygon (shoelace).
pub(super) fn polygon_area(points: &[DVec2]) -> f64 {
    if points.len() < 3 {
        return 0.0;
    }
    let twice: f64 = (0..points.len())
        .map(|k| points[k].perp_dot(points[(k + 1) % points.len()]))
        .sum();
    0.5 * twice.abs()
}

/// ∫1, ∫x, ∫y and ∫xy over a simple polygon (Green's theorem on each edge; the signs follow
/// the polygon's orientation and are made positive).
pub(super) fn polygon_moments(points: &[DVec2]) -> [f64; 4] {
    if points.len() < 3 {
        return [0.0; 4];
    }
    let mut sums = [0.0; 4];
    for k in 0..points.len() {
        let (p, q) = (points[k], points[(k + 1) % points.len()]);
        let cross = p.perp_dot(q);
        sums[0] += cross;
        sums[1] += (p.x + q.x) * cross;
        sums[2] += (p.y + q.y) * cross;
        sums[3] += (p.x * q.y + 2.0 * p.x * p.y + 2.0 * q.x * q.y + q.x * p.y) * cross;
    }
    let sign = sums[0].signum();
    [
        sign * sums[0] / 2.0,
        sign * sums[1] / 6.0,
        sign * sums[2] / 6.0,
        sign * sums[3] / 24.0,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The moments of a unit square, a right triangle and a slanted quadrilateral (either
    /// orientation) against their closed forms and a fine midpoint rule.
    #[test]
    fn moments_are_the_integrals() {
        let square = [
            DVec2::new(1.0, 2.0),
            DVec2::new(2.0, 2.0),
            DVec2::new(2.0, 3.0),
            DVec2::new(1.0, 3.0),
        ];
        let [a, x, y, xy] = polygon_moments(&square);
        assert!((a - 1.0).abs() < 1e-14 && (x - 1.5).abs() < 1e-14 && (y - 2.5).abs() < 1e-14);
        assert!((xy - 3.75).abs() < 1e-14, "{xy}");
        let reversed: Vec<DVec2> = square.iter().rev().copied().collect();
        assert_eq!(polygon_moments(&reversed), [a, x, y, xy]);
        // The triangle (0,0), (1,0), (0,1): area ½, ∫x = ∫y = 1/6, ∫xy = 1/24.
        let triangle = [DVec2::ZERO, DVec2::X, DVec2::Y];
        let [a, x, y, xy] = polygon_moments(&triangle);
        for (got, want) in [(a, 0.5), (x, 1.0 / 6.0), (y, 1.0 / 6.0), (xy, 1.0 / 24.0)] {
            assert!((got - want).abs() < 1e-15, "{got} against {want}");
        }
        // A slanted quadrilateral against a midpoint rule over its bounding box.
        let quad = [
            DVec2::new(0.1, 0.0),
            DVec2::new(1.3, 0.4),
            DVec2::new(1.0, 1.2),
            DVec2::new(-0.2, 0.7),
        ];
        let inside =
            |p: DVec2| (0..4).all(|k| (quad[(k + 1) % 4] - quad[k]).perp_dot(p - quad[k]) >= 0.0);
        let n = 1000;
        let mut reference = [0.0; 4];
        for i in 0..n {
            for j in 0..n {
                let p = DVec2::new(
                    -0.2 + 1.5 * (i as f64 + 0.5) / n as f64,
                    1.2 * (j as f64 + 0.5) / n as f64,
                );
                if inside(p) {
                    let cell = 1.5 * 1.2 / (n * n) as f64;
                    for (r, f) in reference.iter_mut().zip([1.0, p.x, p.y, p.x * p.y]) {
                        *r += f * cell;
                    }
                }
            }
        }
        for (got, want) in polygon_moments(&quad).iter().zip(reference) {
            assert!((got - want).abs() < 2e-3, "{got} against {want}");
        }
    }
}
