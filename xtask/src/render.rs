//! `cargo xtask render [SCENE] [--spp N] [--resolution WxH] [--out DIR] [--frames A..B]
//! [--smooth] [--glint-footprints all|first_hit|never] [--glint-light-cones] [--threads N]`:
//! renders a scene file to linear EXR, tone-mapped PNG and a JSON file of Table-1 statistics,
//! with a progress bar.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use glint_tracer::scene_file::load_scene;
use glint_tracer::{RenderStatistics, render};
use indicatif::{ProgressBar, ProgressStyle};

/// The scene rendered when none is named.
pub(crate) fn default_scene() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/sphere_lights.toml")
}

/// Command-line options of `render`.
#[derive(Debug, clap::Args)]
pub(crate) struct RenderArgs {
    /// The scene file (default: scenes/sphere_lights.toml).
    pub(crate) scene: Option<PathBuf>,
    /// Samples per pixel (default: the scene's).
    #[arg(long)]
    pub(crate) spp: Option<u32>,
    /// Image size as WIDTHxHEIGHT (default: the scene's).
    #[arg(long, value_parser = parse_resolution)]
    pub(crate) resolution: Option<(u32, u32)>,
    /// The longest path in bounces (default: the scene's).
    #[arg(long)]
    pub(crate) max_depth: Option<u32>,
    /// `path` or `direct` (default: the scene's).
    #[arg(long, value_parser = parse_integrator)]
    pub(crate) integrator: Option<glint_tracer::IntegratorKind>,
    /// Output folder.
    #[arg(long, default_value = "target/render")]
    pub(crate) out: PathBuf,
    /// Render camera frames A..B (inclusive), one image each: at most 100000 frames, numbered
    /// within ±2^53.
    #[arg(long, value_parser = parse_frames)]
    pub(crate) frames: Option<(i64, i64)>,
    /// Replace every glint material by its smooth limit (the paper's Fig. 3 comparisons).
    #[arg(long)]
    pub(crate) smooth: bool,
    /// A new particle set in every frame (per-frame independent glints, for contrast with the
    /// model's coherent ones).
    #[arg(long)]
    pub(crate) per_frame_glints: bool,
    /// Sets every glint material's `negligible_count`: skip queries provably expecting fewer
    /// particles (0 traverses every query; default: each material's, 1e-12 unless its scene
    /// file says otherwise).
    #[arg(long, value_name = "COUNT")]
    pub(crate) negligible_count: Option<f64>,
    /// Shade sphere lights at glint hits by one query in the light's own cone (the scene's
    /// `glint_light_cones = true`; see scenes/README.md).
    #[arg(long)]
    pub(crate) glint_light_cones: bool,
    /// Where glint materials use the pixel footprint: `first_hit` (the paper's), `all` (also
    /// through perfect mirrors and glossy lobes of α ≤ 0.05) or `never` (default: the scene's).
    #[arg(long, value_name = "all|first_hit|never", value_parser = parse_glint_footprints)]
    pub(crate) glint_footprints: Option<glint_tracer::GlintFootprints>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub(crate) threads: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    pub(crate) quiet: bool,
}

fn parse_resolution(text: &str) -> Result<(u32, u32), String> {
    let (w, h) = text
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("`{text}` is not WIDTHxHEIGHT"))?;
    let parse = |s: &str| {
        s.trim()
            .parse::<u32>()
            .map_err(|e| format!("`{s}` in `{text}`: {e}"))
    };
    Ok((parse(w)?, parse(h)?))
}

fn parse_integrator(text: &str) -> Result<glint_tracer::IntegratorKind, String> {
    match text {
        "path" => Ok(glint_tracer::IntegratorKind::Path),
        "direct" => Ok(glint_tracer::IntegratorKind::Direct),
        _ => Err(format!("`{text}`: expected `path` or `direct`")),
    }
}

fn parse_glint_footprints(text: &str) -> Result<glint_tracer::GlintFootprints, String> {
    match text {
        "all" => Ok(glint_tracer::GlintFootprints::All),
        "first_hit" => Ok(glint_tracer::GlintFootprints::FirstHit),
        "never" => Ok(glint_tracer::GlintFootprints::Never),
        _ => Err(format!("`{text}`: expected `all`, `first_hit` or `never`")),
    }
}

/// The most frames one `--frames` range renders (about a day of rendering at a second a frame; a
/// longer animation is split into ranges). The range is iterated, never collected.
pub(crate) const MAX_FRAMES: i64 = 100_000;

/// The largest frame number: frames are passed to the camera as doubles, exact to 2⁵³.
const MAX_FRAME_NUMBER: i64 = 1 << 53;

