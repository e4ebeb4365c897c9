//! Batches answer as single rows do, bit for bit, whatever the thread count, the batch's split
//! and the rows' order; the default negligible-query test skips only what it may.

use std::sync::atomic::AtomicBool;

use glint_brdf::QueryScratch;
use glint_eval::{DEFAULT_NEGLIGIBLE_COUNT, EvalAnswer, EvalColumns, EvalRow, MaterialSpec};

/// A frame's worth of first-hit queries in pixel order: a 40 × 30 grid of pixel-sized
/// footprints over a patch of the unit square, 4 samples per pixel, directions near a
/// highlight and near the retro-reflection (far from it: negligible queries), plus three invalid
/// rows.
fn frame_rows() -> Vec<EvalRow> {
    let mut rows = Vec::new();
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut uniform = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let side = 2e-3;
    for y in 0..30 {
        for x in 0..40 {
            for s in 0..4 {
                let uv = [
                    0.3 + (x as f64 + uniform()) * side,
                    0.6 + (y as f64 + uniform()) * side,
                ];
                let theta: f64 = 0.6 + 0.01 * x as f64;
                let wi = [theta.sin(), 0.0, theta.cos()];
                // Near the mirror direction, or near wi itself (the half vector then lies
                // θ ≥ 0.6 rad from the normal, where D is below e⁻⁴⁰).
                let mirror = if s % 2 == 0 { -1.0 } else { 1.0 };
                let wo = [
                    mirror * theta.sin() + 0.05 * (uniform() - 0.5),
                    0.05 * (uniform() - 0.5),
                    theta.cos(),
                ];
                rows.push(EvalRow {
                    wi,
                    wo,
                    uv,
                    duv_dx: [side, 0.0],
                    duv_dy: [0.0, side],
                });
            }
        }
    }
    let good = rows[7];
    rows.insert(
        10,
        EvalRow {
            wi: [0.0; 3],
            ..good
        },
    );
    rows.insert(
        500,
        EvalRow {
            uv: [f64::NAN, 0.5],
            ..good
        },
    );
    rows.insert(
        900,
        EvalRow {
            duv_dx: [1e16, 0.0],
            ..good
        },
    );
    rows
}

fn bits(a: &Result<EvalAnswer, String>) -> String {
    match a {
        Ok(e) => format!(
            "{:x} {:x} {:x} {:?} {:?} {} {:?}",
            e.count.to_bits(),
            e.expected_count.to_bits(),
            e.d_hat.to_bits(),
            e.f_hat.to_array().map(f64::to_bits),
            e.f_smooth.to_array().map(f64::to_bits),
            e.nodes_visited,
            e.negligible_bound.map(f64::to_bits)
        ),
        Err(message) => format!("error: {message}"),
    }
}

#[test]
fn batches_answer_as_single_rows_whatever_the_split() {
    let material = MaterialSpec {
        seed: Some(3),
        ..MaterialSpec::new("beckmann", 0.1, 1e8, 1.0)
    }
    .build()
    .unwrap();
    let rows = frame_rows();
    // Each row alone, each with a fresh scratch: the definition.
    let single: Vec<String> = rows
        .iter()
        .map(|row| bits(&material.eval_row(&mut QueryScratch::new(), row, EvalColumns::ALL)))
        .collect();
    assert_eq!(single.iter().filter(|s| s.starts_with("error")).count(), 3);
    let cancelled = AtomicBool::new(false);
    for threads in [1, 2, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            // Whole, in pieces of odd sizes (scratches carried from one call to the next), and
            // reversed.
            let whole: Vec<String> = material
                .eval_rows(&rows, EvalColumns::ALL, &cancelled)
                .iter()
                .map(|a| bits(a.as_ref().unwrap()))
                .collect();
            assert_eq!(whole, single, "{threads} threads");
            let mut pieces = Vec::new();
            for piece in rows.chunks(777) {
                pieces.extend(
                    material
                        .eval_rows(piece, EvalColumns::ALL, &cancelled)
                        .iter()
                        .map(|a| bits(a.as_ref().unwrap())),
                );
            }
            assert_eq!(pieces, single, "{threads} threads, in pieces");
            let reversed: Vec<EvalRow> = rows.iter().rev().copied().collect();
            let mut answers: Vec<String> = material
                .eval_rows(&reversed, EvalColumns::ALL, &cancelled)
                .iter()
                .map(|a| bits(a.as_ref().unwrap()))
                .collect();
            answers.reverse();
            assert_eq!(answers, single, "{threads} threads, reversed");
            // Shuffled (rows far apart in turn): dispatched in Morton order, not the caller's.
            let shuffle = |i: usize| (i * 7919) % rows.len();
            let shuffled: Vec<EvalRow> = (0..rows.len()).map(|i| rows[shuffle(i)]).collect();
            assert!(!glint_eval::batch::keeps_neighbours_together(
                &shuffled
                    .iter()
                    .map(EvalRow::locality_key)
                    .collect::<Vec<_>>()
            ));
            let answers = material.eval_rows(&shuffled, EvalColumns::ALL, &cancelled);
            for (i, a) in answers.iter().enumerate() {
                assert_eq!(
                    bits(a.as_ref().unwrap()),
                    single[shuffle(i)],
                    "{threads} threads, shuffled"
                );
            }
        });
    }
    // Without the expected count or the smooth BRDF, every other field is the same.
    let fast = material.eval_rows(&rows, EvalColumns::F_HAT, &cancelled);
    for (row, (f, s)) in rows.iter().zip(fast.iter().zip(&single)) {
        match f.as_ref().unwrap() {
            Ok(e) => {
                assert!(e.expected_count.is_nan());
                assert!(e.f_smooth.is_nan());
                let full = material
                    .eval_row(&mut QueryScratch::new(), row, EvalColumns::ALL)
                    .unwrap();
                assert_eq!(
                    bits(&Ok(EvalAnswer {
                        expected_count: full.expected_count,
                        f_smooth: full.f_smooth,
                        ..*e
                    })),
                    *s
                );
            }
            Err(message) => assert_eq!(format!("error: {message}"), *s),
        }
    }
}

