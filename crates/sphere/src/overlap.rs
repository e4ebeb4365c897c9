//! The solid angle of spherical triangle ∩ spherical conic (Sec. 3.3, "overlap computations").
//!
//! Alg. 1 (line 12) needs the fraction of a node's directions that lie in the query once the
//! error criterion (Eq. 10) lets it stop early. Two implementations sit behind
//! [`OverlapMethod`]:
//!
//! - [`OverlapMethod::Planar`], the paper's approximation: do the computation in the plane of
//!   the triangle's vertices, where the cone cuts the planar conic, and take
//!   overlap ≈ Ω(T) · area(planar triangle ∩ planar conic) / area(planar triangle).
//!   It ignores that radial projection does not preserve area ratios; the relative error grows
//!   with the square of the triangle's size (measured in the tests and `cargo xtask validate`).
//! - [`OverlapMethod::Precise`], the reference: the same planar region, but measured with the
//!   exact Jacobian of radial (gnomonic) projection. For the plane n̂·p = h with 2D coordinates
//!   (U, V) centred at the foot point h·n̂, dΩ = h / (U² + V² + h²)^{3/2} dU dV. By Stokes'
//!   theorem Ω = ∮ F dV with F = ∫₀^U h/(s² + V² + h²)^{3/2} ds = h·U / ((V² + h²)·√(U² + V² + h²)),
//!   integrated along the boundary by adaptive Gauss–Legendre quadrature (to ~1e-13 relative).
//!
//! # Why the planar region is exact
//! The valid set is defined by the homogeneous quadratic q and linear sign conditions, so a
//! direction is in it exactly when its radial projection onto the triangle's plane is: the
//! planar region {Q < 0, N > 0} is the exact image. Each valid set is built from one convex
//! conic region and half-planes (see [`crate::conic`]): elliptic E⁺ ∩ T; hyperbolic
//! (T ∩ H) minus (T ∩ D⁺), as D⁺ ⊂ H; both clipped to the upper hemisphere m·n ≥ 0.
//!
//! # The conic arcs: Stokes without leaving the plane
//! The paper maps the planar conic to the unit circle or unit hyperbola by a non-uniform
//! scaling, where the 1-form x dy − y dx integrates to the change of angle (or of hyperbolic
//! parameter). Here the same invariant is used without building the map, which degenerates
//! near the parabolic case: a conic arc from P0 to P2 is the rational quadratic Bézier curve
//! with control point the pole of the chord (where the tangents meet) and weight w, with
//! w² = −Q(P0, P2)/(2 Q(P1)) (Q the conic's symmetric bilinear form; this makes
//! Q(B(t)) ≡ 0). The weight is affine-invariant: on the unit circle an arc of half-angle φ has
//! w = cos φ, on the unit hyperbola w = cosh(Δτ/2), and w = 1 on a parabola. The area between
//! the arc and its chord is therefore g(w) times the area of the control triangle, with
//!
//! ```text
//!   g(w) = w (arccos w − w√(1−w²)) / (1−w²)^{3/2}      (w < 1, ellipse: circle segment
//!                                                       φ − sinφ cosφ over sin³φ / cos φ)
//!   g(w) = w (w√(w²−1) − arccosh w) / (w²−1)^{3/2}     (w > 1, hyperbola, by continuation)
//!   g(w) = 2/3 − 2e/15 − 8e²/105 − 16e³/315 − 128e⁴/3465 − …,  e = 1 − w²   (near the parabola; g(1) = 2/3,
//!                                                       Archimedes' parabolic segment)
//! ```
//!
//! Arcs are halved by de Casteljau subdivision (new weight √((1+w)/2)) until w ≥ 0.7, which
//! keeps control points finite for arcs of up to a whole ellipse; the precise method also halves
//! arcs until w ≤ 1.5, so that near-degenerate hyperbolas (at the elliptic–hyperbolic transition
//! the cone degenerates into two planes, and w → ∞) stay easy to integrate.
//!
//! No allocation; the planar method's only transcendental functions are one arccos/arccosh per
//! conic arc piece and the arctangent of the triangle's solid angle.

use glam::{DMat3, DVec2, DVec3};

use crate::classify::Classification;
use crate::conic::{ConicKind, SphericalConic, scaled_bilinear};
use crate::quadrature::{gauss_legendre_8, integrate};
use crate::triangle::SphericalTriangle;

/// How [`overlap_solid_angle`] measures the overlap of a triangle and a conic.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum OverlapMethod {
    /// The paper's planar approximation (fast; error grows as the triangle's size squared).
    #[default]
    Planar,
    /// The exact gnomonic Jacobian integrated along the boundary (reference; ~1e-13 relative).
    Precise,
}

