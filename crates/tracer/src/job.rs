//! A render job as `cargo xtask render` and the Python package's `glint.render` run it: a scene
//! file loaded once, the command line's options applied to its settings, frames rendered one
//! at a time, and each frame's summary (the JSON written beside the images). Both go through
//! this one path, so a frame or a crop rendered from Python, on a farm's worker, is bit for bit
//! the one the command line renders.
//!
//! A frame's image is returned as the EXR stores it: every channel rounded to a 32-bit float.
//! Tone mapping and bloom ([`RenderJob::display_image`]) start from those values, so that a
//! frame put together from crops gives the same PNG as the frame rendered whole.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use crate::error::TracerError;
use crate::film::{RenderStatistics, render_until};
use crate::image::RgbImage;
use crate::material::Material;
use crate::scene::Scene;
use crate::scene_file::load_scene;
use crate::settings::{
    GlintFootprints, GlintRandomness, IntegratorKind, PixelBounds, RenderSettings,
};

/// What a job changes of the scene file's own settings; `None` and `false` keep the scene's.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RenderOptions {
    /// Samples per pixel.
    pub samples_per_pixel: Option<u32>,
    /// Image width and height in pixels.
    pub resolution: Option<(u32, u32)>,
    /// Only these pixels of the image.
    pub pixel_bounds: Option<PixelBounds>,
    /// The longest path in bounces.
    pub max_depth: Option<u32>,
    /// Path tracing or direct illumination.
    pub integrator: Option<IntegratorKind>,
    /// Where glint materials use the pixel footprint.
    pub glint_footprints: Option<GlintFootprints>,
    /// Every glint material's `negligible_count`.
    pub negligible_count: Option<f64>,
    /// Every glint material replaced by its smooth limit.
    pub smooth: bool,
    /// A new particle set in every frame.
    pub per_frame_glints: bool,
    /// Sphere lights at glint hits shaded by one query in the light's own cone.
    pub glint_light_cones: bool,
}

/// One frame of a job: its image (of the job's pixel bounds) and statistics.
#[derive(Clone, Debug)]
pub struct FrameOutput {
    /// The camera frame.
    pub frame: i64,
    /// Linear radiance, each channel rounded to a 32-bit float (as the EXR holds it).
    pub image: RgbImage,
    /// The pixels rendered, in the full image.
    pub bounds: PixelBounds,
    /// Counts and time.
    pub statistics: RenderStatistics,
}

/// A scene file loaded with its options applied, ready to render frames.
#[derive(Debug)]
pub struct RenderJob {
    /// The scene file.
    pub scene_path: PathBuf,
    /// The scene as rendered (smooth or reseeded materials included).
    pub scene: Scene,
    /// The settings after the options.
    pub settings: RenderSettings,
    /// The options the job was made with.
    pub options: RenderOptions,
    /// Seconds spent loading and building the scene (its prior run included).
    pub build_seconds: f64,
    /// The materials before per-frame reseeding.
    base_materials: Vec<Material>,
    /// Each glint material's planned expected footprint areas (Eq. 11), by name, before
    /// `smooth` removed the glints.
    plans: Vec<(String, Vec<f64>)>,
    /// Each glint material's N per texture square (of each glint part), by name.
    particles: Vec<(String, Vec<u64>)>,
}

