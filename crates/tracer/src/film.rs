//! The render loop: the image (or its [`PixelBounds`]) in 16 × 16 tiles over rayon's threads,
//! each pixel with its own seeded sampler and samples that land in their own pixel only (the
//! filter jitters the sample within the pixel's filter support; nothing is splatted into
//! neighbours), so that the result is bit-identical for any thread count, tile order and
//! pixel bounds.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use glam::{DVec2, DVec3};
use glint_brdf::QueryScratch;
use rayon::prelude::*;

use crate::error::TracerError;
use crate::image::RgbImage;
use crate::integrator::{PathState, filter_offset, radiance};
use crate::limits::MAX_SAMPLE_RADIANCE;
use crate::material::GlintCounters;
use crate::sampler::{MAX_SAMPLES_PER_PIXEL, PixelSampler};
use crate::scene::Scene;
use crate::settings::{PixelBounds, RenderSettings};

/// The tile edge in pixels.
const TILE: u32 = 16;

/// Counts and times of a render, as in the paper's Table 1.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderStatistics {
    /// Glint queries (tree traversals), all materials.
    pub glint: GlintCounters,
    /// Glint queries per scene material that made any: the material's name in the scene file
    /// (or `material i` for a scene built without names) and its counters. The material is the
    /// one a primitive uses, so the glint parts of a mix count under the mix's name.
    pub glint_by_material: Vec<(String, GlintCounters)>,
    /// Rays traced (camera, extension and shadow rays).
    pub rays: u64,
    /// Camera samples taken.
    pub samples: u64,
    /// Samples whose radiance exceeded [`MAX_SAMPLE_RADIANCE`] in some channel and were
    /// clamped to it (extreme light values or estimator gains; the image is then biased there).
    pub clamped_samples: u64,
    /// Samples whose radiance was not finite (an overflow or 0·∞ on the path) and were
    /// discarded: they count as black in their pixel's mean.
    pub discarded_samples: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
}

impl RenderStatistics {
    /// Mean tree nodes visited per glint query.
    #[must_use]
    pub fn nodes_per_query(&self) -> f64 {
        self.glint.nodes_per_query()
    }

    /// Mean particles found per glint query.
    #[must_use]
    pub fn particles_per_query(&self) -> f64 {
        self.glint.particles_per_query()
    }

    /// Glint queries per second of wall-clock time.
    #[must_use]
    pub fn queries_per_second(&self) -> f64 {
        self.glint.queries as f64 / self.seconds.max(1e-9)
    }

    /// Rays per second of wall-clock time.
    #[must_use]
    pub fn rays_per_second(&self) -> f64 {
        self.rays as f64 / self.seconds.max(1e-9)
    }
}

impl std::fmt::Display for RenderStatistics {
    /// One line: time, rays per second and the Table 1 query statistics.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{:.2} s, {:.2} Mrays/s; {} glint queries ({} skipped as negligible, Σ bound {:.1e}), {:.1} nodes ({:.1} meeting the query) per traversed query, {:.3} particles per query (99% at most {:.3}), {:.0} queries/s",
            self.seconds,
            self.rays_per_second() * 1e-6,
            self.glint.queries,
            self.glint.negligible_queries,
            self.glint.negligible_bound,
            self.nodes_per_query(),
            self.glint.overlapping_nodes_per_query(),
            self.particles_per_query(),
            self.glint.particles_per_query_p99(),
            self.queries_per_second()
        )?;
        if self.clamped_samples > 0 || self.discarded_samples > 0 {
            write!(
                f,
                "; {} samples clamped to {MAX_SAMPLE_RADIANCE:e}, {} non-finite samples discarded",
                self.clamped_samples, self.discarded_samples
            )?;
        }
        Ok(())
    }
}

