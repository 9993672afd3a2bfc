//! Onset weighting of the correlation (off in HARK; on in the defaults when no algorithm
//! is named): each frame of each bin enters R_k with a weight that favours sound that has
//! just arrived over sound that has been there a while — the direct path of a talker's
//! onsets over the reverberation that follows them (the precedence effect).
//!
//! For frame t of bin k, with p_t the frame's power and q_t its recent average,
//!
//! - q_t = (1 − 1/T)·q_{t−1} + (1/T)·p_t, T = [`LocalizeConfig::onset_frames`], q starting
//!   at the first frame's power;
//! - r_t = p_t / q_{t−1}, how much louder the frame is than the recent past, where p is
//!   the power xᴴ K⁻¹ x in the whitened domain when the algorithm whitens with a noise
//!   matrix K (where the noise K holds is white, so a loud stationary noise such as a
//!   drone's rotors does not count as new sound); without K, r_t is the mean over the
//!   microphones of each one's |x_m|² against its own average (so a channel's gain
//!   cancels, as coherence normalisation needs);
//! - w_t = (max(0, r_t − 1) / r_t)², the squared share of the frame's power that is new:
//!   0 for a frame no louder than the recent past (a reverberant tail, steady noise),
//!   towards 1 at an onset;
//! - the frame is scaled by √w_t, so the window's correlation is (1/W) Σ_t w_t x_t x_tᴴ.
//!
//! Why the whitened power for the noise-aware algorithms: whitened noise y = L⁻¹n is
//! isotropic, and a weight that depends only on ‖y‖² and its past keeps it isotropic
//! (E[w y yᴴ] ∝ I), so the weighted noise still has K's shape and the whitening stays
//! right; the microphone power would favour frames where the noise happens to be loud
//! and lean the correlation towards the noise's directions (measured: it lost 7–12 points
//! in rotor noise, docs/accuracy.md "Onset weighting").
//!
//! The weights are computed once per frame, causally (from that frame and the ones before
//! it), in frame order; a window only ever sees weighted frames. A noise matrix estimated
//! from the input is estimated from the frames before they are weighted.
//!
//! [`LocalizeConfig::onset_frames`]: crate::config::LocalizeConfig::onset_frames

use crate::backend::Spectra;
use crate::config::Algorithm;
use crate::plan::Plan;
use crate::real::{Real, C};
use faer::c64;

/// The running state of [`onset`](self) weighting for one stream.
#[derive(Debug, Clone)]
pub struct OnsetWeights {
    /// T: the recent average's memory in frames.
    memory: f64,
    /// q per used bin and microphone (None before the first frame): with whitening a
    /// bin's one average is its first entry.
    average: Vec<Option<f64>>,
    /// The next absolute frame to weight.
    next: usize,
    /// The weights of one call, per used bin and frame.
    weights: Vec<f64>,
}

/// Frames whose whitened powers are computed together, one per vector lane.
const LANES: usize = 8;

/// Below this many complex multiply-adds a call weighs its bins on the calling thread
/// (a streamed frame at a time), above it on the thread pool.
const PARALLEL_WORK: usize = 1 << 18;

impl OnsetWeights {
    /// Weighting with a memory of `frames` frames (≥ 1) over `num_bins` bins.
    pub fn new(frames: usize, num_bins: usize, num_mics: usize) -> Self {
        OnsetWeights {
            memory: frames.max(1) as f64,
            average: vec![None; num_bins * num_mics.max(1)],
            next: 0,
            weights: Vec::new(),
        }
    }

    /// A new stream: frame 0 comes next, with no past.
    pub fn reset(&mut self) {
        self.average.iter_mut().for_each(|q| *q = None);
        self.next = 0;
    }

    /// The next absolute frame to weight.
    pub fn next_frame(&self) -> usize {
        self.next
    }

