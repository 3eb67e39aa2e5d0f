//! Running work on a pool of a given size: how the tests and benchmarks show that a result
//! does not depend on the number of threads, which every parallel loop of the project
//! promises.

/// Runs `work` on a fresh pool of `threads` worker threads (at least one) and returns its
/// result.
///
/// ```
/// use rayon::prelude::*;
/// use sphcover_core::on_threads;
///
/// let sum = |threads| on_threads(threads, || (1..=100u64).into_par_iter().sum::<u64>());
/// assert_eq!(sum(1), sum(3));
/// ```
///
/// # Panics
///
/// When the system refuses to start the threads.
pub fn on_threads<R: Send>(threads: usize, work: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
        .unwrap_or_else(|e| panic!("a pool of {threads} threads could not be started: {e}"))
        .install(work)
}