/// A sample's radiance as the film takes it: NaN or infinite channels discard the sample (black,
/// counted in `discarded`), channels above [`MAX_SAMPLE_RADIANCE`] are clamped to it (counted in
/// `clamped`), negative ones (never produced by the materials here) become 0.
fn admit(radiance: DVec3, clamped: &mut u64, discarded: &mut u64) -> DVec3 {
    if !radiance.is_finite() {
        *discarded += 1;
        return DVec3::ZERO;
    }
    if radiance.max_element() > MAX_SAMPLE_RADIANCE {
        *clamped += 1;
    }
    radiance.clamp(DVec3::ZERO, DVec3::splat(MAX_SAMPLE_RADIANCE))
}

/// A rendered image with its statistics.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    /// Linear radiance per pixel of [`RenderOutput::bounds`] (row 0 is the bounds' top row).
    pub image: RgbImage,
    /// The pixels rendered, in the full image of the settings' resolution.
    pub bounds: PixelBounds,
    /// Counts and time.
    pub statistics: RenderStatistics,
}

/// Checks the settings a render depends on.
///
/// # Errors
/// [`TracerError::Settings`] naming the setting.
pub fn validate_settings(settings: &RenderSettings) -> Result<(), TracerError> {
    let fail =
        |setting: &'static str, problem: String| Err(TracerError::Settings { setting, problem });
    if !(1..=16384).contains(&settings.width) || !(1..=16384).contains(&settings.height) {
        return fail(
            "resolution",
            format!(
                "{}x{} is outside 1..=16384 per side",
                settings.width, settings.height
            ),
        );
    }
    if !(1..=MAX_SAMPLES_PER_PIXEL).contains(&settings.samples_per_pixel) {
        return fail(
            "spp",
            format!(
                "{} is outside 1..={MAX_SAMPLES_PER_PIXEL}",
                settings.samples_per_pixel
            ),
        );
    }
    if !(1..=1024).contains(&settings.max_depth) {
        return fail(
            "max_depth",
            format!("{} is outside 1..=1024", settings.max_depth),
        );
    }
    if !(settings.footprint_scale > 0.0 && settings.footprint_scale <= 1e6) {
        return fail(
            "footprint_scale",
            format!(
                "{} must be in (0, 1e6] pixels",
                crate::limits::number(settings.footprint_scale)
            ),
        );
    }
    if !settings.exposure.is_finite() {
        return fail("exposure", "must be finite".into());
    }
    if let Some(problem) = settings
        .pixel_bounds
        .and_then(|b| b.problem(settings.width, settings.height))
    {
        return fail("pixel_bounds", problem);
    }
    Ok(())
}

