//! Ray differentials through perfect specular reflection (Igehy 1999, "Tracing Ray
//! Differentials", Sec. 3.3), and through near-specular glossy reflection (the same transfer
//! about the sampled facet normal, widened by the lobe's spread as ray cones are: Akenine-Möller
//! et al. 2019, "Texture Level of Detail Strategies for Real-Time Ray Tracing", and 2021,
//! "Improved Shader and Texture Level of Detail Using Ray Cones"), so that glint materials seen
//! in mirrors, polished metal and glossy coats get a pixel footprint.
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
//! # Glossy reflection ([`glossy_differential`])
//!
//! A conductor or a plastic coat of roughness α reflects a path about a sampled facet normal m
//! (the half vector of ω_i and the sampled ω_o). The pixel's light there comes from every
//! direction of the lobe, so the region of the next surface one path sample stands for is the
//! pixel's footprint *spread by the lobe*. Two steps:
//!
//! 1. **Transfer about m**, as at a mirror: the offset rays meet the tangent plane and are
//!    reflected about m moved to first order by the normal's derivatives, m + ∂n/∂u·∂u/∂x +
//!    ∂n/∂v·∂v/∂x (the facet turns with the surface; exact for m = n, where it is the mirror's
//!    transfer bit for bit).
//! 2. **Widening by the lobe.** In the plane perpendicular to the reflected ray ω, the offset
//!    rays' direction offsets form a 2 × 2 matrix D (columns: per pixel step in x and in y),
//!    so the footprint at distance t is, far from the reflector, the parallelogram t·D. A
//!    parallelogram spanned by D's columns, used as a box filter, has the second moments
//!    DDᵀ/12. The lobe adds an independent spread of the direction: for Beckmann, slopes are
//!    N(0, α²/2) per axis, facet normals tilt by the slope, and a reflection turns by twice the
//!    tilt, so the reflected direction has a standard deviation σ = √2·α per axis (in the plane
//!    of incidence; out of it the turn is shortened by cos θ_h, which is ignored: the widening
//!    is isotropic, the larger). Second moments add: the widened footprint's matrix D′ must
//!    satisfy D′D′ᵀ/12 = DDᵀ/12 + σ²I, that is D′D′ᵀ = DDᵀ + w²I with the edge widening
//!    w = √12·σ = √24·α ([`GLOSSY_SPREAD_PER_ALPHA`]). Among the D′ with that product the one
//!    keeping D's orientation is D′ = (DDᵀ + w²I)^½·U, with D = (DDᵀ)^½·U the polar
//!    decomposition of D; along each principal axis of the pixel's spread, of length λ, the
//!    edge becomes √(λ² + w²): the footprint axes grow in quadrature, as ray cones widen their
//!    spread angle by the lobe's (Akenine-Möller et al. add the angles; adding variances is what
//!    convolving the pixel with the lobe gives). GGX takes the same w at equal α (its core is
//!    narrower, its tails heavier; its slope variance is infinite, so no moment matches). The
//!    offset rays' origins stay on the reflector: near it the footprint is the reflector's own.
//!
//! As α → 0, m → n and w → 0: D′ → D, and the propagation is the perfect mirror's. An edge
//! of λ rad grows by √(1 + (w/λ)²) − 1 ≈ ½(w/λ)²: at α = 10⁻⁴, the smallest accepted
//! (w = 4.9·10⁻⁴ rad), by 0.16% for the 8.7·10⁻³ rad pixels of the virtual-camera test
//! (`glint_tests::mirror_check`, where the glints match the mirror's) and by 4% for pixels of
//! 1.75·10⁻³ rad, a real blur of a lobe that is not quite a mirror. As α grows the
//! footprint widens, glints average over more particles and fade toward the smooth limit.
//! Past [`GLOSSY_FOOTPRINT_MAX_ALPHA`] (w ≈ 0.25 rad, a 14° cone per path sample: a footprint
//! a quarter as wide as its distance, over which glitter of any density worth rendering is
//! near its smooth limit, and past which a first-order transfer of the offset rays is no
//! longer a fair description) the footprint ends.
//!
//! Diffuse bounces, glint bounces (a flake's reflection is not a lobe) and lobes rougher than
//! [`GLOSSY_FOOTPRINT_MAX_ALPHA`] end the differentials: glint materials reached after one are
//! evaluated by their smooth limit (with their glint sampler), as they are after the first hit
//! under [`crate::GlintFootprints::FirstHit`].

