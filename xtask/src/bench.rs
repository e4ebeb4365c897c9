//! `cargo xtask bench`: run the criterion benchmarks, then collect their medians into one table.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, bail};

/// The geometry benchmarks the summary reports, with what each measures.
const SPHERE_BENCHMARKS: [(&str, &str); 7] = [
    (
        "conic_new",
        "SphericalConic::new (frame, λ1, λ2; one sin/cos)",
    ),
    ("contains", "SphericalConic::contains (one direction)"),
    (
        "classify_tree",
        "classify: count-tree triangles (octant depth 2–8)",
    ),
    ("classify_mixed", "classify: random cases incl. extremes"),
    ("solid_angle", "SphericalTriangle::solid_angle"),
    (
        "overlap_planar",
        "overlap, planar approximation (partial tree cases)",
    ),
    (
        "overlap_precise",
        "overlap, precise reference (partial tree cases)",
    ),
];

/// The tree's primitive benchmarks.
const TREE_BENCHMARKS: [(&str, &str); 18] = [
    ("tea_scalar_8_rounds", "TEA, one 64-bit block, 8 cycles"),
    (
        "tea_x4_8_rounds",
        "TEA, four blocks in one wide::u32x4 call",
    ),
    ("multinomial_exact_n5", "4-way split, exact, n = 5"),
    ("multinomial_exact_n1000", "4-way split, exact, n = 1000"),
    (
        "multinomial_exact_n1000000000",
        "4-way split, exact, n = 10⁹",
    ),
    (
        "multinomial_normal_n5",
        "4-way split, normal mode, n = 5 (exact there)",
    ),
    (
        "multinomial_normal_n1000",
        "4-way split, normal approximation, n = 1000",
    ),
    (
        "multinomial_normal_n1000000000",
        "4-way split, normal approximation, n = 10⁹",
    ),
    (
        "equal_split_bits_n128",
        "spatial split, two bits per particle, n = 128",
    ),
    (
        "equal_split_binomials_n128",
        "spatial split as conditional binomials, n = 128",
    ),
    (
        "equal_split_bits_n384",
        "spatial split, two bits per particle, n = 384 (the switch point)",
    ),
    (
        "equal_split_binomials_n384",
        "spatial split as conditional binomials, n = 384",
    ),
    (
        "equal_split_bits_n512",
        "spatial split, two bits per particle, n = 512",
    ),
    (
        "equal_split_binomials_n512",
        "spatial split as conditional binomials, n = 512",
    ),
    (
        "density_map_build_1024",
        "DensityMap::new, 1024² texels (one megatexel)",
    ),
    (
        "query_spheres_1e6_6deg_a0.1_map_1024",
        "sphere lights' query under a 1024² production-like density map",
    ),
    (
        "query_spheres_1e6_6deg_a0.1_map_1024_bilinear",
        "the same under the 1024² map reconstructed bilinearly",
    ),
    (
        "query_spheres_1e6_6deg_a0.1_map_8192",
        "sphere lights' query under an 8192² production-like density map",
    ),
];

/// The BRDF benchmarks (besides the per-setting multiscale evals).
const BRDF_BENCHMARKS: [(&str, &str); 4] = [
    ("smooth_eval", "smooth microfacet BRDF (Eq. 3), Beckmann"),
    (
        "glint_sample",
        "glint sample: widened α, then the cone; f̂ and the pdf",
    ),
    (
        "glint_pdf_64",
        "glint sampler pdf, 64-point QMC convolution (target ≤ 2 µs)",
    ),
    (
        "eval_overhead_conic",
        "multiscale eval beyond its query: the conic (every query)",
    ),
];

/// Queries per setting for the Table 1 node and particle statistics.
const TABLE1_QUERIES: usize = 4096;

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask lives in the workspace")
        .to_path_buf()
}

