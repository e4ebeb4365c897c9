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
//! - **Rows are dispatched in locality order** ([`answer_rows`]): in the caller's order when it
//!   already keeps neighbouring footprints together (a renderer's pixel order), else sorted by
//!   a Morton (Z-order) key of the footprint's centre in the particles' unit square; then cut
//!   into contiguous runs, one per task, so neighbouring footprints are answered one after the
//!   other on one thread whatever order the caller gave them in.
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

/// The most worker threads any pool of glint may have (`cargo xtask render --threads`, the
/// Python package's `threads`, the C API's pool under `RAYON_NUM_THREADS`): 1024, far more
/// than the cores of one machine, few enough that a pool starts at once. Beyond it a request
/// is refused before any thread is started (4096 threads took 7–25 s to start and then failed
/// with "Resource temporarily unavailable").
pub const MAX_THREADS: usize = 1024;

/// The thread count of a pool: `requested`, else `RAYON_NUM_THREADS` when it is set to a
/// number, else one per core (at most [`MAX_THREADS`]: a machine of more cores gets that
/// many).
///
/// # Errors
/// A requested count (or `RAYON_NUM_THREADS`) of 0 or above [`MAX_THREADS`], naming it.
pub fn thread_count(requested: Option<usize>) -> Result<usize, String> {
    let check = |count: usize, what: &str| {
        if (1..=MAX_THREADS).contains(&count) {
            Ok(count)
        } else {
            Err(format!(
                "{what} = {count}: the number of threads must be in [1, {MAX_THREADS}]"
            ))
        }
    };
    if let Some(count) = requested {
        return check(count, "threads");
    }
    if let Some(value) = std::env::var_os("RAYON_NUM_THREADS") {
        // rayon's own reading: a positive number is the count; anything else is ignored.
        if let Some(count) = value.to_str().and_then(|v| v.trim().parse::<usize>().ok())
            && count > 0
        {
            return check(count, "RAYON_NUM_THREADS");
        }
    }
    Ok(std::thread::available_parallelism()
        .map_or(1, std::num::NonZeroUsize::get)
        .min(MAX_THREADS))
}