use glam::{DVec2, DVec3};

use glint_brdf::frame::orthonormal_basis;

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

/// The edge widening w of a glossy lobe per unit roughness: w = √24·α (see the module
/// documentation: √12 for a box's second moment, √2 for Beckmann's reflected-direction spread).
pub const GLOSSY_SPREAD_PER_ALPHA: f64 = 4.898_979_485_566_356;

/// The roughest lobe that carries a footprint on: max(α_x, α_y) ≤ 0.05, a widening w ≈ 0.245
/// rad. Rougher lobes end the differentials (see the module documentation).
pub const GLOSSY_FOOTPRINT_MAX_ALPHA: f64 = 0.05;

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
    reflected_about(hit, hit.shading_normal, dn, incoming, reflected)
}

/// The differential of `reflected` (the main ray reflected at `hit` about the unit facet normal
/// `facet`, drawn from a lobe of roughness `alpha`): `incoming`'s offset rays reflected about
/// `facet` moved by `dn` = (∂n/∂u, ∂n/∂v), then their direction offsets widened in quadrature
/// by w = [`GLOSSY_SPREAD_PER_ALPHA`]·`alpha` ([`widened`]). `None` where
/// [`reflected_differential`] gives `None`, for `alpha` above
/// [`GLOSSY_FOOTPRINT_MAX_ALPHA`] or not finite, and for a facet that is not a unit vector.
#[must_use]
pub fn glossy_differential(
    hit: &SurfaceHit,
    facet: DVec3,
    alpha: f64,
    dn: (DVec3, DVec3),
    incoming: &RayDifferential,
    reflected: Ray,
) -> Option<RayDifferential> {
    if !(0.0..=GLOSSY_FOOTPRINT_MAX_ALPHA).contains(&alpha) {
        return None;
    }
    // The facet turns with the shading normal: orient it as the normal whose derivatives
    // `dn` are.
    let facet = facet.try_normalize()?;
    let facet = if facet.dot(hit.shading_normal) < 0.0 {
        -facet
    } else {
        facet
    };
    let transferred = reflected_about(hit, facet, dn, incoming, reflected)?;
    widened(&transferred, GLOSSY_SPREAD_PER_ALPHA * alpha)
}

/// `differential` with its offset rays' directions widened by `w` (radians per footprint edge):
/// in the plane perpendicular to the main ray, the direction offsets D (a 2 × 2 matrix,
/// columns per film axis) become D′ = (DDᵀ + w²I)^½·U, D = (DDᵀ)^½·U the polar decomposition,
/// so D′D′ᵀ = DDᵀ + w²I (see the module documentation). Origins are kept; `w` = 0 returns the
/// differential unchanged. `None` when a direction is not finite or `w` is negative or not
/// finite.
#[must_use]
pub fn widened(differential: &RayDifferential, w: f64) -> Option<RayDifferential> {
    if !(w >= 0.0 && w.is_finite()) {
        return None;
    }
    if w == 0.0 {
        return Some(*differential);
    }
    let omega = differential.ray.direction.try_normalize()?;
    let (e1, e2) = orthonormal_basis(omega);
    let dx = differential.rx.direction.try_normalize()? - omega;
    let dy = differential.ry.direction.try_normalize()? - omega;
    // D = [[a, b], [c, d]].
    let (a, b, c, d) = (dx.dot(e1), dy.dot(e1), dx.dot(e2), dy.dot(e2));
    let [u11, u12, u21, u22] = polar_factor([a, b, c, d]);
    // T = DDᵀ + w²I, and its square root (T + √det T·I)/√(tr T + 2√det T) (2 × 2, positive
    // definite).
    let (t11, t12, t22) = (a * a + b * b + w * w, a * c + b * d, c * c + d * d + w * w);
    let root_det = (t11 * t22 - t12 * t12).max(0.0).sqrt();
    let scale = (t11 + t22 + 2.0 * root_det).sqrt();
    let (s11, s12, s22) = (
        (t11 + root_det) / scale,
        t12 / scale,
        (t22 + root_det) / scale,
    );
    // D′ = T^½·U.
    let (a2, b2, c2, d2) = (
        s11 * u11 + s12 * u21,
        s11 * u12 + s12 * u22,
        s12 * u11 + s22 * u21,
        s12 * u12 + s22 * u22,
    );
    let turn = |direction: DVec3, along_e1: f64, along_e2: f64| -> Option<DVec3> {
        let turned = direction.try_normalize()? + along_e1 * e1 + along_e2 * e2;
        turned.try_normalize()
    };
    let rx = turn(differential.rx.direction, a2 - a, c2 - c)?;
    let ry = turn(differential.ry.direction, b2 - b, d2 - d)?;
    Some(RayDifferential {
        ray: differential.ray,
        rx: Ray {
            origin: differential.rx.origin,
            direction: rx,
        },
        ry: Ray {
            origin: differential.ry.origin,
            direction: ry,
        },
    })
}

