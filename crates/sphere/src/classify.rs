//! Triangle–conic classification (Sec. 3.3, "Intersection and overlap computations").
//!
//! # The arc test
//! The great-circle arc from a to b meets the cone {q < 0} exactly where the straight segment
//! from a to b does, because q and the nappe conditions are homogeneous. The paper's symmetric
//! parametrization p(t) = c + t·d with c = a + b, d = a − b, t ∈ [−1, 1] (p(1) = 2a,
//! p(−1) = 2b) turns q along the arc into the quadratic
//!
//! ```text
//!   q(p(t)) = dᵀCd·t² + 2·dᵀCc·t + cᵀCc,
//!   dᵀCd = q(a) + q(b) − 2q(a,b),   dᵀCc = q(a) − q(b),   cᵀCc = q(a) + q(b) + 2q(a,b),
//! ```
//!
//! so three form evaluations per vertex and one bilinear form per edge give every edge's
//! quadratic. Instead of asking only for a root in [−1, 1], the code restricts t to the part of
//! the segment on the valid nappe (a linear condition, clipped exactly) and takes the minimum
//! (or maximum) of the quadratic there: the arc meets the convex cap exactly when that extremum
//! has the right sign. That is the root test of the paper, restricted to the valid part of the
//! double cone.
//!
//! # The decision (see [`crate::conic`] for the shapes)
//! - Elliptic, valid set E⁺ convex: all three vertices in E⁺ ⇒ T ⊂ E⁺ (convexity). Otherwise, if
//!   no edge meets E⁺, then E⁺ (connected) is entirely inside or outside T, decided by whether
//!   T contains the cap's axis ẑ.
//! - Hyperbolic, valid set H \ D⁺ with D⁺ ⊂ closure(H) (⊂ H when k1 < 0): T ⊂ complement(H)
//!   or T ⊂ D⁺ each make T ∩ (H \ D⁺) = ∅ (vertex tests, by convexity; sufficient conditions,
//!   and for k1 < 0 also necessary, as the two closed sets are then disjoint and T connected).
//!   T ⊂ H \ D⁺ iff all vertices are in H, no edge meets D⁺ and the axis ŷ of D⁺ is not in T.
//!   The closure of the valid set contains antipodal points (on the great circle m·ω_i = 0,
//!   or, when ω_i = n, on the horizon), so it is never inside a triangle smaller than a
//!   hemisphere.
//! - The surface condition m·n > 0: a triangle whose vertices all have z ≥ 0 lies in the closed
//!   upper hemisphere and the condition removes only its boundary; otherwise it is never
//!   "inside", and "disjoint" is decided against the larger set without it (still never wrong).
//!
//! # Never wrong
//! Every sign decision that leads to "disjoint" or "inside" is made with a margin proportional
//! to a bound on the rounding error of the quantity tested; anything within the margin answers
//! [`Classification::Partial`].

use glam::DVec3;

use crate::conic::{ConicKind, SphericalConic, scaled_bilinear, scaled_form};
use crate::triangle::SphericalTriangle;

/// How a spherical triangle relates to the valid set of a spherical conic.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Classification {
    /// No normal of the triangle is in the conic (up to a set of zero area).
    Disjoint,
    /// Every normal of the triangle is in the conic (up to a set of zero area).
    TriangleInsideConic,
    /// The conic's valid set lies inside the triangle.
    ConicInsideTriangle,
    /// Anything else, including every case too close to call.
    Partial,
}

/// Relative margin on the quadratic form: far above its rounding error (a few 1e-16 relative
/// to the bound used), far below any geometry the tree resolves.
const FORM_MARGIN: f64 = 1e-12;
/// Relative margin on linear (plane-side) tests.
const LINEAR_MARGIN: f64 = 1e-13;

/// Absolute margin of the axis-in-triangle test: the axis is within ~1e-14 rad of an edge
/// plane before it answers "too close to tell".
const AXIS_MARGIN: f64 = 1e-14;

