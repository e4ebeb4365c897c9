//! Eq. 11's prior run: the footprint area each glint material's count tree is built for.
//!
//! A node is split in space when E[A(query)]/A(node) < E[σ(query)]/σ(node) (Eq. 11), so the
//! tree serves queries of the planned area best. The paper takes E\[A\] from "a brief prior run
//! of the algorithm". A query much smaller than planned descends through directional splits it
//! cannot use and then through every spatial level down to its size; one much larger stops on
//! small boxes it covers only in part. On `stained_glass_closeup` (footprints near 5·10⁻¹⁰ of
//! the particles' square) the library's default of 10⁻⁶ costs 108 nodes per traversed query.
//!
//! The prior run here traces one camera ray per cell of a grid of at most [`PLAN_GRID`]² over
//! the image, at the scene file's resolution and footprint scale, from the camera at its first
//! keyframe, through perfect mirrors and, when the scene file sets `glint_footprints = "all"`,
//! through near-specular glossy lobes as the render does (one direction drawn from the
//! material's sampler; the footprint reflected about its facet and widened by the lobe's spread,
//! [`crate::differentials`]; a diffuse or rougher lobe drawn ends the ray), so that a glint
//! material seen mostly in polished metal or a glossy floor is planned for the footprints it
//! has there. At each glint hit it takes two query directions: toward
//! a light (one picked uniformly) and one drawn from the material's sampler. Eq. 11 compares
//! geometric solid angles where the particles' density is far from uniform, so the mean
//! footprint area is not always the best plan (on `stained_glass` a plan 4⁶ times smaller
//! visits half the nodes). The run therefore counts the nodes those queries visit in trees
//! built for other areas: from the geometric mean of the footprints it moves by factors of 4
//! while the count falls by [`PLAN_GAIN`] or more (within [`PLAN_STEPS`]). This is the paper's
//! prior run, used to measure the cost the plan is meant to lower. Its work is bounded: at most
//! [`PLAN_GRID`]² hits with two queries each per candidate, the first candidate counts at most
//! [`PLAN_NODE_BUDGET`] node visits (weighed by their tests' cost, which grows with the texture
//! tiles a footprint spans), and each later one stops counting once it has visited more nodes
//! than it may to be chosen. `sphere_lights.toml` with `fov = 179.999` and
//! `footprint_scale = 1e6` (footprints of hundreds of tiles) loads in 0.53 s. Candidates share the material's tables and negligible-query
//! test ([`GlintMaterial::with_realization`]); on the scenes in `scenes/` the run
//! adds 0.01–0.14 s to loading.
//!
//! The plan selects which particle set (of the same distribution) the scene renders, so it
//! depends only on the scene file: not on `--resolution`, `--spp`, `--frame` or
//! `--glint-footprints` (the scene file's own `glint_footprints` decides whether glossy lobes
//! are followed: scene files under `"first_hit"` keep the plans they had before glossy
//! footprints), and it is deterministic. A material with `expected_footprint_area`
//! in the scene file keeps that area.

use glam::{DVec2, DVec3};
use glint_brdf::{DiscreteBrdf, Footprint, QueryScratch};

use crate::bounce::{
    Frame, glossy_bounce_differential, mirror_differential, mirror_reflection, offset_origin,
};
use crate::camera::{RayDifferential, texture_footprint};
use crate::material::{GlintMaterial, Lobe, Material};
use crate::sampler::{PixelSampler, uniform_index};
use crate::scene::Scene;
use crate::settings::GlintFootprints;
use crate::shape::Ray;

/// Camera rays per image axis of the prior run, at most (one per pixel for smaller images).
pub const PLAN_GRID: u32 = 48;

/// The plans the prior run may choose: the geometric mean of the footprint areas (rounded to a
/// power of two) times 4^k for k in this range. A factor of 4 is one spatial level of the tree.
pub const PLAN_STEPS: std::ops::RangeInclusive<i32> = -10..=4;

/// The share of the prior run's node visits a step must save to be taken: smaller savings are
/// within the sampling noise of a few hundred queries, and would make the plan of a material
/// seen in few pixels a matter of chance.
pub const PLAN_GAIN: f64 = 0.05;

