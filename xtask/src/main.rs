//! `cargo xtask`: the project's long-running commands.
//!
//! - `cargo xtask render [SCENE] [--spp N] [--resolution WxH] [--out DIR] [--frames A..B]
//!   [--smooth] [--threads N]`: renders a scene (default: `scenes/sphere_lights.toml`) to EXR,
//!   PNG and JSON statistics under `target/render/`; `--frames` takes at most 100000 frames,
//!   checks the camera at each before rendering any, and iterates them one by one.
//! - `cargo xtask scenes [--quick] [--only NAME] [--update-previews]`: every scene with glints
//!   and smooth, side by side, a coherent vs per-frame animation, and the Table 1 reproduction
//!   under `target/scenes/`.
//! - `cargo xtask assets`: writes the procedural meshes and images of the paper's scenes to
//!   `scenes/assets/`.
//! - `cargo xtask validate [--quick]`: the validation suites, written as a Markdown report under
//!   `target/validate/`; exits non-zero when any check fails.
//! - `cargo xtask eval [FILE]`: the model as JSON Lines (specified in `docs/eval.md`), from FILE or
//!   stdin.
//! - `cargo xtask bench [--quick] [--renders-only]`: runs the criterion benchmarks and writes the
//!   per-call table that `docs/performance.md` quotes to `target/bench/summary.md`, and what a
//!   frame of every scene pays for glints (also written into `docs/performance.md`).
//!
//! `validate` and `bench` need the `full` feature (the statistical checkers and criterion),
//! which `cargo xtask` leaves out so that the first `cargo xtask render` compiles only what it
//! runs; without it they build and run the full command ([`full_build`]).

mod assets;
#[cfg(feature = "full")]
mod bench;
#[cfg(feature = "full")]
mod bench_frames;
mod eval;
#[cfg(not(feature = "full"))]
mod full_build;
#[cfg(feature = "full")]
mod plot;
mod render;
mod scenes;
#[cfg(feature = "full")]
mod validate;
#[cfg(feature = "full")]
mod validate_brdf;
#[cfg(feature = "full")]
mod validate_coherence;
#[cfg(feature = "full")]
mod validate_counts;
#[cfg(feature = "full")]
mod validate_dense;
#[cfg(feature = "full")]
mod validate_footprints;
#[cfg(feature = "full")]
mod validate_light_cones;
#[cfg(feature = "full")]
mod validate_lobes;
#[cfg(feature = "full")]
mod validate_maps;
#[cfg(feature = "full")]
mod validate_pdf;
#[cfg(feature = "full")]
mod validate_render;
#[cfg(feature = "full")]
mod validate_stability;
#[cfg(feature = "full")]
mod validate_trade;

use clap::{Parser, Subcommand};

#[derive(Parser, Debug)]
#[command(
    name = "cargo xtask",
    about = "glint's render, validation, evaluation and benchmark commands"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render every scene with glints and smooth, side by side, and the Table 1 reproduction.
    Scenes(scenes::ScenesArgs),
    /// Write the procedural assets of the paper's scenes to scenes/assets.
    Assets {
        /// Where to write them (default: scenes/assets).
        #[arg(long)]
        out: Option<std::path::PathBuf>,
    },
    /// Render a scene file (default: scenes/sphere_lights.toml).
    Render(render::RenderArgs),
    /// Check the model against its definitions by brute force; exit non-zero on any failure.
    Validate {
        /// Smaller sample sizes (under three minutes; part of CI).
        #[arg(long)]
        quick: bool,
        /// Where to write the report (default: target/validate).
        #[arg(long, default_value = "target/validate")]
        out: std::path::PathBuf,
        /// Only the checks whose name contains this text (as the progress bar shows them, e.g.
        /// "footprints"); the report then holds those alone.
        #[arg(long)]
        only: Option<String>,
    },
    /// Evaluate the model for JSON Lines requests (from FILE, or standard input).
    Eval {
        /// The input file (default: standard input).
        file: Option<std::path::PathBuf>,
    },
    /// Run the criterion benchmarks and write the summary table.
    Bench {
        /// Shorter measurement times (noisier figures).
        #[arg(long)]
        quick: bool,
        /// Only what a frame pays for glints (every scene, glint against smooth, and the
        /// profile's breakdown; no criterion benchmarks): written to frames.md and
        /// docs/performance.md.
        #[arg(long)]
        renders_only: bool,
        /// With --renders-only: only the scene with this file stem, written to frames.md alone
        /// (docs/performance.md keeps its table of every scene).
        #[arg(long, requires = "renders_only")]
        only: Option<String>,
        /// Where to write the summary (default: target/bench).
        #[arg(long, default_value = "target/bench")]
        out: std::path::PathBuf,
    },
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Render(args) => render::run(&args),
        Command::Scenes(args) => scenes::run(&args),
        Command::Assets { out } => assets::run(&out.unwrap_or_else(assets::assets_folder)),
        #[cfg(feature = "full")]
        Command::Validate { quick, out, only } => validate::run(quick, &out, only.as_deref()),
        #[cfg(feature = "full")]
        Command::Bench {
            quick,
            renders_only,
            only,
            out,
        } => bench::run(quick, renders_only, only.as_deref(), &out),
        #[cfg(not(feature = "full"))]
        Command::Validate { .. } | Command::Bench { .. } => full_build::run_again(),
        Command::Eval { file } => {
            let failed = eval::run(file.as_deref())?;
            if failed > 0 {
                anyhow::bail!("{failed} line(s) failed");
            }
            Ok(())
        }
    }
}
