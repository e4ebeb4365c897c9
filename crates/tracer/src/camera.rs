//! The perspective camera with ray differentials (Igehy 1999) and keyframed motion, and the
//! texture-space footprint of a pixel at a hit (Sec. 3.1, "Usage in a rendering system").
//!
//! A camera ray carries two offset rays through the neighbouring pixel positions (x + s, y) and
//! (x, y + s), s = the footprint scale in pixels (1 by default). At the first hit the offset
//! rays are intersected with the tangent plane, which gives ∂p/∂x and ∂p/∂y; the chain rule
//! ∂p/∂x = ∂p/∂u·∂u/∂x + ∂p/∂v·∂v/∂x, solved in the least-squares sense (pbrt-v4,
//! "SurfaceInteraction::ComputeDifferentials"), gives the texture-space parallelogram the
//! multiscale BRDF integrates over. Specular bounces carry the offset rays on
//! ([`crate::differentials`]), so a footprint is known wherever a path has only met mirrors.

use glam::{DVec2, DVec3};

use crate::limits::{number, vector};
use crate::shape::{Ray, SurfaceHit};

/// Where the camera is and what it looks at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraPose {
    /// The eye.
    pub position: DVec3,
    /// The point at the image centre.
    pub look_at: DVec3,
    /// The up direction (need not be perpendicular to the view direction).
    pub up: DVec3,
    /// The vertical field of view in degrees, in (0, 180).
    pub fov_degrees: f64,
}

/// A pose at a frame number.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Keyframe {
    /// The frame number.
    pub frame: f64,
    /// The pose.
    pub pose: CameraPose,
}

/// A perspective camera moving through keyframes (one keyframe: a still camera).
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    keyframes: Vec<Keyframe>,
}

/// A camera ray with its two differential rays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayDifferential {
    /// The ray through the sample position.
    pub ray: Ray,
    /// The ray through the position offset by the footprint scale in x.
    pub rx: Ray,
    /// The ray through the position offset by the footprint scale in y.
    pub ry: Ray,
}

/// The camera frozen at one frame for an image of a given size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraView {
    origin: DVec3,
    forward: DVec3,
    /// Right, scaled by the half-width of the image plane at distance 1.
    right: DVec3,
    /// Up, scaled by the half-height of the image plane at distance 1.
    up: DVec3,
    width: f64,
    height: f64,
}

impl Camera {
    /// A camera through `keyframes`, sorted by frame, or `None` when there are none or a pose
    /// is degenerate (eye at the target, up along the view, field of view outside (0°, 180°)).
    #[must_use]
    pub fn new(mut keyframes: Vec<Keyframe>) -> Option<Self> {
        if keyframes.is_empty()
            || keyframes
                .iter()
                .any(|k| !pose_is_valid(&k.pose) || !k.frame.is_finite())
        {
            return None;
        }
        keyframes.sort_by(|a, b| a.frame.total_cmp(&b.frame));
        Some(Self { keyframes })
    }

    /// The keyframes.
    #[must_use]
    pub fn keyframes(&self) -> &[Keyframe] {
        &self.keyframes
    }

    /// The pose at `frame`: linear interpolation between the surrounding keyframes (position,
    /// target, up and field of view), constant before the first and after the last.
    #[must_use]
    pub fn pose_at(&self, frame: f64) -> CameraPose {
        let k = &self.keyframes;
        let next = k.partition_point(|key| key.frame <= frame);
        if next == 0 {
            return k[0].pose;
        }
        if next == k.len() {
            return k[k.len() - 1].pose;
        }
        let (a, b) = (&k[next - 1], &k[next]);
        let s = (frame - a.frame) / (b.frame - a.frame);
        CameraPose {
            position: a.pose.position.lerp(b.pose.position, s),
            look_at: a.pose.look_at.lerp(b.pose.look_at, s),
            up: a.pose.up.lerp(b.pose.up, s),
            fov_degrees: a.pose.fov_degrees + s * (b.pose.fov_degrees - a.pose.fov_degrees),
        }
    }

