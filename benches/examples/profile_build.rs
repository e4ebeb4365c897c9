//! Times building glint materials (`DiscreteBrdf::new`) as `cargo xtask eval`, C and Python
//! build them (the negligible-query test on, τ = 10⁻¹²), for profilers and for the build time
//! the docs quote: `cargo run --release -p glint-benches --example profile_build [ROUNDS]`
//! (under `perf record -g` for a call graph). Prints, per material kind, the median over
//! ROUNDS builds (default 20) of a build whose law is new to the process (α changed in its
//! last digits: the negligible-query test enumerates its law), of a build of a law built
//! before with another seed (the law excess remembered), and without the negligible test.

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
    println!(
        "| material | new law (ms) | a law built before: another seed (ms) | without the negligible test (ms) |"
    );
    println!("|---|---|---|---|");
    for (name, kind, alpha_x, alpha_y) in materials {
        // `law(k)` differs from the others in the last digits of α (a law never built before);
        // `seed(k)` is the first law with another seed (its law excess remembered).
        let median = |negligible_count: f64, new_law: bool| {
            let mut times: Vec<f64> = (0..rounds)
                .map(|k| {
                    let scale = if new_law {
                        1.0 + 1e-9 * (k + 1) as f64
                    } else {
                        1.0
                    };
                    let distribution =
                        Microfacet::new(kind, alpha_x * scale, alpha_y * scale).unwrap();
                    let mut parameters = GlintParameters::new(distribution);
                    parameters.seed = k as u64;
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
        println!(
            "| {name} | {:.2} | {:.2} | {:.2} |",
            median(1e-12, true),
            median(1e-12, false),
            median(0.0, false)
        );
    }
}
