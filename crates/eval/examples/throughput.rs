//! Queries per second through the Rust API, on the queries `python/benchmarks/throughput.py`
//! writes (raw little-endian f64, 12 per query: wi, wo, uv, duv_dx, duv_dy).
//!
//! ```text
//! cargo run --release -p glint-eval --example throughput -- QUERIES.f64
//! ```
//!
//! Prints, for the material of that script, the time of the eval contract's answer
//! (`EvalMaterial::eval`: f̂, count, expected count, smooth f) on one thread and on all, and of
//! a renderer's call alone (`DiscreteBrdf::at(..).evaluate`, no expected count) on one thread.

use std::time::Instant;

use glint_brdf::{DVec2, DVec3, Footprint, QueryScratch};
use glint_eval::MaterialSpec;
use rayon::prelude::*;

fn main() -> Result<(), String> {
    let path = std::env::args()
        .nth(1)
        .ok_or("usage: throughput QUERIES.f64")?;
    let bytes = std::fs::read(&path).map_err(|e| format!("{path}: {e}"))?;
    let numbers: Vec<f64> = bytes
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
        .collect();
    let queries: Vec<&[f64]> = numbers.chunks_exact(12).collect();
    let material = MaterialSpec {
        seed: Some(7),
        ..MaterialSpec::new("beckmann", 0.1, 1e9, 1.0)
    }
    .build()?;
    let n = queries.len() as f64;
    let report = |what: &str, seconds: f64| {
        println!("{what}: {:.0} queries/s ({seconds:.2} s)", n / seconds);
    };

    let eval = |scratch: &mut QueryScratch, q: &[f64]| {
        material
            .eval(
                scratch,
                [q[0], q[1], q[2]],
                [q[3], q[4], q[5]],
                [q[6], q[7]],
                [q[8], q[9]],
                [q[10], q[11]],
            )
            .map_or(0.0, |e| e.count)
    };
    let start = Instant::now();
    let mut scratch = QueryScratch::new();
    let total: f64 = queries.iter().map(|q| eval(&mut scratch, q)).sum();
    report("eval contract, one thread", start.elapsed().as_secs_f64());

    let start = Instant::now();
    let parallel: f64 = queries
        .par_chunks(256)
        .map(|chunk| {
            let mut scratch = QueryScratch::new();
            chunk.iter().map(|q| eval(&mut scratch, q)).sum::<f64>()
        })
        .sum();
    report(
        &format!("eval contract, {} threads", rayon::current_num_threads()),
        start.elapsed().as_secs_f64(),
    );

    let start = Instant::now();
    let mut renderer_total = 0.0;
    for q in &queries {
        let wi = DVec3::new(q[0], q[1], q[2]).normalize();
        let wo = DVec3::new(q[3], q[4], q[5]).normalize();
        let footprint = Footprint::new(
            DVec2::new(q[6], q[7]),
            DVec2::new(q[8], q[9]),
            DVec2::new(q[10], q[11]),
        )
        .map_err(|e| e.to_string())?;
        renderer_total += material
            .brdf()
            .at(&footprint, &mut scratch)
            .evaluate(wi, wo)
            .count;
    }
    report(
        "DiscreteBrdf::at(..).evaluate alone, one thread",
        start.elapsed().as_secs_f64(),
    );
    println!("particles found: {total} (parallel {parallel}, renderer's call {renderer_total})");
    Ok(())
}