    /// The view at `frame` for an image of `width` × `height` pixels (not checked: see
    /// [`Camera::checked_view`]).
    #[must_use]
    pub fn view(&self, frame: f64, width: u32, height: u32) -> CameraView {
        CameraView::new(&self.pose_at(frame), width, height)
    }

    /// The pose at `frame`, checked: keyframes valid alone may interpolate to a degenerate pose
    /// between them (up turning through the view direction, the eye passing through the look-at
    /// point), which would render a black frame.
    ///
    /// # Errors
    /// What is wrong with the pose (see [`pose_problem`]), or a frame that is not finite.
    pub fn checked_pose(&self, frame: f64) -> Result<CameraPose, String> {
        if !frame.is_finite() {
            return Err(format!("the frame number {frame} is not finite"));
        }
        let pose = self.pose_at(frame);
        match pose_problem(&pose) {
            None => Ok(pose),
            Some(problem) => Err(format!("degenerate pose: {problem}")),
        }
    }

    /// The view at `frame` for an image of `width` × `height` pixels, checked as
    /// [`Camera::checked_pose`] does.
    ///
    /// # Errors
    /// As [`Camera::checked_pose`].
    pub fn checked_view(&self, frame: f64, width: u32, height: u32) -> Result<CameraView, String> {
        Ok(CameraView::new(&self.checked_pose(frame)?, width, height))
    }
}

/// What makes `pose` unable to form an image, if anything: coordinates not finite, the eye at
/// the look-at point (closer than 10⁻⁹ of their magnitude, where rounding decides the view
/// direction), up within 10⁻⁶ radians of the view direction, or a field of view outside
/// (0°, 180°).
#[must_use]
pub fn pose_problem(pose: &CameraPose) -> Option<String> {
    if !(pose.position.is_finite() && pose.look_at.is_finite() && pose.up.is_finite()) {
        return Some(format!(
            "position {}, look_at {} and up {} must be finite",
            vector(pose.position),
            vector(pose.look_at),
            vector(pose.up)
        ));
    }
    if !(pose.fov_degrees > 0.0 && pose.fov_degrees < 180.0) {
        return Some(format!(
            "the field of view {}° is outside (0°, 180°)",
            number(pose.fov_degrees)
        ));
    }
    let forward = pose.look_at - pose.position;
    let magnitude = pose.position.abs().max(pose.look_at.abs()).max_element();
    let distance = forward.abs().max_element();
    if !(distance > 1e-9 * magnitude && distance > 0.0) {
        return Some(format!(
            "the eye {} is at the look-at point {}",
            vector(pose.position),
            vector(pose.look_at)
        ));
    }
    if !(pose.up.abs().max_element() > 0.0 && unit(forward).cross(unit(pose.up)).length() > 1e-6) {
        return Some(format!(
            "up {} is zero or along the view direction {}",
            vector(pose.up),
            vector(unit(forward))
        ));
    }
    None
}

/// `v` normalized, also where its squared length would underflow or overflow (then scaled to a
/// largest component of 1 first; the zero vector gives NaN).
fn unit(v: DVec3) -> DVec3 {
    if v.length_squared().is_normal() {
        v.normalize()
    } else {
        (v / v.abs().max_element()).normalize()
    }
}

/// `up` scaled to a largest component of 1 when its squared length is not a normal double
/// (else unchanged, as the cross product with it is normalized anyway).
fn unit_or_self(up: DVec3) -> DVec3 {
    if up.length_squared().is_normal() {
        up
    } else {
        up / up.abs().max_element()
    }
}

fn pose_is_valid(pose: &CameraPose) -> bool {
    pose_problem(pose).is_none()
}

