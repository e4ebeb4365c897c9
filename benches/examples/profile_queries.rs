//! Times count-tree queries at the paper's Table 1 settings in a plain loop, for profilers:
//! `cargo run --release -p glint-benches --example profile_queries [SETTING] [SECONDS]`
//! (under `perf record -g` for a call graph). Prints ns per query and per visited node (and per
//! visited node that meets the query). `ROUNDS=k` makes exactly k passes over the 4096 queries
//! instead, for instruction counts (`valgrind --tool=callgrind`).

use std::time::{Duration, Instant};

use glint_benches::{TABLE1, table1_workload};
use glint_tree::QueryScratch;

fn main() {
    let mut args = std::env::args().skip(1);
    let filter = args.next().unwrap_or_default();
    let seconds: f64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(1.0);
    for setting in TABLE1.iter().filter(|s| s.name.contains(&filter)) {
        let (tree, mut queries) = table1_workload(setting, 4096, 1);
        // UNIFORM=1: ω_i and ω_o uniform over the hemisphere (mostly far from the highlight).
        if std::env::var("UNIFORM").is_ok() {
            let mut rng = glint_tests::SplitMix64::new(5);
            let mut direction = || {
                let [a, b] = rng.uniforms::<2>();
                let (z, phi) = (a.max(1e-3), 2.0 * std::f64::consts::PI * b);
                let r = (1.0 - z * z).sqrt();
                glam::DVec3::new(r * phi.cos(), r * phi.sin(), z)
            };
            for (_, conic) in &mut queries {
                let gamma = setting.gamma_degrees.to_radians();
                *conic = glint_sphere::SphericalConic::new(direction(), direction(), gamma)
                    .expect("valid conic");
            }
        }
        // EPSILON=0 (say) overrides the setting's ε, e.g. to compare exact counts; PARTICLES, N.
        let env = |name: &str| std::env::var(name).ok().and_then(|e| e.parse::<f64>().ok());
        let tree = match (
            env("EPSILON"),
            env("ANGLE_SCALE"),
            env("CACHED_LEVELS"),
            env("PARTICLES"),
        ) {
            (None, None, None, None) => tree,
            (epsilon, angle, levels, particles) => glint_tree::CountTree::new(
                glint_tree::CountTreeConfig {
                    particles: particles.map_or(tree.config().particles, |n| n as u64),
                    epsilon: epsilon.unwrap_or(tree.config().epsilon),
                    cached_levels: levels.map_or(tree.config().cached_levels, |l| l as u32),
                    expected_query_solid_angle: tree.config().expected_query_solid_angle
                        * angle.unwrap_or(1.0),
                    ..*tree.config()
                },
                glint_tests::counts::beckmann_density(setting.alpha, setting.alpha),
            )
            .expect("valid setting"),
        };
        let mut scratch = QueryScratch::new();
        let mut checksum = 0.0;
        for (footprint, conic) in &queries {
            checksum += tree.query(footprint, conic, &mut scratch).count;
        }
        let (mut calls, mut nodes, mut overlapping) = (0u64, 0u64, 0u64);
        let started = Instant::now();
        // ROUNDS=k: exactly k passes over the queries (for instruction counts under valgrind).
        let rounds = env("ROUNDS").map(|r| r as u64);
        while match rounds {
            Some(rounds) => calls < rounds * queries.len() as u64,
            None => started.elapsed() < Duration::from_secs_f64(seconds),
        } {
            for (footprint, conic) in &queries {
                let result = tree.query(footprint, conic, &mut scratch);
                nodes += u64::from(result.nodes_visited);
                overlapping += u64::from(result.nodes_overlapping);
            }
            calls += queries.len() as u64;
        }
        let ns = started.elapsed().as_nanos() as f64;
        println!(
            "{:28} {:6.1} nodes/query ({:5.1} meeting it) {:7.0} ns/query {:6.1} ns/node ({:6.1} per meeting node)  Σcount {:.9}",
            setting.name,
            nodes as f64 / calls as f64,
            overlapping as f64 / calls as f64,
            ns / calls as f64,
            ns / nodes as f64,
            ns / overlapping as f64,
            checksum
        );
    }
}
