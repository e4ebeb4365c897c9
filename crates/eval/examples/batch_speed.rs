//! A batch's cost per row against a renderer's loop over the same queries, on one thread.
//!
//! ```text
//! cargo run --release -p glint-eval --example batch_speed -- QUERIES.f64 'MATERIAL_JSON'
//! ```
//!
//! `QUERIES.f64` holds raw little-endian f64, 12 per query (wi, wo, uv, duv_dx, duv_dy), in the
//! order a renderer made them (`python/benchmarks/first_hit_queries.py` writes a frame's
//! first-hit queries in pixel order). Prints, alternating three times, the time per row of:
//! the renderer's loop (one scratch for all rows, in the given order, `DiscreteBrdf::at(..)
//! .evaluate` as glint-tracer calls it); `EvalMaterial::eval_rows` on a one-thread pool, without
//! the expected count (rows dispatched in Morton order of their footprints, and in input order
//! for comparison) and with it; and `eval_rows` on all threads.

use std::sync::atomic::AtomicBool;
use std::time::Instant;

use glint_brdf::{DVec2, DVec3, Footprint, QueryScratch};
use glint_eval::{EvalColumns, EvalRow, MaterialSpec};

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let path = args
        .next()
        .ok_or("usage: batch_speed QUERIES.f64 MATERIAL_JSON")?;
    let material = args
        .next()
        .ok_or("usage: batch_speed QUERIES.f64 MATERIAL_JSON")?;
    let material: serde_json::Value =
        serde_json::from_str(&material).map_err(|e| format!("material: {e}"))?;
    let material = MaterialSpec::from_json(&material)?.build()?;
    let bytes = std::fs::read(&path).map_err(|e| format!("{path}: {e}"))?;
    let numbers: Vec<f64> = bytes
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
        .collect();
    let rows: Vec<EvalRow> = numbers
        .chunks_exact(12)
        .map(|q| EvalRow {
            wi: [q[0], q[1], q[2]],
            wo: [q[3], q[4], q[5]],
            uv: [q[6], q[7]],
            duv_dx: [q[8], q[9]],
            duv_dy: [q[10], q[11]],
        })
        .collect();
    let n = rows.len() as f64;
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| e.to_string())?;
    let cancelled = AtomicBool::new(false);
    let per_row = |start: Instant| start.elapsed().as_secs_f64() / n * 1e6;
    println!("{} rows", rows.len());
    for round in 0..3 {
        let start = Instant::now();
        let mut scratch = QueryScratch::new();
        let mut found = 0.0;
        for r in &rows {
            let Ok(footprint) = Footprint::new(
                DVec2::from_array(r.uv),
                DVec2::from_array(r.duv_dx),
                DVec2::from_array(r.duv_dy),
            ) else {
                continue;
            };
            let (wi, wo) = (
                DVec3::from_array(r.wi).normalize(),
                DVec3::from_array(r.wo).normalize(),
            );
            found += material
                .brdf()
                .at(&footprint, &mut scratch)
                .evaluate(wi, wo)
                .count;
        }
        let renderer = per_row(start);
        let start = Instant::now();
        let mut scratch = QueryScratch::new();
        for r in &rows {
            let _ = material.eval_row(&mut scratch, r, EvalColumns::F_HAT);
        }
        let rows_loop = per_row(start);
        let start = Instant::now();
        let batch = one.install(|| material.eval_rows(&rows, EvalColumns::F_HAT, &cancelled));
        let batch_time = per_row(start);
        let start = Instant::now();
        one.install(|| {
            glint_eval::batch::answer_rows(
                &rows,
                |_| 0,
                &cancelled,
                |scratch, row| material.eval_row(scratch, row, EvalColumns::F_HAT),
            )
        });
        let input_order = per_row(start);
        let start = Instant::now();
        one.install(|| {
            material.eval_rows(
                &rows,
                EvalColumns {
                    expected_count: true,
                    f_smooth: false,
                },
                &cancelled,
            )
        });
        let with_expected = per_row(start);
        let start = Instant::now();
        material.eval_rows(&rows, EvalColumns::F_HAT, &cancelled);
        let all = per_row(start);
        let batch_found: f64 = batch
            .iter()
            .filter_map(|a| a.as_ref()?.as_ref().ok())
            .map(|e| e.count)
            .sum();
        println!(
            "round {round}: renderer loop {renderer:.2} µs/row; eval_row loop {rows_loop:.2} µs/row; batch, 1 thread {batch_time:.2} µs/row \
             ({:.2}×), in input order {input_order:.2} µs/row, with expected counts \
             {with_expected:.2} µs/row; batch, {} threads {all:.2} \
             µs/row; particles found {found} = {batch_found}",
            batch_time / renderer,
            rayon::current_num_threads()
        );
    }
    Ok(())
}
