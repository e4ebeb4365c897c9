//! The memory and build time of a material's maps, for the figures of docs/performance.md
//! ("Glint maps", memory): `cargo run --release -p glint-benches --example map_memory [SIDE]`
//! (default 4096).
//!
//! First a density map alone (the benchmarks' production map, `production_density_values`,
//! of SIDE² texels): the bytes it holds per texel (counted before building and held), its
//! build time per megatexel, and the process's peak resident memory while building beyond
//! what it held before (the values given, 8 bytes a texel, are not counted; Linux's
//! `/proc/self/status`, the peak reset through `/proc/self/clear_refs`).
//!
//! Then roughness maps of SIDE² texels, each at several
//! `roughness_levels` K, prints the bytes the K level maps hold per texel (counted before
//! building, `MapBytes::of`, which a unit test checks against the built tables), what K maps
//! stored whole would hold, and the material's build time (`DiscreteBrdf::new`: the level maps
//! and their count trees) per megatexel.
//!
//! The maps: a smooth gradient of α (0.02 to 0.4, log-linear across the map, interpolated
//! levels), the same with a grain of ±15% that changes at every texel, a painted map of three
//! values (a disc and stripes; exact levels), and α that cycles through 97 values from 0.01 to
//! 0.31 at every texel (the worst case: every level meets every tile, so the levels share one
//! family of texels, marked "shared"), filtered nearest and bilinear.

use std::sync::Arc;
use std::time::Instant;

use glint_brdf::{
    DensityMap, DiscreteBrdf, DistributionKind, GlintParameters, MapBytes, MapFilter, Microfacet,
    RoughnessMap,
};

fn main() {
    let side: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(4096);
    let texels = side * side;
    let at = |k: usize| {
        (
            (k % side) as f64 / side as f64,
            (k / side) as f64 / side as f64,
        )
    };
    let gradient: Vec<f64> = (0..texels)
        .map(|k| {
            let (x, y) = at(k);
            0.02 * 20f64.powf((0.7 * x + 0.3 * y).min(1.0))
        })
        .collect();
    let painted: Vec<f64> = (0..texels)
        .map(|k| {
            let (x, y) = at(k);
            if ((x - 0.5).powi(2) + (y - 0.4).powi(2)).sqrt() < 0.2 {
                0.05
            } else if (x * 7.0 + y * 3.0).fract() < 0.3 {
                0.3
            } else {
                0.12
            }
        })
        .collect();
    // The gradient with a grain of ±15% that changes at every texel (a hash of the texel).
    let grain: Vec<f64> = gradient
        .iter()
        .enumerate()
        .map(|(k, &alpha)| {
            let hash = (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
            let unit = hash as f64 / (1u64 << 24) as f64;
            (alpha * (0.85 + 0.3 * unit)).clamp(1e-4, 1.0)
        })
        .collect();
    let noise: Vec<f64> = (0..texels)
        .map(|k| 0.01 + 0.3 * (k % 97) as f64 / 96.0)
        .collect();
    density_map(side);
    let whole = DensityMap::bytes_for(side, side) as f64;
    println!("{side} × {side} roughness maps");
    println!();
    println!(
        "| map | K | level maps | bytes per texel (levels) | K maps stored whole | build (ms per megatexel) |"
    );
    println!("|---|---|---|---|---|---|");
    for (name, alphas, filter) in [
        ("smooth gradient", &gradient, MapFilter::Nearest),
        ("gradient with a ±15% grain", &grain, MapFilter::Nearest),
        ("painted, 3 values", &painted, MapFilter::Nearest),
        ("97 values at every texel", &noise, MapFilter::Nearest),
        (
            "97 values at every texel, bilinear",
            &noise,
            MapFilter::Bilinear,
        ),
    ] {
        let alpha = RoughnessMap::new(side, side, alphas).expect("a valid map");
        let alpha = Arc::new(alpha.with_filter(filter));
        for levels in [4, 8, 16] {
            let parameters = GlintParameters {
                alpha_map: Some(Arc::clone(&alpha)),
                roughness_levels: levels,
                ..GlintParameters::new(
                    Microfacet::new(DistributionKind::Beckmann, 0.1, 0.1).expect("valid"),
                )
            };
            let bytes = MapBytes::of(&parameters).expect("valid levels");
            if bytes.check().is_err() {
                println!(
                    "| {name} | {levels} | {} | {:.1} | {:.1} | over the budget |",
                    bytes.level_maps,
                    bytes.levels as f64 / texels as f64,
                    bytes.level_maps as f64 * whole / texels as f64,
                );
                continue;
            }
            let start = Instant::now();
            let material = DiscreteBrdf::new(parameters).expect("a material within budget");
            let seconds = start.elapsed().as_secs_f64();
            assert_eq!(material.map_bytes(), bytes.total());
            let shared = if bytes.shared_levels { ", shared" } else { "" };
            println!(
                "| {name} | {levels} | {}{shared} | {:.1} | {:.1} | {:.0} |",
                bytes.level_maps,
                bytes.levels as f64 / texels as f64,
                bytes.level_maps as f64 * whole / texels as f64,
                1e3 * seconds / (texels as f64 / 1e6),
            );
        }
    }
}

/// The density map's row (see the module docs).
fn density_map(side: usize) {
    let texels = (side * side) as f64;
    let values = glint_benches::production_density_values(side);
    let counted = DensityMap::bytes_for_values(side, side, &values);
    let before = resident_kib("VmRSS");
    // Writing 5 resets the peak (VmHWM) to the current resident set.
    let reset = std::fs::write("/proc/self/clear_refs", "5").is_ok();
    let start = Instant::now();
    let map = DensityMap::new(side, side, &values).expect("a valid map");
    let seconds = start.elapsed().as_secs_f64();
    let peak = resident_kib("VmHWM");
    assert_eq!(map.heap_bytes(), counted);
    println!("{side} × {side} density map (the production map)");
    println!();
    println!(
        "| bytes per texel | build (ms per megatexel) | peak while building (bytes per texel) |"
    );
    println!("|---|---|---|");
    let peak = match (reset, before, peak) {
        (true, Some(before), Some(peak)) => {
            format!(
                "{:.1}",
                1024.0 * peak.saturating_sub(before) as f64 / texels
            )
        }
        _ => "not measured".to_string(),
    };
    println!(
        "| {:.2} | {:.0} | {peak} |",
        counted as f64 / texels,
        1e3 * seconds / (texels / 1e6),
    );
    println!();
}

/// A field of `/proc/self/status`, in KiB (`None` where it cannot be read).
fn resident_kib(field: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|line| line.starts_with(field))?;
    line.split_whitespace().nth(1)?.parse().ok()
}
