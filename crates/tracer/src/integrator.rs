//! Direct illumination and path tracing with next-event estimation, multiple importance
//! sampling (the power heuristic, Veach 1997) and Russian roulette, in the style of pbrt-v4's
//! `PathIntegrator`.
//!
//! Where glint materials get the pixel's footprint is [`GlintFootprints`]: by default at the
//! first hit only and by their smooth limit after, as in the paper (Sec. 3.1). Under
//! [`GlintFootprints::All`] paths carry their ray differentials through perfect mirrors and
//! near-specular glossy lobes (conductors and plastic coats of α ≤
//! [`crate::differentials::GLOSSY_FOOTPRINT_MAX_ALPHA`], widened by the lobe's spread:
//! [`crate::differentials`]), so glints keep a footprint at any depth reached by such bounces
//! alone; a diffuse, glint or rougher bounce ends the differentials. Mirrors
//! ([`Material::Mirror`]) are delta reflections: no light sample there, and the emission the
//! reflected ray finds counts unweighted, as a camera ray's does.

use glam::{DVec2, DVec3};
use glint_brdf::QueryScratch;

use crate::accel::PrimitiveHit;
use crate::bounce::{
    Frame, glossy_bounce_differential, mirror_differential, mirror_reflection, offset_origin,
};
use crate::camera::{RayDifferential, texture_footprint};
use crate::light_cone::ConeVertex;
use crate::material::{GlintCounters, Lobe, Material, ShadingContext};
use crate::sampler::{PixelSampler, uniform_index};
use crate::scene::Scene;
use crate::settings::{
    GlintFootprints, IntegratorKind, LightStrategy, PixelFilter, RenderSettings,
};
use crate::shape::Ray;

/// The power heuristic with β = 2 for one sample of each technique.
#[must_use]
pub fn power_heuristic(pdf_this: f64, pdf_other: f64) -> f64 {
    let (a, b) = (pdf_this * pdf_this, pdf_other * pdf_other);
    if a == 0.0 {
        0.0
    } else if a.is_infinite() {
        1.0
    } else {
        a / (a + b)
    }
}

/// Per-thread working memory and counters.
#[derive(Debug, Default)]
pub struct PathState {
    /// The tree's scratch space.
    pub scratch: QueryScratch,
    /// Glint query counters per material (indexed like [`Scene::materials`]; grown on first
    /// use).
    pub counters: Vec<GlintCounters>,
    /// Rays traced (camera, extension and shadow rays).
    pub rays: u64,
    /// Samples clamped by the film (see [`crate::RenderStatistics::clamped_samples`]).
    pub clamped_samples: u64,
    /// Samples discarded by the film (see [`crate::RenderStatistics::discarded_samples`]).
    pub discarded_samples: u64,
}

/// The counters of material `index`, growing `counters` to hold it.
fn counters_of(counters: &mut Vec<GlintCounters>, index: usize) -> &mut GlintCounters {
    if counters.len() <= index {
        counters.resize(index + 1, GlintCounters::default());
    }
    &mut counters[index]
}

/// The most perfect mirrors [`EmissionWeighting::gains_beyond`] follows before it answers
/// that the path may gain (each costs a ray that the path traces again).
const MIRROR_LOOKAHEAD: u32 = 4;

/// How emission found by BRDF-sampled rays is weighted.
#[derive(Clone, Copy, Debug)]
struct EmissionWeighting {
    use_light_sampling: bool,
    use_brdf_hits: bool,
    light_pick: f64,
}

impl EmissionWeighting {
    /// Whether a BRDF-sampled `ray` that hit `hit` (or escaped) would add any emission: a
    /// cheap test before the BRDF's pdf and value are computed.
    fn finds_emission(
        &self,
        scene: &Scene,
        ray: &Ray,
        hit: Option<&PrimitiveHit>,
        cones: Option<&ConeVertex>,
    ) -> bool {
        if !self.use_brdf_hits {
            return false;
        }
        match hit {
            None => scene.escaped(ray.direction) != DVec3::ZERO,
            Some(hit) => scene.accelerator.primitives()[hit.primitive]
                .light
                .is_some_and(|i| {
                    let light = &scene.lights[i as usize];
                    cones.is_none_or(|c| c.cone(light).is_none())
                        && light.emitted(ray.direction, hit.surface.uv) != DVec3::ZERO
                }),
        }
    }

