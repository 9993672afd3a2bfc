//! The thread pool a program runs soundloc in.
//!
//! The CPU path runs on rayon's global pool. A thread outside the pool that pushes audio
//! hands each push to a pool thread and sleeps until it is done: two wake-ups across
//! cores, ≈ 14 µs per push on a 2-core VM (2026-11-27) — as much as a small array's
//! window costs. [`adopt_current_thread`] makes the calling thread one of the pool's
//! workers instead, so its pushes run where they are made. Programs call it once, first
//! thing, from the thread that will push (the CLI does, from its main thread).

/// Build rayon's global pool with the calling thread as worker 0 and the usual number of
/// threads (`RAYON_NUM_THREADS`, else the logical CPUs). Returns whether it did: not
/// where the pool would have a single thread (then no other thread could run work handed
/// to the pool while this one is busy elsewhere), nor once the global pool exists.
pub fn adopt_current_thread() -> bool {
    let threads = std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|v| v.trim().parse::<usize>().ok())
        .filter(|&n| n > 0)
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    threads >= 2
        && rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .use_current_thread()
            .build_global()
            .is_ok()
}