/// Per-vertex quantities in the conic's standard frame.
#[derive(Clone, Copy)]
struct FrameVertex {
    /// Frame coordinates (x, y, z).
    f: DVec3,
    /// q(f), the scaled quadratic form.
    q: f64,
    /// |k1||x| + k2|y| + s|z|: bounds |∂q/∂f|/2 and, times |f|₁, |q| and its rounding.
    form_scale: f64,
    /// |x| + |y| + |z|.
    norm1: f64,
    /// The component along the surface normal n in the local frame.
    surface_z: f64,
}

impl FrameVertex {
    fn new(conic: &SphericalConic, v: DVec3) -> Self {
        let k = conic.scaled_coefficients();
        let f = conic.to_frame(v);
        let a = f.abs();
        Self {
            f,
            q: scaled_form(k, f),
            form_scale: k.abs().dot(a),
            norm1: a.x + a.y + a.z,
            surface_z: v.z,
        }
    }

    fn form_margin(&self) -> f64 {
        FORM_MARGIN * self.form_scale * self.norm1
    }

    fn linear_margin(&self) -> f64 {
        LINEAR_MARGIN * self.norm1
    }
}

/// The extremum of q along the edge from `a` to `b`, restricted to the part where the linear
/// function `side` (given at the endpoints as `side_a`, `side_b`) is ≥ −margin. Returns the
/// minimum (`maximize = false`) or maximum, or `None` when that part is empty.
fn edge_extremum(
    a: &FrameVertex,
    b: &FrameVertex,
    q_ab: f64,
    side_a: f64,
    side_b: f64,
    side_margin: f64,
    maximize: bool,
) -> Option<f64> {
    // Paper's symmetric form on t ∈ [−1, 1]: p(t) = (a + b) + t(a − b).
    let sign = if maximize { -1.0 } else { 1.0 };
    let qa = sign * a.q;
    let qb = sign * b.q;
    let q_ab = sign * q_ab;
    let quadratic = qa + qb - 2.0 * q_ab; // dᵀCd
    let half_linear = qa - qb; // dᵀCc
    let constant = qa + qb + 2.0 * q_ab; // cᵀCc
    // side(p(t)) = (side_a + side_b) + t(side_a − side_b) ≥ −margin.
    let (mut lo, mut hi) = (-1.0_f64, 1.0_f64);
    let side_constant = side_a + side_b + side_margin;
    let side_slope = side_a - side_b;
    if side_slope > 0.0 {
        lo = lo.max(-side_constant / side_slope);
    } else if side_slope < 0.0 {
        hi = hi.min(-side_constant / side_slope);
    } else if side_constant < 0.0 {
        return None;
    }
    if !(lo <= hi) {
        return None;
    }
    let at = |t: f64| (quadratic * t + 2.0 * half_linear) * t + constant;
    let mut extremum = at(lo).min(at(hi));
    if quadratic > 0.0 {
        let vertex = -half_linear / quadratic;
        if vertex > lo && vertex < hi {
            extremum = extremum.min(at(vertex));
        }
    }
    Some(sign * extremum)
}

/// Where `axis` lies relative to the triangle with vertices in frame coordinates: `Some(true)`
/// strictly inside, `Some(false)` strictly outside, `None` too close to an edge to tell.
fn axis_in_triangle(v: &[FrameVertex; 3], axis: usize) -> Option<bool> {
    let mut inside = true;
    for i in 0..3 {
        let (p, q) = (v[i].f, v[(i + 1) % 3].f);
        // Component `axis` of p × (q − p), the inward edge normal.
        let d = q - p;
        let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
        let side = p[u] * d[w] - p[w] * d[u];
        // Frame coordinates carry an absolute rounding error below 1e-15 (unit inputs), which
        // the absolute term covers; the relative term covers the products.
        let margin =
            LINEAR_MARGIN * (p[u].abs() * d[w].abs() + p[w].abs() * d[u].abs()) + AXIS_MARGIN;
        if side < -margin {
            return Some(false);
        }
        if side <= margin {
            inside = false;
        }
    }
    inside.then_some(true)
}

/// Slack of [`SphericalConic::bounding_cap_misses`] on the scale of the cosines it compares
/// (their rounding errors are ~1e-15).
const CAP_MARGIN: f64 = 1e-10;

