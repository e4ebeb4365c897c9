//! `cargo xtask scenes [--quick] [--only NAME] [--update-previews]`: renders every scene under
//! `scenes/` with its glint materials and with `--smooth` at equal samples (the paper's Fig. 3
//! comparison), writes each pair side by side, measures a camera move with coherent and with
//! per-frame particles and stained_glass's move to the floor with the default dense mode and
//! exact counts, and writes the Table 1 reproduction, all under `target/scenes/`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use glint_tracer::image::RgbImage;
use glint_tracer::material::{GlintCounters, Material};
use glint_tracer::scene_file::{load_scene, parse_scene};
use glint_tracer::{GlintRandomness, RenderSettings, RenderStatistics, Scene, render};

/// Command-line options of `scenes`.
#[derive(Debug, clap::Args)]
pub(crate) struct ScenesArgs {
    /// A quarter of the pixels and of the samples (at least one).
    #[arg(long)]
    pub(crate) quick: bool,
    /// Only the scene with this file stem.
    #[arg(long)]
    pub(crate) only: Option<String>,
    /// Also write the side-by-side previews into scenes/previews/ (committed for the README).
    #[arg(long)]
    pub(crate) update_previews: bool,
    /// Output folder.
    #[arg(long, default_value = "target/scenes")]
    pub(crate) out: PathBuf,
}

/// The glint parameters of a scene: (N, γ in degrees, α_x, α_y) per glint material part, and
/// per roughness level (α rounded to 10⁻³) for a part with a roughness map.
fn glint_parameters(scene: &Scene) -> Vec<(u64, f64, f64, f64)> {
    fn collect(m: &Material, out: &mut Vec<(u64, f64, f64, f64)>) {
        match m {
            Material::Glint(g) => {
                let p = g.brdf.parameters();
                let gamma = p.gamma_radians.to_degrees();
                if p.alpha_map.is_some() {
                    for (alpha, _) in g.brdf.level_trees() {
                        let a = (alpha.unwrap_or(0.0) * 1e3).round() / 1e3;
                        out.push((p.particles, gamma, a, a));
                    }
                } else {
                    let (ax, ay) = p.distribution.alpha();
                    out.push((p.particles, gamma, ax, ay));
                }
            }
            Material::Mix(parts) => parts.iter().for_each(|(_, m)| collect(m, out)),
            _ => {}
        }
    }
    let mut out = vec![];
    scene.materials.iter().for_each(|m| collect(m, &mut out));
    out
}

/// A mean over all glint queries, with its range over the materials when there are several.
fn with_material_range(
    mean: f64,
    statistics: &RenderStatistics,
    per_material: fn(&GlintCounters) -> f64,
) -> String {
    let materials = &statistics.glint_by_material;
    if materials.len() < 2 {
        return format!("{mean:.1}");
    }
    let values = materials.iter().map(|(_, counters)| per_material(counters));
    format!("{mean:.1} ({})", range(values, |x| format!("{x:.1}")))
}

fn range(values: impl Iterator<Item = f64>, format: impl Fn(f64) -> String) -> String {
    let values: Vec<f64> = values.collect();
    let min = values.iter().copied().fold(f64::INFINITY, f64::min);
    let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if values.is_empty() {
        "–".into()
    } else if min == max {
        format(min)
    } else {
        format!("{}–{}", format(min), format(max))
    }
}

fn quick_settings(mut settings: RenderSettings, quick: bool) -> RenderSettings {
    if quick {
        settings.width = (settings.width / 2).max(1);
        settings.height = (settings.height / 2).max(1);
        settings.samples_per_pixel = (settings.samples_per_pixel / 4).max(1);
    }
    settings
}

