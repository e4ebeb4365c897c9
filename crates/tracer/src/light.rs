//! Lights: sphere and rectangle area lights (rectangles optionally textured), a directional
//! light and a lat-long environment map importance-sampled by luminance. Each samples a
//! direction from a shading point with its solid-angle density, and gives that density for a
//! direction found otherwise (for multiple importance sampling).

use std::f64::consts::PI;

use glam::{DVec2, DVec3};

use glint_brdf::cone::uniform_in_cone;

use crate::distribution::Distribution2D;
use crate::image::RgbImage;
use crate::material::Texture;
use crate::shape::{Ray, Rectangle, Sphere};

/// A light's answer to "which direction should this point look at?".
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// The unit direction from the point toward the light (world space).
    pub direction: DVec3,
    /// The radiance arriving along it (for a delta light: the irradiance).
    pub radiance: DVec3,
    /// The solid-angle density of the direction (1 for delta lights).
    pub pdf: f64,
    /// The distance to the light (infinite for directional and environment lights).
    pub distance: f64,
    /// Whether the light is a delta distribution (no other technique can find it).
    pub is_delta: bool,
}

/// A lat-long environment map: u = φ/2π with φ from +x toward +z, v from the top row (θ = 0,
/// +y) to the bottom (θ = π), rotated about +y; importance-sampled by luminance × sin θ.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentMap {
    image: RgbImage,
    scale: DVec3,
    rotation: f64,
    distribution: Distribution2D,
}

/// Rec. 709 luminance.
#[must_use]
pub fn luminance(c: DVec3) -> f64 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

impl EnvironmentMap {
    /// The map of `image` scaled by `scale` and rotated by `rotation` radians about +y.
    #[must_use]
    pub fn new(image: RgbImage, scale: DVec3, rotation: f64) -> Self {
        let (w, h) = (image.width, image.height);
        let function: Vec<f64> = (0..h)
            .flat_map(|y| {
                let sin_theta = (PI * (y as f64 + 0.5) / h as f64).sin();
                let image = &image;
                (0..w).map(move |x| luminance(image.pixels[y * w + x]) * sin_theta)
            })
            .collect();
        Self {
            distribution: Distribution2D::new(&function, w),
            image,
            scale,
            rotation,
        }
    }

    /// A uniform environment of radiance `radiance` (sampled in proportion to sin θ, that is
    /// nearly uniformly over the sphere).
    #[must_use]
    pub fn constant(radiance: DVec3) -> Self {
        Self::new(RgbImage::filled(4, 64, DVec3::ONE), radiance, 0.0)
    }

    /// (u, v) in [0, 1)² of a world direction, v = θ/π from the top.
    fn to_map(&self, direction: DVec3) -> DVec2 {
        let (s, c) = self.rotation.sin_cos();
        // Undo the rotation about +y.
        let d = DVec3::new(
            c * direction.x + s * direction.z,
            direction.y,
            -s * direction.x + c * direction.z,
        );
        let theta = d.y.clamp(-1.0, 1.0).acos();
        let phi = d.z.atan2(d.x).rem_euclid(2.0 * PI);
        DVec2::new(phi / (2.0 * PI), theta / PI)
    }

    fn direction_of(&self, p: [f64; 2]) -> (DVec3, f64) {
        let (phi, theta) = (2.0 * PI * p[0], PI * p[1]);
        let sin_theta = theta.sin();
        let d = DVec3::new(sin_theta * phi.cos(), theta.cos(), sin_theta * phi.sin());
        let (s, c) = self.rotation.sin_cos();
        (
            DVec3::new(c * d.x - s * d.z, d.y, s * d.x + c * d.z),
            sin_theta,
        )
    }

    /// The radiance arriving from world direction `direction` (the light travels along
    /// −direction).
    #[must_use]
    pub fn radiance(&self, direction: DVec3) -> DVec3 {
        let m = self.to_map(direction);
        self.image.lookup_latlong(DVec2::new(m.x, 1.0 - m.y)) * self.scale
    }