fn parse_frames(text: &str) -> Result<(i64, i64), String> {
    let (a, b) = text
        .split_once("..")
        .ok_or_else(|| format!("`{text}` is not A..B"))?;
    let parse = |s: &str| {
        s.trim()
            .parse::<i64>()
            .map_err(|e| format!("`{s}` in `{text}`: {e}"))
    };
    let (a, b) = (parse(a)?, parse(b.trim_start_matches('='))?);
    if b < a {
        return Err(format!("`{text}`: the last frame comes before the first"));
    }
    if a.unsigned_abs() > MAX_FRAME_NUMBER.unsigned_abs()
        || b.unsigned_abs() > MAX_FRAME_NUMBER.unsigned_abs()
    {
        return Err(format!(
            "`{text}`: frame numbers must be within ±{MAX_FRAME_NUMBER} (2^53)"
        ));
    }
    let count = i128::from(b) - i128::from(a) + 1;
    if count > i128::from(MAX_FRAMES) {
        return Err(format!(
            "`{text}`: {count} frames, more than the limit of {MAX_FRAMES} per command (split the range)"
        ));
    }
    Ok((a, b))
}

/// The frames to render: `--frames A..B`, else frame 0. An iterator, never a collection.
fn frame_range(frames: Option<(i64, i64)>) -> std::ops::RangeInclusive<i64> {
    match frames {
        Some((a, b)) => a..=b,
        None => 0..=0,
    }
}

/// Checks the camera at every frame of `frames` before any is rendered: keyframes valid alone
/// may interpolate to a degenerate pose between them (`render` checks each frame again).
fn check_camera(
    scene: &glint_tracer::Scene,
    frames: std::ops::RangeInclusive<i64>,
) -> Result<(), glint_tracer::TracerError> {
    for frame in frames {
        scene.camera.checked_pose(frame as f64).map_err(|problem| {
            glint_tracer::TracerError::Camera {
                frame: frame as f64,
                problem,
            }
        })?;
    }
    Ok(())
}

/// The statistics as one JSON object.
pub(crate) fn statistics_json(
    scene: &Path,
    frame: i64,
    settings: &glint_tracer::RenderSettings,
    smooth: bool,
    threads: usize,
    s: &RenderStatistics,
) -> serde_json::Value {
    serde_json::json!({
        "scene": scene.display().to_string(),
        "frame": frame,
        "resolution": [settings.width, settings.height],
        "spp": settings.samples_per_pixel,
        "smooth": smooth,
        "glint_footprints": match settings.glint_footprints {
            glint_tracer::GlintFootprints::FirstHit => "first_hit",
            glint_tracer::GlintFootprints::All => "all",
            glint_tracer::GlintFootprints::Never => "never",
        },
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
        })).collect::<Vec<_>>(),
    })
}