/// Absolute slack of [`SphericalConic::bounding_cap_against_edges`] on ẑ·(p × q), a hundred
/// times the rounding error of the cross product of unit vectors.
const EDGE_PLANE_MARGIN: f64 = 1e-13;

/// Which side of an edge's great circle a bounding cap of radius θ_max (`sin_max` = sin θ_max)
/// lies on, from `distance` = axis·e and `length` = |e| for the edge's normal e = p × q
/// (axis·e = |e|·sin δ, δ the axis's signed angle from the great circle): `Within` when δ >
/// θ_max, on e's side, `Beyond` when δ < −θ_max, `None` when the cap comes within the margin
/// of the circle. Both angles are below π/2, where sin increases. The components of e carry an
/// absolute rounding error of a few 1e-16 (unit vertices) whatever |e| is, hence the margin's
/// absolute part.
fn cap_side(distance: f64, length: f64, sin_max: f64) -> Option<CapSide> {
    let reach = sin_max * length;
    let margin = EDGE_PLANE_MARGIN + CAP_MARGIN * length;
    if distance > reach + margin {
        Some(CapSide::Within)
    } else if distance < -reach - margin {
        Some(CapSide::Beyond)
    } else {
        None
    }
}

/// The side of an edge's great circle a bounding cap lies on (see [`cap_side`]).
enum CapSide {
    /// On the side the edge's normal p × q points to.
    Within,
    /// On the other side.
    Beyond,
}

impl SphericalConic {
    /// Whether the triangle's bounding cap and the elliptic conic's (centred on ẑ) are apart,
    /// so the two are disjoint: a quick answer for the commonest case (three of a split's four
    /// children miss a small conic). The triangle's cap is centred on u = a + b + c with
    /// radius r, |u|·cos r = min(u·a, u·b, u·c); spherical caps under a hemisphere are convex,
    /// so it holds the triangle. The caps are apart when ∠(u, ẑ) > r + θ_max, that is
    /// u·ẑ < |u|·cos(r + θ_max) = (|u| cos r)·cos θ_max − (|u| sin r)·sin θ_max (both radii are
    /// below π/2, so the sum is below π, where cos decreases).
    fn bounding_cap_misses(&self, triangle: &SphericalTriangle) -> bool {
        let Some((axis, cos_max, sin_max)) = self.bounding_cap() else {
            return false;
        };
        let [a, b, c] = triangle.vertices();
        let u = a + b + c;
        let u_cos_r = u.dot(a).min(u.dot(b)).min(u.dot(c));
        // Only caps of radius below π/2 are claimed: every u·v > 0.
        if !(u_cos_r > 0.0) {
            return false;
        }
        // |u|² sin² r = |u|² − (|u| cos r)² cancels for small cells. The computed |u|² and
        // |u| cos r (the least computed u·v, whichever vertex it is) are within ~1e-15 of the
        // truth, so the difference is within ~1e-14, and |u| sin r within 1e-14/(2|u| sin r):
        // below 1e-11, a hundredth of the margin, when (|u| sin r)² > 1e-6 (r above ~3e-4).
        // Smaller cells take the full test.
        let u_sin_r_squared = u.length_squared() - u_cos_r * u_cos_r;
        if !(u_sin_r_squared > 1e-6) {
            return false;
        }
        let u_sin_r = u_sin_r_squared.sqrt();
        u.dot(axis) < u_cos_r * cos_max - u_sin_r * sin_max - CAP_MARGIN
    }

    /// The elliptic conic's bounding cap (axis ẑ, radius θ_max) against the great circles of
    /// the triangle's edges, from the vertices in the conic's frame: beyond one of them, the
    /// conic and the triangle are disjoint; within all three, the conic lies inside the
    /// triangle. This settles a triangle whose vertices are all outside the conic without the
    /// edge extrema and the axis test (the common case of a cell larger than a small conic).
    /// With the vertices counter-clockwise, e = p × q points into the triangle ([`cap_side`]).
    fn bounding_cap_against_edges(&self, v: &[FrameVertex; 3]) -> Option<Classification> {
        let (_, _, sin_max) = self.bounding_cap()?;
        let mut cap_inside = true;
        for i in 0..3 {
            // In the conic's frame ẑ is the axis: ẑ·e is the z component of e.
            let edge_normal = v[i].f.cross(v[(i + 1) % 3].f);
            match cap_side(edge_normal.z, edge_normal.length(), sin_max) {
                Some(CapSide::Beyond) => return Some(Classification::Disjoint),
                Some(CapSide::Within) => {}
                None => cap_inside = false,
            }
        }
        cap_inside.then_some(Classification::ConicInsideTriangle)
    }

