//! Rays, surface hits and the analytic shapes: spheres and rectangles (parallelograms).
//! Every hit carries its texture coordinates (u, v) and the tangents ∂p/∂u, ∂p/∂v that turn ray
//! differentials into texture-space footprints ([`crate::camera::texture_footprint`]).

use glam::{DVec2, DVec3};
use std::f64::consts::PI;

/// A ray o + t·d, t ∈ (0, t_max).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin.
    pub origin: DVec3,
    /// Direction (unit length).
    pub direction: DVec3,
}

impl Ray {
    /// The point at parameter `t`.
    #[must_use]
    pub fn at(&self, t: f64) -> DVec3 {
        self.origin + t * self.direction
    }
}

/// The geometry of a ray's hit on a surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    /// Ray parameter of the hit.
    pub t: f64,
    /// The point.
    pub point: DVec3,
    /// The unit geometric normal, on the shape's front side (not flipped toward the ray).
    pub geometric_normal: DVec3,
    /// The unit shading normal (interpolated on meshes), on the same side as the geometric one.
    pub shading_normal: DVec3,
    /// Texture coordinates.
    pub uv: DVec2,
    /// ∂p/∂u.
    pub dpdu: DVec3,
    /// ∂p/∂v.
    pub dpdv: DVec3,
}

/// A sphere with the (u, v) parameterization u = φ/2π, v = 1 − θ/π, θ measured from +y and φ
/// from +x toward −z: p = c + r (sin θ cos φ, cos θ, −sin θ sin φ). An image texture then
/// appears upright and unmirrored seen from outside (v = 1, the image's top row, at +y).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub center: DVec3,
    /// Radius (> 0).
    pub radius: f64,
}

impl Sphere {
    /// The nearest ray parameter in (t_min, t_max) where the ray meets the sphere.
    #[must_use]
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<f64> {
        // |o + t d − c|² = r² with |d| = 1: t² + 2 b t + c = 0, solved in the stable form with
        // the discriminant computed from the perpendicular distance (Hearn and Baker; pbrt-v4).
        let oc = ray.origin - self.center;
        let b = oc.dot(ray.direction);
        let perpendicular = oc - b * ray.direction;
        let discriminant = self.radius * self.radius - perpendicular.length_squared();
        if !(discriminant >= 0.0) {
            return None;
        }
        let root = discriminant.sqrt();
        let c = oc.length_squared() - self.radius * self.radius;
        let q = -b - root.copysign(b);
        let (t0, t1) = if q == 0.0 {
            (0.0, 0.0)
        } else {
            let (a, b) = (q, c / q);
            (a.min(b), a.max(b))
        };
        [t0, t1].into_iter().find(|&t| t > t_min && t < t_max)
    }

    /// The hit at ray parameter `t`.
    #[must_use]
    pub fn surface(&self, ray: &Ray, t: f64) -> SurfaceHit {
        let point = ray.at(t);
        let normal = ((point - self.center) / self.radius).normalize();
        self.surface_at(normal, t)
    }

    /// The surface at the unit direction `normal` from the centre.
    #[must_use]
    pub fn surface_at(&self, normal: DVec3, t: f64) -> SurfaceHit {
        let theta = normal.y.clamp(-1.0, 1.0).acos();
        let mut phi = (-normal.z).atan2(normal.x);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let (sin_theta, cos_theta) = theta.sin_cos();
        let (sin_phi, cos_phi) = phi.sin_cos();
        let r = self.radius;
        // ∂p/∂u = 2π ∂p/∂φ; ∂p/∂v = −π ∂p/∂θ (θ = π(1 − v)).
        let dpdu = 2.0 * PI * r * DVec3::new(-sin_theta * sin_phi, 0.0, -sin_theta * cos_phi);
        let dpdv = -PI * r * DVec3::new(cos_theta * cos_phi, -sin_theta, -cos_theta * sin_phi);
        SurfaceHit {
            t,
            point: self.center + r * normal,
            geometric_normal: normal,
            shading_normal: normal,
            uv: DVec2::new(phi / (2.0 * PI), 1.0 - theta / PI),
            dpdu,
            dpdv,
        }
    }

