//! Batches of rows answered at a renderer's speed, for every caller that hands glint many
//! queries at once (the Python package, the C batch call, `cargo xtask eval`).
//!
//! A renderer answers a pixel's queries and then its neighbours' with one [`QueryScratch`],
//! whose memos (split counts, leaf particles, directional splits) the next query meets again.
//! A batch does the same:
//!
//! - **Scratches live per thread, across calls** ([`with_thread_scratch`]): each thread that
//!   answers rows keeps one scratch for its lifetime (a worker pool's threads keep theirs from
//!   one batch to the next), so no call starts with cold memos or allocates them.
//! - **Rows are dispatched in locality order** ([`answer_rows`]): sorted by a Morton (Z-order)
//!   key of the footprint's centre in the particles' unit square, then cut into contiguous
//!   runs, one per task, so neighbouring footprints are answered one after the other on one
//!   thread whatever order the caller gave them in.
//! - **Answers come back in input order, bit for bit whatever the split**: a query's answer is
//!   a function of the query alone (the scratch only remembers draws that the material fixes;
//!   `DESIGN.md`, "The particle set is a function of the material alone"), so the thread
//!   count, the batch's size and the dispatch order never change a bit of it. Tests check it.

use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use glint_brdf::QueryScratch;
use rayon::prelude::*;

/// Rows per parallel task at least: large enough that scheduling is cheap next to ~1–20 µs
/// queries, and that a task's run of neighbouring footprints reuses its memos.
pub const MIN_ROWS_PER_TASK: usize = 256;

/// Tasks per worker thread a batch is cut into at most (a few, so one slow run of rows does
/// not leave the other threads idle at the end).
const TASKS_PER_THREAD: usize = 4;

thread_local! {
    /// This thread's scratch, kept across batches, and whether a call using it is under way
    /// (still set after a panic: its memo tables may be half written).
    static SCRATCH: RefCell<(QueryScratch, bool)> = RefCell::new((QueryScratch::new(), false));
}

/// Runs `f` with this thread's query scratch, which lives as long as the thread and serves
/// every material (its memo entries name the tree they belong to). A scratch left by a call
/// that panicked is replaced first; re-entrant calls (`f` itself asking for the scratch) get a
/// fresh one rather than a panic.
pub fn with_thread_scratch<R>(f: impl FnOnce(&mut QueryScratch) -> R) -> R {
    let mut f = Some(f);
    let kept = SCRATCH.try_with(|cell| {
        cell.try_borrow_mut().ok().map(|mut kept| {
            let (scratch, in_use) = &mut *kept;
            if *in_use {
                *scratch = QueryScratch::new();
            }
            *in_use = true;
            let result = (f.take().expect("called once"))(scratch);
            *in_use = false;
            result
        })
    });
    match kept {
        Ok(Some(result)) => result,
        // Re-entered, or the thread is being torn down: a scratch of this call's own.
        _ => (f.take().expect("not called above"))(&mut QueryScratch::new()),
    }
}

/// The worker pool of this process for batches: built on first use (with rayon's default
/// thread count, `RAYON_NUM_THREADS` or one per core), and built again in a forked child
/// (whose process id differs from the one that built it). A child cannot use its parent's
/// pool: fork copies the pool's state but none of its threads, and a batch would wait for them
/// forever. The parent's pool is leaked in the child, not dropped, since dropping it would
/// signal threads (and perhaps a lock one held at the fork) that do not exist there; it costs
/// one pool per fork. Never rayon's global pool, which cannot be rebuilt.
///
/// # Errors
/// When the operating system refuses the threads.
pub fn process_pool() -> Result<Arc<rayon::ThreadPool>, String> {
    static POOL: Mutex<Option<(u32, Arc<rayon::ThreadPool>)>> = Mutex::new(None);
    let pid = std::process::id();
    let mut pool = POOL.lock().unwrap_or_else(PoisonError::into_inner);
    match pool.as_ref() {
        Some((built_in, current)) if *built_in == pid => Ok(Arc::clone(current)),
        _ => {
            let built = Arc::new(
                rayon::ThreadPoolBuilder::new()
                    .thread_name(|i| format!("glint-{i}"))
                    .build()
                    .map_err(|e| format!("cannot start glint's worker threads: {e}"))?,
            );
            if let Some(inherited) = pool.replace((pid, Arc::clone(&built))) {
                std::mem::forget(inherited);
            }
            Ok(built)
        }
    }
}

