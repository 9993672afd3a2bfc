//! Stage 1 — STFT (HARK MultiFFT): samples → [`Spectra`] `[frame][bin][mic]`.
//!
//! Frame f covers samples [f·hop, f·hop + N); it is multiplied by the analysis window and
//! transformed with a real FFT, X_k = Σ_n w_n x_n e^{−j2πkn/N}, **unscaled**. Only the used
//! bins are kept. The number of frames is ⌊(L − N)/hop⌋ + 1 for L ≥ N samples.
//!
//! Windows (n = 0..N): CONJ (HARK's default; a square-root window whose squares overlap
//! to one), HAMMING 0.54 − 0.46·cos(2πn/(N−1)), HANNING 0.5 − 0.5·cos(2πn/(N−1)),
//! RECTANGLE 1.

use crate::backend::Spectra;
use crate::config::WindowFunction;
use crate::real::{Real, C};
use crate::{Error, Result};
use rayon::prelude::*;
use realfft::{RealFftPlanner, RealToComplex};
use std::ops::Range;
use std::sync::Arc;

/// The analysis window of length `n`.
///
/// CONJ, for i in 0..n: x = 4i/n folded into [0, 1] (x ∈ [1,2) → 2−x, flipped;
/// [2,3) → x−2, flipped; [3,4) → 4−x), x ← 1.9979·x, w = (0.5 − 0.5·cos x)², w ← 1 − w
/// if flipped, w ← √w.
pub fn window_function<T: Real>(kind: WindowFunction, n: usize) -> Vec<T> {
    let nn = n as f64;
    let denom = (n.max(2) - 1) as f64;
    (0..n)
        .map(|i| {
            let w = match kind {
                WindowFunction::Conj => {
                    let x = 4.0 * i as f64 / nn;
                    let (x, flipped) = if x < 1.0 {
                        (x, false)
                    } else if x < 2.0 {
                        (2.0 - x, true)
                    } else if x < 3.0 {
                        (x - 2.0, true)
                    } else {
                        (4.0 - x, false)
                    };
                    let x = 1.9979 * x;
                    let mut w = (0.5 - 0.5 * x.cos()).powi(2);
                    if flipped {
                        w = 1.0 - w;
                    }
                    w.sqrt()
                }
                WindowFunction::Hamming => {
                    0.54 - 0.46 * (2.0 * std::f64::consts::PI * i as f64 / denom).cos()
                }
                WindowFunction::Hanning => 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / denom).cos(),
                WindowFunction::Rectangle => 1.0,
            };
            T::of_f64(w)
        })
        .collect()
}

/// A prepared STFT: FFT plan, window and used bins.
pub struct Stft<T: Real> {
    nfft: usize,
    hop: usize,
    bins: Range<usize>,
    window: Vec<T>,
    fft: Arc<dyn RealToComplex<T>>,
}

impl<T: Real> Stft<T> {
    /// Prepare an N-point STFT with the given hop, window and kept bins.
    pub fn new(nfft: usize, hop: usize, window: WindowFunction, bins: Range<usize>) -> Result<Self> {
        if nfft < 2 || hop == 0 || bins.is_empty() || bins.end > nfft / 2 + 1 {
            return Err(Error::Config(format!(
                "STFT: invalid N = {nfft}, hop = {hop}, bins {}..{}",
                bins.start, bins.end
            )));
        }
        let fft = RealFftPlanner::<T>::new().plan_fft_forward(nfft);
        Ok(Stft {
            nfft,
            hop,
            bins,
            window: window_function(window, nfft),
            fft,
        })
    }

    /// Number of complete frames in `num_samples` samples.
    pub fn num_frames(&self, num_samples: usize) -> usize {
        if num_samples < self.nfft {
            0
        } else {
            (num_samples - self.nfft) / self.hop + 1
        }
    }

    /// Transform every complete frame of `channels` (planar, equal lengths).
    pub fn process(&self, channels: &[Vec<f32>]) -> Result<Spectra<T>> {
        let len = channels.first().map_or(0, |c| c.len());
        self.process_frames(channels, 0..self.num_frames(len))
    }