    /// The axis-aligned bounds.
    #[must_use]
    pub fn bounds(&self) -> (DVec3, DVec3) {
        (
            self.center - DVec3::splat(self.radius),
            self.center + DVec3::splat(self.radius),
        )
    }
}

/// A parallelogram {corner + s·edge_u + t·edge_v : s, t ∈ [0, 1]} with (u, v) = (s, t); its
/// front side is edge_u × edge_v.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rectangle {
    /// The corner at (u, v) = (0, 0).
    pub corner: DVec3,
    /// The edge along u.
    pub edge_u: DVec3,
    /// The edge along v.
    pub edge_v: DVec3,
    normal: DVec3,
    /// Rows of the map from p − corner to (s, t) within the plane (the dual basis).
    dual_u: DVec3,
    dual_v: DVec3,
}

impl Rectangle {
    /// The parallelogram centred at `center` with edges `edge_u`, `edge_v`, or `None` when the
    /// edges are parallel or not finite.
    #[must_use]
    pub fn new(center: DVec3, edge_u: DVec3, edge_v: DVec3) -> Option<Self> {
        let cross = edge_u.cross(edge_v);
        let area_squared = cross.length_squared();
        if !(area_squared > 0.0 && area_squared.is_finite() && center.is_finite()) {
            return None;
        }
        // p − corner = s·u + t·v: s = (v × n)·(p − corner)/|u × v|² etc.
        let dual_u = edge_v.cross(cross) / area_squared;
        let dual_v = cross.cross(edge_u) / area_squared;
        Some(Self {
            corner: center - 0.5 * edge_u - 0.5 * edge_v,
            edge_u,
            edge_v,
            normal: cross / area_squared.sqrt(),
            dual_u,
            dual_v,
        })
    }

    /// The unit normal of the front side.
    #[must_use]
    pub fn normal(&self) -> DVec3 {
        self.normal
    }

    /// The area.
    #[must_use]
    pub fn area(&self) -> f64 {
        self.edge_u.cross(self.edge_v).length()
    }

    /// The point at (s, t).
    #[must_use]
    pub fn point(&self, s: f64, t: f64) -> DVec3 {
        self.corner + s * self.edge_u + t * self.edge_v
    }

    /// The ray parameter in (t_min, t_max) where the ray meets the parallelogram.
    #[must_use]
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<f64> {
        let denominator = ray.direction.dot(self.normal);
        if denominator == 0.0 {
            return None;
        }
        let t = (self.corner - ray.origin).dot(self.normal) / denominator;
        if !(t > t_min && t < t_max) {
            return None;
        }
        let (s, v) = self.parameters(ray.at(t));
        ((0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&v)).then_some(t)
    }

    /// (s, t) of a point in the plane.
    #[must_use]
    pub fn parameters(&self, point: DVec3) -> (f64, f64) {
        let d = point - self.corner;
        (d.dot(self.dual_u), d.dot(self.dual_v))
    }

    /// The hit at ray parameter `t`.
    #[must_use]
    pub fn surface(&self, ray: &Ray, t: f64) -> SurfaceHit {
        let point = ray.at(t);
        let (s, v) = self.parameters(point);
        SurfaceHit {
            t,
            point,
            geometric_normal: self.normal,
            shading_normal: self.normal,
            uv: DVec2::new(s, v),
            dpdu: self.edge_u,
            dpdv: self.edge_v,
        }
    }

