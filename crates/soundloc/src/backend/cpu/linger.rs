//! Keeping the pool's other threads awake across a stream's short serial gaps.
//!
//! A small array's window is tens of µs of parallel work between a few µs of serial work
//! (the next push's STFT, the peaks). Rayon's idle threads go to sleep within a few µs,
//! and waking one costs about what the window's work does (≈ 12 µs on a 2-core VM,
//! 2026-11-27). After a short call the backend therefore hands each other thread that
//! took part a job that waits until the next pass starts or [`LINGER`] has passed,
//! whichever is first, when the gap before this call's pass was shorter than [`LINGER`]
//! too: back-to-back windows find their helpers awake, while a live stream whose blocks
//! arrive every 10 ms does not spin at all after its first call.
//!
//! While it waits, a helper runs any work queued in its pool (`rayon::yield_now`: the
//! next push's STFT, another stream's pass), so lingering never holds work back. Helpers
//! are at most one fewer than the CPU's logical cores. The pass counter is process-wide:
//! any backend's pass ends every helper's wait (harmless: the helper goes back to the
//! pool); a helper of one pool still takes a core that another pool's work could use,
//! for at most [`LINGER`].

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// How long a helper stays awake after a short call.
pub(super) const LINGER: Duration = Duration::from_micros(100);

/// Passes shorter than this leave their helpers waiting.
pub(super) const SHORT_PASS: Duration = Duration::from_millis(2);

/// Passes started so far (process-wide: any pass ends every helper's wait).
static PASSES: AtomicU64 = AtomicU64::new(0);

/// Whether to keep helpers awake after a call whose pass started at `start`, the
/// previous call having ended at `prev_end`: the pass was short and so was the gap
/// before it.
pub(super) fn wanted(prev_end: Option<Instant>, start: Instant) -> bool {
    let gap_short = prev_end.is_none_or(|e| start.saturating_duration_since(e) < LINGER);
    gap_short && start.elapsed() < SHORT_PASS
}

/// A pass starts: lingering helpers return to the pool and take its tasks.
pub(super) fn pass_starts() {
    PASSES.fetch_add(1, Ordering::Release);
}

/// A short call ended: keep up to `helpers` other threads of the current pool awake (at
/// most one fewer than the logical cores).
pub(super) fn keep_awake(helpers: usize) {
    static CORES: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    let cores = *CORES.get_or_init(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let seen = PASSES.load(Ordering::Acquire);
    for _ in 0..helpers.min(cores.saturating_sub(1)) {
        rayon::spawn(move || {
            let t = Instant::now();
            while PASSES.load(Ordering::Acquire) == seen && t.elapsed() < LINGER {
                // Work queued meanwhile runs here; none: a short pause.
                if rayon::yield_now() != Some(rayon::Yield::Executed) {
                    std::hint::spin_loop();
                }
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn helpers_linger_only_after_short_passes_that_came_close_together() {
        let now = Instant::now();
        let ago = |us: u64| now.checked_sub(Duration::from_micros(us)).expect("uptime");
        // The first pass, and a short pass 20 µs after the previous one: linger.
        assert!(wanted(None, now));
        assert!(wanted(Some(ago(20)), now));
        // Live input: the previous pass ended 10 ms before this one started.
        assert!(!wanted(Some(ago(10_000)), now));
        // A long pass (a batch of windows): its helpers were busy all along.
        let long_start = ago(5_000);
        assert!(!wanted(
            long_start.checked_sub(Duration::from_micros(20)),
            long_start
        ));
    }
}