impl CameraView {
    /// The view of `pose` for `width` × `height` pixels.
    #[must_use]
    pub fn new(pose: &CameraPose, width: u32, height: u32) -> Self {
        let forward = unit(pose.look_at - pose.position);
        let right = unit(forward.cross(unit_or_self(pose.up)));
        let up = right.cross(forward);
        let half_height = (0.5 * pose.fov_degrees.to_radians()).tan();
        let aspect = f64::from(width) / f64::from(height);
        Self {
            origin: pose.position,
            forward,
            right: right * (half_height * aspect),
            up: up * half_height,
            width: f64::from(width),
            height: f64::from(height),
        }
    }

    /// The ray through raster position `film` (pixels, y down, (0, 0) the top-left corner).
    #[must_use]
    pub fn ray(&self, film: DVec2) -> Ray {
        let x = 2.0 * film.x / self.width - 1.0;
        let y = 1.0 - 2.0 * film.y / self.height;
        Ray {
            origin: self.origin,
            direction: (self.forward + x * self.right + y * self.up).normalize(),
        }
    }

    /// The ray through `film` with differential rays offset by `scale` pixels.
    #[must_use]
    pub fn ray_differential(&self, film: DVec2, scale: f64) -> RayDifferential {
        RayDifferential {
            ray: self.ray(film),
            rx: self.ray(film + DVec2::new(scale, 0.0)),
            ry: self.ray(film + DVec2::new(0.0, scale)),
        }
    }

    /// The raster position where the ray from the eye toward `point` crosses the image, or
    /// `None` for points behind the camera.
    #[must_use]
    pub fn project(&self, point: DVec3) -> Option<DVec2> {
        let d = point - self.origin;
        let depth = d.dot(self.forward);
        if !(depth > 0.0) {
            return None;
        }
        let x = d.dot(self.right) / (depth * self.right.length_squared());
        let y = d.dot(self.up) / (depth * self.up.length_squared());
        Some(DVec2::new(
            0.5 * (x + 1.0) * self.width,
            0.5 * (1.0 - y) * self.height,
        ))
    }
}

/// The texture-space derivatives of a pixel at a hit: (∂(u,v)/∂x, ∂(u,v)/∂y), or `None` when
/// an offset ray misses the tangent plane or the tangents are degenerate (a sphere's pole).
#[must_use]
pub fn texture_footprint(
    hit: &SurfaceHit,
    differential: &RayDifferential,
) -> Option<(DVec2, DVec2)> {
    let (dpdx, dpdy) = tangent_plane_offsets(hit, differential)?;
    uv_derivatives(hit, dpdx, dpdy)
}

/// (∂p/∂x, ∂p/∂y): where the offset rays meet the hit's tangent plane, relative to the hit, or
/// `None` when an offset ray misses the plane (parallel to it, or meeting it behind its origin).
#[must_use]
pub fn tangent_plane_offsets(
    hit: &SurfaceHit,
    differential: &RayDifferential,
) -> Option<(DVec3, DVec3)> {
    let n = hit.geometric_normal;
    let plane_offset = n.dot(hit.point);
    let on_plane = |r: &Ray| -> Option<DVec3> {
        let denominator = n.dot(r.direction);
        let t = (plane_offset - n.dot(r.origin)) / denominator;
        (t.is_finite() && t > 0.0).then(|| r.at(t))
    };
    let dpdx = on_plane(&differential.rx)? - hit.point;
    let dpdy = on_plane(&differential.ry)? - hit.point;
    Some((dpdx, dpdy))
}

