//! Light cones (`glint_light_cones = true`): at a glint hit with a footprint, each sphere light
//! is shaded by one tree query whose cone is the light's own cone, instead of light samples
//! through the material's cone of radius γ.
//!
//! # The estimator
//! Seen from the shading point p, a sphere light of radius r whose centre is at distance d
//! fills the cone Ω_l of axis ω_c (toward the centre) and half-angle θ_l = asin(r/d), of solid
//! angle σ_l = 2π(1 − cos θ_l). The radiance the footprint's mirror flakes reflect from a light
//! of uniform radiance L_e, with the smooth BRDF f = F D G / (4 cos θ_i cos θ_o) and the change
//! of variables ω ↦ h (dω = 4 (ω_i·h) dh), is
//!
//! ```text
//!   L = L_e ∫_{Ω_l} f cos θ_o dω = L_e ∫_{Ω_h} F G (ω_i·m) / ((m·n) cos θ_i) · p(m) dm,
//! ```
//!
//! with p(m) = D(m)(m·n): cos θ_o has cancelled inside the integral. The discrete model replaces
//! p(m) dm by the flakes in the footprint, count/(N a(A)) (Eq. 6); holding F·G·(ω_i·m)/(m·n) at
//! the axis's half vector h_c gives L ≈ L_e F G (ω_i·h_c) D̂ / (a(A) (h_c·n) cos θ_i), which is
//! exactly L_e · f̂_cone(ω_i, ω_c) · σ_l · cos θ_c with f̂_cone of
//! [`glint_brdf::GlintBxdf::evaluate_in_cone`] (the cos θ_c there and here cancel: using the
//! centre's cosine is exact, not an approximation). What is approximate is F·G·(ω_i·m)/(m·n)
//! held at h_c over the light's conic: a relative error of the order of θ_l times its
//! logarithmic derivative times the shift of p's centroid over the conic (measured by
//! `cargo xtask validate`: +1.1% in the image mean at θ_l = 2.9°, Beckmann α = 0.1,
//! N = 10¹² against the smooth render). There is no light-sampling noise and no γ blur; γ
//! plays no role for these lights.
//!
//! # Visibility
//! One shadow ray toward a direction uniform in Ω_l gives V ∈ {0, 1}, and the estimate is
//! L·V: the light's visible fraction times the flakes' unshadowed radiance (a ratio
//! estimator, as analytic area-light methods use). It is unbiased where the light is wholly
//! visible or wholly hidden. In a penumbra it is unbiased only if the flakes' reflected
//! directions are independent of which part of the light is hidden; for a single glint
//! reflecting a hidden (or visible) part of the light the pixel's expectation is the light's
//! visible fraction of that glint rather than 0 (or all of it). The bias is measured in
//! `cargo xtask validate` (light cones suite).
//!
//! # Which lights, and the other lights
//! A sphere light has a cone at a vertex when the material is a pure glint material with a
//! footprint, the point is outside the sphere, θ_l ≤ 60° (the largest cone glint-brdf
//! accepts; lights below 10⁻⁶ rad are queried with a cone of 10⁻⁶ rad and weighted by their own
//! σ_l) and the whole cone lies above both the shading and the geometric horizon. Every other
//! light (rectangles, directional, environment, sphere lights that fail the test, and all lights
//! on mixtures and smooth materials) is sampled as without light cones: one light chosen
//! uniformly among those *without* a cone, with the power heuristic against BRDF sampling whose
//! light-selection probability is that same 1/count. BRDF-sampled rays that hit a light with a
//! cone at their origin add nothing (the cone counted it).

use glam::DVec3;

use crate::bounce::offset_origin;
use crate::light::Light;
use crate::material::{Material, ShadingContext};
use crate::sampler::uniform_index;
use crate::scene::Scene;
use crate::settings::{LightStrategy, RenderSettings};
use crate::shape::Ray;

/// The smallest cone glint-brdf queries (its range of γ starts at 10⁻⁶ rad).
const SMALLEST_QUERY_CONE: f64 = 1e-6;

/// The largest cone glint-brdf queries (60°).
const LARGEST_QUERY_CONE: f64 = std::f64::consts::FRAC_PI_3;

/// A sphere light's cone seen from a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightCone {
    /// The unit direction toward the light's centre (world space).
    pub axis: DVec3,
    /// The angular radius θ_l = asin(r/d).
    pub half_angle: f64,
    /// σ_l = 2π(1 − cos θ_l), the light's solid angle.
    pub solid_angle: f64,
}