/// The scene files in `scenes/`, sorted by name.
pub(crate) fn scene_files() -> anyhow::Result<Vec<PathBuf>> {
    let folder = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&folder)
        .with_context(|| format!("reading {}", folder.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    Ok(files)
}

pub(crate) fn run(args: &ScenesArgs) -> anyhow::Result<()> {
    crate::assets::ensure()?;
    let folder = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let previews = folder.join("previews");
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    if args.update_previews {
        std::fs::create_dir_all(&previews)?;
    }
    let files: Vec<PathBuf> = scene_files()?
        .into_iter()
        .filter(|p| {
            args.only
                .as_deref()
                .is_none_or(|o| p.file_stem().is_some_and(|s| s == o))
        })
        .collect();
    let mut table = String::from(
        "| scene | N | γ | α | resolution, spp | queries skipped as negligible | mean nodes visited per traversed query (per material) | meeting the query (per material) | mean particles found | glint time | smooth time | glint / smooth |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for path in &files {
        let name = path
            .file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        let glint = load_scene(path)?;
        let mut smooth = load_scene(path)?;
        smooth.make_smooth();
        let settings = quick_settings(glint.settings, args.quick);
        println!(
            "{name}: {}x{}, {} spp",
            settings.width, settings.height, settings.samples_per_pixel
        );
        let with_glints = render(&glint, &settings, 0.0, &|_, _| {})?;
        let without = render(&smooth, &settings, 0.0, &|_, _| {})?;
        let (g, s) = (with_glints.statistics, without.statistics);
        println!("  glint:  {g}\n  smooth: {s}");
        let shown = glint_tracer::job::display_image(&with_glints.image, &settings);
        let shown_smooth = glint_tracer::job::display_image(&without.image, &settings);
        shown.write_png(&args.out.join(format!("{name}.png")), settings.exposure)?;
        shown_smooth.write_png(
            &args.out.join(format!("{name}_smooth.png")),
            settings.exposure,
        )?;
        let pair = RgbImage::side_by_side(&[&shown, &shown_smooth]);
        pair.write_png(
            &args.out.join(format!("{name}_compare.png")),
            settings.exposure,
        )?;
        if args.update_previews {
            let factor = (settings.width as usize).div_ceil(320);
            pair.downsampled(factor)
                .write_png(&previews.join(format!("{name}.png")), settings.exposure)?;
        }
        let parameters = glint_parameters(&glint);
        writeln!(
            table,
            "| {name} | {} | {} | {} | {}×{}, {} | {:.0}% | {} | {} | {:.3} | {:.1} s | {:.1} s | {:.1}× |",
            range(parameters.iter().map(|p| p.0 as f64), |x| format!(
                "{x:.0e}"
            )),
            range(parameters.iter().map(|p| p.1), |x| format!(
                "{}°",
                (x * 1e3).round() / 1e3
            )),
            range(parameters.iter().flat_map(|p| [p.2, p.3]), |x| format!(
                "{x}"
            )),
            settings.width,
            settings.height,
            settings.samples_per_pixel,
            100.0 * g.glint.negligible_queries as f64 / g.glint.queries.max(1) as f64,
            with_material_range(g.nodes_per_query(), &g, GlintCounters::nodes_per_query),
            with_material_range(
                g.glint.overlapping_nodes_per_query(),
                &g,
                GlintCounters::overlapping_nodes_per_query
            ),
            g.particles_per_query(),
            g.seconds,
            s.seconds,
            g.seconds / s.seconds
        )?;
    }
    if args.only.as_deref().is_none_or(|o| o == "glitter_object") {
        table.push_str(&animation(
            &folder.join("glitter_object.toml"),
            args,
            &previews,
        )?);
    }
    if args.only.as_deref().is_none_or(|o| o == "stained_glass") {
        table.push_str(&moving_closer(
            &folder.join("stained_glass.toml"),
            args,
            &previews,
        )?);
    }
    let table_path = args.out.join("table.md");
    std::fs::write(&table_path, &table)?;
    println!("\n{table}\n{}", table_path.display());
    Ok(())
}

/// Frames along stained_glass's camera move (its keyframes: from its view down to the
/// close-up's, Sec. 4's "moving the camera close to the floor") at which the coherence of the
/// glint layer is measured, each over [`CLOSER_STEPS`] steps of a tenth of a frame.
const CLOSER_FRAMES: [f64; 6] = [0.0, 10.0, 20.0, 30.0, 38.0, 44.0];
const CLOSER_STEPS: usize = 3;

/// stained_glass's camera move to the floor, with the default dense mode and with exact
/// counts (`dense = "exact"`, ε = 0, on the floor), at the scene's N = 10⁸ and at 10¹⁰, and
/// with a new particle set at every render for contrast: a filmstrip of frames 0, 8, …, 40, 47, and,
/// at each of [`CLOSER_FRAMES`], the mean absolute change of the glint layer (the image minus
/// the smooth render) over steps of a tenth of a frame against the layer's mean magnitude,
/// the largest over the steps. A pop (the particles redrawn in one step) shows as a step whose
/// change approaches the per-frame particles' (about 1.2 on glitter_object, above).
fn moving_closer(path: &Path, args: &ScenesArgs, previews: &Path) -> anyhow::Result<String> {
    let text = std::fs::read_to_string(path)?;
    let exact_text = text.replacen(
        "[materials.floor]\n",
        "[materials.floor]\ndense = \"exact\"\nepsilon = 0.0\n",
        1,
    );
    anyhow::ensure!(
        exact_text != text,
        "{} has no [materials.floor] to count exactly",
        path.display()
    );
    let mut smooth = load_scene(path)?;
    smooth.make_smooth();
    let mut settings = smooth.settings;
    settings.width = 240;
    settings.height = 135;
    settings.samples_per_pixel = if args.quick { 2 } else { 8 };
    let mut report = String::from(
        "\n**Moving closer** (stained_glass's camera move to the close-up's view, frames 0 to 47, \
         at 240×135; at each frame, steps of 0.1 frame): the glint layer's mean |Δ| between \
         steps over its mean magnitude, the largest of the steps:\n\n\
         | mode | ",
    );
    for frame in CLOSER_FRAMES {
        write!(report, "frame {frame} | ")?;
    }
    report.push_str("\n|---|");
    report.push_str(&"---|".repeat(CLOSER_FRAMES.len()));
    report.push('\n');
    // At N = 10⁸ the floor's queries seldom reach the dense regime: the same move at 10¹⁰ does.
    let dense = |text: &str| text.replacen("particles = 1e8\n", "particles = 1e10\n", 1);
    let rows = [
        ("default", text.clone(), false),
        ("exact", exact_text.clone(), false),
        ("default, N = 10¹⁰", dense(&text), false),
        ("exact, N = 10¹⁰", dense(&exact_text), false),
        ("per-frame particles", text.clone(), true),
    ];
    for (label, scene_text, per_frame) in rows {
        let mut scene = parse_scene(&scene_text, path)?;
        let base = scene.materials.clone();
        let mut renders = 0;
        let mut layer = |frame: f64| -> anyhow::Result<(RgbImage, Vec<f64>)> {
            if per_frame {
                scene.reseed_glints_for_frame(&base, renders)?;
            }
            renders += 1;
            glint_layer(&scene, &smooth, &settings, frame)
        };
        let mean_abs = |v: &mut dyn Iterator<Item = f64>| {
            let (sum, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x.abs(), n + 1));
            sum / n as f64
        };
        write!(report, "| {label} | ")?;
        for start in CLOSER_FRAMES {
            let layers = (0..=CLOSER_STEPS)
                .map(|step| Ok(layer(start + 0.1 * step as f64)?.1))
                .collect::<anyhow::Result<Vec<_>>>()?;
            let largest = layers
                .windows(2)
                .map(|w| {
                    let change = mean_abs(&mut w[0].iter().zip(&w[1]).map(|(a, b)| a - b));
                    let magnitude = 0.5
                        * (mean_abs(&mut w[0].iter().copied())
                            + mean_abs(&mut w[1].iter().copied()));
                    change / magnitude
                })
                .fold(0.0, f64::max);
            write!(report, "{largest:.3} | ")?;
        }
        report.push('\n');
        if label == "default" {
            let frames = [0.0, 8.0, 16.0, 24.0, 32.0, 40.0, 47.0]
                .into_iter()
                .map(|frame| Ok(layer(frame)?.0))
                .collect::<anyhow::Result<Vec<_>>>()?;
            let strip = RgbImage::side_by_side(&frames.iter().collect::<Vec<_>>());
            strip.write_png(&args.out.join("moving_closer.png"), settings.exposure)?;
            if args.update_previews {
                strip.write_png(&previews.join("moving_closer.png"), settings.exposure)?;
            }
        }
    }
    Ok(report)
}

