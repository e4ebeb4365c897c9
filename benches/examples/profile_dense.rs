//! Times the dense-glitter workload of `cargo xtask validate --only dense` (Beckmann α = 0.1,
//! γ = 1°, highlight queries with footprint side 10⁻³) in a plain loop, for profilers:
//! `cargo run --release -p glint-benches --example profile_dense [N ...]` (default N = 10⁶ and
//! 10¹⁰, alternating) in the default dense mode (the lattice regime); `DENSE=sampled` takes
//! the sampled mode, `DENSE=exact` counts exactly, `NODE_SCALE=s` sets the sampled node scale,
//! `EPSILON=e` Eq. 10's ε (0.1), `SECONDS` the time per N (1), `ROUNDS=k` exactly k passes
//! over the 3000 queries instead (for callgrind), `STATS=1` the counts' statistics too.

use std::time::{Duration, Instant};

use glint_tests::SplitMix64;
use glint_tests::counts::{beckmann_density, highlight_query};
use glint_tests::dense::SIDE;
use glint_tree::{CountTree, CountTreeConfig, DenseCounts, QueryScratch};

fn main() {
    let env = |name: &str| std::env::var(name).ok().and_then(|e| e.parse::<f64>().ok());
    let mut densities: Vec<f64> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    if densities.is_empty() {
        densities = vec![1e6, 1e10];
    }
    let node_scale = env("NODE_SCALE").unwrap_or(DenseCounts::DEFAULT_NODE_SCALE);
    let dense = match std::env::var("DENSE").as_deref() {
        Ok("exact") => DenseCounts::Exact,
        Ok("sampled") => DenseCounts::Sampled { node_scale },
        _ => DenseCounts::Lattice { node_scale },
    };
    let mut rng = SplitMix64::new(4242);
    let workload: Vec<_> = (0..3000)
        .map(|_| highlight_query(0.1, 1f64.to_radians(), SIDE, &mut rng))
        .collect();
    let trees: Vec<CountTree> = densities
        .iter()
        .map(|&particles| {
            let config = CountTreeConfig {
                particles: particles as u64,
                seed: 77,
                epsilon: env("EPSILON").unwrap_or(0.1),
                dense,
                ..CountTreeConfig::default()
            };
            CountTree::new(config, beckmann_density(0.1, 0.1)).expect("valid setting")
        })
        .collect();
    let seconds = env("SECONDS").unwrap_or(1.0);
    let rounds = env("ROUNDS").map(|r| r as u64);
    let mut scratch = QueryScratch::new();
    // Alternate the densities over a few passes, so that a shared machine's noise falls on all.
    let passes = if rounds.is_some() { 1 } else { 3 };
    let mut totals = vec![(0.0f64, 0u64, 0u64); trees.len()];
    for _ in 0..passes {
        for (tree, total) in trees.iter().zip(&mut totals) {
            let _ = tree.query(&workload[0].0, &workload[0].1, &mut scratch);
            let started = Instant::now();
            let mut calls = 0u64;
            while match rounds {
                Some(rounds) => calls < rounds * workload.len() as u64,
                None => started.elapsed() < Duration::from_secs_f64(seconds / passes as f64),
            } {
                for (footprint, conic) in &workload {
                    total.1 += u64::from(tree.query(footprint, conic, &mut scratch).nodes_visited);
                }
                calls += workload.len() as u64;
            }
            total.0 += started.elapsed().as_secs_f64();
            total.2 += calls;
        }
    }
    // STATS=1: also what a viewer sees of the counts (`glint_tests::dense`, 2000 positions).
    if std::env::var("STATS").is_ok() {
        for (particles, tree) in densities.iter().zip(&trees) {
            let s = glint_tests::dense::dense_statistics(tree, 2000, 5);
            println!(
                "N = {particles:.0e}: mean {:.4} dispersion {:.3} skewness {:.3} shifted ½ {:.3} \
                 neighbour {:.3} conic moved {:.3}",
                s.mean, s.dispersion, s.skewness, s.shifted, s.neighbour, s.conic_moved
            );
        }
    }
    for (particles, (seconds, nodes, calls)) in densities.iter().zip(totals) {
        println!(
            "N = {particles:.0e}: {:7.2} µs/query {:6.1} nodes/query",
            seconds * 1e6 / calls as f64,
            nodes as f64 / calls as f64
        );
    }
}