/// The range the geometric mean of the footprints is clamped to before the search (a plan far
/// outside any node's area changes nothing, and every candidate stays a valid, normal area).
const PLAN_MEAN_RANGE: [f64; 2] = [1.0 / (1u128 << 126) as f64, (1u64 << 40) as f64];

/// Node visits the first candidate counts at most, each weighed by its node test's cost
/// ([`nodes_visited`]); later candidates count at most 95% of the fewest so far. The prior
/// run's work per glint material is bounded by this times the candidates tried, whatever the
/// footprints: about 0.4 s per candidate at the bound. The shipped scenes' first candidates
/// count 2.4·10³–1.3·10⁵, so the bound leaves them 15 times room.
pub const PLAN_NODE_BUDGET: u64 = 2_000_000;

/// Mirror and glossy bounces the prior run follows after the camera ray, at most.
const PLAN_BOUNCES: u32 = 8;

/// The seed of the prior run's samples (fixed: the plan must not vary between runs).
const PLAN_SEED: u64 = 0x11;

/// One glint hit of the prior run.
#[derive(Clone, Copy, Debug)]
pub struct PlanHit {
    /// The material's index in the scene.
    pub material: usize,
    /// The hit's (u, v) and its derivatives per pixel, before the material's `uv_scale`.
    pub uv: DVec2,
    /// (∂(u,v)/∂x, ∂(u,v)/∂y).
    pub duv: (DVec2, DVec2),
    /// The direction toward the viewer, in the shading frame.
    pub wi: DVec3,
    /// A direction toward a light, in the shading frame, if one was found above the surface.
    pub to_light: Option<DVec3>,
    /// Four uniforms for a draw from the material's sampler.
    pub u_sampler: [f64; 4],
}

impl PlanHit {
    /// The footprint for a glint part with texture scale `uv_scale`, if it is valid.
    fn footprint(&self, uv_scale: f64) -> Option<Footprint> {
        let s = uv_scale;
        let footprint = Footprint::new(self.uv * s, self.duv.0 * s, self.duv.1 * s).ok()?;
        (footprint.area() > 0.0 && footprint.area().is_finite()).then_some(footprint)
    }
}

/// The prior run's glint hits: camera rays through a grid of pixel centres at the scene
/// file's settings, continued through perfect mirrors (and glossy lobes under `"all"`).
#[must_use]
pub fn prior_run(scene: &Scene) -> Vec<PlanHit> {
    let mut hits = Vec::new();
    if !scene.has_glints() {
        return hits;
    }
    let settings = &scene.settings;
    let first_frame = scene.camera.keyframes()[0].frame;
    let view = scene
        .camera
        .view(first_frame, settings.width, settings.height);
    let columns = settings.width.min(PLAN_GRID);
    let rows = settings.height.min(PLAN_GRID);
    for row in 0..rows {
        for column in 0..columns {
            let film = DVec2::new(
                (f64::from(column) + 0.5) * f64::from(settings.width) / f64::from(columns),
                (f64::from(row) + 0.5) * f64::from(settings.height) / f64::from(rows),
            );
            let differential = view.ray_differential(film, settings.footprint_scale);
            let mut sampler = PixelSampler::new(PLAN_SEED, column, row, 0);
            if let Some(hit) = follow(scene, differential, &mut sampler) {
                hits.push(hit);
            }
        }
    }
    hits
}