pub(crate) fn run(args: &RenderArgs) -> anyhow::Result<()> {
    let scene_path = args.scene.clone().unwrap_or_else(default_scene);
    let threads = args
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    if threads == 0 {
        bail!("--threads must be at least 1");
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("cannot start the worker threads")?;
    crate::assets::ensure()?;
    let build_start = std::time::Instant::now();
    let mut scene = load_scene(&scene_path)?;
    let build_seconds = build_start.elapsed().as_secs_f64();
    // Eq. 11's plan per glint material (before `--smooth` removes the glints).
    let plans: serde_json::Map<String, serde_json::Value> = scene
        .material_names
        .iter()
        .zip(&scene.materials)
        .filter(|(_, m)| m.has_glints())
        .map(|(name, m)| (name.clone(), m.expected_footprint_areas().into()))
        .collect();
    if let Some(count) = args.negligible_count {
        scene
            .set_negligible_count(count)
            .context("--negligible-count")?;
    }
    if args.smooth {
        scene.make_smooth();
    }
    let mut settings = scene.settings;
    if args.per_frame_glints {
        settings.glint_randomness = glint_tracer::GlintRandomness::PerFrame;
    }
    let base_materials = scene.materials.clone();
    if args.glint_light_cones {
        settings.glint_light_cones = true;
    }
    if let Some(spp) = args.spp {
        settings.samples_per_pixel = spp;
    }
    if let Some(depth) = args.max_depth {
        settings.max_depth = depth;
    }
    if let Some(integrator) = args.integrator {
        settings.integrator = integrator;
    }
    if let Some(footprints) = args.glint_footprints {
        settings.glint_footprints = footprints;
    }
    if let Some((w, h)) = args.resolution {
        settings.width = w;
        settings.height = h;
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let stem = scene_path
        .file_stem()
        .map_or_else(|| "scene".to_string(), |s| s.to_string_lossy().into_owned());
    let stem = if args.smooth {
        format!("{stem}_smooth")
    } else {
        stem
    };
    check_camera(&scene, frame_range(args.frames))?;
    println!(
        "{}: {}x{}, {} spp, {} thread(s){}; scene built in {:.2} s",
        scene_path.display(),
        settings.width,
        settings.height,
        settings.samples_per_pixel,
        threads,
        if args.smooth { ", smooth" } else { "" },
        build_seconds
    );
    for frame in frame_range(args.frames) {
        if settings.glint_randomness == glint_tracer::GlintRandomness::PerFrame {
            scene.reseed_glints_for_frame(&base_materials, frame)?;
        }
        let bar = if args.quiet {
            ProgressBar::hidden()
        } else {
            ProgressBar::new(1)
        };
        bar.set_style(
            ProgressStyle::with_template(
                "{msg} [{bar:40}] {pos}/{len} tiles, {elapsed} (eta {eta})",
            )
            .expect("a valid template")
            .progress_chars("=> "),
        );
        bar.set_message(format!("frame {frame}"));
        let progress = |done: u64, total: u64| {
            bar.set_length(total);
            bar.set_position(done);
        };
        let output = pool.install(|| render(&scene, &settings, frame as f64, &progress))?;
        bar.finish_and_clear();
        let name = if args.frames.is_some() {
            format!("{stem}_{frame:04}")
        } else {
            stem.clone()
        };
        let exr = args.out.join(format!("{name}.exr"));
        let png = args.out.join(format!("{name}.png"));
        let json = args.out.join(format!("{name}.json"));
        output.image.write_exr(&exr)?;
        crate::scenes::display_image(&output.image, &settings)
            .write_png(&png, settings.exposure)?;
        let s = output.statistics;
        let mut stats = statistics_json(&scene_path, frame, &settings, args.smooth, threads, &s);
        stats["expected_footprint_areas"] = plans.clone().into();
        std::fs::write(&json, serde_json::to_string_pretty(&stats)? + "\n")
            .with_context(|| format!("cannot write {}", json.display()))?;
        println!("frame {frame}: {s} → {}", png.display());
        if s.clamped_samples > 0 || s.discarded_samples > 0 {
            eprintln!(
                "warning: frame {frame}: {} samples above {:e} were clamped and {} non-finite samples discarded (extreme light or material values; see scenes/README.md, Limits)",
                s.clamped_samples,
                glint_tracer::limits::MAX_SAMPLE_RADIANCE,
                s.discarded_samples
            );
        }
        if s.glint_by_material.len() > 1 {
            for (material, c) in &s.glint_by_material {
                println!(
                    "  {material}: {} queries, {:.1} nodes ({:.1} meeting the query) and {:.3} particles per query",
                    c.queries,
                    c.nodes_per_query(),
                    c.overlapping_nodes_per_query(),
                    c.particles_per_query()
                );
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frame ranges are bounded before anything is rendered or allocated: the range that
    /// aborted allocating 8 GB and the widest ones (which overflowed the capacity) are
    /// errors, the largest allowed range is accepted, and ranges are iterated, not collected.
    #[test]
    fn frame_ranges_are_bounded_and_iterated() {
        assert_eq!(parse_frames("0..23"), Ok((0, 23)));
        assert_eq!(parse_frames("3..=3"), Ok((3, 3)));
        assert_eq!(parse_frames("-5..99994"), Ok((-5, 99_994)));
        for (text, words) in [
            ("0..1000000000", "more than the limit of 100000"),
            ("0..100000", "100001 frames"),
            ("-9223372036854775808..9223372036854775807", "within ±"),
            ("9007199254740993..9007199254740994", "within ±"),
            ("5..3", "before the first"),
            ("0..x", "x"),
        ] {
            let error = parse_frames(text).unwrap_err();
            assert!(error.contains(words), "{text}: {error}");
        }
        let range = frame_range(Some((-5, 99_994)));
        assert_eq!(
            std::mem::size_of_val(&range),
            std::mem::size_of::<(i64, i64, bool)>()
        );
        assert_eq!(range.clone().count(), 100_000);
        assert_eq!(frame_range(None).collect::<Vec<_>>(), [0]);
    }

    /// A range whose frames include a degenerate interpolated pose is refused before any frame
    /// is rendered, naming the frame.
    #[test]
    fn the_camera_is_checked_at_every_frame_first() {
        let scene = glint_tracer::scene_file::parse_scene(
            r#"
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
            Path::new("passing.toml"),
        )
        .unwrap();
        assert!(check_camera(&scene, 0..=4).is_ok());
        assert!(check_camera(&scene, 6..=99_999).is_ok());
        let error = check_camera(&scene, 0..=23).unwrap_err().to_string();
        assert!(error.contains("frame 5"), "{error}");
    }
}