/// The Morton (Z-order) key of a footprint centre `uv`: the fractional parts of u and v (the
/// particles tile the unit square) on 2¹⁶ steps each, their bits interleaved. Non-finite
/// coordinates key as 0 (such rows are errors and cost nothing).
#[must_use]
pub fn locality_key(uv: [f64; 2]) -> u64 {
    let step = |x: f64| -> u64 {
        if !x.is_finite() {
            return 0;
        }
        let f = x - x.floor();
        ((f * 65536.0) as u64).min(65535)
    };
    spread(step(uv[0])) | (spread(step(uv[1])) << 1)
}

/// The 16 low bits of `x` moved to the even bit positions.
fn spread(mut x: u64) -> u64 {
    x &= 0xffff;
    x = (x | (x << 8)) & 0x00ff_00ff;
    x = (x | (x << 4)) & 0x0f0f_0f0f;
    x = (x | (x << 2)) & 0x3333_3333;
    (x | (x << 1)) & 0x5555_5555
}

/// Answers every input with `answer` in parallel on the current rayon pool (the caller's
/// `ThreadPool::install`, else rayon's global pool), each thread with its own scratch kept
/// across calls ([`with_thread_scratch`]), dispatching the rows in the order of `key` (rows of
/// equal key in input order; [`locality_key`] of the footprint's centre, or 0 for all when the
/// rows have no footprint) and returning the answers in input order.
///
/// `cancelled` is read before each row: once it is set, the remaining rows are not answered
/// and come back `None` (every answered row is `Some`).
pub fn answer_rows<I: Sync, O: Send>(
    inputs: &[I],
    key: impl Fn(&I) -> u64 + Sync,
    cancelled: &AtomicBool,
    answer: impl Fn(&mut QueryScratch, &I) -> O + Sync,
) -> Vec<Option<O>> {
    let n = inputs.len();
    // The dispatch order: stable, so rows of equal key keep the caller's order.
    let mut order: Vec<(u64, u32)> = inputs
        .iter()
        .enumerate()
        .map(|(i, input)| (key(input), i as u32))
        .collect();
    if order.windows(2).any(|w| w[0].0 > w[1].0) {
        order.sort_unstable();
    }
    let tasks = rayon::current_num_threads().max(1) * TASKS_PER_THREAD;
    let rows_per_task = n.div_ceil(tasks).max(MIN_ROWS_PER_TASK);
    let answered: Vec<Vec<(u32, O)>> = order
        .par_chunks(rows_per_task)
        .map(|run| {
            with_thread_scratch(|scratch| {
                run.iter()
                    .map_while(|&(_, i)| {
                        (!cancelled.load(Ordering::Relaxed))
                            .then(|| (i, answer(scratch, &inputs[i as usize])))
                    })
                    .collect()
            })
        })
        .collect();
    let mut answers: Vec<Option<O>> = (0..n).map(|_| None).collect();
    for (i, o) in answered.into_iter().flatten() {
        answers[i as usize] = Some(o);
    }
    answers
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locality_keys_interleave_the_fractional_parts() {
        assert_eq!(locality_key([0.0, 0.0]), 0);
        // u's top bit is bit 30, v's bit 31.
        assert_eq!(locality_key([0.5, 0.0]), 1 << 30);
        assert_eq!(locality_key([0.0, 0.5]), 1 << 31);
        // Tiles repeat: uv and uv + (3, −2) key alike.
        assert_eq!(locality_key([0.3, 0.7]), locality_key([3.3, -1.3]));
        assert_eq!(locality_key([f64::NAN, 0.0]), 0);
        assert!(locality_key([0.999_999_999, 0.999_999_999]) <= u64::from(u32::MAX));
    }

    #[test]
    fn answers_come_back_in_input_order() {
        let inputs: Vec<u64> = (0..5000).map(|i| (i * 7919) % 1000).collect();
        let cancelled = AtomicBool::new(false);
        let answers = answer_rows(&inputs, |&x| x, &cancelled, |_, &x| x * 2);
        let expected: Vec<Option<u64>> = inputs.iter().map(|&x| Some(x * 2)).collect();
        assert_eq!(answers, expected);
        cancelled.store(true, Ordering::Relaxed);
        let none = answer_rows(&inputs, |&x| x, &cancelled, |_, &x| x);
        assert!(none.iter().all(Option::is_none));
    }

    #[test]
    fn a_reentrant_call_gets_a_scratch_of_its_own() {
        let nested = with_thread_scratch(|_| with_thread_scratch(|_| 3));
        assert_eq!(nested, 3);
    }
}
