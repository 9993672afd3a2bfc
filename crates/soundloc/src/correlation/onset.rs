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
    /// q per used bin, or per used bin and microphone without whitening (None before the
    /// first frame).
    average: Vec<Option<f64>>,
    /// The next absolute frame to weight.
    next: usize,
    /// A frame's values in f64.
    buf: Vec<c64>,
}

impl OnsetWeights {
    /// Weighting with a memory of `frames` frames (≥ 1) over `num_bins` bins.
    pub fn new(frames: usize, num_bins: usize, num_mics: usize) -> Self {
        OnsetWeights {
            memory: frames.max(1) as f64,
            average: vec![None; num_bins * num_mics],
            next: 0,
            buf: Vec::new(),
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
    /// matrix (its whitening) where its algorithm has one.
    pub fn apply<T: Real>(&mut self, plan: &Plan<T>, spectra: &mut Spectra<T>, first: usize, upto: usize) {
        let upto = upto.min(first + spectra.num_frames);
        if upto <= self.next {
            return;
        }
        // Frames dropped before they were weighted (none in the engine's order) are
        // skipped: the average goes on from the frames that are there.
        let from = self.next.max(first);
        let (m, nb) = (spectra.num_mics, spectra.num_bins);
        let keep = 1.0 - 1.0 / self.memory;
        for f in from - first..upto - first {
            for b in 0..nb {
                let x = &mut spectra.data[(f * nb + b) * m..(f * nb + b + 1) * m];
                let w = match whitened_power(plan, b, x, &mut self.buf) {
                    Some(p) => step(&mut self.average[b], p, keep).map_or(0.0, |q| weight(p, q)),
                    None => {
                        // Each microphone against its own past: a channel's gain cancels.
                        let qs = &mut self.average[b * m..(b + 1) * m];
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
                        if n == 0 {
                            0.0
                        } else if sum.is_infinite() {
                            1.0
                        } else {
                            weight(sum / n as f64, 1.0)
                        }
                    }
                };
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

/// The frame's power xᴴ K⁻¹ x in bin `b` through the plan's whitening, where the
/// algorithm whitens (L⁻¹ for the textbook GEVD, exactly lower triangular, and K^{-1/2}
/// for HARK's GEVD: ‖W x‖²; K⁻¹ for GSVD: Re(xᴴ W x)); None without. K's scale (HARK's
/// normalisation) is a constant per bin and cancels in p/q. `buf` holds x in f64.
fn whitened_power<T: Real>(plan: &Plan<T>, b: usize, x: &[C<T>], buf: &mut Vec<c64>) -> Option<f64> {
    let w = plan.whitening_matrix64(b)?;
    let m = x.len();
    buf.clear();
    buf.extend(x.iter().map(|v| c64::new(v.re.to_f64(), v.im.to_f64())));
    let alg = plan.config.algorithm;
    let mut p = 0.0;
    for (i, row) in w.chunks_exact(m).enumerate() {
        let cols = if alg == Algorithm::Gevd { i + 1 } else { m };
        let (mut re, mut im) = (0.0, 0.0);
        for (wij, xj) in row[..cols].iter().zip(&buf[..cols]) {
            re += wij.re * xj.re - wij.im * xj.im;
            im += wij.re * xj.im + wij.im * xj.re;
        }
        p += match alg {
            Algorithm::Gsvd => buf[i].re * re + buf[i].im * im,
            _ => re * re + im * im,
        };
    }
    Some(p.max(0.0))
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
