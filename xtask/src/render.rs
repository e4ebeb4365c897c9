//! `cargo xtask render [SCENE] [--spp N] [--resolution WxH] [--pixel-bounds X0,X1,Y0,Y1]
//! [--out DIR] [--frames A..B] [--smooth] [--glint-footprints all|first_hit|never]
//! [--glint-light-cones] [--threads N]`: renders a scene file to linear EXR, tone-mapped PNG and
//! a JSON file of Table-1 statistics, with a progress bar, through `glint_tracer::job` (as
//! Python's `glint.render` does).

use std::path::{Path, PathBuf};

use anyhow::Context;
use glint_tracer::PixelBounds;
use glint_tracer::job::{RenderJob, RenderOptions};
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
    /// Render only pixels X0..X1 × Y0..Y1 of the image (half-open, row 0 at the top, as
    /// pbrt's `--pixelbounds`): exactly those pixels of the full render, bit for bit. Outputs
    /// are named `<scene>[_<frame>]_pxX0-X1_Y0-Y1` and record their bounds (the EXR's data
    /// window, the JSON's `pixel_bounds`).
    #[arg(long, value_name = "X0,X1,Y0,Y1", value_parser = parse_pixel_bounds)]
    pub(crate) pixel_bounds: Option<PixelBounds>,
    /// Worker threads, 1 to 1024 (`glint_eval::batch::MAX_THREADS`; default: all cores).
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

fn parse_pixel_bounds(text: &str) -> Result<PixelBounds, String> {
    let numbers = text
        .split(',')
        .map(|s| {
            s.trim()
                .parse::<u32>()
                .map_err(|e| format!("`{s}` in `{text}`: {e}"))
        })
        .collect::<Result<Vec<u32>, String>>()?;
    let [x0, x1, y0, y1] = numbers[..] else {
        return Err(format!("`{text}` is not X0,X1,Y0,Y1"));
    };
    Ok(PixelBounds { x0, x1, y0, y1 })
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

pub(crate) fn run(args: &RenderArgs) -> anyhow::Result<()> {
    let scene_path = args.scene.clone().unwrap_or_else(default_scene);
    // At most MAX_THREADS, checked before any thread starts (glint_eval::batch::thread_pool).
    let threads = args.threads.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map_or(1, |n| n.get())
            .min(glint_eval::batch::MAX_THREADS)
    });
    let pool = glint_eval::batch::thread_pool(Some(threads), |i| format!("glint-render-{i}"))
        .map_err(|e| anyhow::anyhow!("--{e}"))?;
    crate::assets::ensure()?;
    let options = RenderOptions {
        samples_per_pixel: args.spp,
        resolution: args.resolution,
        pixel_bounds: args.pixel_bounds,
        max_depth: args.max_depth,
        integrator: args.integrator,
        glint_footprints: args.glint_footprints,
        negligible_count: args.negligible_count,
        smooth: args.smooth,
        per_frame_glints: args.per_frame_glints,
        glint_light_cones: args.glint_light_cones,
    };
    let mut job = RenderJob::load(&scene_path, options)?;
    let settings = job.settings;
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
    check_camera(&job.scene, frame_range(args.frames))?;
    let bounds = settings.bounds();
    println!(
        "{}: {}x{}{}, {} spp, {} thread(s){}; scene built in {:.2} s",
        scene_path.display(),
        settings.width,
        settings.height,
        settings.pixel_bounds.map_or_else(String::new, |b| format!(
            " (pixels {}..{} x {}..{})",
            b.x0, b.x1, b.y0, b.y1
        )),
        settings.samples_per_pixel,
        threads,
        if args.smooth { ", smooth" } else { "" },
        job.build_seconds
    );
    let particles: Vec<String> = job
        .glint_particles()
        .iter()
        .map(|(name, n)| {
            let n: Vec<String> = n.iter().map(|n| format!("{:.3e}", *n as f64)).collect();
            format!("{name} {}", n.join(" + "))
        })
        .collect();
    if !particles.is_empty() {
        println!("  flakes per texture square (N): {}", particles.join(", "));
    }
    for frame in frame_range(args.frames) {
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
        let never = std::sync::atomic::AtomicBool::new(false);
        let output = pool.install(|| job.render_frame(frame, &progress, &never))?;
        bar.finish_and_clear();
        let mut name = if args.frames.is_some() {
            format!("{stem}_{frame:04}")
        } else {
            stem.clone()
        };
        if settings.pixel_bounds.is_some() {
            name = format!(
                "{name}_px{}-{}_{}-{}",
                bounds.x0, bounds.x1, bounds.y0, bounds.y1
            );
        }
        let exr = args.out.join(format!("{name}.exr"));
        let png = args.out.join(format!("{name}.png"));
        let json = args.out.join(format!("{name}.json"));
        job.write_outputs(&output, threads, [&exr, &png, &json])?;
        let s = output.statistics;
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
                    "  {material}: {} queries, {:.1} nodes ({:.1} meeting the query) and {:.3} particles per query (99% at most {:.3})",
                    c.queries,
                    c.nodes_per_query(),
                    c.overlapping_nodes_per_query(),
                    c.particles_per_query(),
                    c.particles_per_query_p99()
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
    /// `--threads` beyond glint_eval's MAX_THREADS is refused at once, before the scene is
    /// read or any thread starts (4096 threads spent 7–25 s starting and then failed with
    /// "Resource temporarily unavailable").
    #[test]
    fn too_many_threads_are_refused_before_anything_starts() {
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            args: RenderArgs,
        }
        for (threads, message) in [
            (
                "4096",
                "--threads = 4096: the number of threads must be in [1, 1024]",
            ),
            (
                "0",
                "--threads = 0: the number of threads must be in [1, 1024]",
            ),
        ] {
            let cli = <Cli as clap::Parser>::try_parse_from([
                "render",
                "no/such/scene.toml",
                "--threads",
                threads,
            ])
            .unwrap();
            let error = run(&cli.args).unwrap_err().to_string();
            assert_eq!(error, message);
        }
    }

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