/// The solid angle (steradians) of the directions in `triangle` that lie in `conic`'s valid set.
/// Always finite and within [0, Ω(triangle)].
#[must_use]
pub fn overlap_solid_angle(
    triangle: &SphericalTriangle,
    conic: &SphericalConic,
    method: OverlapMethod,
) -> f64 {
    let triangle_solid_angle = triangle.solid_angle();
    match conic.classify(triangle) {
        Classification::Disjoint => return 0.0,
        Classification::TriangleInsideConic => return triangle_solid_angle,
        Classification::ConicInsideTriangle | Classification::Partial => {}
    }
    let plane = TrianglePlane::new(triangle, conic);
    let result = match method {
        OverlapMethod::Planar => {
            let area = plane.overlap(conic, &PlanarArea);
            let triangle_area = 0.5 * plane.vertices[1].perp_dot(plane.vertices[2]);
            triangle_solid_angle * area / triangle_area
        }
        OverlapMethod::Precise => {
            let integrand = GnomonicSolidAngle {
                foot: plane.foot,
                height: plane.height,
                tolerance: 1e-14 * triangle_solid_angle,
            };
            plane.overlap(conic, &integrand)
        }
    };
    if result.is_finite() {
        result.clamp(0.0, triangle_solid_angle)
    } else {
        // Unreachable for valid triangles; never hand a NaN to the count tree.
        0.5 * triangle_solid_angle
    }
}