    /// Classifies `triangle` against this conic's valid set (see the module docs). The answers
    /// [`Classification::Disjoint`], [`Classification::TriangleInsideConic`] and
    /// [`Classification::ConicInsideTriangle`] are never wrong; any doubt gives
    /// [`Classification::Partial`]. No trigonometry, no allocation.
    #[must_use]
    pub fn classify(&self, triangle: &SphericalTriangle) -> Classification {
        if self.bounding_cap_misses(triangle) {
            return Classification::Disjoint;
        }
        let [a, b, c] = triangle.vertices();
        let v = [
            FrameVertex::new(self, a),
            FrameVertex::new(self, b),
            FrameVertex::new(self, c),
        ];
        let k = self.scaled_coefficients();
        let q_edge = || {
            [
                scaled_bilinear(k, v[0].f, v[1].f),
                scaled_bilinear(k, v[1].f, v[2].f),
                scaled_bilinear(k, v[2].f, v[0].f),
            ]
        };
        let edge_margin = |i: usize, j: usize| {
            4.0 * FORM_MARGIN * (v[i].form_scale + v[j].form_scale) * (v[i].norm1 + v[j].norm1)
        };
        let in_upper_hemisphere = v.iter().all(|x| x.surface_z >= 0.0);
        match self.kind() {
            ConicKind::Elliptic => {
                // E⁺ = {q < 0, z > 0}: convex.
                let inside = v.map(|x| x.q < -x.form_margin() && x.f.z > x.linear_margin());
                if in_upper_hemisphere && inside.iter().all(|&i| i) {
                    return Classification::TriangleInsideConic;
                }
                // A vertex inside E⁺, the triangle not: partial. (The edge test below says the
                // same: the edge from that vertex has q(2a) = 4q(a) < 0 at its end t = 1.)
                if inside.iter().any(|&i| i) {
                    return Classification::Partial;
                }
                if let Some(answer) = self.bounding_cap_against_edges(&v) {
                    return answer;
                }
                let q_edge = q_edge();
                let edge_meets_cap = |i: usize| {
                    let (p, r) = (&v[i], &v[(i + 1) % 3]);
                    let side_margin = p.linear_margin() + r.linear_margin();
                    edge_extremum(p, r, q_edge[i], p.f.z, r.f.z, side_margin, false)
                        .is_some_and(|min_q| min_q < edge_margin(i, (i + 1) % 3))
                };
                if (0..3).any(edge_meets_cap) {
                    return Classification::Partial;
                }
                match axis_in_triangle(&v, 2) {
                    Some(true) => Classification::ConicInsideTriangle,
                    Some(false) => Classification::Disjoint,
                    None => Classification::Partial,
                }
            }
            ConicKind::Hyperbolic => {
                // Valid set H \ D⁺, H = {m·ω_i > 0}, D⁺ = {q ≥ 0, y ≥ 0} ⊂ H.
                let (cos_half, sin_half) = self.half_angle_cos_sin();
                let facing = v.map(|x| cos_half * x.f.z + sin_half * x.f.y);
                if (0..3).all(|i| facing[i] < -v[i].linear_margin()) {
                    return Classification::Disjoint;
                }
                if v.iter()
                    .all(|x| x.q > x.form_margin() && x.f.y > x.linear_margin())
                {
                    return Classification::Disjoint;
                }
                if !in_upper_hemisphere || (0..3).any(|i| facing[i] <= v[i].linear_margin()) {
                    return Classification::Partial;
                }
                let q_edge = q_edge();
                let edge_meets_cap = |i: usize| {
                    let (p, r) = (&v[i], &v[(i + 1) % 3]);
                    let side_margin = p.linear_margin() + r.linear_margin();
                    edge_extremum(p, r, q_edge[i], p.f.y, r.f.y, side_margin, true)
                        .is_some_and(|max_q| max_q > -edge_margin(i, (i + 1) % 3))
                };
                if (0..3).any(edge_meets_cap) {
                    return Classification::Partial;
                }
                match axis_in_triangle(&v, 1) {
                    Some(false) => Classification::TriangleInsideConic,
                    _ => Classification::Partial,
                }
            }
        }
    }
}