impl RenderJob {
    /// Loads `scene_path` and applies `options`.
    ///
    /// # Errors
    /// The scene file's errors ([`TracerError::Scene`], [`TracerError::Asset`]), and
    /// [`TracerError::Settings`] naming an option out of range (`spp`, `resolution`,
    /// `pixel_bounds`, `max_depth`, `negligible_count`).
    pub fn load(scene_path: &Path, options: RenderOptions) -> Result<Self, TracerError> {
        let start = std::time::Instant::now();
        let mut scene = load_scene(scene_path)?;
        let build_seconds = start.elapsed().as_secs_f64();
        let glints = || {
            scene
                .material_names
                .iter()
                .zip(&scene.materials)
                .filter(|(_, m)| m.has_glints())
        };
        let plans = glints()
            .map(|(name, m)| (name.clone(), m.expected_footprint_areas()))
            .collect();
        let particles = glints()
            .map(|(name, m)| (name.clone(), m.glint_particles()))
            .collect();
        if let Some(count) = options.negligible_count {
            scene
                .set_negligible_count(count)
                .map_err(|e| TracerError::Settings {
                    setting: "negligible_count",
                    problem: e.to_string(),
                })?;
        }
        if options.smooth {
            scene.make_smooth();
        }
        let mut settings = scene.settings;
        if options.per_frame_glints {
            settings.glint_randomness = GlintRandomness::PerFrame;
        }
        if options.glint_light_cones {
            settings.glint_light_cones = true;
        }
        if let Some(spp) = options.samples_per_pixel {
            settings.samples_per_pixel = spp;
        }
        if let Some(depth) = options.max_depth {
            settings.max_depth = depth;
        }
        if let Some(integrator) = options.integrator {
            settings.integrator = integrator;
        }
        if let Some(footprints) = options.glint_footprints {
            settings.glint_footprints = footprints;
        }
        if let Some((width, height)) = options.resolution {
            settings.width = width;
            settings.height = height;
        }
        if options.pixel_bounds.is_some() {
            settings.pixel_bounds = options.pixel_bounds;
        }
        crate::film::validate_settings(&settings)?;
        let base_materials = scene.materials.clone();
        Ok(Self {
            scene_path: scene_path.to_path_buf(),
            scene,
            settings,
            options,
            build_seconds,
            base_materials,
            plans,
            particles,
        })
    }

    /// Renders only `bounds` from now on (`None`: the whole image), as if the job had been
    /// loaded with them: a farm's worker renders every tile of a frame from one loaded scene.
    ///
    /// # Errors
    /// [`TracerError::Settings`] naming `pixel_bounds` when they are empty or outside the
    /// image; the job is then unchanged.
    pub fn set_pixel_bounds(&mut self, bounds: Option<PixelBounds>) -> Result<(), TracerError> {
        let settings = RenderSettings {
            pixel_bounds: bounds.or(self.scene.settings.pixel_bounds),
            ..self.settings
        };
        crate::film::validate_settings(&settings)?;
        self.settings = settings;
        self.options.pixel_bounds = bounds;
        Ok(())
    }

    /// Each glint material's N per texture square (one per glint part), by name: what a
    /// material given in `flakes_per_mm2` converted to on its shape.
    #[must_use]
    pub fn glint_particles(&self) -> &[(String, Vec<u64>)] {
        &self.particles
    }

    /// Renders camera frame `frame`; `progress(done, total)` is called as tiles finish, and
    /// the render stops when `cancelled` becomes true ([`crate::film::render_until`]).
    ///
    /// # Errors
    /// [`TracerError::Camera`] when the camera's pose at `frame` is degenerate,
    /// [`TracerError::Cancelled`].
    pub fn render_frame(
        &mut self,
        frame: i64,
        progress: &(dyn Fn(u64, u64) + Sync),
        cancelled: &AtomicBool,
    ) -> Result<FrameOutput, TracerError> {
        if self.settings.glint_randomness == GlintRandomness::PerFrame {
            self.scene
                .reseed_glints_for_frame(&self.base_materials, frame)
                .map_err(|e| TracerError::Settings {
                    setting: "glint_randomness",
                    problem: e.to_string(),
                })?;
        }
        let output = render_until(
            &self.scene,
            &self.settings,
            frame as f64,
            progress,
            cancelled,
        )?;
        let mut image = output.image;
        for p in &mut image.pixels {
            *p = p.as_vec3().as_dvec3();
        }
        Ok(FrameOutput {
            frame,
            image,
            bounds: output.bounds,
            statistics: output.statistics,
        })
    }

    /// The image as the PNG shows it: with the scene's bloom, if any (the EXR has none).
    #[must_use]
    pub fn display_image(&self, image: &RgbImage) -> RgbImage {
        display_image(image, &self.settings)
    }