    /// Transform frames `frames` only (frame f of the result is STFT frame
    /// `frames.start + f`): bounded memory on long recordings.
    pub fn process_frames(&self, channels: &[Vec<f32>], frames: Range<usize>) -> Result<Spectra<T>> {
        let m = channels.len();
        let len = channels.first().map_or(0, |c| c.len());
        if m == 0 || channels.iter().any(|c| c.len() != len) {
            return Err(Error::Mismatch(
                "STFT: channels must be non-empty and of equal length".into(),
            ));
        }
        if frames.end > self.num_frames(len) {
            return Err(Error::Mismatch(format!(
                "STFT: frames {}..{} asked, the signal has {}",
                frames.start,
                frames.end,
                self.num_frames(len)
            )));
        }
        let nf = frames.len();
        let first = frames.start;
        let nb = self.bins.len();
        let mut out = Spectra::zeros(nf, nb, m);
        let frame_len = nb * m;
        out.data
            .par_chunks_mut(frame_len.max(1))
            .enumerate()
            .for_each_init(
                || {
                    (
                        self.fft.make_input_vec(),
                        self.fft.make_output_vec(),
                        self.fft.make_scratch_vec(),
                    )
                },
                |(inp, spec, scratch), (f, dst)| {
                    let off = (first + f) * self.hop;
                    for (mic, ch) in channels.iter().enumerate() {
                        for (i, v) in inp.iter_mut().enumerate() {
                            *v = T::of_f64(ch[off + i] as f64) * self.window[i];
                        }
                        // Lengths come from this plan's own buffers: cannot fail.
                        let _ = self.fft.process_with_scratch(inp, spec, scratch);
                        for (b, k) in self.bins.clone().enumerate() {
                            dst[b * m + mic] = spec[k];
                        }
                    }
                },
            );
        Ok(out)
    }

    /// The kept bins.
    pub fn bins(&self) -> Range<usize> {
        self.bins.clone()
    }
}

/// Convenience: a complex zero.
pub fn czero<T: Real>() -> C<T> {
    C::new(T::zero(), T::zero())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conj_window_is_a_square_root_partition_of_unity() {
        // The CONJ window's squares at half-frame overlap sum to ~1 (it is HARK's
        // "conjugate" window); also symmetric-ish, 0 at the start, 1 at N/2.
        let n = 512;
        let w = window_function::<f64>(WindowFunction::Conj, n);
        assert!(w[0].abs() < 1e-12);
        assert!((w[n / 2] - 1.0).abs() < 1e-12);
        for i in 0..n / 2 {
            let s = w[i].powi(2) + w[i + n / 2].powi(2);
            assert!((s - 1.0).abs() < 2e-3, "i = {i}: {s}");
        }
    }

    fn check_tone<T: Real>() {
        // A cosine at bin 20 with amplitude 1000 under a rectangular window gives
        // |X_20| = 1000·N/2 (unscaled FFT) and phase 0 at frame 0.
        let n = 512;
        let k0 = 20;
        let len = 4000;
        let x: Vec<f32> = (0..len)
            .map(|i| (1000.0 * (2.0 * std::f64::consts::PI * k0 as f64 * i as f64 / n as f64).cos()) as f32)
            .collect();
        let stft = Stft::<T>::new(n, 160, WindowFunction::Rectangle, 16..89).unwrap();
        let s = stft.process(&[x.clone(), x]).unwrap();
        assert_eq!(s.num_frames, (len - n) / 160 + 1);
        let z = s.frame_bin(0, k0 - 16)[1];
        assert!((z.re.to_f64() - 256000.0).abs() < 256000.0 * 1e-5, "{z:?}");
        assert!(z.im.to_f64().abs() < 1.0);
        let other = s.frame_bin(0, 30 - 16)[0];
        assert!(other.norm().to_f64() < 1.0);
    }

    #[test]
    fn tone_lands_in_its_bin_unscaled_f32() {
        check_tone::<f32>();
    }
    #[test]
    fn tone_lands_in_its_bin_unscaled_f64() {
        check_tone::<f64>();
    }
}