    /// The axis-aligned bounds.
    #[must_use]
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let corners = [
            self.corner,
            self.corner + self.edge_u,
            self.corner + self.edge_v,
            self.corner + self.edge_u + self.edge_v,
        ];
        let min = corners.iter().fold(DVec3::INFINITY, |m, c| m.min(*c));
        let max = corners.iter().fold(DVec3::NEG_INFINITY, |m, c| m.max(*c));
        (min, max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(origin: DVec3, target: DVec3) -> Ray {
        Ray {
            origin,
            direction: (target - origin).normalize(),
        }
    }

    /// ∂p/∂u and ∂p/∂v of a surface against central differences of its parameterization.
    fn check_tangents(hit: &SurfaceHit, point_at: impl Fn(DVec2) -> DVec3) {
        let h = 1e-6;
        let du = (point_at(hit.uv + DVec2::new(h, 0.0)) - point_at(hit.uv - DVec2::new(h, 0.0)))
            / (2.0 * h);
        let dv = (point_at(hit.uv + DVec2::new(0.0, h)) - point_at(hit.uv - DVec2::new(0.0, h)))
            / (2.0 * h);
        assert!(
            (du - hit.dpdu).length() < 1e-6 * (1.0 + du.length()),
            "{du} {}",
            hit.dpdu
        );
        assert!(
            (dv - hit.dpdv).length() < 1e-6 * (1.0 + dv.length()),
            "{dv} {}",
            hit.dpdv
        );
        assert!((point_at(hit.uv) - hit.point).length() < 1e-9);
        // The normal is perpendicular to both tangents.
        assert!(hit.geometric_normal.dot(hit.dpdu).abs() < 1e-9 * hit.dpdu.length().max(1.0));
        assert!(hit.geometric_normal.dot(hit.dpdv).abs() < 1e-9 * hit.dpdv.length().max(1.0));
    }

    #[test]
    fn sphere_hits_lie_on_the_sphere_with_consistent_tangents() {
        let sphere = Sphere {
            center: DVec3::new(0.3, -0.2, 1.0),
            radius: 0.7,
        };
        let point_at = |uv: DVec2| {
            let (phi, theta) = (2.0 * PI * uv.x, PI * (1.0 - uv.y));
            let direction = DVec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                -theta.sin() * phi.sin(),
            );
            sphere.center + sphere.radius * direction
        };
        let mut hits = 0;
        for i in 0..200 {
            let a = f64::from(i) * 0.37;
            let origin = DVec3::new(3.0 * a.cos(), 2.0 * (a * 1.7).sin(), 3.0 * a.sin() + 1.0);
            let target = sphere.center + 0.5 * DVec3::new((a * 3.1).sin(), (a * 2.3).cos(), 0.2);
            let r = ray(origin, target);
            let t = sphere
                .intersect(&r, 0.0, f64::INFINITY)
                .expect("aimed inside");
            let hit = sphere.surface(&r, t);
            assert!(((hit.point - sphere.center).length() - sphere.radius).abs() < 1e-12);
            assert!(
                hit.geometric_normal.dot(r.direction) < 0.0,
                "nearest hit faces the ray"
            );
            check_tangents(&hit, point_at);
            hits += 1;
        }
        assert_eq!(hits, 200);
        // From inside, the far side; missing rays miss.
        let inside = ray(sphere.center, sphere.center + DVec3::X);
        let t = sphere.intersect(&inside, 0.0, f64::INFINITY).unwrap();
        assert!((t - sphere.radius).abs() < 1e-12);
        let miss = ray(DVec3::new(0.0, 5.0, 0.0), DVec3::new(5.0, 5.0, 0.0));
        assert_eq!(sphere.intersect(&miss, 0.0, f64::INFINITY), None);
    }

    #[test]
    fn rectangle_hits_and_tangents() {
        let rect = Rectangle::new(
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(2.0, 0.0, 0.5),
            DVec3::new(0.0, 0.3, -1.5),
        )
        .unwrap();
        let point_at = |uv: DVec2| rect.point(uv.x, uv.y);
        for i in 0..100 {
            let (s, t) = (
                f64::from(i % 10) / 10.0 + 0.05,
                f64::from(i / 10) / 10.0 + 0.05,
            );
            let target = rect.point(s, t);
            let r = ray(DVec3::new(0.5, 4.0, 2.0), target);
            let hit_t = rect
                .intersect(&r, 0.0, f64::INFINITY)
                .expect("aimed inside");
            let hit = rect.surface(&r, hit_t);
            assert!((hit.uv - DVec2::new(s, t)).length() < 1e-12);
            check_tangents(&hit, point_at);
        }
        let outside = ray(DVec3::new(0.5, 4.0, 2.0), rect.point(1.2, 0.5));
        assert_eq!(rect.intersect(&outside, 0.0, f64::INFINITY), None);
        assert!(Rectangle::new(DVec3::ZERO, DVec3::X, 2.0 * DVec3::X).is_none());
    }
}