    /// Weight the frames of `spectra` (whose frame 0 is absolute frame `first`) up to,
    /// not including, absolute frame `upto`, those not weighted yet, with `plan`'s noise
    /// matrix (its whitening) where its algorithm has one. Bins are independent and each
    /// frame's power is computed on its own, so the weights are the same however the
    /// frames are split into calls and however many threads run them.
    pub fn apply<T: Real>(&mut self, plan: &Plan<T>, spectra: &mut Spectra<T>, first: usize, upto: usize) {
        let upto = upto.min(first + spectra.num_frames);
        if upto <= self.next {
            return;
        }
        // Frames dropped before they were weighted (none in the engine's order) are
        // skipped: the average goes on from the frames that are there.
        let from = self.next.max(first);
        let (m, nb) = (spectra.num_mics.max(1), spectra.num_bins);
        let (f0, nf) = (from - first, upto - from);
        let keep = 1.0 - 1.0 / self.memory;
        self.weights.clear();
        self.weights.resize(nb * nf, 0.0);
        let data = &spectra.data[f0 * nb * m..(f0 + nf) * nb * m];
        let bin = |b: usize, q: &mut [Option<f64>], w: &mut [f64]| match plan.whitening_matrix64(b) {
            Some(wm) => whitened_weights(plan.config.algorithm, wm, data, nb, m, b, &mut q[0], keep, w),
            None => microphone_weights(data, nb, m, b, q, keep, w),
        };
        let work = nf
            * nb
            * m
            * if plan.whitening_matrix64(0).is_some() {
                m
            } else {
                1
            };
        if work >= PARALLEL_WORK {
            use rayon::prelude::*;
            self.average
                .par_chunks_mut(m)
                .zip(self.weights.par_chunks_mut(nf))
                .enumerate()
                .for_each(|(b, (q, w))| bin(b, q, w));
        } else {
            for (b, (q, w)) in self
                .average
                .chunks_mut(m)
                .zip(self.weights.chunks_mut(nf))
                .enumerate()
            {
                bin(b, q, w);
            }
        }
        for (f, frame) in spectra.data[f0 * nb * m..(f0 + nf) * nb * m]
            .chunks_mut(nb * m)
            .enumerate()
        {
            for (b, x) in frame.chunks_mut(m).enumerate() {
                let w = self.weights[b * nf + f];
                if w != 1.0 {
                    let g = T::of_f64(w.sqrt());
                    for v in x.iter_mut() {
                        *v = C::new(v.re * g, v.im * g);
                    }
                }
            }
        }
        self.next = upto;
    }
}

/// Bin `b`'s weights for the frames of `data` (frame-major, `nb` bins of `wm`'s order)
/// from their whitened powers, into `w`; `q` is the bin's recent average.
#[allow(clippy::too_many_arguments)]
fn whitened_weights<T: Real>(
    alg: Algorithm,
    wm: &[c64],
    data: &[C<T>],
    nb: usize,
    m: usize,
    b: usize,
    q: &mut Option<f64>,
    keep: f64,
    w: &mut [f64],
) {
    let (mut xr, mut xi) = (vec![0.0; m * LANES], vec![0.0; m * LANES]);
    let mut p = [0.0; LANES];
    for (c, wc) in w.chunks_mut(LANES).enumerate() {
        for l in 0..wc.len() {
            let x = &data[((c * LANES + l) * nb + b) * m..][..m];
            for (j, v) in x.iter().enumerate() {
                xr[j * LANES + l] = v.re.to_f64();
                xi[j * LANES + l] = v.im.to_f64();
            }
        }
        whitened_powers(
            wm,
            m,
            alg == Algorithm::Gevd,
            alg == Algorithm::Gsvd,
            &xr,
            &xi,
            &mut p,
        );
        for (wt, &p) in wc.iter_mut().zip(&p) {
            *wt = step(q, p, keep).map_or(0.0, |q| weight(p, q));
        }
    }
}