/// Follows one camera ray through perfect mirrors (and, under `"all"`, through glossy lobes
/// below [`crate::differentials::GLOSSY_FOOTPRINT_MAX_ALPHA`], along a direction drawn from the
/// material's sampler) to the first other surface: a [`PlanHit`] if it has glints and a
/// footprint.
fn follow(
    scene: &Scene,
    mut differential: RayDifferential,
    sampler: &mut PixelSampler,
) -> Option<PlanHit> {
    let follow_glossy = scene.settings.glint_footprints == GlintFootprints::All;
    for _ in 0..=PLAN_BOUNCES {
        let ray = differential.ray;
        let hit = scene.intersect(&ray, f64::INFINITY)?;
        let primitive = scene.accelerator.primitives()[hit.primitive];
        if primitive.light.is_some() {
            return None;
        }
        let surface = hit.surface;
        let (geometric_normal, frame) = Frame::facing(&surface, ray.direction);
        let material = primitive.material as usize;
        match &scene.materials[material] {
            Material::Mirror(_) => {
                let reflected = mirror_reflection(&surface, &frame, geometric_normal, &ray)?;
                differential =
                    mirror_differential(scene, &primitive, &surface, &differential, reflected)?;
            }
            glints if glints.has_glints() => {
                let duv = texture_footprint(&surface, &differential)?;
                let u_pick = sampler.next_1d();
                let u_light = sampler.next_2d();
                let to_light = (!scene.lights.is_empty())
                    .then(|| {
                        let pick = uniform_index(u_pick, scene.lights.len());
                        scene.lights[pick].sample(surface.point, u_light)
                    })
                    .flatten()
                    .map(|sample| frame.to_local(sample.direction))
                    .filter(|w| w.z > 0.0);
                let [a, b] = sampler.next_2d();
                let [c, d] = sampler.next_2d();
                return Some(PlanHit {
                    material,
                    uv: surface.uv,
                    duv,
                    wi: frame.to_local(-ray.direction),
                    to_light,
                    u_sampler: [a, b, c, d],
                });
            }
            other if follow_glossy => {
                let wi = frame.to_local(-ray.direction);
                let u_lobe = sampler.next_1d();
                let [a, b] = sampler.next_2d();
                let [c, d] = sampler.next_2d();
                let (wo, lobe) = other.sample_lobe(wi, u_lobe, [a, b, c, d], surface.uv)?;
                let Lobe::Glossy { alpha } = lobe else {
                    return None;
                };
                let direction = frame.to_world(wo);
                if direction.dot(geometric_normal) <= 0.0 {
                    return None;
                }
                let reflected = Ray {
                    origin: offset_origin(surface.point, geometric_normal, direction),
                    direction,
                };
                differential = glossy_bounce_differential(
                    scene,
                    &primitive,
                    &surface,
                    &frame,
                    (wi, wo),
                    alpha,
                    &differential,
                    reflected,
                )?;
            }
            _ => return None,
        }
    }
    None
}

/// The area of the prior run's footprints on `glint` (geometric mean, rounded to a power of
/// two, within `PLAN_MEAN_RANGE`), or `None` if it saw none.
#[must_use]
pub fn mean_area(glint: &GlintMaterial, hits: &[&PlanHit]) -> Option<f64> {
    let logs: Vec<f64> = hits
        .iter()
        .filter_map(|hit| hit.footprint(glint.uv_scale))
        .map(|f| f.area().log2())
        .collect();
    (!logs.is_empty()).then(|| {
        let [lowest, highest] = PLAN_MEAN_RANGE;
        (logs.iter().sum::<f64>() / logs.len() as f64)
            .round()
            .exp2()
            .clamp(lowest, highest)
    })
}

/// A query of the prior run on one glint part: the footprint and the two directions.
#[derive(Clone, Copy, Debug)]
pub struct PlanQuery {
    footprint: Footprint,
    wi: DVec3,
    wo: DVec3,
}

/// The prior run's queries on `glint` at `hits`, toward the light and along a direction drawn
/// from its sampler, leaving out those its tree skips as negligible (they visit nothing
/// whatever the plan, as the skip does not depend on it).
#[must_use]
pub fn plan_queries(
    glint: &GlintMaterial,
    hits: &[&PlanHit],
    scratch: &mut QueryScratch,
) -> Vec<PlanQuery> {
    let negligible_count = glint.brdf.parameters().negligible_count;
    let mut queries = Vec::new();
    for hit in hits {
        let Some(footprint) = hit.footprint(glint.uv_scale) else {
            continue;
        };
        // The sampler at the footprint's centre, as the bound BRDF samples (under a roughness
        // map, the levels weighted by their densities there).
        let sampled = glint
            .brdf
            .sample_direction_at(hit.wi, hit.u_sampler, footprint.center());
        for wo in [hit.to_light, sampled].into_iter().flatten() {
            let bound = glint
                .brdf
                .at(&footprint, scratch)
                .expected_count_bound(hit.wi, wo);
            if bound >= negligible_count {
                queries.push(PlanQuery {
                    footprint,
                    wi: hit.wi,
                    wo,
                });
            }
        }
    }
    queries
}

