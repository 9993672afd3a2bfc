//! Stage 2 — correlation windows (HARK AddCorrelation / NormalizeCorrelation).
//!
//! R_k = (1/W) Σ_{f ∈ window} x_{k,f} x_{k,f}ᴴ over W = WINDOW frames, one result every
//! PERIOD frames. WINDOW_TYPE picks the frames for result frame c:
//! - FUTURE (HARK default): [c, c+W−1] for every c with c mod PERIOD = 0;
//! - MIDDLE: [c − (⌊W/2⌋ + W mod 2 − 1), c + ⌊W/2⌋];
//! - PAST: [c−W+1, c], fired when c mod PERIOD = 0 and (c ≠ 0 or PERIOD = 1) — the causal
//!   choice streaming uses.
//!
//! soundloc emits a result only for windows that lie entirely inside the signal (HARK
//! would also fire on partly filled accumulators at the edges of a stream); frames that
//! produce no result produce no output line.
//!
//! Scaling (HARK quirk, keeps single precision well conditioned): R ← R / (max_ij |Re R_ij| + 1).

pub mod onset;
pub mod running;

use crate::backend::{Job, Spectra, WindowSpec};
use crate::config::WindowType;
use crate::real::{Real, C};

/// The windows of a signal of `num_frames` frames, in result order (a
/// [`WindowScheduler`] run to the end of the signal).
pub fn schedule(num_frames: usize, window: usize, period: usize, window_type: WindowType) -> Vec<WindowSpec> {
    let mut s = WindowScheduler::new(window, period, window_type);
    let mut out = Vec::new();
    s.due(num_frames, &mut out);
    out
}

/// Streaming window schedule: answers "which windows are complete once `n` frames have
/// arrived?" without knowing where the signal ends. Windows come out in result order, each
/// exactly once; a window is complete when its last frame has arrived. Result frames c run
/// 0, PERIOD, 2·PERIOD, …; the frames of c follow WINDOW_TYPE (module docs).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WindowScheduler {
    window: usize,
    period: usize,
    window_type: WindowType,
    /// The next result frame c to consider.
    next_c: usize,
}

impl WindowScheduler {
    /// A schedule starting at result frame 0.
    pub fn new(window: usize, period: usize, window_type: WindowType) -> Self {
        WindowScheduler {
            window,
            period,
            window_type,
            next_c: 0,
        }
    }

    /// The first frame of result frame c's window, or None when c produces no window.
    fn start_of(&self, c: usize) -> Option<usize> {
        let w = self.window;
        match self.window_type {
            WindowType::Future => Some(c),
            WindowType::Middle => c.checked_sub(w / 2 + w % 2 - 1),
            WindowType::Past => (c != 0 || self.period == 1)
                .then(|| (c + 1).checked_sub(w))
                .flatten(),
        }
    }

    /// Append to `out` every window not yet returned that lies entirely inside frames
    /// `0..num_frames`.
    pub fn due(&mut self, num_frames: usize, out: &mut Vec<WindowSpec>) {
        if self.window == 0 || self.period == 0 {
            return;
        }
        while self.next_c < num_frames {
            let c = self.next_c;
            if let Some(start) = self.start_of(c) {
                if start + self.window > num_frames {
                    return;
                }
                out.push(WindowSpec {
                    frame: c,
                    start,
                    len: self.window,
                });
            }
            self.next_c += self.period;
        }
    }

    /// The first frame of the next window to complete. Result frames that produce no
    /// window are skipped.
    pub fn next_start(&self) -> usize {
        self.next_window().1
    }

    /// The result frame of the next window to complete, and the window's first frame.
    pub fn next_window(&self) -> (usize, usize) {
        let mut c = self.next_c;
        loop {
            if let Some(start) = self.start_of(c) {
                return (c, start);
            }
            c += self.period.max(1);
        }
    }

    /// The last frame of the next window to complete (the frame whose arrival completes
    /// it).
    pub fn next_last_frame(&self) -> usize {
        self.next_start() + self.window.max(1) - 1
    }

    /// Frames between a result frame c and the last frame of its window: W − 1 for
    /// FUTURE, ⌊W/2⌋ for MIDDLE, 0 for PAST (causal).
    pub fn latency_frames(&self) -> usize {
        match self.window_type {
            WindowType::Future => self.window.saturating_sub(1),
            WindowType::Middle => self.window / 2,
            WindowType::Past => 0,
        }
    }

    /// Start again at result frame 0.
    pub fn reset(&mut self) {
        self.next_c = 0;
    }
}