pub(crate) fn run(
    quick: bool,
    renders_only: bool,
    only: Option<&str>,
    out: &Path,
) -> anyhow::Result<()> {
    if renders_only {
        let table = crate::bench_frames::run(quick, only, out)?;
        println!("{table}\n{}", out.join("frames.md").display());
        return Ok(());
    }
    let root = workspace_root();
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    let mut command = Command::new(cargo);
    command
        .current_dir(&root)
        .args(["bench", "-p", "glint-benches", "--"]);
    if quick {
        command.args(["--warm-up-time", "1", "--measurement-time", "2"]);
    }
    let status = command.status().context("running cargo bench")?;
    if !status.success() {
        bail!("cargo bench failed: {status}");
    }
    let target =
        std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| root.join("target"), PathBuf::from);
    let median = |group: &str, name: &str| -> anyhow::Result<f64> {
        let path = target
            .join("criterion")
            .join(group)
            .join(name)
            .join("new/estimates.json");
        let json = std::fs::read_to_string(&path)
            .with_context(|| format!("reading {}", path.display()))?;
        median_point_estimate(&json).with_context(|| format!("no median in {}", path.display()))
    };
    let mut table = String::from(
        "## Geometry (glint-sphere)\n\n| benchmark | what | median per call |\n|---|---|---|\n",
    );
    for (name, what) in SPHERE_BENCHMARKS {
        writeln!(
            table,
            "| sphere/{name} | {what} | {:.1} ns |",
            median("sphere", name)?
        )?;
    }
    table.push_str("\n## Count tree primitives (glint-tree)\n\n| benchmark | what | median per call |\n|---|---|---|\n");
    for (name, what) in TREE_BENCHMARKS {
        writeln!(
            table,
            "| tree/{name} | {what} | {:.1} ns |",
            median("tree", name)?
        )?;
    }
    table.push_str(
        "\n## BRDF (glint-brdf)\n\n| benchmark | what | median per call |\n|---|---|---|\n",
    );
    for (name, what) in BRDF_BENCHMARKS {
        writeln!(
            table,
            "| brdf/{name} | {what} | {:.1} ns |",
            median("brdf", name)?
        )?;
    }
    writeln!(
        table,
        "\n## Table 1 settings (Beckmann, ε = 0.1, exact multinomials, footprint side 10⁻³, \
         directions near the highlight; {TABLE1_QUERIES} queries for the means)\n\n\
         | setting | N | γ | α | Alg. 2 entries | tree build | mean nodes visited (meeting the query) | mean particles found | median per query | per visited node | multiscale eval |\n\
         |---|---|---|---|---|---|---|---|---|---|---|"
    )?;
    for setting in &glint_benches::TABLE1 {
        let started = std::time::Instant::now();
        let (tree, _) = glint_benches::table1_workload(setting, 0, 1);
        let build = started.elapsed();
        let statistics = glint_benches::table1_statistics(setting, TABLE1_QUERIES, 1);
        let nodes = statistics.nodes_visited;
        let per_query = median("tree", &format!("query_{}", setting.name))?;
        writeln!(
            table,
            "| {} | {:.0e} | {}° | {} | {} | {:.2} ms | {nodes:.1} ({:.1}) | {:.2} | {:.1} µs | {:.0} ns | {:.1} µs |",
            setting.name,
            setting.particles as f64,
            setting.gamma_degrees,
            setting.alpha,
            tree.quadrature().len(),
            build.as_secs_f64() * 1e3,
            statistics.nodes_overlapping,
            statistics.particles_found,
            per_query / 1000.0,
            per_query / nodes,
            median("brdf", &format!("eval_{}", setting.name))? / 1000.0
        )?;
    }
    writeln!(
        table,
        "\n## What a frame pays for glints\n{}",
        crate::bench_frames::run(quick, None, out)?
    )?;
    scene_table(quick, out, &mut table)?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let path = out.join("summary.md");
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let header = format!(
        "# glint benchmarks\n\nOne core, criterion medians ({} measurement); machine: {threads} \
         hardware threads.\n\n",
        if quick { "quick" } else { "full" }
    );
    std::fs::write(&path, header + &table)
        .with_context(|| format!("writing {}", path.display()))?;
    println!("\n{table}\nsummary: {}", path.display());
    Ok(())
}

/// The paper's Table 1 per scene: `cargo xtask scenes` (quick when `quick`) into `out/scenes`,
/// its table appended.
fn scene_table(quick: bool, out: &Path, table: &mut String) -> anyhow::Result<()> {
    let args = crate::scenes::ScenesArgs {
        quick,
        only: None,
        update_previews: false,
        out: out.join("scenes"),
    };
    crate::scenes::run(&args)?;
    let scenes = std::fs::read_to_string(args.out.join("table.md"))?;
    writeln!(
        table,
        "\n## The paper's Table 1, per scene (`cargo xtask scenes`{})\n\n{scenes}",
        if quick { " --quick" } else { "" }
    )?;
    Ok(())
}

/// The `point_estimate` of the `median` object in criterion's `estimates.json` (nanoseconds).
fn median_point_estimate(json: &str) -> Option<f64> {
    let median = &json[json.find("\"median\"")?..];
    let field = &median[median.find("\"point_estimate\"")? + "\"point_estimate\"".len()..];
    let value = field.trim_start().strip_prefix(':')?.trim_start();
    let end =
        value.find(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | 'e' | 'E' | '-' | '+')))?;
    value[..end].parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_criterion_median() {
        let json = r#"{"mean":{"confidence_interval":{"confidence_level":0.95,"lower_bound":1.0,"upper_bound":2.0},"point_estimate":1.5,"standard_error":0.1},"median":{"confidence_interval":{"confidence_level":0.95,"lower_bound":40.0,"upper_bound":41.0},"point_estimate":40.27,"standard_error":0.2}}"#;
        assert_eq!(median_point_estimate(json), Some(40.27));
        assert_eq!(median_point_estimate("{}"), None);
    }
}