    /// The frame's summary: the scene file and the assets it read (`sources`), the job's
    /// settings, the pixel bounds, the statistics (the paper's Table 1 quantities) and the
    /// planned footprint areas; `threads` is recorded as given.
    #[must_use]
    pub fn summary(&self, output: &FrameOutput, threads: usize) -> serde_json::Value {
        let s = &output.statistics;
        let b = output.bounds;
        let settings = &self.settings;
        let sources: Vec<String> = std::iter::once(&self.scene_path)
            .chain(&self.scene.assets)
            .map(|p| p.display().to_string())
            .collect();
        serde_json::json!({
            "scene": self.scene_path.display().to_string(),
            "sources": sources,
            "frame": output.frame,
            "resolution": [settings.width, settings.height],
            "pixel_bounds": [b.x0, b.x1, b.y0, b.y1],
            "spp": settings.samples_per_pixel,
            "smooth": self.options.smooth,
            "glint_footprints": match settings.glint_footprints {
                GlintFootprints::FirstHit => "first_hit",
                GlintFootprints::All => "all",
                GlintFootprints::Never => "never",
            },
            "exposure": settings.exposure,
            "bloom": settings.bloom.map(|b| serde_json::json!({
                "threshold": b.threshold,
                "radius": b.radius,
                "strength": b.strength,
            })),
            "threads": threads,
            "seconds": s.seconds,
            "rays": s.rays,
            "rays_per_second": s.rays_per_second(),
            "glint_queries": s.glint.queries,
            "negligible_queries": s.glint.negligible_queries,
            "negligible_bound": s.glint.negligible_bound,
            "nodes_per_query": s.nodes_per_query(),
            "overlapping_nodes_per_query": s.glint.overlapping_nodes_per_query(),
            "particles_per_query": s.particles_per_query(),
            "particles_per_query_p99": s.glint.particles_per_query_p99(),
            "particles_histogram": s.glint.particles.nonempty(),
            "queries_per_second": s.queries_per_second(),
            "clamped_samples": s.clamped_samples,
            "discarded_samples": s.discarded_samples,
            "materials": s.glint_by_material.iter().map(|(name, c)| serde_json::json!({
                "name": name,
                "glint_queries": c.queries,
                "negligible_queries": c.negligible_queries,
                "negligible_bound": c.negligible_bound,
                "nodes_per_query": c.nodes_per_query(),
                "overlapping_nodes_per_query": c.overlapping_nodes_per_query(),
                "particles_per_query": c.particles_per_query(),
                "particles_per_query_p99": c.particles_per_query_p99(),
                "particles_histogram": c.particles.nonempty(),
            })).collect::<Vec<_>>(),
            "particles_per_square": self.particles.iter()
                .map(|(name, n)| (name.clone(), serde_json::json!(n)))
                .collect::<serde_json::Map<_, _>>(),
            "expected_footprint_areas": self.plans.iter()
                .map(|(name, areas)| (name.clone(), serde_json::json!(areas)))
                .collect::<serde_json::Map<_, _>>(),
        })
    }

    /// Writes the frame's linear EXR (recording its bounds in the full image), its PNG (with
    /// bloom, over the bounds alone) and its summary JSON.
    ///
    /// # Errors
    /// [`TracerError::Output`] naming the file that cannot be written.
    pub fn write_outputs(
        &self,
        output: &FrameOutput,
        threads: usize,
        [exr, png, json]: [&Path; 3],
    ) -> Result<(), TracerError> {
        output.image.write_exr_in(
            exr,
            output.bounds,
            self.settings.width,
            self.settings.height,
        )?;
        self.display_image(&output.image)
            .write_png(png, self.settings.exposure)?;
        let text = serde_json::to_string_pretty(&self.summary(output, threads))
            .expect("a JSON value always serializes")
            + "\n";
        std::fs::write(json, text).map_err(|e| TracerError::Output {
            path: json.to_path_buf(),
            problem: e.to_string(),
        })
    }
}