/// Bin `b`'s weights without whitening: each microphone's power against its own recent
/// average (`q`, one per microphone), so a channel's gain cancels.
fn microphone_weights<T: Real>(
    data: &[C<T>],
    nb: usize,
    m: usize,
    b: usize,
    qs: &mut [Option<f64>],
    keep: f64,
    w: &mut [f64],
) {
    for (f, wt) in w.iter_mut().enumerate() {
        let x = &data[(f * nb + b) * m..][..m];
        let (mut sum, mut n) = (0.0, 0usize);
        for (v, q) in x.iter().zip(qs.iter_mut()) {
            let p = v.re.to_f64().powi(2) + v.im.to_f64().powi(2);
            match step(q, p, keep) {
                // Sound after digital silence: new, as in `weight`.
                Some(q) if q <= 0.0 && p > 0.0 => sum = f64::INFINITY,
                Some(q) if q > 0.0 => sum += p / q,
                _ => continue,
            }
            n += 1;
        }
        *wt = if n == 0 {
            0.0
        } else if sum.is_infinite() {
            1.0
        } else {
            weight(sum / n as f64, 1.0)
        };
    }
}

/// The share of a window's frames that the weights leave as independent snapshots,
/// (Σw)² / (W·Σw²) (Kish's effective sample size over W), for noise alone: white complex
/// Gaussian frames on `num_mics` microphones, whitened (`whitened`: one power per frame)
/// or each microphone against its own average, with a memory of `frames` frames. The
/// source count's MDL ([`crate::subspace::count`]) takes N = W·hop/N_fft snapshots from
/// unweighted frames; weighted ones carry fewer, and with the nominal N it counted noise
/// as sources (silent windows of the room default). Computed once per plan from 20 000
/// frames of a fixed pseudo-random sequence (deterministic; within about 1 % of the
/// limit). A model: it takes the microphones' noise as independent and the frames as
/// independent, where real noise is partly coherent across a small array at low
/// frequencies and overlapping frames are not, so a bin's actual share can differ (by up
/// to about 2× in a coherent field).
pub fn snapshot_fraction(frames: usize, num_mics: usize, whitened: bool) -> f64 {
    let keep = 1.0 - 1.0 / frames.max(1) as f64;
    let m = num_mics.max(1);
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    // |z|² of a unit complex Gaussian is exponential: −ln(u), u uniform in (0, 1].
    let mut exp = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        -(((state >> 11) as f64 + 1.0) / (1u64 << 53) as f64).ln()
    };
    let mut q = vec![None; if whitened { 1 } else { m }];
    let (mut s1, mut s2) = (0.0, 0.0);
    for t in 0..20_200 {
        let w = if whitened {
            let p: f64 = (0..m).map(|_| exp()).sum();
            step(&mut q[0], p, keep).map_or(0.0, |q| weight(p, q))
        } else {
            let mut sum = 0.0;
            for qm in q.iter_mut() {
                let p = exp();
                sum += step(qm, p, keep).map_or(1.0, |q| p / q);
            }
            weight(sum / m as f64, 1.0)
        };
        if t >= 200 {
            s1 += w;
            s2 += w * w;
        }
    }
    if s2 > 0.0 {
        (s1 * s1 / (s2 * 20_000.0)).clamp(1e-3, 1.0)
    } else {
        1.0
    }
}

/// Update a recent average with the power `p` of a new frame; returns the average up to
/// the frame before (None for the first frame, which starts the average at `p`).
fn step(q: &mut Option<f64>, p: f64, keep: f64) -> Option<f64> {
    let before = *q;
    *q = Some(before.map_or(p, |q| keep * q + (1.0 - keep) * p));
    before.filter(|q| q.is_finite())
}

/// w = (max(0, p − q)/p)² for a frame of power `p` after a recent average `q` (0 for a
/// silent or non-finite frame, 1 for sound after silence).
pub fn weight(p: f64, q: f64) -> f64 {
    if !(p > 0.0 && p.is_finite()) {
        return 0.0;
    }
    if q.is_nan() || q <= 0.0 {
        return 1.0;
    }
    let share = ((p - q) / p).max(0.0);
    share * share
}

