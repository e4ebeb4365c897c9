//! What a rendered frame pays for glints: every scene in `scenes/` rendered with glints and
//! smooth at equal samples (alternating, the median ratio), the glint queries it made, the
//! time added per traversed query, and, where `perf` is installed, a profile of the glint
//! render on one thread that splits its time into the parts of the glint model.

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

use anyhow::Context;
use glint_tracer::{RenderSettings, RenderStatistics, Scene};

/// Where `docs/performance.md` holds the table this module writes.
const TABLE_BEGIN: &str = "<!-- cargo xtask bench: frame costs -->";
const TABLE_END: &str = "<!-- end of frame costs -->";

/// Glint/smooth render pairs per scene and thread count (the medians are reported). Renders on
/// the shared development machine move by 5–10% from one run to the next, which the time added
/// per traversed query, a difference, magnifies; five pairs keep one disturbed pair from
/// setting it.
const PAIRS: usize = 5;

/// The parts of a glint render's time, in the order a sample's call stack is matched against
/// them: a sample belongs to the first part that names any frame of its stack (so the tree's
/// own functions called by Eq. 10's overlap count as overlap, and the tree query called by
/// f̂ counts as the tree query).
const PARTS: [(&str, &[&str]); 6] = [
    (
        "negligible bound",
        &[
            "negligible::",
            "particle_density_bound",
            "expected_count_bound",
        ],
    ),
    (
        "overlap areas (Eq. 10's early stop)",
        &[
            "directional_fraction",
            "overlap_share",
            "integral_over_conic_within",
            "overlap_solid_angle",
            "expected_count_by",
            "overlap_area",
        ],
    ),
    ("sampling pdf", &["GlintSampler::pdf", "sampling_pdf"]),
    (
        "glint sampling",
        &[
            "GlintSampler::sample_direction",
            "DiscreteBrdf::sample_direction",
        ],
    ),
    ("tree query (Alg. 1)", &["glint_tree::"]),
    (
        "f̂ around the query (conic, Fresnel, Eq. 5)",
        &[
            "DiscreteBrdf::query",
            "GlintMaterial::eval",
            "glint_brdf::glint::",
        ],
    ),
];

/// The function a sample must be under to count as render time.
const RENDER_FRAME: &str = "glint_tracer::film::render";

/// One scene's measurements.
struct SceneCost {
    name: String,
    settings: RenderSettings,
    /// One per thread count.
    runs: Vec<PairedRuns>,
}