/// (∂(u,v)/∂x, ∂(u,v)/∂y) from (∂p/∂x, ∂p/∂y) in the tangent plane, or `None` when the tangents
/// are degenerate.
#[must_use]
pub fn uv_derivatives(hit: &SurfaceHit, dpdx: DVec3, dpdy: DVec3) -> Option<(DVec2, DVec2)> {
    // Least squares: [∂p/∂u ∂p/∂v]ᵀ[∂p/∂u ∂p/∂v] (du, dv)ᵀ = [∂p/∂u ∂p/∂v]ᵀ dp.
    let (a, b, c) = (
        hit.dpdu.dot(hit.dpdu),
        hit.dpdu.dot(hit.dpdv),
        hit.dpdv.dot(hit.dpdv),
    );
    let determinant = a * c - b * b;
    if !(determinant > 1e-300 && determinant.is_finite()) || determinant < 1e-12 * a * c {
        return None;
    }
    let solve = |dp: DVec3| {
        let (r, s) = (hit.dpdu.dot(dp), hit.dpdv.dot(dp));
        DVec2::new((c * r - b * s) / determinant, (a * s - b * r) / determinant)
    };
    let (duv_dx, duv_dy) = (solve(dpdx), solve(dpdy));
    (duv_dx.is_finite() && duv_dy.is_finite()).then_some((duv_dx, duv_dy))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shape::{Rectangle, Sphere};

    fn pose() -> CameraPose {
        CameraPose {
            position: DVec3::new(0.0, 2.0, 4.0),
            look_at: DVec3::new(0.0, 0.0, 0.0),
            up: DVec3::Y,
            fov_degrees: 40.0,
        }
    }

    #[test]
    fn rays_project_back_to_their_pixels() {
        let view = CameraView::new(&pose(), 320, 200);
        for (x, y) in [(0.0, 0.0), (160.0, 100.0), (17.5, 190.25), (319.0, 3.0)] {
            let film = DVec2::new(x, y);
            let ray = view.ray(film);
            let back = view.project(ray.at(3.7)).unwrap();
            assert!((back - film).length() < 1e-9, "{film} {back}");
        }
        let centre = view.ray(DVec2::new(160.0, 100.0));
        assert!((centre.direction - (-pose().position).normalize()).length() < 1e-12);
    }

    #[test]
    fn keyframes_interpolate_and_clamp() {
        let mut later = pose();
        later.position = DVec3::new(2.0, 2.0, 4.0);
        later.fov_degrees = 60.0;
        let camera = Camera::new(vec![
            Keyframe {
                frame: 10.0,
                pose: later,
            },
            Keyframe {
                frame: 0.0,
                pose: pose(),
            },
        ])
        .unwrap();
        assert_eq!(camera.pose_at(-5.0), pose());
        assert_eq!(camera.pose_at(20.0), later);
        let mid = camera.pose_at(5.0);
        assert!((mid.position - DVec3::new(1.0, 2.0, 4.0)).length() < 1e-12);
        assert!((mid.fov_degrees - 50.0).abs() < 1e-12);
        let mut bad = pose();
        bad.look_at = bad.position;
        assert!(
            Camera::new(vec![Keyframe {
                frame: 0.0,
                pose: bad
            }])
            .is_none()
        );
        assert!(Camera::new(vec![]).is_none());
    }

    /// Keyframes each valid alone whose interpolated pose is degenerate at a frame between
    /// them: up turning through the view direction, the eye passing through the look-at
    /// point. The checked pose at that frame is an error saying why; frames beside it are not.
    #[test]
    fn interpolated_poses_are_checked_per_frame() {
        let key = |frame: f64, position: DVec3, up: DVec3| Keyframe {
            frame,
            pose: CameraPose {
                position,
                look_at: DVec3::ZERO,
                up,
                fov_degrees: 40.0,
            },
        };
        let eye = DVec3::new(0.0, 0.0, 5.0);
        // Looking along −z, up turns from (0, 1, −1) to (0, −1, −1): (0, 0, −1) at frame 5.
        let flip = Camera::new(vec![
            key(0.0, eye, DVec3::new(0.0, 1.0, -1.0)),
            key(10.0, eye, DVec3::new(0.0, -1.0, -1.0)),
        ])
        .unwrap();
        let problem = flip.checked_pose(5.0).unwrap_err();
        assert!(problem.contains("along the view direction"), "{problem}");
        assert!(flip.checked_pose(4.0).is_ok() && flip.checked_pose(6.0).is_ok());
        // Up turns from +y to −y through zero.
        let through_zero =
            Camera::new(vec![key(0.0, eye, DVec3::Y), key(10.0, eye, -DVec3::Y)]).unwrap();
        assert!(through_zero.checked_pose(5.0).is_err());
        // The eye moves from +z to −z through the look-at point at frame 5.
        let through =
            Camera::new(vec![key(0.0, eye, DVec3::Y), key(10.0, -eye, DVec3::Y)]).unwrap();
        let problem = through.checked_pose(5.0).unwrap_err();
        assert!(problem.contains("at the look-at point"), "{problem}");
        assert!(through.checked_pose(4.0).is_ok());
        assert!(through.checked_pose(f64::NAN).is_err());
        // Poses of any scale are checked without overflow: tiny and huge up vectors are fine.
        let mut tiny = pose();
        tiny.up = DVec3::new(0.0, 1e-300, 0.0);
        assert_eq!(pose_problem(&tiny), None);
        tiny.up = DVec3::new(0.0, 1e300, 0.0);
        assert_eq!(pose_problem(&tiny), None);
        let view = CameraView::new(&tiny, 4, 4);
        assert!(view.ray(DVec2::new(1.0, 1.0)).direction.is_finite());
    }

    type Tracer<'a> = dyn Fn(&Ray) -> Option<SurfaceHit> + 'a;

    /// The footprint from ray differentials against the one measured by tracing the
    /// neighbouring pixels' rays to the surface and differencing their (u, v): equal on a plane
    /// (to rounding) and to first order on a sphere (the error shrinks with the pixel size).
    #[test]
    fn footprints_match_neighbouring_pixels() {
        let rect = Rectangle::new(
            DVec3::ZERO,
            DVec3::new(3.0, 0.0, 0.4),
            DVec3::new(0.2, 0.0, -2.5),
        )
        .unwrap();
        let sphere = Sphere {
            center: DVec3::new(0.0, 0.3, 0.0),
            radius: 0.8,
        };
        for (width, tolerance_plane, tolerance_sphere) in [(200, 1e-9, 0.05), (2000, 1e-9, 0.005)] {
            let view = CameraView::new(&pose(), width, width);
            let mut checked = 0;
            for i in 0..40 {
                let film = DVec2::new(
                    f64::from(width) * (0.1 + 0.8 * f64::from(i % 8) / 7.0),
                    f64::from(width) * (0.1 + 0.8 * f64::from(i / 8) / 4.0),
                );
                let differential = view.ray_differential(film, 1.0);
                let shapes: [&Tracer<'_>; 2] = [
                    &|r: &Ray| {
                        rect.intersect(r, 0.0, f64::INFINITY)
                            .map(|t| rect.surface(r, t))
                    },
                    &|r: &Ray| {
                        sphere
                            .intersect(r, 0.0, f64::INFINITY)
                            .map(|t| sphere.surface(r, t))
                    },
                ];
                for (k, trace) in shapes.iter().enumerate() {
                    let (Some(hit), Some(hx), Some(hy)) = (
                        trace(&differential.ray),
                        trace(&differential.rx),
                        trace(&differential.ry),
                    ) else {
                        continue;
                    };
                    // Skip the sphere's seam, where u jumps by 1.
                    if (hx.uv.x - hit.uv.x).abs() > 0.5 || (hy.uv.x - hit.uv.x).abs() > 0.5 {
                        continue;
                    }
                    let (dx, dy) = texture_footprint(&hit, &differential).unwrap();
                    let (mx, my) = (hx.uv - hit.uv, hy.uv - hit.uv);
                    let tolerance = if k == 0 {
                        tolerance_plane
                    } else {
                        tolerance_sphere
                    };
                    let scale = mx.length().max(my.length());
                    assert!((dx - mx).length() <= tolerance * scale, "{k}: {dx} vs {mx}");
                    assert!((dy - my).length() <= tolerance * scale, "{k}: {dy} vs {my}");
                    checked += 1;
                }
            }
            assert!(checked >= 20, "checked {checked}");
        }
    }
}
