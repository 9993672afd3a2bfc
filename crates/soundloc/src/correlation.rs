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

use crate::backend::{Spectra, WindowSpec};
use crate::config::WindowType;
use crate::real::{Real, C};

/// The windows of a signal of `num_frames` frames, in result order.
pub fn schedule(num_frames: usize, window: usize, period: usize, window_type: WindowType) -> Vec<WindowSpec> {
    let mut out = Vec::new();
    if window == 0 || period == 0 {
        return out;
    }
    let mut c = 0usize;
    while c < num_frames {
        let (start, fire) = match window_type {
            WindowType::Future => (Some(c), true),
            WindowType::Middle => (c.checked_sub(window / 2 + window % 2 - 1), true),
            WindowType::Past => ((c + 1).checked_sub(window), c != 0 || period == 1),
        };
        if let (Some(start), true) = (start, fire) {
            if start + window <= num_frames {
                out.push(WindowSpec {
                    frame: c,
                    start,
                    len: window,
                });
            }
        }
        c += period;
    }
    out
}

/// R = (1/W) Σ x xᴴ over frames `w.start .. w.start + w.len` of used bin `bin`, row-major
/// M × M into `out`, then HARK's scaling. Returns the scale divisor max|Re R_ij| + 1.
pub fn correlate<T: Real>(spectra: &Spectra<T>, w: &WindowSpec, bin: usize, out: &mut [C<T>]) -> T {
    let m = spectra.num_mics;
    let nb = spectra.num_bins;
    debug_assert_eq!(out.len(), m * m);
    // X: the window's W × M block of this bin (row stride = one frame).
    let first = (w.start * nb + bin) * m;
    let last = ((w.start + w.len - 1) * nb + bin) * m + m;
    let x = faer::MatRef::from_row_major_slice_with_stride(&spectra.data[first..last], w.len, m, nb * m);
    // Rᵀ = Xᴴ X, i.e. R_ij = Σ_f x_i conj(x_j); written column-major into `out`, which is
    // then R in row-major order.
    let mut r = faer::MatMut::from_column_major_slice_mut(out, m, m);
    let inv_w = T::one() / T::of_f64(w.len as f64);
    faer::linalg::matmul::matmul(
        r.as_mut(),
        faer::Accum::Replace,
        x.adjoint(),
        x,
        C::new(inv_w, T::zero()),
        faer::Par::Seq,
    );
    let mut mx = T::zero();
    for v in out.iter() {
        if v.re.abs() > mx {
            mx = v.re.abs();
        }
    }
    let s = mx + T::one();
    let inv_s = T::one() / s;
    for i in 0..m {
        for j in i..m {
            // Average the two triangles: exactly Hermitian.
            let v = (out[i * m + j] + out[j * m + i].conj()) * C::new(inv_s * T::of_f64(0.5), T::zero());
            out[i * m + j] = v;
            out[j * m + i] = v.conj();
        }
        out[i * m + i].im = T::zero();
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

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