    /// Whether the path can still gain radiance beyond the BRDF-sampled `ray` of the vertex at
    /// `depth` (with depth + 1 < `max_depth`), which hits `next`: false exactly where every later
    /// contribution is 0, so that the vertex's f (a glint query) is not needed. The path ends
    /// where the ray escapes or meets an emitter (which does not reflect), adding only their
    /// emission; a chain of perfect mirrors is followed (deterministic, so the rays are the
    /// ones the path will trace) to where it escapes, meets an emitter, or runs out of depth.
    /// Anything else, such as a surface the path shades, answers true. Counts its rays in
    /// `rays`.
    #[allow(clippy::too_many_arguments)]
    fn gains_beyond(
        &self,
        scene: &Scene,
        ray: &Ray,
        next: Option<&PrimitiveHit>,
        cones: Option<&ConeVertex>,
        depth: u32,
        max_depth: u32,
        rays: &mut u64,
    ) -> bool {
        let primitives = scene.accelerator.primitives();
        let Some(mut hit) = next.copied() else {
            return self.finds_emission(scene, ray, None, cones);
        };
        if primitives[hit.primitive].light.is_some() {
            return self.finds_emission(scene, ray, Some(&hit), cones);
        }
        let mut ray = *ray;
        // `hit` is the vertex at `hit_depth`.
        for hit_depth in depth + 1..=depth + MIRROR_LOOKAHEAD {
            if hit_depth >= max_depth {
                return false;
            }
            if !matches!(
                scene.materials[primitives[hit.primitive].material as usize],
                Material::Mirror(_)
            ) {
                return true;
            }
            let (geometric_normal, frame) = Frame::facing(&hit.surface, ray.direction);
            let Some(reflected) = mirror_reflection(&hit.surface, &frame, geometric_normal, &ray)
            else {
                return false;
            };
            ray = reflected;
            // Beyond a mirror, emission counts unweighted (as for camera rays).
            *rays += 1;
            match scene.intersect(&ray, f64::INFINITY) {
                None => return scene.escaped(ray.direction) != DVec3::ZERO,
                Some(h) => match primitives[h.primitive].light {
                    Some(i) => {
                        let light = &scene.lights[i as usize];
                        return light.emitted(ray.direction, h.surface.uv) != DVec3::ZERO;
                    }
                    None => hit = h,
                },
            }
        }
        true
    }

    /// The radiance that `ray` carries back from what it hits (an area light) or, when it
    /// escapes, from the environment. `previous` is the BRDF density and origin of the sample
    /// that produced the ray (`None` for camera rays, which see emission unweighted); such
    /// emission is MIS-weighted against light sampling, or dropped under light-only sampling.
    /// `cones`: the previous vertex's light cones, whose lights BRDF rays do not count again
    /// and which leave the other lights a larger selection probability.
    fn emitted_along(
        &self,
        scene: &Scene,
        ray: &Ray,
        hit: Option<&PrimitiveHit>,
        previous: Option<(f64, DVec3)>,
        cones: Option<&ConeVertex>,
    ) -> DVec3 {
        let (le, pdf_light) = match hit {
            None => {
                let le = scene.escaped(ray.direction);
                let pdf = |origin: DVec3| -> f64 {
                    scene
                        .lights
                        .iter()
                        .filter(|l| matches!(l, crate::light::Light::Environment(_)))
                        .map(|l| l.pdf(origin, ray.direction))
                        .sum()
                };
                (le, previous.map(|(_, origin)| pdf(origin)))
            }
            Some(hit) => {
                let Some(index) = scene.accelerator.primitives()[hit.primitive].light else {
                    return DVec3::ZERO;
                };
                let light = &scene.lights[index as usize];
                if previous.is_some() && cones.is_some_and(|c| c.cone(light).is_some()) {
                    return DVec3::ZERO;
                }
                let le = light.emitted(ray.direction, hit.surface.uv);
                (
                    le,
                    previous.map(|(_, origin)| light.pdf(origin, ray.direction)),
                )
            }
        };
        if le == DVec3::ZERO {
            return DVec3::ZERO;
        }
        match (previous, pdf_light) {
            (Some((pdf_brdf, _)), Some(pdf_light)) => {
                if !self.use_brdf_hits {
                    DVec3::ZERO
                } else if self.use_light_sampling {
                    let pick = cones.map_or(self.light_pick, |c| c.pick_probability(&scene.lights));
                    le * power_heuristic(pdf_brdf, pdf_light * pick)
                } else {
                    le
                }
            }
            _ => le,
        }
    }
}