/// The powers xᴴ K⁻¹ x of [`LANES`] frames of one bin through the plan's whitening `w`
/// (M × M, row-major): ‖W x‖² with W = L⁻¹ for the textbook GEVD (`lower`: only its
/// lower triangle is read) or K^{-1/2} for HARK's GEVD, Re(xᴴ W x) with W = K⁻¹ for GSVD
/// (`quadratic`). `xr`, `xi`: the frames' parts, microphone-major (`x[j * LANES + l]`:
/// microphone j of frame l). K's scale (HARK's normalisation) is a constant per bin and
/// cancels in p/q. Runs on AVX-512 where the CPU has it, else [`whitened_powers_generic`];
/// each lane's sums run in the same order in every build and whatever the other lanes
/// hold, so the bits are the same.
fn whitened_powers(
    w: &[c64],
    m: usize,
    lower: bool,
    quadratic: bool,
    xr: &[f64],
    xi: &[f64],
    p: &mut [f64; LANES],
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx512f") {
        // SAFETY: the CPU supports AVX-512F (checked just above).
        return unsafe { whitened_powers_avx512(w, m, lower, quadratic, xr, xi, p) };
    }
    whitened_powers_generic(w, m, lower, quadratic, xr, xi, p)
}

crate::subspace::simd::dispatch!(
    /// [`whitened_powers_in`] built for AVX2 where the CPU has it, else as it is.
    fn whitened_powers_generic(
        w: &[c64],
        m: usize,
        lower: bool,
        quadratic: bool,
        xr: &[f64],
        xi: &[f64],
        p: &mut [f64; LANES],
    ) => whitened_powers_in
);

/// [`whitened_powers_in`] with the eight lanes in one register: multiplies, adds and
/// subtractions in its order (no fused multiply-add).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn whitened_powers_avx512(
    w: &[c64],
    m: usize,
    lower: bool,
    quadratic: bool,
    xr: &[f64],
    xi: &[f64],
    p: &mut [f64; LANES],
) {
    use std::arch::x86_64::*;
    assert!(w.len() >= m * m && xr.len() >= m * LANES && xi.len() >= m * LANES);
    let (xr, xi) = (xr.as_ptr(), xi.as_ptr());
    // SAFETY (every load): row i < m and column j < m, so lanes i·8 .. i·8 + 8 and
    // j·8 .. j·8 + 8 lie within xr and xi (asserted above).
    let load = |k: usize| unsafe {
        (
            _mm512_loadu_pd(xr.add(k * LANES)),
            _mm512_loadu_pd(xi.add(k * LANES)),
        )
    };
    let mut acc = _mm512_setzero_pd();
    for i in 0..m {
        let (mut re, mut im) = (_mm512_setzero_pd(), _mm512_setzero_pd());
        for (j, wij) in w[i * m..i * m + if lower { i + 1 } else { m }].iter().enumerate() {
            let (a, c) = load(j);
            let (wr, wi) = (_mm512_set1_pd(wij.re), _mm512_set1_pd(wij.im));
            re = _mm512_add_pd(re, _mm512_sub_pd(_mm512_mul_pd(wr, a), _mm512_mul_pd(wi, c)));
            im = _mm512_add_pd(im, _mm512_add_pd(_mm512_mul_pd(wr, c), _mm512_mul_pd(wi, a)));
        }
        let term = if quadratic {
            let (a, c) = load(i);
            _mm512_add_pd(_mm512_mul_pd(a, re), _mm512_mul_pd(c, im))
        } else {
            _mm512_add_pd(_mm512_mul_pd(re, re), _mm512_mul_pd(im, im))
        };
        acc = _mm512_add_pd(acc, term);
    }
    let acc = _mm512_max_pd(acc, _mm512_setzero_pd());
    // SAFETY: p holds LANES = 8 doubles.
    unsafe { _mm512_storeu_pd(p.as_mut_ptr(), acc) };
}

