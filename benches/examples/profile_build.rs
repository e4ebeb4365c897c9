//! Times building glint materials (`DiscreteBrdf::new`) as `cargo xtask eval`, C and Python
//! build them (the negligible-query test on, τ = 10⁻¹²), for profilers and for the build time
//! the docs quote: `cargo run --release -p glint-benches --example profile_build [ROUNDS]`
//! (under `perf record -g` for a call graph). Prints the median build time per material kind
//! over ROUNDS builds (default 20), each with another seed.

use std::time::Instant;

use glint_brdf::{DiscreteBrdf, DistributionKind, GlintParameters, Microfacet};

fn main() {
    let rounds: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    let materials = [
        ("Beckmann α = 0.1", DistributionKind::Beckmann, 0.1, 0.1),
        ("GGX α = 0.1", DistributionKind::Ggx, 0.1, 0.1),
        ("Beckmann α = 0.3", DistributionKind::Beckmann, 0.3, 0.3),
        ("Beckmann α = 0.01", DistributionKind::Beckmann, 0.01, 0.01),
        ("GGX α = (0.05, 0.3)", DistributionKind::Ggx, 0.05, 0.3),
    ];
    println!("| material | median build (ms) | without the negligible test (ms) |");
    println!("|---|---|---|");
    for (name, kind, alpha_x, alpha_y) in materials {
        let median = |negligible_count: f64| {
            let mut times: Vec<f64> = (0..rounds)
                .map(|seed| {
                    let mut parameters =
                        GlintParameters::new(Microfacet::new(kind, alpha_x, alpha_y).unwrap());
                    parameters.seed = seed as u64;
                    parameters.negligible_count = negligible_count;
                    let started = Instant::now();
                    let brdf = DiscreteBrdf::new(parameters).unwrap();
                    let elapsed = started.elapsed().as_secs_f64() * 1e3;
                    std::hint::black_box(brdf);
                    elapsed
                })
                .collect();
            times.sort_by(f64::total_cmp);
            times[times.len() / 2]
        };
        println!("| {name} | {:.2} | {:.2} |", median(1e-12), median(0.0));
    }
}