/// A worker pool of [`thread_count`]`(requested)` threads named by `name`: where every pool of
/// glint is built, so [`MAX_THREADS`] holds everywhere.
///
/// # Errors
/// [`thread_count`]'s, or the operating system refusing the threads.
pub fn thread_pool(
    requested: Option<usize>,
    name: impl Fn(usize) -> String + Send + Sync + 'static,
) -> Result<rayon::ThreadPool, String> {
    let count = thread_count(requested)?;
    rayon::ThreadPoolBuilder::new()
        .num_threads(count)
        .thread_name(name)
        .build()
        .map_err(|e| format!("cannot start {count} worker threads: {e}"))
}

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
/// thread count, `RAYON_NUM_THREADS` or one per core, within [`MAX_THREADS`]:
/// [`thread_count`]), and built again in a forked child
/// (whose process id differs from the one that built it). A child cannot use its parent's
/// pool: fork copies the pool's state but none of its threads, and a batch would wait for them
/// forever. The parent's pool is leaked in the child, not dropped, since dropping it would
/// signal threads (and perhaps a lock one held at the fork) that do not exist there; it costs
/// one pool per fork. Never rayon's global pool, which cannot be rebuilt.
///
/// # Errors
/// `RAYON_NUM_THREADS` beyond [`MAX_THREADS`], or the operating system refusing the threads.
pub fn process_pool() -> Result<Arc<rayon::ThreadPool>, String> {
    static POOL: Mutex<Option<(u32, Arc<rayon::ThreadPool>)>> = Mutex::new(None);
    let pid = std::process::id();
    let mut pool = POOL.lock().unwrap_or_else(PoisonError::into_inner);
    match pool.as_ref() {
        Some((built_in, current)) if *built_in == pid => Ok(Arc::clone(current)),
        _ => {
            let built = Arc::new(
                thread_pool(None, |i| format!("glint-{i}"))
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
/// across calls ([`with_thread_scratch`]), and returns the answers in input order.
///
/// Rows go to threads in contiguous runs of a dispatch order: the caller's own when it already
/// keeps neighbours together ([`keeps_neighbours_together`]: a renderer's pixel order), else
/// the order of `key` (rows of equal key in input order; [`locality_key`] of the footprint's
/// centre, or 0 for all when the rows have no footprint). Reordering costs a sort and a cache
/// miss per row, which rows already in order do not pay.
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
    let tasks = rayon::current_num_threads().max(1) * TASKS_PER_THREAD;
    let rows_per_task = n.div_ceil(tasks).max(MIN_ROWS_PER_TASK);
    let keys: Vec<u64> = inputs.iter().map(&key).collect();
    let mut answers: Vec<Option<O>> = Vec::with_capacity(n);
    if keeps_neighbours_together(&keys) {
        let starts: Vec<usize> = (0..n).step_by(rows_per_task).collect();
        let answered: Vec<Vec<O>> = starts
            .par_iter()
            .map(|&start| {
                answer_run(
                    start..(start + rows_per_task).min(n),
                    inputs,
                    cancelled,
                    &answer,
                )
            })
            .collect();
        for (&start, outputs) in starts.iter().zip(answered) {
            answers.resize_with(start, || None);
            answers.extend(outputs.into_iter().map(Some));
        }
        answers.resize_with(n, || None);
        return answers;
    }
    // The dispatch order: stable, so rows of equal key keep the caller's order.
    let mut order: Vec<(u64, u32)> = keys.into_iter().zip(0..).collect();
    order.sort_unstable();
    let answered: Vec<Vec<O>> = order
        .par_chunks(rows_per_task)
        .map(|run| {
            answer_run(
                run.iter().map(|&(_, i)| i as usize),
                inputs,
                cancelled,
                &answer,
            )
        })
        .collect();
    answers.resize_with(n, || None);
    for (run, outputs) in order.chunks(rows_per_task).zip(answered) {
        for (&(_, i), o) in run.iter().zip(outputs) {
            answers[i as usize] = Some(o);
        }
    }
    answers
}

/// The answers to the rows `run` of `inputs` with this thread's scratch, in the run's order (a
/// prefix of it when `cancelled` is set).
fn answer_run<I, O>(
    run: impl Iterator<Item = usize>,
    inputs: &[I],
    cancelled: &AtomicBool,
    answer: &impl Fn(&mut QueryScratch, &I) -> O,
) -> Vec<O> {
    with_thread_scratch(|scratch| {
        run.map_while(|i| (!cancelled.load(Ordering::Relaxed)).then(|| answer(scratch, &inputs[i])))
            .collect()
    })
}

/// Whether rows in the order of `keys` ([`locality_key`]s) already keep neighbouring
/// footprints together: at most one row in [`JUMPS_PER_ROW_IN_ORDER`] moves to another cell of
/// a 16 × 16 grid of the unit square than the row before it (the top 8 bits of the 32-bit
/// key). A frame's rows in pixel order move to a neighbouring cell every few dozen pixels
/// along a scanline; rows in random order move on almost every row.
#[must_use]
pub fn keeps_neighbours_together(keys: &[u64]) -> bool {
    if keys.windows(2).all(|w| w[0] <= w[1]) {
        return true;
    }
    let jumps = keys.windows(2).filter(|w| w[0] >> 24 != w[1] >> 24).count();
    jumps * JUMPS_PER_ROW_IN_ORDER <= keys.len()
}

/// See [`keeps_neighbours_together`]: rows in order jump to another grid cell at most once in
/// this many rows.
const JUMPS_PER_ROW_IN_ORDER: usize = 16;

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
    fn pixel_order_keeps_neighbours_together_and_random_order_does_not() {
        // A 256 × 64 image of pixel footprints over the unit square, 4 samples a pixel.
        let pixels: Vec<u64> = (0..64)
            .flat_map(|y| {
                (0..256 * 4).map(move |x| locality_key([(x / 4) as f64 / 256.0, y as f64 / 64.0]))
            })
            .collect();
        assert!(keeps_neighbours_together(&pixels));
        let scattered: Vec<u64> = (0..pixels.len())
            .map(|i| pixels[(i * 7919) % pixels.len()])
            .collect();
        assert!(!keeps_neighbours_together(&scattered));
        let mut sorted = scattered;
        sorted.sort_unstable();
        assert!(keeps_neighbours_together(&sorted));
        assert!(keeps_neighbours_together(&[]));
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