#[inline(always)]
fn whitened_powers_in(
    w: &[c64],
    m: usize,
    lower: bool,
    quadratic: bool,
    xr: &[f64],
    xi: &[f64],
    p: &mut [f64; LANES],
) {
    *p = [0.0; LANES];
    for i in 0..m {
        let row = &w[i * m..i * m + if lower { i + 1 } else { m }];
        let (mut re, mut im) = ([0.0; LANES], [0.0; LANES]);
        for (j, wij) in row.iter().enumerate() {
            let (a, c) = (&xr[j * LANES..][..LANES], &xi[j * LANES..][..LANES]);
            for l in 0..LANES {
                re[l] += wij.re * a[l] - wij.im * c[l];
                im[l] += wij.re * c[l] + wij.im * a[l];
            }
        }
        let (a, c) = (&xr[i * LANES..][..LANES], &xi[i * LANES..][..LANES]);
        for l in 0..LANES {
            p[l] += if quadratic {
                a[l] * re[l] + c[l] * im[l]
            } else {
                re[l] * re[l] + im[l] * im[l]
            };
        }
    }
    for v in p.iter_mut() {
        *v = v.max(0.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_weight_favours_new_sound() {
        assert_eq!(weight(1.0, 1.0), 0.0); // as loud as the recent past
        assert_eq!(weight(0.5, 1.0), 0.0); // a decaying tail
        assert!((weight(4.0, 1.0) - 0.5625).abs() < 1e-12); // (3/4)²
        assert!(weight(1e6, 1.0) > 0.999); // an onset
        assert_eq!(weight(1.0, 0.0), 1.0); // sound after silence
        assert_eq!(weight(0.0, 1.0), 0.0);
        assert_eq!(weight(f64::NAN, 1.0), 0.0);
    }

    /// The frame-at-a-time power (the first form of this module), the lanes' reference.
    fn scalar_power(alg: Algorithm, w: &[c64], x: &[c64]) -> f64 {
        let m = x.len();
        let mut p = 0.0;
        for (i, row) in w.chunks_exact(m).enumerate() {
            let cols = if alg == Algorithm::Gevd { i + 1 } else { m };
            let (mut re, mut im) = (0.0, 0.0);
            for (wij, xj) in row[..cols].iter().zip(&x[..cols]) {
                re += wij.re * xj.re - wij.im * xj.im;
                im += wij.re * xj.im + wij.im * xj.re;
            }
            p += match alg {
                Algorithm::Gsvd => x[i].re * re + x[i].im * im,
                _ => re * re + im * im,
            };
        }
        p.max(0.0)
    }

    #[test]
    fn lanes_give_each_frame_its_own_power_bit_for_bit() {
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for m in [1, 7, 60] {
            let w: Vec<c64> = (0..m * m).map(|_| c64::new(next(), next())).collect();
            let frames: Vec<Vec<c64>> = (0..LANES)
                .map(|_| (0..m).map(|_| c64::new(next(), next())).collect())
                .collect();
            let (mut xr, mut xi) = (vec![0.0; m * LANES], vec![0.0; m * LANES]);
            for (l, x) in frames.iter().enumerate() {
                for (j, v) in x.iter().enumerate() {
                    xr[j * LANES + l] = v.re;
                    xi[j * LANES + l] = v.im;
                }
            }
            type Powers = fn(&[c64], usize, bool, bool, &[f64], &[f64], &mut [f64; LANES]);
            let builds: [(&str, Powers); 3] = [
                ("dispatched", whitened_powers),
                ("AVX2 or baseline", whitened_powers_generic),
                ("baseline", whitened_powers_in),
            ];
            for alg in [Algorithm::Gevd, Algorithm::GevdHark, Algorithm::Gsvd] {
                let (lower, quadratic) = (alg == Algorithm::Gevd, alg == Algorithm::Gsvd);
                for (build, powers) in builds {
                    let mut p = [0.0; LANES];
                    powers(&w, m, lower, quadratic, &xr, &xi, &mut p);
                    for (l, frame) in frames.iter().enumerate() {
                        let want = scalar_power(alg, &w, frame);
                        assert_eq!(
                            p[l].to_bits(),
                            want.to_bits(),
                            "{alg:?}, {m} mics, lane {l}, {build}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn weighted_noise_keeps_a_fraction_of_its_snapshots() {
        for whitened in [true, false] {
            for (m, t) in [(8, 10), (60, 10), (8, 20)] {
                let f = snapshot_fraction(t, m, whitened);
                assert!(f > 0.05 && f < 0.6, "{m} mics, T {t}, whitened {whitened}: {f}");
                assert_eq!(f, snapshot_fraction(t, m, whitened)); // deterministic
            }
        }
    }
}