/// The radiance arriving at the camera along `camera_ray`: not finite when the path overflowed,
/// which the film counts (see [`crate::RenderStatistics::discarded_samples`]).
pub fn radiance(
    scene: &Scene,
    settings: &RenderSettings,
    camera_ray: &RayDifferential,
    sampler: &mut PixelSampler,
    state: &mut PathState,
) -> DVec3 {
    let max_depth = match settings.integrator {
        IntegratorKind::Direct => 1,
        IntegratorKind::Path => settings.max_depth,
    };
    let use_light_sampling = settings.light_strategy != LightStrategy::BrdfOnly;
    let use_brdf_hits = settings.light_strategy != LightStrategy::LightOnly;
    let light_count = scene.lights.len();
    let light_pick = if light_count > 0 {
        1.0 / light_count as f64
    } else {
        0.0
    };
    let weighting = EmissionWeighting {
        use_light_sampling,
        use_brdf_hits,
        light_pick,
    };

    let mut radiance = DVec3::ZERO;
    let mut throughput = DVec3::ONE;
    let mut ray = camera_ray.ray;
    // The density and origin of the BRDF sample that produced `ray` (None for camera rays).
    let mut previous: Option<(f64, DVec3)> = None;
    // The light cones of the vertex that produced `ray`, if any.
    let mut previous_cones: Option<ConeVertex> = None;
    // The path's ray differential while it is known (see `GlintFootprints`).
    let mut differential = match settings.glint_footprints {
        GlintFootprints::Never => None,
        GlintFootprints::FirstHit | GlintFootprints::All => Some(*camera_ray),
    };
    let mut depth = 0u32;
    // What `ray` hits, when the previous vertex traced it before computing its f (below).
    let mut traced: Option<Option<PrimitiveHit>> = None;
    loop {
        let hit = traced.take().unwrap_or_else(|| {
            state.rays += 1;
            scene.intersect(&ray, f64::INFINITY)
        });
        radiance += throughput
            * weighting.emitted_along(scene, &ray, hit.as_ref(), previous, previous_cones.as_ref());
        let Some(hit) = hit else {
            break;
        };
        let primitive = scene.accelerator.primitives()[hit.primitive];
        let surface = hit.surface;
        if primitive.light.is_some() {
            // Emitters do not reflect.
            break;
        }
        if depth >= max_depth {
            break;
        }
        let material = &scene.materials[primitive.material as usize];
        let (geometric_normal, frame) = Frame::facing(&surface, ray.direction);
        let wi_world = -ray.direction;
        let wi = frame.to_local(wi_world);
        if let Material::Mirror(mirror) = material {
            // A delta reflection: no light sample, and f·cos/pdf = R.
            let Some(reflected) = mirror_reflection(&surface, &frame, geometric_normal, &ray)
            else {
                break;
            };
            throughput *= mirror.reflectance(wi.z);
            if throughput == DVec3::ZERO {
                break;
            }
            ray = reflected;
            differential = differential
                .filter(|_| settings.glint_footprints == GlintFootprints::All)
                .and_then(|d| mirror_differential(scene, &primitive, &surface, &d, ray));
            previous = None;
            previous_cones = None;
            depth += 1;
            if !continue_path(&mut throughput, depth, settings, sampler) {
                break;
            }
            continue;
        }
        let footprint = match &differential {
            Some(d) if material.has_glints() => texture_footprint(&surface, d),
            _ => None,
        };
        let mut ctx = ShadingContext {
            uv: surface.uv,
            footprint,
            scratch: &mut state.scratch,
            counters: counters_of(&mut state.counters, primitive.material as usize),
        };
        // Next-event estimation: one light, chosen uniformly (among the lights without a cone
        // when light cones shade the others).
        let u_pick = sampler.next_1d();
        let u_light = sampler.next_2d();
        let cones = ConeVertex::at(
            settings,
            material,
            &ctx,
            surface.point,
            [frame.t, frame.b, frame.n],
            geometric_normal,
        );
        let picked = match &cones {
            Some(cones) => {
                radiance += throughput
                    * cones.direct(scene, material, wi, &mut ctx, u_light, &mut state.rays);
                cones
                    .pick(&scene.lights, u_pick)
                    .map(|i| (i, cones.pick_probability(&scene.lights)))
            }
            None => (light_count > 0).then(|| (uniform_index(u_pick, light_count), light_pick)),
        };
        if let (true, Some((light_index, light_pick))) = (use_light_sampling, picked) {
            let light = &scene.lights[light_index];
            if let Some(sample) = light.sample(surface.point, u_light) {
                let wo = frame.to_local(sample.direction);
                let same_side = sample.direction.dot(geometric_normal) > 0.0;
                // A dark point of a textured light adds nothing: no ray, no f.
                if same_side && wo.z > 0.0 && sample.radiance != DVec3::ZERO {
                    let unoccluded = |rays: &mut u64| {
                        let origin =
                            offset_origin(surface.point, geometric_normal, sample.direction);
                        let shadow = Ray {
                            origin,
                            direction: sample.direction,
                        };
                        *rays += 1;
                        let t_max = if sample.distance.is_finite() {
                            sample.distance * (1.0 - 1e-7)
                        } else {
                            f64::INFINITY
                        };
                        !scene.occluded(&shadow, t_max)
                    };
                    // The shadow ray is traced only if f needs it: for a glint query, after
                    // the negligible test and before the traversal. Any order gives the same
                    // contribution.
                    let rays = &mut state.rays;
                    let f = material
                        .eval_if_visible(wi, wo, &mut ctx, || unoccluded(rays))
                        .unwrap_or(DVec3::ZERO);
                    if f != DVec3::ZERO {
                        let pdf_light = sample.pdf * light_pick;
                        let weight = if sample.is_delta || !use_brdf_hits {
                            1.0
                        } else {
                            power_heuristic(pdf_light, material.pdf(wi, wo, surface.uv))
                        };
                        radiance += throughput * f * sample.radiance * (wo.z * weight / pdf_light);
                    }
                }
            }
        }
        // Extension: sample the BRDF.
        let u_lobe = sampler.next_1d();
        let [u0, u1] = sampler.next_2d();
        let [u2, u3] = sampler.next_2d();
        let Some((wo, lobe)) = material.sample_lobe(wi, u_lobe, [u0, u1, u2, u3], surface.uv)
        else {
            break;
        };
        let direction = frame.to_world(wo);
        if direction.dot(geometric_normal) <= 0.0 {
            break;
        }
        ray = Ray {
            origin: offset_origin(surface.point, geometric_normal, direction),
            direction,
        };
        // The ray goes before f (a tree query for glints) and the pdf: where the path ends at
        // what the ray hits, only emission along it can still count, so f and the pdf are
        // computed only when there is some (a throughput that would overflow there is not
        // computed either: the sample keeps what it has gathered). And f goes before the pdf
        // (a quadrature over the cone for glints): where f is 0, as for most glint queries, the
        // pdf is not needed.
        state.rays += 1;
        let next = scene.intersect(&ray, f64::INFINITY);
        if depth + 1 >= max_depth {
            // The last bounce.
            if weighting.finds_emission(scene, &ray, next.as_ref(), cones.as_ref()) {
                let f = material.eval(wi, wo, &mut ctx);
                let pdf = if f == DVec3::ZERO {
                    0.0
                } else {
                    material.pdf(wi, wo, surface.uv)
                };
                if pdf > 0.0 && pdf.is_finite() {
                    let previous = Some((pdf, surface.point));
                    let le = weighting.emitted_along(
                        scene,
                        &ray,
                        next.as_ref(),
                        previous,
                        cones.as_ref(),
                    );
                    radiance += throughput * f * le * (wo.z / pdf);
                }
            }
            break;
        }
        if !weighting.gains_beyond(
            scene,
            &ray,
            next.as_ref(),
            cones.as_ref(),
            depth,
            max_depth,
            &mut state.rays,
        ) {
            break;
        }
        traced = Some(next);
        let f = material.eval(wi, wo, &mut ctx);
        if f == DVec3::ZERO {
            break;
        }
        let pdf = material.pdf(wi, wo, surface.uv);
        if !(pdf > 0.0 && pdf.is_finite()) {
            break;
        }
        previous = Some((pdf, surface.point));
        previous_cones = cones;
        // The footprint goes on through near-specular glossy lobes under `All` (see
        // `crate::differentials`), and ends at any other bounce.
        differential = match (differential, lobe) {
            (Some(d), Lobe::Glossy { alpha })
                if settings.glint_footprints == GlintFootprints::All =>
            {
                glossy_bounce_differential(
                    scene,
                    &primitive,
                    &surface,
                    &frame,
                    (wi, wo),
                    alpha,
                    &d,
                    ray,
                )
            }
            _ => None,
        };
        throughput *= f * (wo.z / pdf);
        if !throughput.is_finite() {
            // An overflow (or 0·∞) on the path: the sample has no meaningful value; the film
            // discards and counts it.
            return DVec3::NAN;
        }
        if throughput == DVec3::ZERO {
            break;
        }
        depth += 1;
        if !continue_path(&mut throughput, depth, settings, sampler) {
            break;
        }
    }
    // Not finite after an overflow: the film discards and counts such samples.
    radiance
}