/// Renders `scene` at camera frame `frame`; `progress(done, total)` is called as tiles finish.
/// Every pixel is finite, non-negative and at most [`MAX_SAMPLE_RADIANCE`]: samples beyond are
/// clamped or discarded and counted in the statistics.
///
/// # Errors
/// [`TracerError::Settings`] for settings out of range, [`TracerError::Camera`] when the
/// camera's pose at `frame` is degenerate.
pub fn render(
    scene: &Scene,
    settings: &RenderSettings,
    frame: f64,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<RenderOutput, TracerError> {
    render_until(scene, settings, frame, progress, &AtomicBool::new(false))
}

/// [`render`], stopped when `cancelled` becomes true: pixels not yet started are skipped and
/// the render returns [`TracerError::Cancelled`] within about one pixel's samples (the Python
/// package sets it on Ctrl-C).
///
/// # Errors
/// As [`render`], and [`TracerError::Cancelled`].
pub fn render_until(
    scene: &Scene,
    settings: &RenderSettings,
    frame: f64,
    progress: &(dyn Fn(u64, u64) + Sync),
    cancelled: &AtomicBool,
) -> Result<RenderOutput, TracerError> {
    validate_settings(settings)?;
    let start = Instant::now();
    let (width, height) = (settings.width, settings.height);
    let view = scene
        .camera
        .checked_view(frame, width, height)
        .map_err(|problem| TracerError::Camera { frame, problem })?;
    // Tiles cover the bounds from their corner; a pixel's value does not depend on its tile.
    let bounds = settings.bounds();
    let (crop_width, crop_height) = (bounds.width(), bounds.height());
    let tiles_x = crop_width.div_ceil(TILE);
    let tiles_y = crop_height.div_ceil(TILE);
    let total = u64::from(tiles_x * tiles_y);
    let done = std::sync::atomic::AtomicU64::new(0);
    // Each worker keeps one query scratch across its tiles (its memo of split counts serves
    // neighbouring tiles too, and is allocated once); a tile's counters are its own. The memo
    // never changes an answer, so the image does not depend on which worker renders a tile.
    let tiles: Vec<(Vec<DVec3>, PathState)> = (0..tiles_x * tiles_y)
        .into_par_iter()
        .map_init(QueryScratch::new, |scratch, tile| {
            let (x0, y0) = (
                bounds.x0 + (tile % tiles_x) * TILE,
                bounds.y0 + (tile / tiles_x) * TILE,
            );
            let (x1, y1) = ((x0 + TILE).min(bounds.x1), (y0 + TILE).min(bounds.y1));
            let mut state = PathState {
                scratch: std::mem::take(scratch),
                ..PathState::default()
            };
            let mut pixels = Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize);
            for y in y0..y1 {
                for x in x0..x1 {
                    if cancelled.load(Ordering::Relaxed) {
                        break;
                    }
                    let mut sum = DVec3::ZERO;
                    for index in 0..settings.samples_per_pixel {
                        let mut sampler = PixelSampler::new(settings.seed, x, y, index);
                        let offset = filter_offset(settings.filter, sampler.next_2d());
                        let film = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5) + offset;
                        let ray = view.ray_differential(film, settings.footprint_scale);
                        let sample = radiance(scene, settings, &ray, &mut sampler, &mut state);
                        sum += admit(
                            sample,
                            &mut state.clamped_samples,
                            &mut state.discarded_samples,
                        );
                    }
                    pixels.push(sum / f64::from(settings.samples_per_pixel));
                }
            }
            let finished = done.fetch_add(1, Ordering::Relaxed) + 1;
            progress(finished, total);
            *scratch = std::mem::take(&mut state.scratch);
            (pixels, state)
        })
        .collect();
    if cancelled.load(Ordering::Relaxed) {
        return Err(TracerError::Cancelled);
    }
    let mut image = RgbImage::filled(crop_width as usize, crop_height as usize, DVec3::ZERO);
    let mut statistics = RenderStatistics::default();
    let mut by_material = vec![GlintCounters::default(); scene.materials.len()];
    for (tile, (pixels, state)) in tiles.iter().enumerate() {
        let tile = tile as u32;
        // Tile corners relative to the bounds.
        let (x0, y0) = ((tile % tiles_x) * TILE, (tile / tiles_x) * TILE);
        let tile_width = (x0 + TILE).min(crop_width) - x0;
        for (i, p) in pixels.iter().enumerate() {
            let (x, y) = (x0 + i as u32 % tile_width, y0 + i as u32 / tile_width);
            image.pixels[(y * crop_width + x) as usize] = *p;
        }
        for (m, counters) in state.counters.iter().enumerate() {
            by_material[m].add(counters);
        }
        statistics.rays += state.rays;
        statistics.clamped_samples += state.clamped_samples;
        statistics.discarded_samples += state.discarded_samples;
    }
    for (m, counters) in by_material.into_iter().enumerate() {
        statistics.glint.add(&counters);
        if counters.queries > 0 {
            let name = scene
                .material_names
                .get(m)
                .cloned()
                .unwrap_or_else(|| format!("material {m}"));
            statistics.glint_by_material.push((name, counters));
        }
    }
    statistics.samples =
        u64::from(crop_width) * u64::from(crop_height) * u64::from(settings.samples_per_pixel);
    statistics.seconds = start.elapsed().as_secs_f64();
    Ok(RenderOutput {
        image,
        bounds,
        statistics,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene_file::parse_scene;
    use crate::settings::LightStrategy;
    use crate::test_scenes::GLITTER_FLOOR;
    use std::path::Path;

    fn scene(text: &str) -> Scene {
        parse_scene(text, Path::new("test.toml")).unwrap()
    }

    fn mean(image: &RgbImage) -> DVec3 {
        image.mean()
    }

    /// A white furnace: diffuse surfaces of albedo 1 (a sphere above a floor, so paths bounce
    /// between them) in a uniform environment of radiance 0.5 reflect exactly 0.5 everywhere.
    #[test]
    fn white_furnace_returns_the_environment() {
        let s = scene(
            r#"
[render]
resolution = [24, 16]
spp = 64
max_depth = 64
[camera]
position = [0, 1.5, 4]
look_at = [0, 0.3, 0]
[materials.white]
type = "diffuse"
colour = 1.0
[[shapes]]
type = "sphere"
center = [0, 0.6, 0]
radius = 0.6
material = "white"
[[shapes]]
type = "rectangle"
center = [0, 0, 0]
u = [6, 0, 0]
v = [0, 0, -6]
material = "white"
[[lights]]
type = "environment"
radiance = 0.5
"#,
        );
        let output = render(&s, &s.settings, 0.0, &|_, _| {}).unwrap();
        let m = mean(&output.image);
        // 384 pixels × 64 samples; per-sample spread ≲ 0.5 from roulette: σ(mean) ≈ 2e-3.
        assert!(
            (m - DVec3::splat(0.5)).abs().max_element() < 0.01,
            "furnace mean {m}"
        );
        let worst = output
            .image
            .pixels
            .iter()
            .map(|p| (p.x - 0.5).abs())
            .fold(0.0, f64::max);
        assert!(worst < 0.25, "a pixel strays {worst} from 0.5");
    }

    /// Light sampling, BRDF sampling and their MIS combination estimate the same image: block
    /// means over a diffuse floor and a plastic sphere lit by area lights agree within noise.
    #[test]
    fn mis_and_unweighted_estimators_agree() {
        let text = r#"
[render]
resolution = [32, 24]
spp = 256
max_depth = 2
[camera]
position = [0, 1.2, 3.5]
look_at = [0, 0.2, 0]
[materials.floor]
type = "conductor"
distribution = "ggx"
alpha = 0.12
eta = [0.2, 0.9, 1.1]
k = [3.9, 2.4, 2.2]
[materials.shiny]
type = "plastic"
colour = [0.2, 0.3, 0.6]
alpha = 0.08
distribution = "ggx"
[[shapes]]
type = "rectangle"
center = [0, 0, 0]
u = [5, 0, 0]
v = [0, 0, -5]
material = "floor"
[[shapes]]
type = "sphere"
center = [0.8, 0.4, 0.5]
radius = 0.4
material = "shiny"
[[lights]]
type = "sphere"
center = [-1, 2, 1]
radius = 0.3
power = 30
[[lights]]
type = "rectangle"
center = [0, 1.0, -2.5]
u = [3, 0, 0]
v = [0, 1.5, 0]
radiance = 2.0
"#;
        let mut s = scene(text);
        s.settings.samples_per_pixel = 16;
        // 4 × 4 blocks of 8 × 6 pixels; per strategy, the block means of 16 renders with
        // independent seeds give a mean and its standard error.
        let block = |image: &RgbImage, bx: usize, by: usize| {
            let mut sum = 0.0;
            for y in by * 6..by * 6 + 6 {
                for x in bx * 8..bx * 8 + 8 {
                    sum += crate::light::luminance(image.pixels[y * 32 + x]);
                }
            }
            sum / 48.0
        };
        let seeds = 16;
        let mut estimates = vec![];
        for strategy in [
            LightStrategy::Mis,
            LightStrategy::LightOnly,
            LightStrategy::BrdfOnly,
        ] {
            s.settings.light_strategy = strategy;
            let mut blocks = vec![vec![]; 16];
            for seed in 0..seeds {
                s.settings.seed = seed + 1000 * strategy as u64;
                let image = render(&s, &s.settings, 0.0, &|_, _| {}).unwrap().image;
                for (b, values) in blocks.iter_mut().enumerate() {
                    values.push(block(&image, b % 4, b / 4));
                }
            }
            let stats: Vec<(f64, f64)> = blocks
                .iter()
                .map(|v| {
                    let n = v.len() as f64;
                    let mean = v.iter().sum::<f64>() / n;
                    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
                    (mean, (var / n).sqrt())
                })
                .collect();
            estimates.push(stats);
        }
        // 32 comparisons of Student t with 15 degrees of freedom: |t| < 5 has family-wise
        // significance below 1%. A relative floor of 0.5% covers blocks with no noise at all.
        for b in 0..16 {
            let (reference, se_reference) = estimates[0][b];
            for (k, other) in estimates.iter().enumerate().skip(1) {
                let (value, se) = other[b];
                let spread = (se * se + se_reference * se_reference).sqrt() + 0.005 * reference;
                assert!(
                    (value - reference).abs() < 5.0 * spread,
                    "block {b}: strategy {k} gives {value} ± {se}, MIS {reference} ± {se_reference}"
                );
            }
        }
    }

    /// Each glint material's queries are counted under its own name, and the materials'
    /// counters add up to the totals.
    #[test]
    fn glint_statistics_are_kept_per_material() {
        let s = scene(
            r#"
[render]
resolution = [48, 24]
spp = 2
[camera]
position = [0, 1, 3]
look_at = [0, 0, 0]
[materials.sparse]
type = "glint"
alpha = 0.1
particles = 1e5
gamma = 1
[materials.dense]
type = "glint"
alpha = 0.1
particles = 1e9
gamma = 1
dense = "exact"
[materials.plain]
type = "diffuse"
colour = 0.5
[[shapes]]
type = "rectangle"
center = [-1, 0, 0]
u = [2, 0, 0]
v = [0, 0, -4]
material = "sparse"
[[shapes]]
type = "rectangle"
center = [1, 0, 0]
u = [2, 0, 0]
v = [0, 0, -4]
material = "dense"
[[shapes]]
type = "sphere"
center = [0, 0.3, -0.5]
radius = 0.3
material = "plain"
[[lights]]
type = "sphere"
center = [0, 1, -2]
radius = 0.1
power = 20
"#,
        );
        let statistics = render(&s, &s.settings, 0.0, &|_, _| {}).unwrap().statistics;
        let names: Vec<&str> = statistics
            .glint_by_material
            .iter()
            .map(|(name, _)| name.as_str())
            .collect();
        assert_eq!(names, ["sparse", "dense"]);
        let mut sum = GlintCounters::default();
        for (name, counters) in &statistics.glint_by_material {
            assert!(counters.queries > 100, "{name}: {counters:?}");
            // Every split tests at most four children, and splits only nodes meeting the query.
            assert!(counters.nodes_overlapping >= counters.queries, "{name}");
            assert!(
                counters.nodes_overlapping <= counters.nodes_visited,
                "{name}"
            );
            assert!(
                counters.nodes_visited <= counters.queries + 4 * counters.nodes_overlapping,
                "{name}"
            );
            sum.add(counters);
        }
        assert_eq!(sum, statistics.glint);
        // 10⁴ times the particles take more levels to resolve (counted exactly: the lattice
        // would answer the dense material from fewer cells).
        let [(_, sparse), (_, dense)] = &statistics.glint_by_material[..] else {
            unreachable!("two materials")
        };
        assert!(dense.nodes_per_query() > sparse.nodes_per_query() + 4.0);
    }

    /// A camera looking down at a glint floor that fills its view (α = 0.3, N = 10⁶, γ = 5°,
    /// every query traversed), 16×12 at 4 spp, with the `[render]` lines `render` and then
    /// `rest` (lights, more materials and shapes).
    fn glint_floor_scene(render: &str, rest: &str) -> String {
        format!(
            r#"
[render]
resolution = [16, 12]
spp = 4
{render}
[camera]
position = [0, 1, 0]
look_at = [0, 0, -1]
fov = 40
[materials.glitter]
type = "glint"
alpha = 0.3
particles = 1e6
gamma = 5
negligible_count = 0
[[shapes]]
type = "rectangle"
center = [0, 0, 0]
u = [40, 0, 0]
v = [0, 0, -40]
material = "glitter"
{rest}"#
        )
    }

    /// A BRDF sample's f (a glint query) is computed only where the path can still gain from
    /// it. A glint floor under the sun alone sends every BRDF-sampled ray into a black sky, so
    /// a path of up to five bounces makes exactly the queries and the image of direct
    /// lighting: one query per camera sample, for the sun, not two. A mirror the sampled rays
    /// meet, which sends them on into the sky, changes neither; one that sends them on to a
    /// light does.
    #[test]
    fn glint_queries_skip_brdf_samples_that_gain_nothing() {
        let floor = glint_floor_scene(
            "integrator = \"path\"\nmax_depth = 5",
            r#"
[materials.mirror]
type = "mirror"
colour = 0.9
[[lights]]
type = "directional"
direction = [0, 4, -1]
irradiance = 1
"#,
        );
        let floor = floor.as_str();
        // Out of the camera's view (the floor fills it) and below the sun's shadow rays, it
        // faces the camera: the floor's sampled rays that meet it go back up into the sky.
        let mirror = r#"
[[shapes]]
type = "rectangle"
center = [0, 1.25, -3]
u = [40, 0, 0]
v = [0, 2.5, 0]
material = "mirror"
"#;
        let run = |text: &str| {
            let s = scene(text);
            let output = render(&s, &s.settings, 0.0, &|_, _| {}).unwrap();
            (
                output.statistics.glint.queries,
                output.image,
                output.statistics.rays,
            )
        };
        let (direct_queries, direct, _) = run(&floor.replace("\"path\"", "\"direct\""));
        let (path_queries, path, path_rays) = run(floor);
        let (mirror_queries, mirrored, mirror_rays) = run(&format!("{floor}{mirror}"));
        let samples = 16 * 12 * 4;
        assert_eq!(direct_queries, samples);
        assert_eq!(path_queries, samples);
        assert_eq!(mirror_queries, samples);
        assert!(mean(&direct).max_element() > 0.0);
        assert_eq!(path.pixels, direct.pixels);
        assert_eq!(mirrored.pixels, direct.pixels);
        // A quarter of the samples' BRDF rays, at least, meet the mirror and are followed
        // past it (a ray each).
        assert!(
            mirror_rays > path_rays + samples / 4,
            "{mirror_rays} rays, {path_rays} without the mirror"
        );
        // Where the mirror sends them on to a light, their f is computed: with a sphere light
        // above the camera, in their way.
        let light = r#"
[[lights]]
type = "sphere"
center = [0, 6, 2]
radius = 3
power = 100
"#;
        let (lit_queries, _, _) = run(&format!("{floor}{mirror}{light}"));
        assert!(lit_queries > samples + samples / 8, "{lit_queries} queries");
    }

    /// A light sample at a dark point of a light (here a light that emits nothing) costs no
    /// shadow ray and no glint query: its contribution is 0 whatever they would answer.
    #[test]
    fn dark_light_samples_cost_no_query() {
        let s = scene(&glint_floor_scene(
            "integrator = \"direct\"",
            r#"
[[lights]]
type = "rectangle"
center = [0, 2, -3]
u = [2, 0, 0]
v = [0, 0, 2]
radiance = 0
"#,
        ));
        let output = render(&s, &s.settings, 0.0, &|_, _| {}).unwrap();
        assert_eq!(output.statistics.glint.queries, 0);
        // Camera rays and BRDF-sampled rays only.
        assert!(output.statistics.rays <= 2 * 16 * 12 * 4);
        assert_eq!(mean(&output.image), DVec3::ZERO);
    }

    /// The film takes every sample's radiance explicitly: non-finite ones are discarded and
    /// counted, those above the cap clamped to it and counted, so that a pixel is always
    /// finite and at most MAX_SAMPLE_RADIANCE.
    #[test]
    fn samples_beyond_the_film_range_are_counted() {
        let (mut clamped, mut discarded) = (0, 0);
        let cases = [
            (DVec3::new(0.5, 1.0, 2.0), DVec3::new(0.5, 1.0, 2.0)),
            (
                DVec3::new(1e300, 0.5, 0.0),
                DVec3::new(MAX_SAMPLE_RADIANCE, 0.5, 0.0),
            ),
            (DVec3::new(f64::INFINITY, 0.5, 0.0), DVec3::ZERO),
            (DVec3::new(f64::NAN, 0.5, 0.0), DVec3::ZERO),
            (DVec3::new(-1.0, 0.5, 0.0), DVec3::new(0.0, 0.5, 0.0)),
        ];
        for (sample, expected) in cases {
            assert_eq!(admit(sample, &mut clamped, &mut discarded), expected);
        }
        assert_eq!((clamped, discarded), (1, 2));
        let statistics = RenderStatistics {
            clamped_samples: 1,
            discarded_samples: 2,
            ..RenderStatistics::default()
        };
        let line = statistics.to_string();
        assert!(
            line.contains("1 samples clamped") && line.contains("2 non-finite"),
            "{line}"
        );
    }

    /// A frame whose interpolated camera pose is degenerate is an error naming the frame, not
    /// a black image; the frames around it render.
    #[test]
    fn degenerate_frames_are_errors_naming_the_frame() {
        let s = scene(
            r#"
[render]
resolution = [8, 6]
spp = 1
[camera]
position = [0, 0, 5]
look_at = [0, 0, 0]
[[camera.keyframes]]
frame = 0
[[camera.keyframes]]
frame = 10
position = [0, 0, -5]
[materials.grey]
type = "diffuse"
[[shapes]]
type = "sphere"
center = [0, -2, 0]
radius = 1
material = "grey"
[[lights]]
type = "directional"
direction = [0, 1, 0]
irradiance = 1
"#,
        );
        assert!(render(&s, &s.settings, 4.0, &|_, _| {}).is_ok());
        match render(&s, &s.settings, 5.0, &|_, _| {}) {
            Err(error @ TracerError::Camera { frame, .. }) => {
                assert_eq!(frame, 5.0);
                assert!(error.to_string().contains("frame 5"), "{error}");
            }
            other => panic!("{other:?}"),
        }
    }

    /// The image is bit-identical for one thread and for several, glints included.
    #[test]
    fn images_do_not_depend_on_the_thread_count() {
        let text = GLITTER_FLOOR;
        let s = scene(text);
        let outputs: Vec<RenderOutput> = [1, 2, 3]
            .into_iter()
            .map(|threads| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                pool.install(|| render(&s, &s.settings, 0.0, &|_, _| {}).unwrap())
            })
            .collect();
        // The query statistics too (the same queries, summed in tile order).
        for output in &outputs[1..] {
            assert_eq!(
                output.statistics.glint_by_material,
                outputs[0].statistics.glint_by_material
            );
        }
        let images: Vec<RgbImage> = outputs.into_iter().map(|o| o.image).collect();
        for image in &images[1..] {
            assert!(
                images[0]
                    .pixels
                    .iter()
                    .zip(&image.pixels)
                    .all(|(a, b)| a.to_array().map(f64::to_bits) == b.to_array().map(f64::to_bits))
            );
        }
        assert!(mean(&images[0]).x > 0.0, "the glints must show");
    }

    fn same_bits(a: &[DVec3], b: &[DVec3]) -> bool {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(a, b)| a.to_array().map(f64::to_bits) == b.to_array().map(f64::to_bits))
    }

    /// Pixel bounds render exactly the full image's pixels there, bit for bit, whatever the
    /// bounds' alignment to tiles (single pixels, bounds straddling tiles, the whole image), and
    /// count only their own samples.
    #[test]
    fn pixel_bounds_give_the_full_images_pixels_bit_for_bit() {
        let s = scene(GLITTER_FLOOR);
        let full = render(&s, &s.settings, 0.0, &|_, _| {}).unwrap();
        assert_eq!(full.bounds, PixelBounds::full(40, 24));
        for [x0, x1, y0, y1] in [
            [0, 40, 0, 24],
            [3, 21, 5, 22],
            [39, 40, 23, 24],
            [16, 32, 0, 24],
        ] {
            let bounds = PixelBounds { x0, x1, y0, y1 };
            let mut settings = s.settings;
            settings.pixel_bounds = Some(bounds);
            let crop = render(&s, &settings, 0.0, &|_, _| {}).unwrap();
            assert_eq!(crop.bounds, bounds);
            assert_eq!(
                (crop.image.width, crop.image.height),
                ((x1 - x0) as usize, (y1 - y0) as usize)
            );
            let expected: Vec<DVec3> = (y0..y1)
                .flat_map(|y| (x0..x1).map(move |x| (x, y)))
                .map(|(x, y)| full.image.pixels[(y * 40 + x) as usize])
                .collect();
            assert!(same_bits(&crop.image.pixels, &expected), "{bounds:?}");
            assert_eq!(
                crop.statistics.samples,
                u64::from((x1 - x0) * (y1 - y0)) * u64::from(settings.samples_per_pixel)
            );
        }
    }

    /// Bounds that are empty or reach outside the image are errors naming `pixel_bounds`, from
    /// the settings and from a scene file.
    #[test]
    fn bad_pixel_bounds_are_named_errors() {
        let s = scene(GLITTER_FLOOR);
        for [x0, x1, y0, y1] in [[5, 5, 0, 4], [0, 41, 0, 24], [0, 40, 10, 25], [7, 3, 0, 1]] {
            let mut settings = s.settings;
            settings.pixel_bounds = Some(PixelBounds { x0, x1, y0, y1 });
            let error = render(&s, &settings, 0.0, &|_, _| {})
                .unwrap_err()
                .to_string();
            assert!(error.contains("pixel_bounds"), "{error}");
            let text = GLITTER_FLOOR.replace(
                "spp = 2",
                &format!("spp = 2\npixel_bounds = [{x0}, {x1}, {y0}, {y1}]"),
            );
            let error = parse_scene(&text, Path::new("bounds.toml"))
                .unwrap_err()
                .to_string();
            assert!(error.contains("render.pixel_bounds"), "{error}");
        }
        let text = GLITTER_FLOOR.replace("spp = 2", "spp = 2\npixel_bounds = [1, 2, 3]");
        assert!(parse_scene(&text, Path::new("b.toml")).is_err());
        let text = GLITTER_FLOOR.replace("spp = 2", "spp = 2\npixel_bounds = [8, 24, 4, 20]");
        let s = scene(&text);
        assert_eq!(
            s.settings.pixel_bounds,
            Some(PixelBounds {
                x0: 8,
                x1: 24,
                y0: 4,
                y1: 20
            })
        );
    }

    /// A cancelled render stops and says so; an uncancelled one is the plain render.
    #[test]
    fn a_cancelled_render_returns_cancelled() {
        let s = scene(GLITTER_FLOOR);
        let cancelled = AtomicBool::new(true);
        let result = render_until(&s, &s.settings, 0.0, &|_, _| {}, &cancelled);
        assert_eq!(result.unwrap_err(), TracerError::Cancelled);
        let running = AtomicBool::new(false);
        let a = render_until(&s, &s.settings, 0.0, &|_, _| {}, &running).unwrap();
        let b = render(&s, &s.settings, 0.0, &|_, _| {}).unwrap();
        assert!(same_bits(&a.image.pixels, &b.image.pixels));
    }
}