/// Tree nodes visited by `queries` on `brdf`, each weighed by what testing a node against its
/// footprint costs ([`Footprint::node_test_cost`]: 1 for footprints within four texture tiles,
/// more for larger ones), counted until the sum exceeds `limit` (a candidate that has visited
/// more cannot be chosen). So [`PLAN_NODE_BUDGET`] bounds the prior run's work, not only its
/// nodes, whatever the footprints.
#[must_use]
pub fn nodes_visited(
    brdf: &DiscreteBrdf,
    queries: &[PlanQuery],
    scratch: &mut QueryScratch,
    limit: u64,
) -> u64 {
    let mut nodes = 0u64;
    for query in queries {
        let result = brdf
            .at(&query.footprint, scratch)
            .evaluate(query.wi, query.wo);
        let cost = query.footprint.node_test_cost().min(1e9);
        nodes = nodes.saturating_add((f64::from(result.nodes_visited) * cost) as u64);
        if nodes > limit {
            break;
        }
    }
    nodes
}

/// The plan for `glint` from the prior run's hits on it: starting from the mean footprint
/// area, the area moves by factors of 4 (one spatial level) while each step saves at least
/// [`PLAN_GAIN`] of the nodes the queries visit, within [`PLAN_STEPS`]. `None` if the run saw none of its footprints.
///
/// # Errors
/// A candidate tree that cannot be built (never for a material that built once).
pub fn planned_area(
    glint: &GlintMaterial,
    hits: &[&PlanHit],
) -> Result<Option<f64>, glint_brdf::BrdfError> {
    let Some(mean) = mean_area(glint, hits) else {
        return Ok(None);
    };
    let mut scratch = QueryScratch::default();
    let queries = plan_queries(glint, hits, &mut scratch);
    let mut cost = |k: i32, limit: u64| -> Result<u64, glint_brdf::BrdfError> {
        // The queries are those the material's negligible-query test keeps, and the
        // candidate keeps that test (it does not depend on the area): it skips none of them.
        let seed = glint.brdf.parameters().seed;
        let candidate = glint.with_realization(seed, mean * 4f64.powi(k))?;
        Ok(nodes_visited(
            &candidate.brdf,
            &queries,
            &mut scratch,
            limit,
        ))
    };
    let (mut best, mut fewest) = (0, cost(0, PLAN_NODE_BUDGET)?);
    for direction in [-1, 1] {
        let mut k = best + direction;
        while PLAN_STEPS.contains(&k) {
            // A step is taken if it visits at most (1 − PLAN_GAIN) of the fewest nodes so far:
            // each candidate costs at most what the best one did.
            let limit = ((1.0 - PLAN_GAIN) * fewest as f64) as u64;
            let nodes = cost(k, limit)?;
            if nodes > limit {
                break;
            }
            (best, fewest) = (k, nodes);
            k += direction;
        }
        if best != 0 {
            break;
        }
    }
    Ok(Some(mean * 4f64.powi(best)))
}