/// Russian roulette on the throughput's largest channel once `depth` reaches the roulette
/// depth: whether the path goes on (its throughput then divided by the survival probability).
fn continue_path(
    throughput: &mut DVec3,
    depth: u32,
    settings: &RenderSettings,
    sampler: &mut PixelSampler,
) -> bool {
    if depth >= settings.roulette_depth {
        let survive = throughput.max_element().min(0.95);
        let u = sampler.next_1d();
        if !(u < survive) {
            return false;
        }
        *throughput /= survive;
    }
    true
}

/// The film offset of a pixel sample for the filter (filter importance sampling: every sample
/// has weight 1). The Gaussian's truncated marginal is inverted from a tabulated CDF.
#[must_use]
pub fn filter_offset(filter: PixelFilter, u: [f64; 2]) -> DVec2 {
    match filter {
        PixelFilter::Box => DVec2::new(u[0] - 0.5, u[1] - 0.5),
        PixelFilter::Gaussian => DVec2::new(truncated_gaussian(u[0]), truncated_gaussian(u[1])),
    }
}

/// The inverse CDF of the Gaussian (σ = 0.5) truncated to [−1.5, 1.5]: linear interpolation
/// in a 4096-entry table built once by bisection on the closed-form CDF Φ(x) ∝ erf(x/(σ√2)).
/// The offsets' variance matches the truncated Gaussian's to 1e-4 (tested).
fn truncated_gaussian(u: f64) -> f64 {
    const ENTRIES: usize = 4096;
    static TABLE: std::sync::OnceLock<Vec<f64>> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        const SIGMA: f64 = 0.5;
        const RADIUS: f64 = 1.5;
        let cdf = |x: f64| glint_brdf::distribution::erf(x / (SIGMA * std::f64::consts::SQRT_2));
        let (lo_value, hi_value) = (cdf(-RADIUS), cdf(RADIUS));
        (0..=ENTRIES)
            .map(|i| {
                let target = lo_value + (i as f64 / ENTRIES as f64) * (hi_value - lo_value);
                let (mut lo, mut hi) = (-RADIUS, RADIUS);
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if cdf(mid) < target {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                0.5 * (lo + hi)
            })
            .collect()
    });
    let x = u.clamp(0.0, 1.0) * ENTRIES as f64;
    let i = (x as usize).min(ENTRIES - 1);
    let f = x - i as f64;
    table[i] + f * (table[i + 1] - table[i])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn power_heuristic_is_a_partition_of_unity() {
        for (a, b) in [(1.0, 2.0), (0.3, 0.0), (5.0, 5.0), (1e-3, 1e3)] {
            assert!((power_heuristic(a, b) + power_heuristic(b, a) - 1.0).abs() < 1e-15);
        }
        assert_eq!(power_heuristic(0.0, 1.0), 0.0);
    }

    #[test]
    fn gaussian_filter_offsets_have_the_truncated_variance() {
        let n = 100_000;
        let mut second_moment = 0.0;
        for i in 0..n {
            let x = truncated_gaussian((f64::from(i) + 0.5) / f64::from(n));
            assert!(x.abs() <= 1.5);
            second_moment += x * x;
        }
        second_moment /= f64::from(n);
        // Var of N(0, ¼) truncated at ±3σ: σ²(1 − 2·3φ(3)/(2Φ(3) − 1)) = 0.25·0.97335.
        assert!(
            (second_moment - 0.25 * 0.973_35).abs() < 1e-4,
            "{second_moment}"
        );
    }
}