/// The orthogonal factor U of the polar decomposition M = (MMᵀ)^½·U of the 2 × 2 matrix
/// `[m11, m12, m21, m22]` (row by row): the rotation closest to M where det M ≥ 0, the
/// reflection closest to it where det M < 0 (any orthogonal U serves a singular M; a zero M
/// gives the identity).
fn polar_factor([a, b, c, d]: [f64; 4]) -> [f64; 4] {
    // The rotation by θ = atan2(c − b, a + d) (or the reflection about θ/2 with
    // θ = atan2(c + b, a − d)), its cosine and sine taken as p/r and q/r without the angle.
    let rotation = a * d - b * c >= 0.0;
    let (p, q) = if rotation {
        (a + d, c - b)
    } else {
        (a - d, c + b)
    };
    // The offsets are differences of unit vectors (at most 2): no overflow.
    let r = (p * p + q * q).sqrt();
    let (cos, sin) = if r > 0.0 && r.is_finite() {
        (p / r, q / r)
    } else {
        (1.0, 0.0)
    };
    if rotation {
        [cos, -sin, sin, cos]
    } else {
        [cos, sin, sin, -cos]
    }
}

/// The differential of `reflected`: `incoming`'s offset rays reflected at their points on the
/// tangent plane about the unit `facet` normal (oriented as the shading normal) moved by `dn`.
fn reflected_about(
    hit: &SurfaceHit,
    facet: DVec3,
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
    let n = facet;
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

    /// The direction offsets of `differential` in the plane perpendicular to its main ray, as
    /// the matrix [[a, b], [c, d]] of the module documentation (in the basis of
    /// `orthonormal_basis(ω)`).
    fn offsets(differential: &RayDifferential) -> [f64; 4] {
        let omega = differential.ray.direction.normalize();
        let (e1, e2) = orthonormal_basis(omega);
        let dx = differential.rx.direction.normalize() - omega;
        let dy = differential.ry.direction.normalize() - omega;
        [dx.dot(e1), dy.dot(e1), dx.dot(e2), dy.dot(e2)]
    }

    /// A differential along `omega` whose offset rays leave from `origin` ± small offsets with
    /// the direction offsets `[a, b, c, d]` (see [`offsets`]).
    fn with_offsets(omega: DVec3, [a, b, c, d]: [f64; 4]) -> RayDifferential {
        let omega = omega.normalize();
        let (e1, e2) = orthonormal_basis(omega);
        let ray = |direction: DVec3, origin: DVec3| Ray { origin, direction };
        RayDifferential {
            ray: ray(omega, DVec3::ZERO),
            rx: ray((omega + a * e1 + c * e2).normalize(), 1e-3 * e1),
            ry: ray((omega + b * e1 + d * e2).normalize(), 1e-3 * e2),
        }
    }

    /// From the definition: the widened offsets D′ satisfy D′D′ᵀ = DDᵀ + w²I (second moments
    /// add), keep D's orientation (det D′ has det D's sign, and D′ → D as w → 0), leave the
    /// origins and the main ray alone, and w = 0 changes nothing, bit for bit.
    #[test]
    fn widening_adds_the_lobes_second_moments() {
        let mut rng = glint_tests::SplitMix64::new(34);
        for case in 0..400 {
            let scale = 10f64.powf(-4.0 + 2.0 * rng.uniform());
            let mut d = [0.0; 4];
            for x in &mut d {
                *x = scale * (2.0 * rng.uniform() - 1.0);
            }
            if case % 7 == 0 {
                // Rank 1: the offset rays along one line.
                d[3] = d[2] * d[1] / d[0];
            }
            let omega = DVec3::new(
                rng.uniform() - 0.5,
                rng.uniform() - 0.5,
                rng.uniform() - 0.5,
            );
            let differential = with_offsets(omega, d);
            let d = offsets(&differential);
            assert_eq!(widened(&differential, 0.0), Some(differential));
            for w in [scale * 1e-6, scale * 0.3, scale * 3.0] {
                let out = widened(&differential, w).unwrap();
                assert_eq!(out.ray, differential.ray);
                assert_eq!(out.rx.origin, differential.rx.origin);
                assert_eq!(out.ry.origin, differential.ry.origin);
                let [a, b, c, e] = offsets(&out);
                let product = [a * a + b * b, a * c + b * e, c * c + e * e];
                let expected = [
                    d[0] * d[0] + d[1] * d[1] + w * w,
                    d[0] * d[2] + d[1] * d[3],
                    d[2] * d[2] + d[3] * d[3] + w * w,
                ];
                let size = expected[0] + expected[2];
                for (p, q) in product.iter().zip(expected) {
                    // Normalized directions: second-order terms of the offsets' size.
                    assert!(
                        (p - q).abs() <= (1e-9 + 4.0 * size) * size,
                        "{case}: {product:?} vs {expected:?}"
                    );
                }
                let (det, det_in) = (a * e - b * c, d[0] * d[3] - d[1] * d[2]);
                assert!(det * det_in >= -1e-12 * size * size, "{case}: orientation");
                if w < scale * 1e-5 {
                    for (p, q) in [a, b, c, e].iter().zip(d) {
                        assert!((p - q).abs() <= 1e-5 * scale, "{case}: {p} vs {q}");
                    }
                }
            }
        }
        let d = with_offsets(DVec3::Z, [1e-3, 0.0, 0.0, 1e-3]);
        for bad in [-1e-3, f64::NAN, f64::INFINITY] {
            assert_eq!(widened(&d, bad), None);
        }
        // Parallel offset rays (D = 0): the lobe alone, w along both axes.
        let parallel = with_offsets(DVec3::Z, [0.0; 4]);
        let [a, b, c, e] = offsets(&widened(&parallel, 1e-3).unwrap());
        assert!(
            (a - 1e-3).abs() < 1e-9 && (e - 1e-3).abs() < 1e-9,
            "{a} {e}"
        );
        assert!(b.abs() < 1e-9 && c.abs() < 1e-9, "{b} {c}");
    }

    /// A camera over a glossy floor (the plane y = 0) seeing a far wall (the plane z = −4000, so
    /// that the footprint there is the far field t·D) in it.
    /// The glossy transfer about the shading normal (a facet m = n) with α = 0 is the mirror's,
    /// bit for bit; as α → 0 the footprint on the wall converges to the mirror's; it grows with
    /// α, with the predicted far-field area; past the roughness limit there is none.
    #[test]
    fn glossy_footprints_converge_to_the_mirrors_and_widen_with_roughness() {
        let floor = Rectangle::new(
            DVec3::ZERO,
            DVec3::new(20.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, -20.0),
        )
        .unwrap();
        let wall = Rectangle::new(
            DVec3::new(0.0, 0.0, -4000.0),
            DVec3::new(20000.0, 0.0, 0.0),
            DVec3::new(0.0, 20000.0, 0.0),
        )
        .unwrap();
        let pose = CameraPose {
            position: DVec3::new(0.0, 1.0, 3.0),
            look_at: DVec3::new(0.0, 0.0, 0.0),
            up: DVec3::Y,
            fov_degrees: 20.0,
        };
        let view = CameraView::new(&pose, 200, 200);
        let differential = view.ray_differential(DVec2::new(100.0, 120.0), 1.0);
        let ray = differential.ray;
        let hit = floor.surface(&ray, floor.intersect(&ray, 1e-9, f64::INFINITY).unwrap());
        let reflected = Ray {
            origin: hit.point,
            direction: reflect(ray.direction, hit.shading_normal),
        };
        let next = wall.surface(
            &reflected,
            wall.intersect(&reflected, 1e-9, f64::INFINITY).unwrap(),
        );
        let dn = (DVec3::ZERO, DVec3::ZERO);
        let area = |d: &RayDifferential| {
            let (x, y) = texture_footprint(&next, d).unwrap();
            x.perp_dot(y).abs()
        };
        let mirror = reflected_differential(&hit, dn, &differential, reflected).unwrap();
        let glossy = |alpha: f64| {
            glossy_differential(
                &hit,
                hit.shading_normal,
                alpha,
                dn,
                &differential,
                reflected,
            )
        };
        assert_eq!(glossy(0.0), Some(mirror));
        // Either orientation of the facet.
        assert_eq!(
            glossy_differential(&hit, -hit.shading_normal, 0.0, dn, &differential, reflected),
            Some(mirror)
        );
        let mirror_area = area(&mirror);
        let (x0, y0) = texture_footprint(&next, &mirror).unwrap();
        let mut last = mirror_area;
        for alpha in [1e-4, 1e-3, 3e-3, 1e-2, 3e-2, GLOSSY_FOOTPRINT_MAX_ALPHA] {
            let carried = glossy(alpha).unwrap();
            let a = area(&carried);
            assert!(a > last, "α = {alpha}: {a:e} after {last:e}");
            last = a;
            // The far-field prediction: |det D′| = √det(DDᵀ + w²I), against |det D|, scales
            // the area on the wall, to first order in the offsets (which reach w = 0.245 rad).
            let [p, q, r, s] = offsets(&mirror);
            let w = GLOSSY_SPREAD_PER_ALPHA * alpha;
            let t = [p * p + q * q + w * w, p * r + q * s, r * r + s * s + w * w];
            let ratio = (t[0] * t[2] - t[1] * t[1]).sqrt() / (p * s - q * r).abs();
            assert!(
                (a / mirror_area / ratio - 1.0).abs() < 0.01 + w,
                "α = {alpha}: area ratio {} against {ratio}",
                a / mirror_area
            );
        }
        // Convergence as α → 0: the edges grow by √(1 + (w/λ)²) − 1 ≈ ½(w/λ)², so the
        // footprint's difference from the mirror's falls with α², below 10⁻³ at α = 10⁻⁵ (w is
        // 0.03 of these pixels' 1.75·10⁻³ rad).
        let size = x0.length().max(y0.length());
        let difference = |alpha: f64| {
            let (x, y) = texture_footprint(&next, &glossy(alpha).unwrap()).unwrap();
            (x - x0).length().max((y - y0).length()) / size
        };
        let (coarse, fine) = (difference(1e-4), difference(1e-5));
        assert!(fine < 1e-3, "{fine}");
        assert!(fine < 0.03 * coarse, "{coarse} then {fine}");
        for alpha in [GLOSSY_FOOTPRINT_MAX_ALPHA * 1.001, 0.5, f64::NAN, -1e-3] {
            assert_eq!(glossy(alpha), None, "{alpha}");
        }
        assert_eq!(
            glossy_differential(&hit, DVec3::ZERO, 1e-3, dn, &differential, reflected),
            None
        );
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
