//! The thread pool a program runs soundloc in.
//!
//! The CPU path runs on rayon's global pool, or inside [`install`] on a pool that survives
//! `fork` (the Python binding's). A thread outside the pool that pushes audio
//! hands each push to a pool thread and sleeps until it is done: two wake-ups across
//! cores, ≈ 14 µs per push on a 2-core VM (2026-11-27) — as much as a small array's
//! window costs. [`adopt_current_thread`] makes the calling thread one of the pool's
//! workers instead, so its pushes run where they are made. Programs call it once, first
//! thing, from the thread that will push (the CLI does, from its main thread).
//!
//! The adopted thread runs pool work only while it is inside a rayon call itself. While
//! it waits elsewhere (on a channel, a socket, a joined thread), work that other threads
//! hand to the pool has one worker fewer; a pool of one thread is therefore never
//! adopted, since nothing could then run that work until the thread came back.

/// Runs `f` in a pool of soundloc's own (rayon's default size) that survives `fork`:
/// every rayon call inside `f` runs on that pool's threads. Rayon's global pool does not
/// survive a fork (the child inherits the pool but not its threads, so its first parallel
/// call waits forever); this one is rebuilt in a process whose id differs from the one it
/// was built in, the old one left alone. For embedders whose processes fork after using
/// soundloc: Python's `multiprocessing` (fork is its default start method on Linux until
/// 3.14), `ProcessPoolExecutor`, data-loader workers. The Python binding runs every call
/// through it. Where no threads can be started `f` runs on the global pool.
pub fn install<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    match forked_pool() {
        Some(p) => p.install(f),
        None => f(),
    }
}

/// The pool [`install`] uses: this process's, built on first use.
fn forked_pool() -> Option<&'static rayon::ThreadPool> {
    static POOL: std::sync::Mutex<Option<(u32, &'static rayon::ThreadPool)>> = std::sync::Mutex::new(None);
    let pid = std::process::id();
    let mut p = POOL.lock().unwrap_or_else(|e| e.into_inner());
    match *p {
        Some((at, pool)) if at == pid => Some(pool),
        _ => {
            // Leaked on purpose: an inherited pool's threads are gone, so it is never
            // dropped (dropping it would signal threads this process does not have).
            let pool: &'static rayon::ThreadPool = Box::leak(Box::new(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(default_threads(|k| std::env::var(k).ok()))
                    .thread_name(|i| format!("soundloc-{i}"))
                    .build()
                    .ok()?,
            ));
            *p = Some((pid, pool));
            Some(pool)
        }
    }
}

/// Build rayon's global pool with the calling thread as worker 0 and the thread count
/// rayon would choose itself (`RAYON_NUM_THREADS`, else the deprecated
/// `RAYON_RS_NUM_CPUS`, else the logical CPUs). Returns whether it did: not where the
/// pool would have a single thread (see the module docs), nor once the global pool
/// exists (then nothing changes).
pub fn adopt_current_thread() -> bool {
    let threads = default_threads(|k| std::env::var(k).ok());
    threads >= 2
        && rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .use_current_thread()
            .build_global()
            .is_ok()
}

/// Rayon's own rule for the size of a pool built without `num_threads` (rayon-core
/// 1.13, `ThreadPoolBuilder::get_num_threads`), with the environment read through `env`.
fn default_threads(env: impl Fn(&str) -> Option<String>) -> usize {
    let cpus = || std::thread::available_parallelism().map_or(1, |n| n.get());
    let var = |k: &str| env(k).and_then(|s| s.parse::<usize>().ok());
    match var("RAYON_NUM_THREADS") {
        Some(x @ 1..) => x,
        Some(0) => cpus(),
        None => match var("RAYON_RS_NUM_CPUS") {
            Some(x @ 1..) => x,
            _ => cpus(),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::default_threads;

    #[test]
    fn the_thread_count_follows_rayons_rule() {
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
        let with = |vars: &[(&str, &str)]| {
            let vars: Vec<(String, String)> =
                vars.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
            default_threads(move |k| vars.iter().find(|(n, _)| n == k).map(|(_, v)| v.clone()))
        };
        assert_eq!(with(&[]), cpus);
        assert_eq!(with(&[("RAYON_NUM_THREADS", "3")]), 3);
        assert_eq!(with(&[("RAYON_NUM_THREADS", "0")]), cpus);
        // Not a number (rayon does not trim either): the deprecated variable, then the CPUs.
        assert_eq!(with(&[("RAYON_NUM_THREADS", " 3")]), cpus);
        assert_eq!(with(&[("RAYON_NUM_THREADS", "x"), ("RAYON_RS_NUM_CPUS", "1")]), 1);
        assert_eq!(with(&[("RAYON_RS_NUM_CPUS", "5")]), 5);
        assert_eq!(with(&[("RAYON_NUM_THREADS", "2"), ("RAYON_RS_NUM_CPUS", "5")]), 2);
    }
}