    /// A direction and its solid-angle density from two uniforms.
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> Option<(DVec3, f64)> {
        let (p, pdf_map) = self.distribution.sample(u);
        let (direction, sin_theta) = self.direction_of(p);
        let pdf = pdf_map / (2.0 * PI * PI * sin_theta);
        (pdf > 0.0 && pdf.is_finite()).then_some((direction, pdf))
    }

    /// The solid-angle density of [`EnvironmentMap::sample`] at `direction`.
    #[must_use]
    pub fn pdf(&self, direction: DVec3) -> f64 {
        let m = self.to_map(direction);
        let sin_theta = (PI * m.y).sin();
        if !(sin_theta > 0.0) {
            return 0.0;
        }
        self.distribution.pdf([m.x, m.y]) / (2.0 * PI * PI * sin_theta)
    }
}

/// The density of directions uniform in a cone of half-angle θ_max: 1/(2π(1 − cos θ_max)).
fn sphere_cone_pdf(theta_max: f64) -> f64 {
    1.0 / (4.0 * PI * (0.5 * theta_max).sin().powi(2))
}

/// A light.
#[derive(Clone, Debug)]
pub enum Light {
    /// A sphere emitting `radiance` from every point of its surface, outward.
    Sphere {
        /// Where it is.
        sphere: Sphere,
        /// Emitted radiance.
        radiance: DVec3,
    },
    /// A parallelogram emitting from its front side (both when `two_sided`).
    Rectangle {
        /// Where it is.
        rectangle: Rectangle,
        /// Emitted radiance over (u, v).
        radiance: Texture,
        /// Whether the back side emits too.
        two_sided: bool,
    },
    /// Light from one direction (a delta distribution), e.g. the sun.
    Directional {
        /// Unit direction from the scene toward the light.
        direction: DVec3,
        /// Irradiance on a surface facing the light.
        irradiance: DVec3,
    },
    /// Light from every direction at infinity.
    Environment(EnvironmentMap),
}

impl Light {
    /// The radiance a ray sees when it hits this light's surface at `point` (texture
    /// coordinates `uv`) travelling along `ray_direction`.
    #[must_use]
    pub fn emitted(&self, ray_direction: DVec3, uv: DVec2) -> DVec3 {
        match self {
            Self::Sphere { radiance, .. } => *radiance,
            Self::Rectangle {
                rectangle,
                radiance,
                two_sided,
            } => {
                if *two_sided || ray_direction.dot(rectangle.normal()) < 0.0 {
                    radiance.at(uv)
                } else {
                    DVec3::ZERO
                }
            }
            Self::Directional { .. } | Self::Environment(_) => DVec3::ZERO,
        }
    }