/// The default skips queries provably below 10⁻¹² expected particles (the tracer's τ), and
/// `negligible_count = 0` traverses every query; both count the same particles here.
#[test]
fn the_negligible_test_is_on_by_default() {
    assert_eq!(DEFAULT_NEGLIGIBLE_COUNT, 1e-12);
    let spec = MaterialSpec {
        seed: Some(3),
        ..MaterialSpec::new("beckmann", 0.1, 1e8, 1.0)
    };
    let default = spec.build().unwrap();
    let traverse_all = MaterialSpec {
        negligible_count: Some(0.0),
        ..spec
    }
    .build()
    .unwrap();
    let rows = frame_rows();
    let cancelled = AtomicBool::new(false);
    let (a, b) = (
        default.eval_rows(&rows, EvalColumns::ALL, &cancelled),
        traverse_all.eval_rows(&rows, EvalColumns::ALL, &cancelled),
    );
    let mut skipped = 0;
    for (a, b) in a.iter().zip(&b) {
        let (Ok(a), Ok(b)) = (a.as_ref().unwrap(), b.as_ref().unwrap()) else {
            continue;
        };
        assert!(b.negligible_bound.is_none());
        if let Some(bound) = a.negligible_bound {
            skipped += 1;
            assert!(bound < 1e-12, "{bound}");
            // Alg. 2's quadrature has an absolute tolerance: its expected count may exceed the
            // proven bound by that much, never by more.
            assert!(b.expected_count < 1e-12, "{}", b.expected_count);
            assert_eq!(a.count, 0.0);
            assert_eq!(b.count, 0.0);
        } else {
            assert_eq!(a.count.to_bits(), b.count.to_bits());
        }
    }
    assert!(
        skipped > rows.len() / 5,
        "{skipped} of {} skipped",
        rows.len()
    );
}

/// A pool beyond `MAX_THREADS` is refused before any thread starts (`xtask render --threads
/// 4096` spent 7–25 s starting threads and then failed with "Resource temporarily
/// unavailable"); counts within [1, MAX_THREADS] are built.
#[test]
fn a_pool_beyond_max_threads_is_refused_before_it_starts() {
    use glint_eval::batch::{MAX_THREADS, thread_count, thread_pool};
    assert_eq!(MAX_THREADS, 1024);
    for refused in [0, MAX_THREADS + 1, 4096, usize::MAX] {
        let error = thread_pool(Some(refused), |i| format!("test-{i}")).unwrap_err();
        assert_eq!(
            error,
            format!("threads = {refused}: the number of threads must be in [1, 1024]")
        );
        assert!(thread_count(Some(refused)).is_err());
    }
    let pool = thread_pool(Some(3), |i| format!("test-{i}")).unwrap();
    assert_eq!(pool.current_num_threads(), 3);
    assert_eq!(thread_count(Some(MAX_THREADS)), Ok(MAX_THREADS));
    let default = thread_count(None).unwrap();
    assert!((1..=MAX_THREADS).contains(&default));
}

/// A tidy test: `scenes/README.md`'s Limits table states the thread limit.
#[test]
fn the_scenes_readme_states_the_thread_limit() {
    let readme = include_str!("../../../scenes/README.md");
    let row = readme
        .lines()
        .find(|line| line.starts_with("| worker threads"))
        .expect("a worker threads row in scenes/README.md's Limits");
    let stated = format!("| 1–{} |", glint_eval::batch::MAX_THREADS);
    assert!(row.contains(&stated), "{stated:?} is not in {row:?}");
}