/// `image` as the PNG of a render with `settings` shows it: with its bloom, if any.
#[must_use]
pub fn display_image(image: &RgbImage, settings: &RenderSettings) -> RgbImage {
    match settings.bloom {
        Some(b) => image.bloomed(b.threshold, b.radius, b.strength),
        None => image.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A glittery floor as a scene file in a temporary folder.
    fn scene_file(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("glint-job-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("floor.toml");
        std::fs::write(&path, crate::test_scenes::GLITTER_FLOOR).unwrap();
        path
    }

    /// Options override the scene's settings; a crop of a job is the full frame's pixels as
    /// 32-bit floats; its summary and its EXR record the bounds.
    #[test]
    fn a_jobs_crop_is_the_full_frames_pixels() {
        let path = scene_file("crop");
        let never = AtomicBool::new(false);
        let options = RenderOptions {
            samples_per_pixel: Some(3),
            resolution: Some((20, 12)),
            ..RenderOptions::default()
        };
        let mut full = RenderJob::load(&path, options).unwrap();
        assert_eq!(
            (
                full.settings.width,
                full.settings.height,
                full.settings.samples_per_pixel
            ),
            (20, 12, 3)
        );
        let whole = full.render_frame(0, &|_, _| {}, &never).unwrap();
        assert!(
            whole
                .image
                .pixels
                .iter()
                .all(|p| *p == p.as_vec3().as_dvec3())
        );
        let bounds = PixelBounds {
            x0: 3,
            x1: 17,
            y0: 2,
            y1: 9,
        };
        let mut crop = RenderJob::load(
            &path,
            RenderOptions {
                pixel_bounds: Some(bounds),
                ..options
            },
        )
        .unwrap();
        let part = crop.render_frame(0, &|_, _| {}, &never).unwrap();
        assert_eq!(part.bounds, bounds);
        for y in 2..9 {
            for x in 3..17 {
                assert_eq!(
                    part.image.pixels[((y - 2) * 14 + x - 3) as usize],
                    whole.image.pixels[(y * 20 + x) as usize]
                );
            }
        }
        // The whole-image job given the bounds afterwards renders the same crop.
        let bad = full.set_pixel_bounds(Some(PixelBounds { y1: 13, ..bounds }));
        assert!(bad.unwrap_err().to_string().contains("pixel_bounds"));
        assert_eq!(full.settings.pixel_bounds, None);
        full.set_pixel_bounds(Some(bounds)).unwrap();
        let again = full.render_frame(0, &|_, _| {}, &never).unwrap();
        assert_eq!(again.image.pixels, part.image.pixels);
        full.set_pixel_bounds(None).unwrap();
        assert_eq!(full.settings.bounds(), PixelBounds::full(20, 12));
        let summary = crop.summary(&part, 1);
        assert_eq!(summary["pixel_bounds"], serde_json::json!([3, 17, 2, 9]));
        assert_eq!(summary["resolution"], serde_json::json!([20, 12]));
        assert!(
            summary["expected_footprint_areas"]["glitter"][0]
                .as_f64()
                .unwrap()
                > 0.0
        );
        // N per texture square, and the particles-per-query histogram: every query in a bin,
        // the 99% bound one of the bins' edges.
        assert!(
            summary["particles_per_square"]["glitter"][0]
                .as_u64()
                .unwrap()
                >= 1
        );
        let histogram = summary["particles_histogram"].as_array().unwrap();
        let binned: u64 = histogram.iter().map(|b| b[1].as_u64().unwrap()).sum();
        assert_eq!(binned, summary["glint_queries"].as_u64().unwrap());
        let p99 = summary["particles_per_query_p99"].as_f64().unwrap();
        assert!(
            histogram.iter().any(|b| b[0].as_f64() == Some(p99)),
            "{p99}"
        );
        let dir = path.parent().unwrap();
        let files = ["c.exr", "c.png", "c.json"].map(|f| dir.join(f));
        crop.write_outputs(&part, 1, [&files[0], &files[1], &files[2]])
            .unwrap();
        let back = RgbImage::load(&files[0]).unwrap();
        assert_eq!(back.pixels, part.image.pixels);
        let bad = RenderJob::load(
            &path,
            RenderOptions {
                pixel_bounds: Some(PixelBounds { x1: 21, ..bounds }),
                ..options
            },
        );
        assert!(bad.unwrap_err().to_string().contains("pixel_bounds"));
        std::fs::remove_dir_all(dir).ok();
    }
}