    /// A direction from `point` toward the light from two uniforms, or `None` when the light
    /// cannot be seen from there (behind a one-sided emitter, inside a sphere light).
    #[must_use]
    pub fn sample(&self, point: DVec3, u: [f64; 2]) -> Option<LightSample> {
        match self {
            Self::Sphere { sphere, radiance } => {
                // Uniform in the cone of directions that see the sphere (pbrt-v4, "Sphere").
                let to_center = sphere.center - point;
                let d2 = to_center.length_squared();
                let r2 = sphere.radius * sphere.radius;
                if !(d2 > r2) {
                    return None;
                }
                // The cone's half-angle θ_max = asin(r/d); 1 − cos θ_max = 2 sin²(θ_max/2) stays
                // accurate for tiny, distant spheres.
                let theta_max = (r2 / d2).sqrt().asin();
                let axis = to_center / d2.sqrt();
                let direction = uniform_in_cone(axis, theta_max, u[0], u[1]);
                let ray = Ray {
                    origin: point,
                    direction,
                };
                // Rounding can put a direction at the silhouette just past the sphere: take the
                // closest approach then.
                let distance = sphere
                    .intersect(&ray, 0.0, f64::INFINITY)
                    .unwrap_or_else(|| direction.dot(to_center));
                Some(LightSample {
                    direction,
                    radiance: *radiance,
                    pdf: sphere_cone_pdf(theta_max),
                    distance,
                    is_delta: false,
                })
            }
            Self::Rectangle {
                rectangle,
                radiance,
                two_sided,
            } => {
                // Uniform in area, converted to solid angle: pdf = d² / (|cos θ_l| · area).
                let target = rectangle.point(u[0], u[1]);
                let offset = target - point;
                let distance = offset.length();
                let direction = offset / distance;
                let cos_light = -direction.dot(rectangle.normal());
                if !(cos_light > 0.0 || (*two_sided && cos_light < 0.0)) {
                    return None;
                }
                let pdf = distance * distance / (cos_light.abs() * rectangle.area());
                (pdf.is_finite() && pdf > 0.0).then(|| LightSample {
                    direction,
                    radiance: radiance.at(DVec2::new(u[0], u[1])),
                    pdf,
                    distance,
                    is_delta: false,
                })
            }
            Self::Directional {
                direction,
                irradiance,
            } => Some(LightSample {
                direction: *direction,
                radiance: *irradiance,
                pdf: 1.0,
                distance: f64::INFINITY,
                is_delta: true,
            }),
            Self::Environment(map) => {
                let (direction, pdf) = map.sample(u)?;
                Some(LightSample {
                    direction,
                    radiance: map.radiance(direction),
                    pdf,
                    distance: f64::INFINITY,
                    is_delta: false,
                })
            }
        }
    }

    /// The solid-angle density with which [`Light::sample`] from `point` picks `direction`
    /// (0 for delta lights and directions that miss the light).
    #[must_use]
    pub fn pdf(&self, point: DVec3, direction: DVec3) -> f64 {
        match self {
            Self::Sphere { sphere, .. } => {
                let to_center = sphere.center - point;
                let d2 = to_center.length_squared();
                let r2 = sphere.radius * sphere.radius;
                if !(d2 > r2) {
                    return 0.0;
                }
                let ray = Ray {
                    origin: point,
                    direction,
                };
                if sphere.intersect(&ray, 0.0, f64::INFINITY).is_none() {
                    return 0.0;
                }
                sphere_cone_pdf((r2 / d2).sqrt().asin())
            }
            Self::Rectangle {
                rectangle,
                two_sided,
                ..
            } => {
                let ray = Ray {
                    origin: point,
                    direction,
                };
                let Some(t) = rectangle.intersect(&ray, 0.0, f64::INFINITY) else {
                    return 0.0;
                };
                let cos_light = -direction.dot(rectangle.normal());
                if !(cos_light > 0.0 || (*two_sided && cos_light < 0.0)) {
                    return 0.0;
                }
                t * t / (cos_light.abs() * rectangle.area())
            }
            Self::Directional { .. } => 0.0,
            Self::Environment(map) => map.pdf(direction),
        }
    }

