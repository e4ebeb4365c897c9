//! `cargo xtask validate` and `bench` from the lean build: the `cargo xtask` alias builds this
//! crate without the `full` feature (no statrs, no criterion), so that the first
//! `cargo xtask render` compiles only what rendering needs. These two commands then run this
//! crate again with its default features, which cargo builds on first use, passing the same
//! arguments and returning its exit status.

use anyhow::Context;

/// Runs `cargo run --release --package xtask -- <this process's arguments>` (default features,
/// `full` among them) and exits with its status.
pub(crate) fn run_again() -> anyhow::Result<()> {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let status = std::process::Command::new(&cargo)
        .args(["run", "--release", "--quiet", "--package", "xtask", "--"])
        .args(std::env::args_os().skip(1))
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .status()
        .with_context(|| format!("cannot run {}", cargo.to_string_lossy()))?;
    std::process::exit(status.code().unwrap_or(1));
}
