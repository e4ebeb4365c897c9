//! Times building glint materials (`DiscreteBrdf::new`) as `cargo xtask eval`, C and Python
//! build them (the negligible-query test on, τ = 10⁻¹²), for profilers and for the build time
//! the docs quote: `cargo run --release -p glint-benches --example profile_build [ROUNDS]`
//! (under `perf record -g` for a call graph). Prints, per material kind, the median over
//! ROUNDS builds (default 20) of a build whose law is new to the process (α changed in its
//! last digits: the negligible-query test enumerates its law), of a build of a law built
//! before with another seed (the law excess remembered), and without the negligible test.
//!
//! `profile_build eval-lines laws|seeds [N]` instead prints N (default 1500) `cargo xtask eval`
//! lines of one material each, one `eval` of a pixel-sized footprint near the highlight:
//! Beckmann with α from 0.05 to 0.5 (N laws) or α = 0.1 with N seeds (one law). The figures
//! of docs/eval.md time `cargo xtask eval` on them.

use std::time::Instant;

use glint_brdf::{DiscreteBrdf, DistributionKind, GlintParameters, Microfacet};

fn main() {
    let arguments: Vec<String> = std::env::args().skip(1).collect();
    if arguments.first().map(String::as_str) == Some("eval-lines") {
        let laws = match arguments.get(1).map(String::as_str) {
            Some("laws") => true,
            Some("seeds") => false,
            _ => panic!("eval-lines laws|seeds [N]"),
        };
        let n: usize = arguments.get(2).map_or(1500, |s| s.parse().expect("N"));
        print_eval_lines(laws, n);
        return;
    }
    let rounds: usize = arguments.first().and_then(|s| s.parse().ok()).unwrap_or(20);
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

/// `n` one-line materials for `cargo xtask eval`: Beckmann α from 0.05 to 0.5 with seed k
/// (`laws`), or α = 0.1 with seed k, one `eval` each near the highlight.
fn print_eval_lines(laws: bool, n: usize) {
    for k in 0..n {
        let alpha = if laws && n > 1 {
            0.05 + 0.45 * k as f64 / (n - 1) as f64
        } else {
            0.1
        };
        println!(
            "{{\"op\": \"eval\", \"material\": {{\"distribution\": \"beckmann\", \"alpha\": {alpha}, \
             \"particles\": 1e6, \"gamma_degrees\": 1.0, \"seed\": {k}}}, \"uv\": [0.3, 0.4], \
             \"duv_dx\": [0.001, 0.0], \"duv_dy\": [0.0, 0.001], \"wi\": [0.0, 0.0, 1.0], \
             \"wo\": [0.1, 0.0, 0.99]}}"
        );
    }
}
