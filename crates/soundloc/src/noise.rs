//! The noise correlation matrix K_k per frequency bin.
//!
//! K_k = (1/F) Σ_f x_{k,f} x_{k,f}ᴴ over F noise-only frames (averaged like R, without
//! R's scaling), from a noise recording, a time range of the input, or a file
//! ([`crate::formats::noise_cm`]). Identity when none is given. K is kept in f64; the plan
//! derives the per-algorithm whitening from it once.

use crate::real::{Real, C};
use crate::{Error, Result};
use num_complex::Complex;

/// K_k for a range of absolute FFT bins, `[bin][i][j]` row-major, f64.
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseMatrices {
    /// Number of microphones M.
    pub num_mics: usize,
    /// First absolute bin held.
    pub first_bin: usize,
    /// Number of bins held.
    pub num_bins: usize,
    /// Number of frames averaged (0 when unknown, e.g. from a file).
    pub num_frames: usize,
    /// `[bin][i][j]`.
    pub data: Vec<Complex<f64>>,
}

impl NoiseMatrices {
    /// K_k = I for every bin of `bins`.
    pub fn identity(num_mics: usize, bins: std::ops::Range<usize>) -> Self {
        let mut data = vec![Complex::new(0.0, 0.0); bins.len() * num_mics * num_mics];
        for b in 0..bins.len() {
            for i in 0..num_mics {
                data[(b * num_mics + i) * num_mics + i] = Complex::new(1.0, 0.0);
            }
        }
        NoiseMatrices {
            num_mics,
            first_bin: bins.start,
            num_bins: bins.len(),
            num_frames: 0,
            data,
        }
    }

    /// Average x xᴴ over frames `frames` of `spectra` (whose bins start at absolute bin
    /// `first_bin`).
    pub fn from_spectra<T: Real>(
        spectra: &crate::backend::Spectra<T>,
        first_bin: usize,
        frames: std::ops::Range<usize>,
    ) -> Result<Self> {
        let m = spectra.num_mics;
        if frames.is_empty() || frames.end > spectra.num_frames {
            return Err(Error::TooShort(format!(
                "noise estimate: needs at least one frame, got frames {}..{} of {}",
                frames.start, frames.end, spectra.num_frames
            )));
        }
        let nb = spectra.num_bins;
        let mut data = vec![Complex::new(0.0, 0.0); nb * m * m];
        let scale = 1.0 / frames.len() as f64;
        for b in 0..nb {
            let k = &mut data[b * m * m..(b + 1) * m * m];
            for f in frames.clone() {
                let x = spectra.frame_bin(f, b);
                for i in 0..m {
                    let xi = Complex::new(x[i].re.to_f64(), x[i].im.to_f64());
                    for j in 0..m {
                        let xj = Complex::new(x[j].re.to_f64(), -x[j].im.to_f64());
                        k[i * m + j] += xi * xj;
                    }
                }
            }
            for v in k.iter_mut() {
                *v *= scale;
            }
        }
        Ok(NoiseMatrices {
            num_mics: m,
            first_bin,
            num_bins: nb,
            num_frames: frames.len(),
            data,
        })
    }

    /// K at absolute bin `bin` (row-major M × M), if held.
    pub fn bin(&self, bin: usize) -> Option<&[Complex<f64>]> {
        if bin < self.first_bin || bin >= self.first_bin + self.num_bins {
            return None;
        }
        let mm = self.num_mics * self.num_mics;
        let o = (bin - self.first_bin) * mm;
        Some(&self.data[o..o + mm])
    }

    /// Convert to a compute precision (used by backends that update K online).
    pub fn to_precision<T: Real>(&self) -> Vec<C<T>> {
        self.data
            .iter()
            .map(|z| C::new(T::of_f64(z.re), T::of_f64(z.im)))
            .collect()
    }
}