/// The glint/smooth pairs of one scene on some threads: the medians over the pairs.
struct PairedRuns {
    threads: usize,
    /// Glint render seconds.
    glint: f64,
    /// Smooth render seconds.
    smooth: f64,
    /// Of the pairs' glint / smooth ratios.
    ratio: f64,
    /// Of the pairs' glint − smooth differences (seconds): each pair's renders ran back to
    /// back, under the same load.
    added: f64,
    /// The glint render's statistics (the same in every pair).
    statistics: RenderStatistics,
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// Renders `path` with glints and smooth, alternating, on one thread and on all.
fn measure(path: &Path, quick: bool) -> anyhow::Result<SceneCost> {
    let glint = glint_tracer::scene_file::load_scene(path)?;
    let mut smooth = glint_tracer::scene_file::load_scene(path)?;
    smooth.make_smooth();
    let mut settings = glint.settings;
    if quick {
        settings.width = (settings.width / 2).max(1);
        settings.height = (settings.height / 2).max(1);
    }
    let all = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut thread_counts = vec![1];
    if all > 1 {
        thread_counts.push(all);
    }
    let name = path
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let mut runs = Vec::new();
    for threads in thread_counts {
        let pool = glint_eval::batch::thread_pool(Some(threads), |i| format!("glint-bench-{i}"))
            .map_err(anyhow::Error::msg)?;
        let render = |scene: &Scene| -> anyhow::Result<RenderStatistics> {
            Ok(pool
                .install(|| glint_tracer::render(scene, &settings, 0.0, &|_, _| {}))?
                .statistics)
        };
        let (mut glint_times, mut smooth_times) = (Vec::new(), Vec::new());
        let (mut ratios, mut differences) = (Vec::new(), Vec::new());
        let mut statistics = None;
        for _ in 0..if quick { 1 } else { PAIRS } {
            let g = render(&glint)?;
            let s = render(&smooth)?;
            glint_times.push(g.seconds);
            smooth_times.push(s.seconds);
            ratios.push(g.seconds / s.seconds);
            differences.push(g.seconds - s.seconds);
            statistics = Some(g);
        }
        let run = PairedRuns {
            threads,
            glint: median(&mut glint_times),
            smooth: median(&mut smooth_times),
            ratio: median(&mut ratios),
            added: median(&mut differences),
            statistics: statistics.context("no render")?,
        };
        println!(
            "{name}, {threads} thread(s): glint {:.2} s, smooth {:.2} s, {:.2}×",
            run.glint, run.smooth, run.ratio
        );
        runs.push(run);
    }
    Ok(SceneCost {
        name,
        settings,
        runs,
    })
}

/// The glint render of `path` on one thread under `perf record`, its samples split into
/// [`PARTS`]: the share of samples per part (the rest last), or `None` without `perf`.
fn profile(path: &Path, settings: &RenderSettings, out: &Path) -> Option<Vec<f64>> {
    let perf_available = Command::new("perf")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !perf_available {
        return None;
    }
    let exe = std::env::current_exe().ok()?;
    let data = out.join("perf.data");
    let status = Command::new("perf")
        .args([
            "record",
            "-q",
            "-F",
            "250",
            "--call-graph",
            "dwarf,16384",
            "-o",
        ])
        .arg(&data)
        .arg("--")
        .arg(&exe)
        .arg("render")
        .arg(path)
        .args(["--threads", "1", "--quiet", "--resolution"])
        .arg(format!("{}x{}", settings.width, settings.height))
        .arg("--out")
        .arg(out.join("profile-render"))
        .status()
        .ok()?;
    if !status.success() {
        return None;
    }
    let script = Command::new("perf")
        .args(["script", "--no-inline", "-F", "ip,sym", "-i"])
        .arg(&data)
        .output()
        .ok()?;
    let _ = std::fs::remove_file(&data);
    Some(split_samples(&String::from_utf8_lossy(&script.stdout)))
}

/// The shares of `perf script` samples (blank-line separated call stacks, one `address symbol`
/// per line) per part of [`PARTS`], the rest last. Only samples within the render (a frame
/// names [`RENDER_FRAME`]) count: loading the scene and building the trees are not in the
/// render's time.
fn split_samples(script: &str) -> Vec<f64> {
    let mut counts = vec![0usize; PARTS.len() + 1];
    let mut total = 0usize;
    for sample in script.split("\n\n") {
        let frames: Vec<&str> = sample
            .lines()
            .filter_map(|line| line.trim().split_once(' ').map(|(_, symbol)| symbol))
            .collect();
        if !frames.iter().any(|frame| frame.contains(RENDER_FRAME)) {
            continue;
        }
        total += 1;
        let part = PARTS
            .iter()
            .position(|(_, names)| {
                frames
                    .iter()
                    .any(|frame| names.iter().any(|n| frame.contains(n)))
            })
            .unwrap_or(PARTS.len());
        counts[part] += 1;
    }
    counts
        .iter()
        .map(|&c| c as f64 / total.max(1) as f64)
        .collect()
}

/// Measures every scene (or only the one whose file stem is `only`), writes the tables to
/// `out/frames.md` and, when every scene was measured, into `docs/performance.md` (between its
/// markers), and returns them.
pub(crate) fn run(quick: bool, only: Option<&str>, out: &Path) -> anyhow::Result<String> {
    crate::assets::ensure()?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut costs = Vec::new();
    let mut profiles = Vec::new();
    let files: Vec<_> = crate::scenes::scene_files()?
        .into_iter()
        .filter(|path| only.is_none_or(|only| path.file_stem().is_some_and(|stem| stem == only)))
        .collect();
    if files.is_empty() {
        anyhow::bail!("no scene named {:?} in scenes/", only.unwrap_or_default());
    }
    for path in files {
        let cost = measure(&path, quick)?;
        profiles.push(profile(&path, &cost.settings, out));
        costs.push(cost);
    }
    let tables = tables(&costs, &profiles, quick)?;
    let path = out.join("frames.md");
    std::fs::write(&path, &tables).with_context(|| format!("writing {}", path.display()))?;
    if only.is_some() {
        return Ok(tables);
    }
    let docs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/performance.md");
    let text =
        std::fs::read_to_string(&docs).with_context(|| format!("reading {}", docs.display()))?;
    if let (Some(begin), Some(end)) = (text.find(TABLE_BEGIN), text.find(TABLE_END)) {
        let updated = format!("{}{TABLE_BEGIN}\n{tables}{}", &text[..begin], &text[end..]);
        std::fs::write(&docs, updated).with_context(|| format!("writing {}", docs.display()))?;
        println!("updated {}", docs.display());
    }
    Ok(tables)
}

fn tables(
    costs: &[SceneCost],
    profiles: &[Option<Vec<f64>>],
    quick: bool,
) -> anyhow::Result<String> {
    let mut table = format!(
        "\nEach scene at its default settings{}; glint and `--smooth` at equal samples, \
         alternating, {} pair(s) per row: the medians of the times, of the pairs' ratios and \
         of the pairs' differences. \"Added per traversed query\" is that median difference \
         (glint − smooth time) / traversed queries.\n\n\
         | scene | resolution, spp | threads | glint | smooth | glint / smooth | traversed queries | skipped as negligible | added per traversed query |\n\
         |---|---|---|---|---|---|---|---|---|\n",
        if quick { " at half resolution" } else { "" },
        if quick { 1 } else { PAIRS }
    );
    for cost in costs {
        for run in &cost.runs {
            let traversed = run.statistics.glint.traversed_queries();
            let added = if traversed > 0 {
                format!(
                    "{:.2} µs",
                    run.added * 1e6 / traversed as f64 * run.threads as f64
                )
            } else {
                "—".to_owned()
            };
            writeln!(
                table,
                "| {} | {}×{}, {} | {} | {:.2} s | {:.2} s | {:.2}× | {traversed} | {} | {added} |",
                cost.name,
                cost.settings.width,
                cost.settings.height,
                cost.settings.samples_per_pixel,
                run.threads,
                run.glint,
                run.smooth,
                run.ratio,
                run.statistics.glint.negligible_queries,
            )?;
        }
    }
    if profiles.iter().any(Option::is_some) {
        write!(
            table,
            "\nWhere the one-thread glint render's time goes (`perf record` call stacks at 250 Hz; \
             a sample counts in the first part, in the table's order, that names a frame of its \
             stack; the rest is what glint and smooth renders share: rays, light and smooth \
             BRDFs, the film). Seconds are the share times the median glint time above; \
             \"glint parts\" sums the parts before the rest, to set against the measured \
             glint − smooth time (the median of the pairs' differences above).\n\n| scene |"
        )?;
        for (name, _) in PARTS {
            write!(table, " {name} |")?;
        }
        table.push_str(" rest | glint parts | glint − smooth |\n|---|");
        for _ in 0..=PARTS.len() + 2 {
            table.push_str("---|");
        }
        table.push('\n');
        for (cost, shares) in costs.iter().zip(profiles) {
            let (Some(shares), Some(run)) = (shares, cost.runs.first()) else {
                continue;
            };
            write!(table, "| {} |", cost.name)?;
            for share in shares {
                write!(
                    table,
                    " {:.0}% ({:.2} s) |",
                    share * 100.0,
                    share * run.glint
                )?;
            }
            let parts: f64 = shares[..PARTS.len()].iter().sum();
            writeln!(table, " {:.2} s | {:.2} s |", parts * run.glint, run.added)?;
        }
    } else {
        table.push_str("\n(`perf` is not installed: no breakdown of the glint time.)\n");
    }
    Ok(table)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_go_to_the_first_part_their_stack_names() {
        let script = "\
            \t 0 glint_tree::ndf::Quadrature::integral\n\
            \t 1 glint_sphere::classify::<impl glint_sphere::conic::SphericalConic>::classify\n\
            \t 2 glint_tree::tree::law::<impl glint_tree::tree::CountTree>::integral_over_conic_within\n\
            \t 3 glint_tree::tree::query::<impl glint_tree::tree::CountTree>::query\n\
            \t 4 glint_tracer::film::render\n\
            \n\
            \t 5 glint_tree::sampling::binomial\n\
            \t 6 glint_tree::tree::query::<impl glint_tree::tree::CountTree>::query\n\
            \t 6 glint_tracer::film::render\n\
            \n\
            \t 7 glint_brdf::discrete::DiscreteBrdf::sampling_pdf\n\
            \t 7 glint_tracer::film::render\n\
            \n\
            \t 8 glint_tree::ndf::NdfQuadrature::build\n\
            \t 8 glint_tracer::scene_file::load_scene\n\
            \n\
            \t 9 obvhs::cwbvh::CwBvh::ray_traverse\n\
            \t 9 glint_tracer::film::render\n";
        let shares = split_samples(script);
        assert_eq!(shares.len(), PARTS.len() + 1);
        // overlap, tree query, sampling pdf, rest: a quarter each (scene loading not counted).
        assert_eq!(shares[1], 0.25);
        assert_eq!(shares[4], 0.25);
        assert_eq!(shares[2], 0.25);
        assert_eq!(shares[PARTS.len()], 0.25);
        assert_eq!(shares.iter().sum::<f64>(), 1.0);
    }
}