    /// The radiance from the environment along a ray that escapes the scene (0 for other
    /// lights).
    #[must_use]
    pub fn escaped(&self, direction: DVec3) -> DVec3 {
        match self {
            Self::Environment(map) => map.radiance(direction),
            _ => DVec3::ZERO,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lights() -> Vec<Light> {
        let mut sky = RgbImage::filled(16, 8, DVec3::splat(0.2));
        sky.pixels[3 * 16 + 5] = DVec3::new(40.0, 30.0, 10.0);
        sky.pixels[16 + 12] = DVec3::new(0.0, 5.0, 1.0);
        vec![
            Light::Sphere {
                sphere: Sphere {
                    center: DVec3::new(0.5, 2.0, -0.3),
                    radius: 0.4,
                },
                radiance: DVec3::ONE,
            },
            Light::Sphere {
                sphere: Sphere {
                    center: DVec3::new(3.0, 1.0, 0.0),
                    radius: 0.01,
                },
                radiance: DVec3::ONE,
            },
            Light::Rectangle {
                rectangle: Rectangle::new(
                    DVec3::new(0.0, 1.5, 0.0),
                    DVec3::new(1.0, 0.0, 0.0),
                    DVec3::new(0.0, 0.2, 1.0),
                )
                .unwrap(),
                radiance: Texture::Constant(DVec3::ONE),
                two_sided: true,
            },
            Light::Environment(EnvironmentMap::new(sky, DVec3::ONE, 0.7)),
        ]
    }

    /// Every sampler's reported density equals its `pdf` at the sampled direction, and the
    /// density integrates to 1 over the directions that see the light: the sum of 1/pdf over
    /// samples estimates the light's solid angle, which a uniform-sphere estimate confirms.
    #[test]
    fn light_pdfs_match_their_definitions() {
        let point = DVec3::new(0.1, 0.2, 0.3);
        let mut rng = glint_tests::SplitMix64::new(7u64);
        let mut next = move || rng.uniform();
        for (k, light) in lights().iter().enumerate() {
            let n = 200_000;
            let mut inverse_pdf_sum = 0.0;
            for _ in 0..n {
                let s = light.sample(point, [next(), next()]).unwrap();
                let again = light.pdf(point, s.direction);
                assert!(
                    (again - s.pdf).abs() <= 1e-6 * s.pdf,
                    "{k}: {again} vs {}",
                    s.pdf
                );
                inverse_pdf_sum += 1.0 / s.pdf;
            }
            let solid_angle_by_sampling = inverse_pdf_sum / f64::from(n);
            // The solid angle the light covers, by uniform directions on the sphere.
            let mut seen = 0u32;
            for _ in 0..n {
                let z = 2.0 * next() - 1.0;
                let phi = 2.0 * PI * next();
                let r = (1.0 - z * z).sqrt();
                let d = DVec3::new(r * phi.cos(), r * phi.sin(), z);
                if light.pdf(point, d) > 0.0 {
                    seen += 1;
                }
            }
            let solid_angle_uniform = 4.0 * PI * f64::from(seen) / f64::from(n);
            let sigma = 4.0 * PI * (f64::from(seen.max(1)) / f64::from(n) / f64::from(n)).sqrt();
            assert!(
                (solid_angle_by_sampling - solid_angle_uniform).abs()
                    < 5.0 * sigma + 0.02 * solid_angle_uniform,
                "{k}: {solid_angle_by_sampling} vs {solid_angle_uniform}"
            );
        }
        // The tiny sphere: its exact solid angle 2π(1 − cos θ_max).
        let tiny = &lights()[1];
        let s = tiny.sample(point, [0.3, 0.6]).unwrap();
        let d2 = (DVec3::new(3.0, 1.0, 0.0) - point).length_squared();
        let exact = 2.0 * PI * (1.0 - (1.0 - 1e-4 / d2).sqrt());
        assert!((1.0 / s.pdf - exact).abs() < 1e-9 * exact);
    }

    #[test]
    fn environment_radiance_and_sampling_follow_the_map() {
        let Light::Environment(map) = &lights()[3] else {
            unreachable!()
        };
        // The bright texel (luminance 30.7 against 0.2 elsewhere) draws about 62% of samples.
        let mut bright = 0;
        for i in 0..10_000 {
            let u = [
                (f64::from(i) * 0.754_877_666) % 1.0,
                (f64::from(i) + 0.5) / 10_000.0,
            ];
            let (d, _) = map.sample(u).unwrap();
            let m = map.to_map(d);
            if (m.x * 16.0) as usize == 5 && (m.y * 8.0) as usize == 3 {
                bright += 1;
            }
        }
        assert!(bright > 5000, "bright texel drawn {bright} times in 10⁴");
        let uniform = EnvironmentMap::constant(DVec3::splat(0.5));
        assert_eq!(
            uniform.radiance(DVec3::new(0.3, -0.9, 0.1).normalize()),
            DVec3::splat(0.5)
        );
    }
}