/// `scene` rendered at `frame` with `settings`, and its glint layer: the luminance of the
/// image minus `smooth`'s (the same scene with smooth materials), per pixel.
fn glint_layer(
    scene: &Scene,
    smooth: &Scene,
    settings: &RenderSettings,
    frame: f64,
) -> anyhow::Result<(RgbImage, Vec<f64>)> {
    let image = render(scene, settings, frame, &|_, _| {})?.image;
    let reference = render(smooth, settings, frame, &|_, _| {})?.image;
    let layer = image
        .pixels
        .iter()
        .zip(&reference.pixels)
        .map(|(a, b)| glint_tracer::light::luminance(*a - *b))
        .collect();
    Ok((image, layer))
}

/// glitter_object's camera move with coherent particles and with a new particle set per frame:
/// filmstrips of frames 0, 4, …, 20, and, over seven steps of a tenth of a frame (the image moves
/// by under a pixel per step), the mean absolute change of the glint layer (the image minus the
/// smooth render) between steps, against the layer's mean magnitude. Coherent glints persist from
/// step to step; per-frame ones are redrawn every step and flicker.
fn animation(path: &Path, args: &ScenesArgs, previews: &Path) -> anyhow::Result<String> {
    let mut scene = load_scene(path)?;
    let base = scene.materials.clone();
    let mut settings = scene.settings;
    settings.width = 240;
    settings.height = 135;
    settings.samples_per_pixel = if args.quick { 2 } else { 8 };
    let mut smooth = load_scene(path)?;
    smooth.make_smooth();
    let mut report = String::from(
        "\n**Animation** (glitter_object's camera move at 240×135; seven steps of 0.1 frame): mean |glint layer| and mean |Δ glint layer| between steps:\n\n",
    );
    for randomness in [GlintRandomness::Coherent, GlintRandomness::PerFrame] {
        let label = match randomness {
            GlintRandomness::Coherent => "coherent",
            GlintRandomness::PerFrame => "per_frame",
        };
        let mut show = |index: i64, frame: f64| -> anyhow::Result<(RgbImage, Vec<f64>)> {
            if randomness == GlintRandomness::PerFrame {
                scene.reseed_glints_for_frame(&base, index)?;
            }
            glint_layer(&scene, &smooth, &settings, frame)
        };
        let mut frames = vec![];
        for frame in (0..=20).step_by(4) {
            frames.push(show(frame, frame as f64)?.0);
        }
        let mut layers = vec![];
        for step in 0..7 {
            layers.push(show(100 + step, 0.1 * step as f64)?.1);
        }
        let mean_abs = |v: &[f64]| v.iter().map(|x| x.abs()).sum::<f64>() / v.len() as f64;
        let magnitude = layers.iter().map(|l| mean_abs(l)).sum::<f64>() / layers.len() as f64;
        let change = layers
            .windows(2)
            .map(|w| {
                mean_abs(
                    &w[0]
                        .iter()
                        .zip(&w[1])
                        .map(|(a, b)| a - b)
                        .collect::<Vec<_>>(),
                )
            })
            .sum::<f64>()
            / (layers.len() - 1) as f64;
        writeln!(
            report,
            "- {label}: |layer| {magnitude:.4}, |Δ| {change:.4} (ratio {:.2})",
            change / magnitude
        )?;
        let strip = RgbImage::side_by_side(&frames.iter().collect::<Vec<_>>());
        strip.write_png(
            &args.out.join(format!("animation_{label}.png")),
            settings.exposure,
        )?;
        if args.update_previews {
            strip.write_png(
                &previews.join(format!("animation_{label}.png")),
                settings.exposure,
            )?;
        }
    }
    Ok(report)
}