/// Sets the `expected_footprint_area` of every glint part whose scene file left it open
/// ([`GlintMaterial::plan_footprint_area`]) to its plan from the scene's prior run (parts the
/// run never saw keep the library's default).
///
/// # Errors
/// A tree that cannot be rebuilt (never for materials that built once).
pub fn apply(scene: &mut Scene) -> Result<(), glint_brdf::BrdfError> {
    let hits = prior_run(scene);
    let mut materials = std::mem::take(&mut scene.materials);
    for (index, material) in materials.iter_mut().enumerate() {
        let on_it: Vec<&PlanHit> = hits.iter().filter(|h| h.material == index).collect();
        if on_it.is_empty() {
            continue;
        }
        *material = material.map_glints(&|glint| {
            if !glint.plan_footprint_area {
                return Ok(glint.clone());
            }
            match planned_area(glint, &on_it)? {
                Some(area) if area != glint.brdf.parameters().expected_footprint_area => {
                    glint.with_realization(glint.brdf.parameters().seed, area)
                }
                _ => Ok(glint.clone()),
            }
        })?;
    }
    scene.materials = materials;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene_file::parse_scene;
    use std::path::Path;

    /// A glint floor (material 0, 8 m × 8 m at y = 0) under a small sphere light, seen by
    /// `camera` (a `[camera]` section's body); `floor` goes into the floor's material and
    /// `more` after the floor's shape.
    fn glint_floor_scene(camera: &str, floor: &str, more: &str) -> Scene {
        glint_floor_scene_rendered("", camera, floor, more)
    }

    /// [`glint_floor_scene`] with `render` added to the `[render]` section.
    fn glint_floor_scene_rendered(render: &str, camera: &str, floor: &str, more: &str) -> Scene {
        let text = format!(
            r#"
            [render]
            {render}
            resolution = [32, 32]
            spp = 1
            integrator = "path"
            max_depth = 2

            [camera]
            {camera}

            [materials.floor]
            type = "glint"
            alpha = 0.05
            particles = 1e8
            gamma = 1.0
            {floor}

            [[shapes]]
            type = "rectangle"
            center = [0.0, 0.0, 0.0]
            u = [4.0, 0.0, 0.0]
            v = [0.0, 0.0, -4.0]
            material = "floor"

            {more}

            [[lights]]
            type = "sphere"
            center = [0.3, 2.0, 0.2]
            radius = 0.1
            power = 10.0
            "#
        );
        parse_scene(&text, Path::new("plan.toml")).unwrap()
    }

    /// A camera straight above the glint floor at `height`, with a 10° field of view; the
    /// particles' square is 8 m wide (uv_scale 0.5); `extra` goes into the floor's material.
    fn floor_scene(height: f64, extra: &str) -> Scene {
        let camera = format!(
            "position = [0.0, {height}, 0.0]\nlook_at = [0.0, 0.0, 0.0]\nup = [0.0, 0.0, -1.0]\nfov = 10"
        );
        glint_floor_scene(&camera, &format!("uv_scale = 0.5\n{extra}"), "")
    }

    fn glint(scene: &Scene) -> &GlintMaterial {
        match &scene.materials[0] {
            Material::Glint(g) => g,
            other => panic!("expected the glint floor, got {other:?}"),
        }
    }

    /// The footprints the prior run records are the pixels' areas on the floor: seen from
    /// straight above at height h, a pixel of a 10° field of view over 32 pixels covers
    /// (2h·tan 5°/32)² m², and the particles' square is 4 m / 0.5 = 8 m wide. Near the image
    /// centre the rays are almost vertical, so the geometric mean is within 1% of that.
    #[test]
    fn footprints_are_the_pixels_on_the_floor() {
        for height in [0.5, 3.0] {
            let scene = floor_scene(height, "");
            let hits = prior_run(&scene);
            assert_eq!(hits.len(), 32 * 32, "every camera ray meets the floor");
            let g = glint(&scene);
            let pixel = 2.0 * height * 5f64.to_radians().tan() / 32.0;
            let expected = (pixel / 8.0).powi(2);
            let logs: Vec<f64> = hits
                .iter()
                .map(|h| h.footprint(g.uv_scale).unwrap().area().ln())
                .collect();
            let mean = (logs.iter().sum::<f64>() / logs.len() as f64).exp();
            assert!(
                (mean / expected - 1.0).abs() < 0.01,
                "height {height}: mean footprint {mean:e}, a pixel {expected:e}"
            );
            let hits: Vec<&PlanHit> = hits.iter().collect();
            let rounded = mean_area(g, &hits).unwrap();
            assert_eq!(rounded, mean.log2().round().exp2());
        }
    }

    /// The plan is a local minimum of the prior run's node visits over the steps of 4: no
    /// neighbouring area saves PLAN_GAIN of them, and it visits no more nodes than the mean
    /// footprint area does.
    #[test]
    fn the_plan_is_where_the_prior_run_visits_fewest_nodes() {
        let scene = floor_scene(0.5, "");
        let g = glint(&scene);
        let planned = g.brdf.parameters().expected_footprint_area;
        let hits = prior_run(&scene);
        let hits: Vec<&PlanHit> = hits.iter().collect();
        let mean = mean_area(g, &hits).unwrap();
        let mut scratch = QueryScratch::default();
        let queries = plan_queries(g, &hits, &mut scratch);
        let mut cost = |area: f64| {
            let candidate = g
                .rebuilt(|p| {
                    p.expected_footprint_area = area;
                    p.negligible_count = 0.0;
                })
                .unwrap();
            nodes_visited(&candidate.brdf, &queries, &mut scratch, u64::MAX) as f64
        };
        let at_plan = cost(planned);
        assert!(at_plan > 0.0, "the prior run traverses the tree");
        assert!(
            at_plan <= cost(mean),
            "the plan is no worse than the mean area"
        );
        for neighbour in [planned / 4.0, planned * 4.0] {
            assert!(
                cost(neighbour) > (1.0 - PLAN_GAIN) * at_plan,
                "a step to {neighbour:e} saves more than {PLAN_GAIN} of {at_plan} nodes"
            );
        }
    }

    /// The plan depends on the scene file alone: loading twice gives the same trees, and a
    /// material that sets `expected_footprint_area` keeps it.
    #[test]
    fn plans_are_reproducible_and_scene_files_may_fix_them() {
        let a = floor_scene(0.5, "");
        let b = floor_scene(0.5, "");
        assert_eq!(glint(&a).brdf.parameters(), glint(&b).brdf.parameters());
        assert!(glint(&a).plan_footprint_area);
        let fixed = floor_scene(0.5, "expected_footprint_area = 3e-5");
        assert_eq!(
            glint(&fixed).brdf.parameters().expected_footprint_area,
            3e-5
        );
        assert!(!glint(&fixed).plan_footprint_area);
    }

    /// A glint floor seen only in a 45° panel of material `panel` (a material section's
    /// body), with `render` in the `[render]` section.
    fn panel_scene(render: &str, panel: &str) -> Scene {
        let camera = "position = [0.0, 1.0, 3.0]\nlook_at = [0.0, 1.0, 0.0]\nfov = 10";
        let mirror = format!(
            r#"
            [materials.panel]
            {panel}

            [[shapes]]
            type = "rectangle"
            center = [0.0, 1.0, 0.0]
            u = [2.0, 0.0, 0.0]
            v = [0.0, 1.4142, 1.4142]
            material = "panel"
            "#
        );
        glint_floor_scene_rendered(render, camera, "", &mirror)
    }

    /// The prior run follows perfect mirrors: a glint floor seen only in a 45° mirror gets
    /// every camera ray's footprint; with a diffuse panel in the mirror's place, none.
    #[test]
    fn the_prior_run_sees_glints_through_mirrors() {
        let mirrored = panel_scene("", r#"type = "mirror""#);
        let hits = prior_run(&mirrored);
        assert_eq!(hits.len(), 32 * 32);
        assert!(hits.iter().all(|h| h.material == 0));
        let diffuse = panel_scene("", r#"type = "diffuse""#);
        assert!(prior_run(&diffuse).is_empty());
    }

    /// Under `glint_footprints = "all"` the prior run follows glossy lobes as the render does:
    /// a conductor panel of α = 10⁻⁴ gives every camera ray the mirror's footprint (the mean
    /// area within 1%, the plan the same); a plastic coat of that α gives the coat's share of
    /// them; a rough conductor (α = 0.3, past the limit) none. Under `"first_hit"` glossy
    /// panels end every ray, as before.
    #[test]
    fn the_prior_run_follows_glossy_lobes_under_all() {
        let all = r#"glint_footprints = "all""#;
        let conductor = |alpha: f64| {
            format!(
                "type = \"conductor\"\nalpha = {alpha}\neta = [0.2, 0.9, 1.1]\nk = [3.9, 2.4, 2.2]"
            )
        };
        let mirror = panel_scene(all, r#"type = "mirror""#);
        let g = glint(&mirror);
        let mirror_hits = prior_run(&mirror);
        let area = |hits: &[PlanHit]| {
            let hits: Vec<&PlanHit> = hits.iter().collect();
            let logs: Vec<f64> = hits
                .iter()
                .map(|h| h.footprint(g.uv_scale).unwrap().area().ln())
                .collect();
            (logs.iter().sum::<f64>() / logs.len() as f64).exp()
        };
        let polished = panel_scene(all, &conductor(1e-4));
        let hits = prior_run(&polished);
        assert_eq!(hits.len(), 32 * 32);
        let ratio = area(&hits) / area(&mirror_hits);
        assert!((ratio - 1.0).abs() < 0.01, "area ratio {ratio}");
        assert_eq!(
            glint(&polished).brdf.parameters(),
            glint(&mirror).brdf.parameters()
        );
        // Rougher, within the limit: wider footprints.
        let satin = prior_run(&panel_scene(all, &conductor(0.02)));
        assert!(!satin.is_empty());
        assert!(area(&satin) > 10.0 * area(&mirror_hits));
        let coat = prior_run(&panel_scene(
            all,
            "type = \"plastic\"\nalpha = 1e-4\ncolour = 0.5",
        ));
        assert!(
            !coat.is_empty() && coat.len() < 32 * 32,
            "{} of the camera rays reach the floor through the coat",
            coat.len()
        );
        assert!(prior_run(&panel_scene(all, &conductor(0.3))).is_empty());
        assert!(prior_run(&panel_scene("", &conductor(1e-4))).is_empty());
    }

    /// Footprints far below any node's area (10⁻³⁰⁰ of the texture) still plan a valid area,
    /// within the clamped range.
    #[test]
    fn extreme_footprints_plan_a_valid_area() {
        let scene = floor_scene(0.5, "");
        let g = glint(&scene);
        let tiny = PlanHit {
            material: 0,
            uv: DVec2::new(0.3, 0.6),
            duv: (DVec2::new(1e-150, 0.0), DVec2::new(0.0, 1e-150)),
            wi: DVec3::new(0.1, 0.0, 1.0).normalize(),
            to_light: Some(DVec3::new(-0.1, 0.05, 1.0).normalize()),
            u_sampler: [0.3, 0.7, 0.2, 0.9],
        };
        let hits = vec![&tiny; 16];
        assert_eq!(mean_area(g, &hits), Some(PLAN_MEAN_RANGE[0]));
        let planned = planned_area(g, &hits).unwrap().unwrap();
        assert!(planned > 0.0 && planned.is_normal(), "planned {planned:e}");
    }

    /// Footprints spanning many texture tiles make each node test dearer, and the plan's
    /// budget counts that cost: a query over a 40-tile sliver is charged 10 times its nodes, so
    /// the run's work stays within [`PLAN_NODE_BUDGET`] per candidate (a legal scene of such
    /// footprints took 56.7 s to load when nodes were counted alone).
    #[test]
    fn the_budget_weighs_nodes_by_their_tests_cost() {
        let scene = floor_scene(0.5, "");
        let g = glint(&scene);
        let hit = |duv: (DVec2, DVec2)| PlanHit {
            material: 0,
            uv: DVec2::new(0.3, 0.6),
            duv,
            wi: DVec3::new(0.1, 0.0, 1.0).normalize(),
            to_light: Some(DVec3::new(-0.1, 0.0, 1.0).normalize()),
            u_sampler: [0.3, 0.7, 0.2, 0.9],
        };
        // uv_scale 0.5: a sliver 1e-3 by 80 is 40 tiles long (41 spanned).
        let sliver = hit((DVec2::new(2e-3, 0.0), DVec2::new(0.0, 80.0)));
        let mut scratch = QueryScratch::default();
        let queries = plan_queries(g, &[&sliver], &mut scratch);
        assert!(!queries.is_empty());
        let query = &queries[..1];
        let cost = query[0].footprint.node_test_cost();
        assert!((cost - 41.0 / 4.0).abs() < 1e-12, "{cost}");
        let nodes = g
            .brdf
            .at(&query[0].footprint, &mut scratch)
            .evaluate(query[0].wi, query[0].wo)
            .nodes_visited;
        assert_eq!(
            nodes_visited(&g.brdf, query, &mut scratch, u64::MAX),
            (f64::from(nodes) * cost) as u64
        );
    }
}