/// The cone of `light` seen from `point` if it is a sphere light that light cones handle there:
/// outside the sphere, θ_l ≤ 60°, and the whole cone above the planes of `normal` and
/// `geometric_normal`.
#[must_use]
pub fn sphere_light_cone(
    light: &Light,
    point: DVec3,
    normal: DVec3,
    geometric_normal: DVec3,
) -> Option<LightCone> {
    let Light::Sphere { sphere, .. } = light else {
        return None;
    };
    let to_center = sphere.center - point;
    let d2 = to_center.length_squared();
    let r2 = sphere.radius * sphere.radius;
    if !(d2 > r2 && d2.is_finite()) {
        return None;
    }
    let sin_half = (r2 / d2).sqrt();
    let half_angle = sin_half.asin();
    let axis = to_center / d2.sqrt();
    // The cone is above a plane when its axis makes more than θ_l with the plane: n·axis > sin θ_l.
    let above = axis.dot(normal) > sin_half && axis.dot(geometric_normal) > sin_half;
    (half_angle <= LARGEST_QUERY_CONE && above).then(|| LightCone {
        axis,
        half_angle,
        solid_angle: glint_brdf::cone::cone_solid_angle(half_angle),
    })
}

/// A path vertex where light cones replace light sampling of some sphere lights.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ConeVertex {
    point: DVec3,
    /// The shading frame (x, y, z = shading normal) in world space.
    frame: [DVec3; 3],
    geometric_normal: DVec3,
}

impl ConeVertex {
    /// The vertex if light cones apply: the setting is on, light sampling is used, the
    /// material is a pure glint material and it has a footprint here (one it can query: a
    /// footprint beyond [`glint_brdf::Footprint::MAX_EDGE`] shades the smooth limit, lit by
    /// light samples).
    pub(crate) fn at(
        settings: &RenderSettings,
        material: &Material,
        ctx: &ShadingContext<'_>,
        point: DVec3,
        frame: [DVec3; 3],
        geometric_normal: DVec3,
    ) -> Option<Self> {
        let applies = settings.glint_light_cones
            && settings.light_strategy != LightStrategy::BrdfOnly
            && matches!(material, Material::Glint(g) if g.footprint(ctx).is_some());
        applies.then_some(Self {
            point,
            frame,
            geometric_normal,
        })
    }

    /// The cone of `light` at this vertex, if light cones handle it.
    pub(crate) fn cone(&self, light: &Light) -> Option<LightCone> {
        sphere_light_cone(light, self.point, self.frame[2], self.geometric_normal)
    }

    /// How many lights are left to light sampling here.
    pub(crate) fn sampled_count(&self, lights: &[Light]) -> usize {
        lights.iter().filter(|l| self.cone(l).is_none()).count()
    }

    /// The probability with which light sampling picks each light left to it (0 if none is).
    pub(crate) fn pick_probability(&self, lights: &[Light]) -> f64 {
        match self.sampled_count(lights) {
            0 => 0.0,
            n => 1.0 / n as f64,
        }
    }

    /// The light chosen uniformly by `u` among those left to light sampling.
    pub(crate) fn pick(&self, lights: &[Light], u: f64) -> Option<usize> {
        let n = self.sampled_count(lights);
        if n == 0 {
            return None;
        }
        let k = uniform_index(u, n);
        lights
            .iter()
            .enumerate()
            .filter(|(_, l)| self.cone(l).is_none())
            .nth(k)
            .map(|(i, _)| i)
    }

    fn to_local(self, w: DVec3) -> DVec3 {
        DVec3::new(
            w.dot(self.frame[0]),
            w.dot(self.frame[1]),
            w.dot(self.frame[2]),
        )
    }

    /// The radiance reflected toward `wi` (local) from every light with a cone, each from one
    /// query and one shadow ray: L_e·f̂_cone·σ_l·cos θ_c·V (see the module docs). `u` is the
    /// vertex's light-sample pair, rotated per light (Cranley–Patterson) for its shadow ray.
    pub(crate) fn direct(
        &self,
        scene: &Scene,
        material: &Material,
        wi: DVec3,
        ctx: &mut ShadingContext<'_>,
        u: [f64; 2],
        rays: &mut u64,
    ) -> DVec3 {
        let Material::Glint(glint) = material else {
            return DVec3::ZERO;
        };
        let mut total = DVec3::ZERO;
        for (index, light) in scene.lights.iter().enumerate() {
            let Some(cone) = self.cone(light) else {
                continue;
            };
            let Light::Sphere { radiance, .. } = light else {
                continue;
            };
            let axis = self.to_local(cone.axis);
            let half = cone.half_angle.max(SMALLEST_QUERY_CONE);
            let f = glint.evaluate_in_cone(wi, axis, half, ctx);
            if f == DVec3::ZERO {
                continue;
            }
            // The shadow ray: a direction uniform in the light's cone.
            let k = index as f64 + 1.0;
            let v = [
                (u[0] + k * 0.618_033_988_749_895).fract(),
                (u[1] + k * 0.754_877_666_246_693).fract(),
            ];
            let Some(sample) = light.sample(self.point, v) else {
                continue;
            };
            let shadow = Ray {
                origin: offset_origin(self.point, self.geometric_normal, sample.direction),
                direction: sample.direction,
            };
            *rays += 1;
            if scene.occluded(&shadow, sample.distance * (1.0 - 1e-7)) {
                continue;
            }
            total += f * *radiance * (cone.solid_angle * axis.z);
        }
        total
    }
}
