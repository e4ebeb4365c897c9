//! Ray differentials through perfect specular reflection (Igehy 1999, "Tracing Ray
//! Differentials", Sec. 3.3), so that glint materials seen in mirrors get a pixel footprint.
//!
//! A [`RayDifferential`] is carried as two offset rays (the footprint scale apart on the film).
//! At a mirror the offset rays meet the tangent plane at p + ∂p/∂x and p + ∂p/∂y (as at the
//! first hit, [`crate::camera::tangent_plane_offsets`]); the shading normal there is n
//! moved to first order, n + ∂n/∂u·∂u/∂x + ∂n/∂v·∂v/∂x, renormalized; each offset ray leaves
//! from its point, reflected about its normal. The offset rays are never traced through the
//! scene: the next hit intersects them with its own tangent plane.
//!
//! - Planar mirrors (∂n = 0): the reflected offset rays are exactly the rays of the camera
//!   mirrored in the plane, so the footprint in a flat mirror is the virtual camera's footprint
//!   (tested by `glint_tests::mirror_check`, `tests/tests/footprints.rs`).
//! - Spheres: ∂n/∂u = (∂p/∂u)/r, ∂n/∂v = (∂p/∂v)/r, exact; the transfer through the tangent
//!   plane is first order, so the footprint is the first-order one.
//! - Meshes: the derivative of the interpolated vertex normal within the hit triangle
//!   ([`Mesh::shading_normal_derivatives`]); flat-shaded triangles count as planar, so a
//!   faceted curved mirror's footprint ignores the normal's jumps between facets.
//!
//! Where a path meets a non-specular surface, it stops carrying differentials: glossy and
//! diffuse reflection spread a pixel over a large solid angle, the footprint a single path
//! sample would need is not defined by the pixel alone, and glint materials there evaluate their
//! smooth limit (with their glint sampler), as they do after the first hit under
//! [`crate::GlintFootprints::FirstHit`].

use glam::{DVec2, DVec3};

use crate::accel::Geometry;
use crate::camera::{RayDifferential, tangent_plane_offsets, uv_derivatives};
use crate::mesh::Mesh;
use crate::shape::{Ray, SurfaceHit};

/// `direction` reflected about the unit `normal` (either orientation): d − 2(d·n)n.
#[must_use]
pub fn reflect(direction: DVec3, normal: DVec3) -> DVec3 {
    direction - 2.0 * direction.dot(normal) * normal
}

/// (∂n/∂u, ∂n/∂v) of the unit shading normal of `hit` on `geometry` (see the module
/// documentation); `meshes` are the scene's meshes.
#[must_use]
pub fn normal_derivatives(
    geometry: &Geometry,
    meshes: &[Mesh],
    hit: &SurfaceHit,
) -> (DVec3, DVec3) {
    match geometry {
        // n = (p − c)/r.
        Geometry::Sphere(sphere) => (hit.dpdu / sphere.radius, hit.dpdv / sphere.radius),
        Geometry::Rectangle(_) => (DVec3::ZERO, DVec3::ZERO),
        Geometry::Triangle { mesh, triangle } => meshes
            .get(*mesh as usize)
            .map_or((DVec3::ZERO, DVec3::ZERO), |m| {
                m.shading_normal_derivatives(*triangle as usize, hit.point)
            }),
    }
}