/// R = (1/W) Σ x xᴴ over frames `w.start .. w.start + w.len` of used bin `bin`, row-major
/// M × M into `out`, then HARK's scaling. Returns the scale divisor max|Re R_ij| + 1. One
/// window on its own: a direct [`running`] step, summed in f64.
pub fn correlate<T: Real>(spectra: &Spectra<T>, w: &WindowSpec, bin: usize, out: &mut [C<T>]) -> T {
    let m = spectra.num_mics;
    let mut sum = vec![C::new(0.0, 0.0); m * m];
    let job = Job::once(spectra, std::slice::from_ref(w));
    running::run_bin(
        &mut sum,
        running::Step::Direct,
        &job,
        w,
        bin,
        false,
        &mut Vec::new(),
        out,
    )
}

/// A channel whose power is at most this fraction of the loudest channel's is silent for
/// [`normalize_coherence`] (a dead microphone, or the rounding a sliding sum leaves).
pub const SILENT: f64 = 1e-10;

/// Coherence normalisation ([`crate::config::LocalizeConfig::coherence`]) of one M × M
/// matrix in place: R_ij ← R_ij · (s_i s_j) with s_i = 1/√R_ii, so the diagonal becomes
/// exactly 1; a silent channel (R_ii ≤ [`SILENT`] · max_j R_jj, or not finite) gets
/// s_i = 0, a zero row and column. Scale-free, so HARK's scaling before it does not matter. The GPU's
/// `coherence_f64` (correlate.cu) computes the same in the same order.
pub fn normalize_coherence<U: Real>(r: &mut [C<U>], m: usize) {
    debug_assert_eq!(r.len(), m * m);
    let mut s = [0.0f64; 64];
    let mut big = Vec::new();
    let s: &mut [f64] = if m <= 64 {
        &mut s[..m]
    } else {
        big.resize(m, 0.0);
        &mut big
    };
    let mx = (0..m)
        .map(|i| r[i * m + i].re.to_f64())
        .filter(|d| d.is_finite())
        .fold(0.0f64, f64::max);
    for (i, si) in s.iter_mut().enumerate() {
        let d = r[i * m + i].re.to_f64();
        *si = if d > SILENT * mx && d.is_finite() {
            1.0 / d.sqrt()
        } else {
            0.0
        };
    }
    for i in 0..m {
        for j in 0..m {
            let k = s[i] * s[j];
            let v = &mut r[i * m + j];
            *v = if i == j {
                C::new(U::of_f64(if k > 0.0 { 1.0 } else { 0.0 }), U::zero())
            } else {
                C::new(U::of_f64(v.re.to_f64() * k), U::of_f64(v.im.to_f64() * k))
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Channel gains cancel: the coherence matrix of G R G is R's (to rounding), with a
    /// unit diagonal; a silent channel gets a zero row and column.
    #[test]
    fn coherence_cancels_channel_gains() {
        let m = 5;
        // R = Y Yᴴ from a fixed complex Y (M × 7), positive definite.
        let y: Vec<C<f64>> = (0..m * 7)
            .map(|q| {
                C::new(
                    ((q * 37 % 11) as f64 - 5.0) / 3.0,
                    ((q * 53 % 13) as f64 - 6.0) / 4.0,
                )
            })
            .collect();
        let r: Vec<C<f64>> = (0..m * m)
            .map(|q| {
                (0..7)
                    .map(|f| y[(q / m) * 7 + f] * y[(q % m) * 7 + f].conj())
                    .sum()
            })
            .collect();
        let g = [1.0, 1.3, 0.6, 2.5, 0.9];
        let mut a = r.clone();
        let mut b: Vec<C<f64>> = (0..m * m).map(|q| r[q] * (g[q / m] * g[q % m])).collect();
        normalize_coherence(&mut a, m);
        normalize_coherence(&mut b, m);
        for q in 0..m * m {
            assert!(
                (a[q] - b[q]).norm() < 1e-14,
                "entry {q}: {:?} vs {:?}",
                a[q],
                b[q]
            );
        }
        for i in 0..m {
            assert_eq!(a[i * m + i], C::new(1.0, 0.0));
            // The coherence of two channels: R_01 / √(R_00 R_11).
            let want = r[i * m] / (r[i * m + i].re * r[0].re).sqrt();
            assert!((a[i * m] - want).norm() < 1e-14);
        }
        // Channel 2 silent.
        let mut c = r.clone();
        for (q, v) in c.iter_mut().enumerate() {
            if q / m == 2 || q % m == 2 {
                *v = C::new(0.0, 0.0);
            }
        }
        normalize_coherence(&mut c, m);
        assert!((0..m).all(|k| c[2 * m + k] == C::new(0.0, 0.0) && c[k * m + 2] == C::new(0.0, 0.0)));
        assert_eq!(c[0], C::new(1.0, 0.0));
        assert!((c[1] - a[1]).norm() < 1e-14);
        // Rounding left on a silent channel (a sliding sum's residue) is silence too:
        // channel 2 scaled by 10⁻⁶ (its power by 10⁻¹², below SILENT).
        let mut e = r.clone();
        for (q, v) in e.iter_mut().enumerate() {
            let k = usize::from(q / m == 2) + usize::from(q % m == 2);
            *v *= 1e-6f64.powi(k as i32);
        }
        normalize_coherence(&mut e, m);
        assert!((0..m).all(|k| e[2 * m + k] == C::new(0.0, 0.0)));
    }

    #[test]
    fn future_windows_every_period_inside_the_signal() {
        let w = schedule(230, 50, 50, WindowType::Future);
        let frames: Vec<usize> = w.iter().map(|w| w.frame).collect();
        assert_eq!(frames, vec![0, 50, 100, 150]);
        assert!(w.iter().all(|w| w.start == w.frame && w.len == 50));
    }

    #[test]
    fn past_windows_end_at_c_and_skip_c0() {
        let w = schedule(230, 50, 50, WindowType::Past);
        assert_eq!(w[0].frame, 50);
        assert_eq!(w[0].start, 1);
        assert_eq!(w.last().unwrap().frame, 200);
        let p1 = schedule(60, 50, 1, WindowType::Past);
        assert_eq!(p1.len(), 11); // c = 49..=59
        assert_eq!(p1[0].frame, 49);
        assert_eq!(p1[0].start, 0);
    }

    #[test]
    fn middle_windows_centre_on_c() {
        let w = schedule(300, 50, 50, WindowType::Middle);
        // W = 50: frames [c-24, c+25].
        assert_eq!(w[0].frame, 50);
        assert_eq!(w[0].start, 26);
        let w3 = schedule(300, 3, 1, WindowType::Middle);
        // W = 3: [c-1, c+1].
        assert_eq!((w3[0].frame, w3[0].start), (1, 0));
    }

    #[test]
    fn streaming_schedule_equals_the_whole_signal_schedule() {
        for wt in [WindowType::Future, WindowType::Middle, WindowType::Past] {
            for (w, p) in [(50, 50), (50, 1), (3, 2), (1, 1), (7, 10)] {
                let whole = schedule(400, w, p, wt);
                let mut s = WindowScheduler::new(w, p, wt);
                let mut got = Vec::new();
                for n in 0..400 {
                    s.due(n, &mut got);
                    let before = got.len();
                    // The next window needs frame `last`, i.e. more than n frames.
                    let last = s.next_last_frame();
                    assert!(last >= n, "{wt:?} {w} {p}");
                    s.due(n + 1, &mut got);
                    assert_eq!(got.len() > before, last == n, "{wt:?} {w} {p}");
                    for x in &got[before..] {
                        assert_eq!(
                            x.start + x.len,
                            n + 1,
                            "{wt:?} {w} {p}: completes at its last frame"
                        );
                    }
                }
                assert_eq!(got, whole, "{wt:?} {w} {p}");
            }
        }
    }

    #[test]
    fn correlation_is_scaled_hermitian_average() {
        let mut s = Spectra::<f64>::zeros(4, 1, 2);
        let xs = [
            [C::new(1.0, 2.0), C::new(-3.0, 0.5)],
            [C::new(0.0, 1.0), C::new(2.0, -1.0)],
        ];
        for (f, x) in xs.iter().enumerate() {
            s.data[f * 2] = x[0];
            s.data[f * 2 + 1] = x[1];
        }
        let mut r = vec![C::new(0.0, 0.0); 4];
        let scale = correlate(
            &s,
            &WindowSpec {
                frame: 0,
                start: 0,
                len: 2,
            },
            0,
            &mut r,
        );
        // Unscaled R00 = (|1+2j|² + |j|²)/2 = 3, R11 = (9.25 + 5)/2 = 7.125 → divisor 8.125.
        assert!((scale - 8.125).abs() < 1e-12);
        let r01 = (xs[0][0] * xs[0][1].conj() + xs[1][0] * xs[1][1].conj()) / 2.0 / 8.125;
        assert!((r[1] - r01).norm() < 1e-12);
        assert!((r[2] - r01.conj()).norm() < 1e-12);
        assert!((r[0].re - 3.0 / 8.125).abs() < 1e-12);
    }
}