impl SphericalConic {
    /// How the conic meets the four children of a triangle that holds it (one it classifies
    /// [`Classification::ConicInsideTriangle`]), the children as [`SphericalTriangle::subdivide`]
    /// orders them (the corners at a, b and c, then the centre). The centre child's edges
    /// divide the parent: when the conic's bounding cap lies on one side of each of them, the
    /// child on that side holds the conic and the other three miss it (the valid set lies in
    /// the parent and in the cap). `None` when the cap comes within the margin of an inner
    /// edge, or the conic has no bounding cap: classify the children one by one. Three cross
    /// products instead of four classifications.
    #[must_use]
    pub fn classify_children_of_holder(
        &self,
        children: &[SphericalTriangle; 4],
    ) -> Option<[Classification; 4]> {
        let (axis, _, sin_max) = self.bounding_cap()?;
        let [mab, mbc, mca] = children[3].vertices();
        // The centre's edges, counter-clockwise, and the corner child beyond each.
        let inner_edges = [(mab, mbc, 1), (mbc, mca, 2), (mca, mab, 0)];
        let mut holder = 3;
        for (p, q, corner) in inner_edges {
            // Points into the centre child.
            let edge_normal = p.cross(q);
            match cap_side(axis.dot(edge_normal), edge_normal.length(), sin_max) {
                Some(CapSide::Within) => {}
                Some(CapSide::Beyond) if holder == 3 => holder = corner,
                _ => return None,
            }
        }
        let mut answers = [Classification::Disjoint; 4];
        answers[holder] = Classification::ConicInsideTriangle;
        Some(answers)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Tiny triangles whose farthest vertex (from their centre) lies just inside the conic at the
    /// tip of its major axis, the others outside along the same great circle: the configuration
    /// where the bounding-cap test is tightest. Never disjoint, down to cells of 1e-8 rad.
    #[test]
    fn tiny_triangles_reaching_into_the_conic_are_not_disjoint() {
        let direction = |theta: f64, phi: f64| {
            DVec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            )
        };
        let mut checked = 0;
        for gamma_degrees in [0.5, 5.0, 20.0, 60.0] {
            for (wi, wo) in [
                (direction(0.3, 0.0), direction(0.5, 2.5)),
                (direction(1.2, 1.0), direction(0.1, 4.0)),
                (direction(0.7, 0.0), direction(0.7, 0.0)),
            ] {
                let conic =
                    SphericalConic::new(wi, wo, f64::to_radians(gamma_degrees)).expect("valid");
                let Some((axis, cos_max, sin_max)) = conic.bounding_cap() else {
                    continue;
                };
                let [x, y, _] = conic.frame();
                let tip = sin_max.atan2(cos_max);
                for r in [1e-3, 1e-5, 1e-6, 1e-7, 1e-8] {
                    for side in [1.0, -1.0] {
                        let along = |angle: f64| angle.cos() * axis + side * angle.sin() * x;
                        let inside = along(tip - 1e-3 * r);
                        let outer = along(tip + 2.0 * r);
                        let (b, c) = (outer + r * y, outer - r * y);
                        let triangle = SphericalTriangle::new(inside, b, c).expect("valid");
                        if !conic.contains(triangle.vertices()[0])
                            && !triangle.vertices().iter().any(|&v| conic.contains(v))
                        {
                            continue;
                        }
                        checked += 1;
                        assert_ne!(
                            conic.classify(&triangle),
                            Classification::Disjoint,
                            "γ {gamma_degrees}° r {r}"
                        );
                    }
                }
            }
        }
        assert!(checked >= 80, "{checked}");
    }
}