/// The differential of `reflected` (the main ray mirrored at `hit` about its shading normal):
/// `incoming`'s offset rays reflected at their points on the tangent plane, about the shading
/// normal moved by `dn` = (∂n/∂u, ∂n/∂v). `None` when an offset ray misses the tangent plane or
/// the tangents are degenerate on a curved surface: the path then carries no footprint.
#[must_use]
pub fn reflected_differential(
    hit: &SurfaceHit,
    dn: (DVec3, DVec3),
    incoming: &RayDifferential,
    reflected: Ray,
) -> Option<RayDifferential> {
    let (dpdx, dpdy) = tangent_plane_offsets(hit, incoming)?;
    let planar = dn.0 == DVec3::ZERO && dn.1 == DVec3::ZERO;
    let (duv_dx, duv_dy) = if planar {
        (DVec2::ZERO, DVec2::ZERO)
    } else {
        uv_derivatives(hit, dpdx, dpdy)?
    };
    let n = hit.shading_normal;
    let offset = |ray: &Ray, dp: DVec3, duv: DVec2| -> Option<Ray> {
        let normal = if planar {
            n
        } else {
            (n + dn.0 * duv.x + dn.1 * duv.y).try_normalize()?
        };
        let direction = reflect(ray.direction, normal);
        direction.is_finite().then_some(Ray {
            origin: hit.point + dp,
            direction,
        })
    };
    Some(RayDifferential {
        ray: reflected,
        rx: offset(&incoming.rx, dpdx, duv_dx)?,
        ry: offset(&incoming.ry, dpdy, duv_dy)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{CameraPose, CameraView, texture_footprint};
    use crate::shape::{Rectangle, Sphere};

    fn hit_sphere(sphere: &Sphere, ray: &Ray) -> Option<SurfaceHit> {
        sphere
            .intersect(ray, 1e-9, f64::INFINITY)
            .map(|t| sphere.surface(ray, t))
    }

    /// A curved mirror: the footprint on a plane seen in a sphere, from the propagated
    /// differentials, against the one measured by tracing the neighbouring pixels' rays through
    /// the reflection and differencing their (u, v). First order: the error shrinks with the
    /// pixel size.
    #[test]
    fn sphere_reflection_matches_neighbouring_pixels() {
        let sphere = Sphere {
            center: DVec3::ZERO,
            radius: 1.0,
        };
        let floor = Rectangle::new(
            DVec3::new(0.0, -1.5, 0.0),
            DVec3::new(0.0, 0.0, -20.0),
            DVec3::new(20.0, 0.0, 0.0),
        )
        .unwrap();
        let pose = CameraPose {
            position: DVec3::new(0.0, 0.5, 5.0),
            look_at: DVec3::ZERO,
            up: DVec3::Y,
            fov_degrees: 30.0,
        };
        let bounce = |ray: &Ray| -> Option<(SurfaceHit, Ray)> {
            let hit = hit_sphere(&sphere, ray)?;
            let reflected = Ray {
                origin: hit.point + 1e-9 * hit.geometric_normal,
                direction: reflect(ray.direction, hit.shading_normal),
            };
            Some((hit, reflected))
        };
        let on_floor = |ray: &Ray| {
            floor
                .intersect(ray, 1e-9, f64::INFINITY)
                .map(|t| floor.surface(ray, t))
        };
        for (width, tolerance) in [(400u32, 0.08), (4000, 0.008)] {
            let view = CameraView::new(&pose, width, width);
            let mut checked = 0;
            for i in 0..64 {
                let film = DVec2::new(
                    f64::from(width) * (0.3 + 0.4 * f64::from(i % 8) / 7.0),
                    f64::from(width) * (0.5 + 0.2 * f64::from(i / 8) / 7.0),
                );
                let differential = view.ray_differential(film, 1.0);
                let traced = [differential.ray, differential.rx, differential.ry]
                    .map(|r| bounce(&r).and_then(|(_, reflected)| on_floor(&reflected)));
                let [Some(main), Some(hx), Some(hy)] = traced else {
                    continue;
                };
                let (hit, reflected) = bounce(&differential.ray).unwrap();
                let dn = normal_derivatives(&Geometry::Sphere(sphere), &[], &hit);
                let carried = reflected_differential(&hit, dn, &differential, reflected).unwrap();
                let (dx, dy) = texture_footprint(&main, &carried).unwrap();
                let (mx, my) = (hx.uv - main.uv, hy.uv - main.uv);
                let scale = mx.length().max(my.length());
                assert!((dx - mx).length() <= tolerance * scale, "{dx} vs {mx}");
                assert!((dy - my).length() <= tolerance * scale, "{dy} vs {my}");
                // Curvature matters: ignoring ∂n would be far off.
                let flat = reflected_differential(
                    &hit,
                    (DVec3::ZERO, DVec3::ZERO),
                    &differential,
                    reflected,
                )
                .unwrap();
                let (fx, fy) = texture_footprint(&main, &flat).unwrap();
                let flat_error = (fx - mx).length().max((fy - my).length());
                assert!(flat_error > 0.3 * scale, "{fx}, {fy} vs {mx}, {my}");
                checked += 1;
            }
            assert!(checked >= 30, "checked {checked}");
        }
    }

    /// Mesh normal derivatives against central differences of the interpolated normal.
    #[test]
    fn mesh_normal_derivatives_match_finite_differences() {
        let mesh = Mesh {
            positions: vec![
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(2.0, 0.1, 0.0),
                DVec3::new(0.3, 0.0, -1.5),
            ],
            normals: vec![
                DVec3::new(0.1, 1.0, 0.2).normalize(),
                DVec3::new(-0.3, 1.0, 0.0).normalize(),
                DVec3::new(0.0, 1.0, -0.4).normalize(),
            ],
            uvs: vec![
                DVec2::new(0.1, 0.2),
                DVec2::new(0.9, 0.3),
                DVec2::new(0.2, 0.8),
            ],
            triangles: vec![[0, 1, 2]],
        };
        let at = |b1: f64, b2: f64| mesh.surface(0, 1.0, b1, b2);
        let hit = at(0.3, 0.25);
        let (dndu, dndv) = mesh.shading_normal_derivatives(0, hit.point);
        // A step in (u, v) as a step in barycentrics: [Δuv₁ Δuv₂] (db1, db2) = duv.
        let h = 1e-6;
        let step = |du: DVec2| {
            let (a, b) = (DVec2::new(0.8, 0.1), DVec2::new(0.1, 0.6));
            let det = a.perp_dot(b);
            let db1 = (b.y * du.x - b.x * du.y) / det;
            let db2 = (a.x * du.y - a.y * du.x) / det;
            (at(0.3 + db1, 0.25 + db2).shading_normal - at(0.3 - db1, 0.25 - db2).shading_normal)
                / (2.0 * h)
        };
        let (fu, fv) = (step(DVec2::new(h, 0.0)), step(DVec2::new(0.0, h)));
        assert!((fu - dndu).length() < 1e-6, "{fu} {dndu}");
        assert!((fv - dndv).length() < 1e-6, "{fv} {dndv}");
        assert!(dndu.length() > 0.1);
    }
}
