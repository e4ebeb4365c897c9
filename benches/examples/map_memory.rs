//! The memory and build time of a material's roughness levels, for the figures of
//! docs/performance.md ("Glint maps", memory): `cargo run --release -p glint-benches --example
//! map_memory [SIDE]` (default 4096). For roughness maps of SIDE² texels, each at several
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