/// The share of a density's mass over `triangle` that lies in `conic`'s valid set, for a density
/// that varies linearly across the triangle: `vertex_densities` are its values at the three
/// vertices, and it is interpolated linearly in the plane of the vertices (as the planar
/// overlap measures area there). Where p has a gradient across a cell, the overlap's share of
/// the cell's solid angle misses it: on the flank of a lobe (Beckmann α = 0.1, a cell of 1°)
/// p varies by a third across the cell, and shares by solid angle were 4% low in the mean.
/// Exact for linear densities up to the planar approximation's error; 0 if the density's mass
/// over the triangle is not positive. Always within [0, 1].
#[must_use]
pub fn overlap_share_with_linear_density(
    triangle: &SphericalTriangle,
    conic: &SphericalConic,
    vertex_densities: [f64; 3],
) -> f64 {
    match conic.classify(triangle) {
        Classification::Disjoint => return 0.0,
        Classification::TriangleInsideConic => return 1.0,
        Classification::ConicInsideTriangle | Classification::Partial => {}
    }
    let plane = TrianglePlane::new(triangle, conic);
    let [_, v1, v2] = plane.vertices;
    let [g0, g1, g2] = vertex_densities;
    // f(u, v) = g0 + a·u + b·v through the vertices (0, 0), (u1, 0), (u2, v2).
    let a = (g1 - g0) / v1.x;
    let b = (g2 - g0 - a * v2.x) / v2.y;
    let density = LinearDensity {
        coefficients: DVec3::new(g0, a, b),
    };
    let inside = plane.overlap(conic, &density);
    // A linear function's mean over a triangle is its mean at the vertices.
    let total = 0.5 * v1.perp_dot(v2) * (g0 + g1 + g2) / 3.0;
    let share = inside / total;
    if share.is_finite() && total > 0.0 {
        share.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// The plane through a triangle's vertices, in the conic's standard frame, with 2D coordinates
/// (u, v) whose origin is the first vertex.
struct TrianglePlane {
    /// The triangle's vertices in 2D; the first is the origin and the second is on the u axis.
    vertices: [DVec2; 3],
    /// Columns e1, e2 and the first vertex: p = G·(u, v, 1) in frame coordinates.
    to_frame: DMat3,
    /// The 2D point closest to the sphere's centre, and its distance h from it.
    foot: DVec2,
    height: f64,
    /// The surface normal n in frame coordinates.
    surface_normal: DVec3,
    /// Whether the triangle dips below the horizon and must be clipped to m·n ≥ 0.
    needs_horizon_clip: bool,
}

impl TrianglePlane {
    fn new(triangle: &SphericalTriangle, conic: &SphericalConic) -> Self {
        let [a, b, c] = triangle.vertices();
        let origin = conic.to_frame(a);
        // Edge vectors from world differences keep full relative precision for tiny triangles.
        let edge_ab = conic.to_frame(b - a);
        let edge_ac = conic.to_frame(c - a);
        let normal = edge_ab.cross(edge_ac).normalize();
        let e1 = edge_ab.normalize();
        let e2 = normal.cross(e1);
        let height = normal.dot(origin);
        let [x, y, z] = conic.frame();
        Self {
            vertices: [
                DVec2::ZERO,
                DVec2::new(edge_ab.dot(e1), 0.0),
                DVec2::new(edge_ac.dot(e1), edge_ac.dot(e2)),
            ],
            to_frame: DMat3::from_cols(e1, e2, origin),
            foot: DVec2::new(-origin.dot(e1), -origin.dot(e2)),
            height,
            surface_normal: DVec3::new(x.z, y.z, z.z),
            needs_horizon_clip: a.z < 0.0 || b.z < 0.0 || c.z < 0.0,
        }
    }

    /// A linear function of frame coordinates, restricted to the plane: ℓ·p = l·(u, v, 1).
    fn linear(&self, frame_functional: DVec3) -> DVec3 {
        self.to_frame.transpose() * frame_functional
    }

    /// The scaled quadratic form q restricted to the plane, as a symmetric 3×3 matrix acting on
    /// (u, v, 1).
    fn quadratic(&self, conic: &SphericalConic) -> DMat3 {
        let k = conic.scaled_coefficients();
        let g = [
            self.to_frame.x_axis,
            self.to_frame.y_axis,
            self.to_frame.z_axis,
        ];
        let entry = |i: usize, j: usize| scaled_bilinear(k, g[i], g[j]);
        DMat3::from_cols(
            DVec3::new(entry(0, 0), entry(0, 1), entry(0, 2)),
            DVec3::new(entry(1, 0), entry(1, 1), entry(1, 2)),
            DVec3::new(entry(2, 0), entry(2, 1), entry(2, 2)),
        )
    }

    /// ∫ over (triangle ∩ valid set) of the measure `integral` stands for.
    fn overlap(&self, conic: &SphericalConic, integral: &impl BoundaryIntegral) -> f64 {
        let mut polygon = ConvexPolygon::from_triangle(self.vertices);
        if self.needs_horizon_clip {
            polygon = polygon.clip(self.linear(self.surface_normal));
        }
        let form = self.quadratic(conic);
        match conic.kind() {
            ConicKind::Elliptic => {
                let cap = ConvexConicRegion {
                    form,
                    nappe: self.linear(DVec3::Z),
                };
                cap.area_within(&polygon, integral)
            }
            ConicKind::Hyperbolic => {
                let (cos_half, sin_half) = conic.half_angle_cos_sin();
                let facing = polygon.clip(self.linear(DVec3::new(0.0, sin_half, cos_half)));
                let excluded_cap = ConvexConicRegion {
                    form: -form,
                    nappe: self.linear(DVec3::Y),
                };
                facing.integrate(integral) - excluded_cap.area_within(&facing, integral)
            }
        }
    }
}

/// A measure on the plane, integrated along oriented boundary pieces by Stokes' theorem.
trait BoundaryIntegral {
    /// The contribution of the straight piece from `start` to `end`.
    fn line(&self, start: DVec2, end: DVec2) -> f64;
    /// The contribution of a conic arc piece, with weight in [0.7, [`Self::MAX_ARC_WEIGHT`]].
    fn arc(&self, arc: &RationalArc) -> f64;
    /// Arcs of larger weight are halved first. A hyperbola arc of weight w ≫ 1 hugs its control
    /// polygon and crosses most of it for t within ~1/w of the ends, which defeats quadrature;
    /// each halving maps w to √((1+w)/2).
    const MAX_ARC_WEIGHT: f64;
}

/// Planar area: ½∮(u dv − v du).
struct PlanarArea;

impl BoundaryIntegral for PlanarArea {
    // g(w) is exact for any weight.
    const MAX_ARC_WEIGHT: f64 = f64::INFINITY;

    fn line(&self, start: DVec2, end: DVec2) -> f64 {
        0.5 * start.perp_dot(end)
    }

    fn arc(&self, arc: &RationalArc) -> f64 {
        let weight = arc.control.z;
        let control = arc.control.truncate() / weight;
        let control_triangle = (control - arc.start).perp_dot(arc.end - arc.start).abs();
        // The chord, plus the segment between chord and arc (which bulges outward).
        0.5 * arc.start.perp_dot(arc.end) + conic_segment_ratio(weight) * 0.5 * control_triangle
    }
}

/// A linear density f(u, v) = c₀ + c₁u + c₂v: ∮ F dv with F(u, v) = ∫₀ᵘ f ds
/// = c₀u + c₁u²/2 + c₂uv. Along a line F is quadratic in the parameter, so Simpson's rule is
/// exact; along an arc piece (weight 0.7–1.5, a smooth rational quadratic) the 8-point
/// Gauss–Legendre rule is exact to far below the planar approximation's error.
struct LinearDensity {
    coefficients: DVec3,
}

impl LinearDensity {
    fn potential(&self, p: DVec2) -> f64 {
        let c = self.coefficients;
        p.x * (c.x + 0.5 * c.y * p.x + c.z * p.y)
    }
}

impl BoundaryIntegral for LinearDensity {
    const MAX_ARC_WEIGHT: f64 = 1.5;

    fn line(&self, start: DVec2, end: DVec2) -> f64 {
        let middle = 0.5 * (start + end);
        (self.potential(start) + 4.0 * self.potential(middle) + self.potential(end)) / 6.0
            * (end.y - start.y)
    }

    fn arc(&self, arc: &RationalArc) -> f64 {
        gauss_legendre_8(
            &mut |t| {
                let (point, velocity) = arc.point_and_velocity(t);
                self.potential(point) * velocity.y
            },
            0.0,
            1.0,
        )
    }
}

/// Solid angle: ∮ F dV with F = h·U / ((V² + h²)√(U² + V² + h²)), (U, V) = (u, v) − foot.
struct GnomonicSolidAngle {
    foot: DVec2,
    height: f64,
    tolerance: f64,
}

impl GnomonicSolidAngle {
    fn potential(&self, p: DVec2) -> f64 {
        let d = p - self.foot;
        let h2 = self.height * self.height;
        let v2h2 = d.y * d.y + h2;
        self.height * d.x / (v2h2 * (d.x * d.x + v2h2).sqrt())
    }
}

impl BoundaryIntegral for GnomonicSolidAngle {
    const MAX_ARC_WEIGHT: f64 = 1.5;

    fn line(&self, start: DVec2, end: DVec2) -> f64 {
        let delta = end - start;
        if delta.y == 0.0 {
            return 0.0;
        }
        integrate(
            |t| self.potential(start + t * delta) * delta.y,
            0.0,
            1.0,
            self.tolerance,
        )
    }

    fn arc(&self, arc: &RationalArc) -> f64 {
        integrate(
            |t| {
                let (point, velocity) = arc.point_and_velocity(t);
                self.potential(point) * velocity.y
            },
            0.0,
            1.0,
            self.tolerance,
        )
    }
}

/// g(w): the area between a conic arc of weight w and its chord, over the area of the
/// triangle formed by the chord and the arc's control point (see the module docs).
fn conic_segment_ratio(w: f64) -> f64 {
    // (1 − w)(1 + w) keeps full relative precision near w = 1, where 1 − w² would not.
    let e = (1.0 - w) * (1.0 + w);
    if e.abs() < 1e-3 {
        // Truncation error below 1e-14 for |e| < 1e-3.
        2.0 / 3.0 - e * (2.0 / 15.0 + e * (8.0 / 105.0 + e * (16.0 / 315.0 + e * (128.0 / 3465.0))))
    } else if e > 0.0 {
        let root = e.sqrt();
        w * (w.acos() - w * root) / (e * root)
    } else {
        let root = (-e).sqrt();
        w * (w * root - w.acosh()) / (-e * root)
    }
}

/// How the boundary of a conic region runs between two of its points.
#[derive(Clone, Copy, Debug)]
enum ConicPath {
    /// Along a proper conic arc.
    Arc(RationalArc),
    /// Along two straight pieces meeting at a corner (a degenerate conic: a line pair).
    Corner(DVec2),
    /// Along the straight chord (both points on one line of a line pair; or no arc exists).
    Chord,
}

/// A rational quadratic Bézier arc with end points `start`, `end` (weight 1) and homogeneous
/// control point `control` = (w·P1, w).
#[derive(Clone, Copy, Debug)]
struct RationalArc {
    start: DVec2,
    control: DVec3,
    end: DVec2,
}

impl RationalArc {
    /// The path along the conic `form` from `start` to `end` that bounds the convex region
    /// {form < 0} on its left (counter-clockwise traversal).
    fn of_conic(form: &DMat3, start: DVec2, end: DVec2) -> ConicPath {
        let h0 = start.extend(1.0);
        let h2 = end.extend(1.0);
        let tangent0 = *form * h0;
        let tangent2 = *form * h2;
        let pole = tangent0.cross(tangent2);
        if pole.length_squared() <= 1e-28 * tangent0.length_squared() * tangent2.length_squared() {
            // One tangent line through both points: they lie on a straight part of a
            // degenerate conic (a line pair), and the path is the chord.
            return ConicPath::Chord;
        }
        let chord_form = h0.dot(tangent2);
        let pole_form = pole.dot(*form * pole);
        // Rounding bound of Q(pole): a few ulps of the absolute form |pole|ᵀ|M||pole|.
        let absolute = pole.abs();
        let absolute_form = absolute.dot(
            DMat3::from_cols(form.x_axis.abs(), form.y_axis.abs(), form.z_axis.abs()) * absolute,
        );
        let corner = || {
            // The path turns at the pole: a line pair (at the elliptic–hyperbolic transition
            // the cone degenerates into two planes), or a hyperbola so sharp (w > 1e8) that
            // its control polygon is exact to ~1/w. If the points lie on one line of a pair the
            // pole is rounding noise along it; the caller keeps the corner only inside the
            // polygon, where the path must run.
            if pole.z.abs() <= 1e-14 * pole.truncate().length() {
                ConicPath::Chord
            } else {
                ConicPath::Corner(pole.truncate() / pole.z)
            }
        };
        if pole_form.abs() <= 8.0 * f64::EPSILON * absolute_form {
            return corner();
        }
        let weight_squared_over_pole = -chord_form / (2.0 * pole_form);
        if !(weight_squared_over_pole > 0.0 && weight_squared_over_pole.is_finite()) {
            // The points are on different branches; no arc of the region joins them.
            return ConicPath::Chord;
        }
        if weight_squared_over_pole * pole.z * pole.z > 1e16 {
            return corner();
        }
        let mut control = pole * weight_squared_over_pole.sqrt();
        if control.z.abs() >= 1.0 {
            // A hyperbola or parabola: the finite arc has w ≥ 1; −control passes through
            // infinity.
            if control.z < 0.0 {
                control = -control;
            }
        } else {
            // An ellipse: of the two arcs, the boundary of the region on the left lies to the
            // right of the chord.
            let mid = (start + end + 2.0 * control.truncate()) / (2.0 + 2.0 * control.z);
            if (end - start).perp_dot(mid - start) > 0.0 {
                control = -control;
            }
        }
        if !(1.0 + control.z > 1e-12) {
            return ConicPath::Chord;
        }
        ConicPath::Arc(Self {
            start,
            control,
            end,
        })
    }

    /// The two halves at t = ½ (de Casteljau on homogeneous points), each in standard form.
    fn split(&self) -> [Self; 2] {
        let w = self.control.z;
        let mid = (self.start + self.end + 2.0 * self.control.truncate()) / (2.0 + 2.0 * w);
        let normalize = 1.0 / (2.0 * (1.0 + w)).sqrt();
        [
            Self {
                start: self.start,
                control: (self.start.extend(1.0) + self.control) * normalize,
                end: mid,
            },
            Self {
                start: mid,
                control: (self.control + self.end.extend(1.0)) * normalize,
                end: self.end,
            },
        ]
    }

    /// The point at parameter t ∈ [0, 1] and its derivative with respect to t.
    fn point_and_velocity(&self, t: f64) -> (DVec2, DVec2) {
        let s = 1.0 - t;
        let (p0, p1, p2, w) = (
            self.start,
            self.control.truncate(),
            self.end,
            self.control.z,
        );
        let numerator = s * s * p0 + 2.0 * t * s * p1 + t * t * p2;
        let denominator = s * s + 2.0 * t * s * w + t * t;
        let numerator_dt = 2.0 * (s * (p1 - p0) + t * (p2 - p1));
        let denominator_dt = 2.0 * (s * (w - 1.0) + t * (1.0 - w));
        let point = numerator / denominator;
        let velocity = (numerator_dt - point * denominator_dt) / denominator;
        (point, velocity)
    }

    /// Adds `integral` over this arc, halving it until every piece has a weight in
    /// [0.7, `MAX_ARC_WEIGHT`].
    fn integrate<I: BoundaryIntegral>(&self, integral: &I) -> f64 {
        if (0.7..=I::MAX_ARC_WEIGHT).contains(&self.control.z) {
            return integral.arc(self);
        }
        let [left, right] = self.split();
        left.integrate(integral) + right.integrate(integral)
    }
}

/// A convex polygon of at most [`ConvexPolygon::CAPACITY`] vertices, counter-clockwise.
#[derive(Clone, Copy, Debug)]
struct ConvexPolygon {
    vertices: [DVec2; Self::CAPACITY],
    len: usize,
}

impl ConvexPolygon {
    /// A triangle clipped by two half-planes has at most five vertices.
    const CAPACITY: usize = 6;

    fn from_triangle(v: [DVec2; 3]) -> Self {
        let mut vertices = [DVec2::ZERO; Self::CAPACITY];
        vertices[..3].copy_from_slice(&v);
        Self { vertices, len: 3 }
    }

    fn vertices(&self) -> &[DVec2] {
        &self.vertices[..self.len]
    }

    /// The part where l·(u, v, 1) ≥ 0 (Sutherland–Hodgman with one plane).
    fn clip(&self, line: DVec3) -> Self {
        let mut out = Self {
            vertices: [DVec2::ZERO; Self::CAPACITY],
            len: 0,
        };
        let value = |p: DVec2| line.dot(p.extend(1.0));
        let n = self.len;
        for i in 0..n {
            let (p, q) = (self.vertices[i], self.vertices[(i + 1) % n]);
            let (vp, vq) = (value(p), value(q));
            if vp >= 0.0 && out.len < Self::CAPACITY {
                out.vertices[out.len] = p;
                out.len += 1;
            }
            if (vp >= 0.0) != (vq >= 0.0) && out.len < Self::CAPACITY {
                out.vertices[out.len] = p + (vp / (vp - vq)) * (q - p);
                out.len += 1;
            }
        }
        out
    }

    fn integrate(&self, integral: &impl BoundaryIntegral) -> f64 {
        let v = self.vertices();
        (0..v.len())
            .map(|i| integral.line(v[i], v[(i + 1) % v.len()]))
            .sum()
    }

    /// Whether `p` is inside or within 1e-9 of the polygon's size outside it.
    fn contains_nearly(&self, p: DVec2) -> bool {
        let v = self.vertices();
        let size = (0..v.len())
            .map(|i| (v[i] - v[0]).length())
            .fold(0.0, f64::max);
        (0..v.len()).all(|i| {
            let edge = v[(i + 1) % v.len()] - v[i];
            edge.perp_dot(p - v[i]) >= -1e-9 * size * edge.length()
        })
    }

    fn contains(&self, p: DVec2) -> bool {
        let v = self.vertices();
        (0..v.len()).all(|i| (v[(i + 1) % v.len()] - v[i]).perp_dot(p - v[i]) >= 0.0)
    }
}

/// The convex planar region {form < 0, nappe > 0}, a plane section of one nappe of a convex
/// cone: the inside of an ellipse, a parabola or one branch of a hyperbola.
struct ConvexConicRegion {
    form: DMat3,
    nappe: DVec3,
}

impl ConvexConicRegion {
    /// The parameter interval [t0, t1] ⊂ [0, 1] of the segment p + t(q − p) inside the region
    /// (one interval, by convexity), or `None`.
    fn segment_interval(&self, p: DVec2, q: DVec2) -> Option<(f64, f64)> {
        let hp = p.extend(1.0);
        let hd = (q - p).extend(0.0);
        let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
        let nappe_at_p = self.nappe.dot(hp);
        let nappe_slope = self.nappe.dot(hd);
        if nappe_slope > 0.0 {
            lo = lo.max(-nappe_at_p / nappe_slope);
        } else if nappe_slope < 0.0 {
            hi = hi.min(-nappe_at_p / nappe_slope);
        } else if nappe_at_p <= 0.0 {
            return None;
        }
        if !(lo < hi) {
            return None;
        }
        // form(t) = α t² + 2β t + c.
        let md = self.form * hd;
        let alpha = hd.dot(md);
        let beta = hp.dot(md);
        let c = hp.dot(self.form * hp);
        let (t0, t1) = if alpha == 0.0 {
            if beta > 0.0 {
                (lo, hi.min(-c / (2.0 * beta)))
            } else if beta < 0.0 {
                (lo.max(-c / (2.0 * beta)), hi)
            } else if c < 0.0 {
                (lo, hi)
            } else {
                return None;
            }
        } else {
            let discriminant = beta * beta - alpha * c;
            if discriminant <= 0.0 {
                if alpha > 0.0 {
                    return None;
                }
                (lo, hi)
            } else {
                let k = -(beta + beta.signum() * discriminant.sqrt());
                let (r0, r1) = if k == 0.0 {
                    (0.0, 0.0)
                } else {
                    let (a, b) = (k / alpha, c / k);
                    (a.min(b), a.max(b))
                };
                if alpha > 0.0 {
                    (lo.max(r0), hi.min(r1))
                } else {
                    // Two candidate pieces; convexity allows one (keep the longer on ties).
                    let first = (lo, hi.min(r0));
                    let second = (lo.max(r1), hi);
                    if first.1 - first.0 >= second.1 - second.0 {
                        first
                    } else {
                        second
                    }
                }
            }
        };
        (t0 < t1).then_some((t0, t1))
    }

    /// ∫ over polygon ∩ region, assembling the boundary counter-clockwise: the polygon's edges
    /// inside the region, joined by the conic arcs between an exit and the next entry.
    fn area_within(&self, polygon: &ConvexPolygon, integral: &impl BoundaryIntegral) -> f64 {
        let v = polygon.vertices();
        let n = v.len();
        let mut total = 0.0;
        // (point, whether it is the polygon vertex that ends/starts the edge)
        let mut first_entry: Option<(DVec2, bool)> = None;
        let mut last_exit: Option<(DVec2, bool)> = None;
        for i in 0..n {
            let (p, q) = (v[i], v[(i + 1) % n]);
            let Some((t0, t1)) = self.segment_interval(p, q) else {
                continue;
            };
            let entry = if t0 == 0.0 { p } else { p + t0 * (q - p) };
            let exit = if t1 == 1.0 { q } else { p + t1 * (q - p) };
            match last_exit {
                Some((previous, at_vertex)) => {
                    if !(at_vertex && t0 == 0.0) {
                        total += self.arc(previous, entry, polygon, integral);
                    }
                }
                None => first_entry = Some((entry, t0 == 0.0)),
            }
            total += integral.line(entry, exit);
            last_exit = Some((exit, t1 == 1.0));
        }
        match (first_entry, last_exit) {
            (Some((entry, entry_at_vertex)), Some((exit, exit_at_vertex))) => {
                if !(entry_at_vertex && exit_at_vertex) {
                    total += self.arc(exit, entry, polygon, integral);
                }
                total
            }
            _ => self.whole_ellipse_within(polygon, integral),
        }
    }

    /// The conic's path from `start` to `end` inside `polygon`, integrated.
    fn arc(
        &self,
        start: DVec2,
        end: DVec2,
        polygon: &ConvexPolygon,
        integral: &impl BoundaryIntegral,
    ) -> f64 {
        if start == end {
            return 0.0;
        }
        match RationalArc::of_conic(&self.form, start, end) {
            ConicPath::Arc(arc) => arc.integrate(integral),
            ConicPath::Corner(corner) if polygon.contains_nearly(corner) => {
                integral.line(start, corner) + integral.line(corner, end)
            }
            ConicPath::Corner(_) | ConicPath::Chord => integral.line(start, end),
        }
    }

    /// When no polygon edge meets the region: the whole region if it is a bounded ellipse with
    /// its centre inside the polygon, else nothing.
    fn whole_ellipse_within(
        &self,
        polygon: &ConvexPolygon,
        integral: &impl BoundaryIntegral,
    ) -> f64 {
        if polygon.len < 3 {
            // Clipped away entirely (below the horizon, or facing away from the light).
            return 0.0;
        }
        let m = &self.form;
        let (a11, a12, a22) = (m.x_axis.x, m.y_axis.x, m.y_axis.y);
        let determinant = a11 * a22 - a12 * a12;
        if !(a11 > 0.0 && determinant > 0.0) {
            return 0.0;
        }
        let (b1, b2) = (m.z_axis.x, m.z_axis.y);
        let centre = DVec2::new(a12 * b2 - a22 * b1, a12 * b1 - a11 * b2) / determinant;
        let value_at_centre = m.z_axis.z + b1 * centre.x + b2 * centre.y;
        if !(value_at_centre < 0.0)
            || self.nappe.dot(centre.extend(1.0)) <= 0.0
            || !polygon.contains(centre)
        {
            return 0.0;
        }
        let half_width = DVec2::new((-value_at_centre / a11).sqrt(), 0.0);
        let (left, right) = (centre - half_width, centre + half_width);
        self.arc(right, left, polygon, integral) + self.arc(left, right, polygon, integral)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(theta: f64, phi: f64) -> DVec3 {
        DVec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    }

    /// Triangles of 0.5°–6° about the conics of ω_i, ω_o at 0°–80° (elliptic and hyperbolic),
    /// some across the horizon, with the conic's boundary through them.
    fn weighted_cases() -> Vec<(SphericalTriangle, SphericalConic)> {
        let mut cases = Vec::new();
        for (k, &(theta_i, theta_o, gamma_deg)) in [
            (0.3, 0.2, 2.0f64),
            (1.2, 1.3, 5.0),
            (1.5, 1.4, 10.0),
            (0.0, 0.05, 1.0),
        ]
        .iter()
        .enumerate()
        {
            let conic = SphericalConic::new(
                unit(theta_i, 0.1),
                unit(theta_o, 3.0),
                gamma_deg.to_radians(),
            )
            .expect("conic");
            let half = conic.wi() + conic.wo();
            for size_deg in [0.5, 2.0, 6.0] {
                let size = f64::to_radians(size_deg);
                for shift in [-0.6, 0.0, 0.4] {
                    // A triangle straddling the conic's edge near the half vector.
                    let centre = (half.normalize()
                        + conic.frame()[0] * (0.5 * gamma_deg.to_radians() + shift * size))
                        .normalize();
                    let [x, y, _] = conic.frame();
                    let a = (centre + size * (x + 0.2 * y * k as f64)).normalize();
                    let b = (centre + size * (-0.5 * x + 0.9 * y)).normalize();
                    let c = (centre + size * (-0.4 * x - y)).normalize();
                    if let Ok(t) = SphericalTriangle::new(a, b, c) {
                        cases.push((t, conic));
                    }
                }
            }
        }
        cases
    }

    /// ∫ f over the planar triangle's points in the conic, over ∫ f, on a barycentric grid.
    fn weighted_share_by_grid(t: &SphericalTriangle, conic: &SphericalConic, g: [f64; 3]) -> f64 {
        let [a, b, c] = t.vertices();
        let steps = 600;
        let (mut inside, mut total) = (0.0, 0.0);
        for i in 0..steps {
            for j in 0..steps - i {
                let (x, y) = (
                    (f64::from(i) + 1.0 / 3.0) / f64::from(steps),
                    (f64::from(j) + 1.0 / 3.0) / f64::from(steps),
                );
                let weight = g[0] * (1.0 - x - y) + g[1] * x + g[2] * y;
                let point = a + x * (b - a) + y * (c - a);
                total += weight;
                if conic.contains(point) {
                    inside += weight;
                }
            }
        }
        inside / total
    }

    #[test]
    fn a_constant_density_gives_the_planar_share() {
        for (t, conic) in weighted_cases() {
            let planar = overlap_solid_angle(&t, &conic, OverlapMethod::Planar) / t.solid_angle();
            let weighted = overlap_share_with_linear_density(&t, &conic, [2.0; 3]);
            assert!(
                (planar - weighted).abs() < 1e-9,
                "{planar} against {weighted}"
            );
        }
    }

    #[test]
    fn a_linear_density_weighs_the_overlap() {
        let mut partial = 0;
        for (t, conic) in weighted_cases() {
            for g in [[1.0, 2.0, 3.0], [5.0, 0.1, 1.0], [0.0, 0.0, 1.0]] {
                let exact = overlap_share_with_linear_density(&t, &conic, g);
                let grid = weighted_share_by_grid(&t, &conic, g);
                // The grid's error: about one row of cells along the boundary.
                assert!(
                    (exact - grid).abs() < 2e-3,
                    "{exact} against the grid's {grid}"
                );
                partial += usize::from(exact > 0.01 && exact < 0.99);
            }
        }
        assert!(partial >= 12, "only {partial} cases cut the triangle");
    }

    #[test]
    fn segment_ratio_is_continuous_through_the_parabola() {
        // Circle: half-angle φ, w = cos φ; segment φ − sin φ cos φ over sin³φ / cos φ.
        let phi: f64 = 0.9;
        let expected = (phi - phi.sin() * phi.cos()) * phi.cos() / phi.sin().powi(3);
        assert!((conic_segment_ratio(phi.cos()) - expected).abs() < 1e-14);
        // Both sides of the series' switch point (|1 − w²| = 1e-3), pinned from a 40-digit
        // evaluation of the closed forms.
        for (w, pinned) in [
            (0.999_951, 0.666_653_599_588_388),
            (1.000_049, 0.666_679_732_921_745_3),
            (0.9999, 0.666_639_998_285_612_7),
            (1.0001, 0.666_693_331_619_149_2),
            (0.99, 0.663_982_754_975_140_7),
            (1.01, 0.669_316_291_489_471),
        ] {
            let got = conic_segment_ratio(w);
            assert!(
                (got - pinned).abs() < 2e-13,
                "g({w}) = {got}, expected {pinned}"
            );
        }
        assert!((conic_segment_ratio(1.0) - 2.0 / 3.0).abs() < 1e-16);
        // Values pinned from a 40-digit evaluation.
        assert!((conic_segment_ratio(0.5) - 0.472_799_717_437_430_2).abs() < 1e-14);
        assert!((conic_segment_ratio(2.0) - 0.826_436_002_466_035_8).abs() < 1e-14);
    }

    /// A near-degenerate cone (ω_i ≈ −ω_o near the horizon, γ = 0.01°, λ1 ≈ 1e-5): the planar
    /// section is a sharp hyperbola (w ~ 300), which must not be taken for its corner; the
    /// fraction 0.94435 is the share of 10⁶ points of the triangle in the conic by definition.
    #[test]
    fn sharp_hyperbola_is_not_a_corner() {
        let wi = DVec3::new(
            -0.231_152_004_830_095_32,
            -0.972_917_639_542_587_9,
            0.000_131_643_103_125_275_16,
        );
        let wo = DVec3::new(
            0.231_152_006_576_690_44,
            0.972_917_646_893_997_5,
            4.709_370_053_387_99e-5,
        );
        let conic = SphericalConic::new(wi, wo, 0.000_178_735_804_056_672_06).unwrap();
        let triangle = SphericalTriangle::new(
            DVec3::new(
                -0.424_831_724_648_778_5,
                0.100_922_080_720_517_34,
                0.899_629_223_266_444_2,
            ),
            DVec3::new(
                -0.424_862_566_160_379_9,
                0.100_905_039_236_474_51,
                0.899_616_569_952_056,
            ),
            DVec3::new(
                -0.424_848_069_102_240_2,
                0.100_889_673_651_941_65,
                0.899_625_139_672_354_1,
            ),
        )
        .unwrap();
        for method in [OverlapMethod::Planar, OverlapMethod::Precise] {
            let fraction = overlap_solid_angle(&triangle, &conic, method) / triangle.solid_angle();
            assert!((fraction - 0.944_43).abs() < 5e-4, "{method:?}: {fraction}");
        }
    }

    #[test]
    fn unit_circle_area_from_arcs() {
        // form = u² + v² − 1: the unit disk, inside a big square.
        let region = ConvexConicRegion {
            form: DMat3::from_diagonal(DVec3::new(1.0, 1.0, -1.0)),
            nappe: DVec3::new(0.0, 0.0, 1.0),
        };
        let square = ConvexPolygon {
            vertices: [
                DVec2::new(-2.0, -2.0),
                DVec2::new(2.0, -2.0),
                DVec2::new(2.0, 2.0),
                DVec2::new(-2.0, 2.0),
                DVec2::ZERO,
                DVec2::ZERO,
            ],
            len: 4,
        };
        let area = region.area_within(&square, &PlanarArea);
        assert!((area - std::f64::consts::PI).abs() < 1e-13, "{area}");
        // Half plane v ≥ 0.5 of the disk: the circular segment of half-angle acos(0.5).
        let cut = square.clip(DVec3::new(0.0, 1.0, -0.5));
        let phi = 0.5_f64.acos();
        let expected = phi - phi.sin() * phi.cos();
        let area = region.area_within(&cut, &PlanarArea);
        assert!((area - expected).abs() < 1e-13, "{area} vs {expected}");
        // The complementary part, v ≤ 0.5: an arc of more than half the circle.
        let rest = square.clip(DVec3::new(0.0, -1.0, 0.5));
        let area = region.area_within(&rest, &PlanarArea);
        assert!(
            (area - (std::f64::consts::PI - expected)).abs() < 1e-13,
            "{area}"
        );
    }

    #[test]
    fn hyperbola_and_parabola_segments() {
        // Right branch u² − v² > 1, u > 0, cut by u ≤ 2: area 2·(2√3 − ln(2 + √3))/2.
        let hyperbola = ConvexConicRegion {
            form: DMat3::from_diagonal(DVec3::new(-1.0, 1.0, 1.0)),
            nappe: DVec3::new(1.0, 0.0, 0.0),
        };
        let band = ConvexPolygon::from_triangle([
            DVec2::new(2.0, -10.0),
            DVec2::new(2.0, 10.0),
            DVec2::new(-10.0, 0.0),
        ]);
        let expected = 2.0 * 3.0_f64.sqrt() - (2.0 + 3.0_f64.sqrt()).ln();
        let area = hyperbola.area_within(&band, &PlanarArea);
        assert!((area - expected).abs() < 1e-12, "{area} vs {expected}");
        // Parabola v > u², cut by v ≤ 1: area 4/3.
        let parabola = ConvexConicRegion {
            form: DMat3::from_cols(
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(0.0, 0.0, -0.5),
                DVec3::new(0.0, -0.5, 0.0),
            ),
            nappe: DVec3::new(0.0, 0.0, 1.0),
        };
        let cap = ConvexPolygon::from_triangle([
            DVec2::new(-10.0, 1.0),
            DVec2::new(0.0, -10.0),
            DVec2::new(10.0, 1.0),
        ]);
        let area = parabola.area_within(&cap, &PlanarArea);
        assert!((area - 4.0 / 3.0).abs() < 1e-12, "{area}");
    }
}
