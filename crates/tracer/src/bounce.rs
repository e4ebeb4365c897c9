//! The local geometry of a bounce: shading frames, ray origins offset off the surface, and the
//! reflection of a ray and of its ray differential at a perfect mirror. Shared by the
//! integrators, the light cones and the prior run ([`crate::plan`]).

use glam::DVec3;
use glint_brdf::frame::orthonormal_basis;

use crate::accel::Primitive;
use crate::camera::RayDifferential;
use crate::differentials::{
    glossy_differential, normal_derivatives, reflect, reflected_differential,
};
use crate::scene::Scene;
use crate::shape::{Ray, SurfaceHit};

/// The ray reflected by a perfect mirror at `surface` (about the shading normal of `frame`),
/// or `None` when it would leave below the geometric normal.
pub(crate) fn mirror_reflection(
    surface: &SurfaceHit,
    frame: &Frame,
    geometric_normal: DVec3,
    incoming: &Ray,
) -> Option<Ray> {
    let direction = reflect(incoming.direction, frame.n);
    (direction.dot(geometric_normal) > 0.0).then(|| Ray {
        origin: offset_origin(surface.point, geometric_normal, direction),
        direction,
    })
}

/// The ray differential `incoming` carried through the mirror bounce at `surface` of
/// `primitive` onto `reflected` (see [`crate::differentials`]), or `None` when it is lost.
pub(crate) fn mirror_differential(
    scene: &Scene,
    primitive: &Primitive,
    surface: &SurfaceHit,
    incoming: &RayDifferential,
    reflected: Ray,
) -> Option<RayDifferential> {
    let dn = normal_derivatives(&primitive.geometry, scene.accelerator.meshes(), surface);
    reflected_differential(surface, dn, incoming, reflected)
}

/// The ray differential `incoming` carried through a glossy bounce at `surface` of
/// `primitive` onto `reflected`, the sample of a lobe of roughness `alpha` that reflected the
/// local `wi` into `wo` in `frame` (about their half vector; see
/// [`crate::differentials::glossy_differential`]), or `None` when it is lost or the lobe is too
/// rough to carry a footprint.
#[allow(clippy::too_many_arguments)]
pub(crate) fn glossy_bounce_differential(
    scene: &Scene,
    primitive: &Primitive,
    surface: &SurfaceHit,
    frame: &Frame,
    (wi, wo): (DVec3, DVec3),
    alpha: f64,
    incoming: &RayDifferential,
    reflected: Ray,
) -> Option<RayDifferential> {
    if !(alpha <= crate::differentials::GLOSSY_FOOTPRINT_MAX_ALPHA) {
        return None;
    }
    let facet = frame.to_world((wi + wo).try_normalize()?);
    let dn = normal_derivatives(&primitive.geometry, scene.accelerator.meshes(), surface);
    glossy_differential(surface, facet, alpha, dn, incoming, reflected)
}

/// A local shading frame: z the shading normal, x along ∂p/∂u.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Frame {
    pub(crate) t: DVec3,
    pub(crate) b: DVec3,
    pub(crate) n: DVec3,
}

impl Frame {
    /// Two-sided shading: the geometric normal and the shading frame turned to face the side
    /// a ray travelling along `direction` arrives from.
    pub(crate) fn facing(surface: &SurfaceHit, direction: DVec3) -> (DVec3, Self) {
        let facing = if direction.dot(surface.geometric_normal) > 0.0 {
            -1.0
        } else {
            1.0
        };
        (
            surface.geometric_normal * facing,
            Self::new(surface.shading_normal * facing, surface.dpdu),
        )
    }

    pub(crate) fn new(n: DVec3, dpdu: DVec3) -> Self {
        let t = dpdu - n * n.dot(dpdu);
        let t = if t.length_squared() > 1e-24 * dpdu.length_squared().max(1e-300) && t.is_finite() {
            t.normalize()
        } else {
            orthonormal_basis(n).0
        };
        Self {
            t,
            b: n.cross(t),
            n,
        }
    }
    pub(crate) fn to_local(self, w: DVec3) -> DVec3 {
        DVec3::new(w.dot(self.t), w.dot(self.b), w.dot(self.n))
    }
    pub(crate) fn to_world(self, w: DVec3) -> DVec3 {
        w.x * self.t + w.y * self.b + w.z * self.n
    }
}

/// A ray origin on the side of the surface that `direction` leaves by.
pub(crate) fn offset_origin(point: DVec3, normal: DVec3, direction: DVec3) -> DVec3 {
    let eps = 1e-9 * (1.0 + point.abs().max_element());
    if direction.dot(normal) >= 0.0 {
        point + eps * normal
    } else {
        point - eps * normal
    }
}
