//! The noise correlation matrix K_k per frequency bin.
//!
//! K_k = (1/F) Σ_f x_{k,f} x_{k,f}ᴴ over F noise-only frames (averaged like R, without
//! R's scaling), from a noise recording, a time range of the input, or a file
//! ([`crate::formats::noise_cm`]). Identity when none is given. K is kept in f64; the plan
//! derives the per-algorithm whitening from it once.

pub mod policy;

use crate::config::LocalizeConfig;
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
        if frames.is_empty() || frames.end > spectra.num_frames {
            return Err(Error::TooShort(format!(
                "noise estimate: needs at least one frame, got frames {}..{} of {}",
                frames.start, frames.end, spectra.num_frames
            )));
        }
        let mut sum = CorrelationSum::new(spectra.num_bins, spectra.num_mics);
        sum.add(spectra, frames);
        sum.finish(first_bin)
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

/// A running Σ x xᴴ per bin in f64, frames added in time order: the sum behind every K
/// estimate, so a K gathered frame by frame from a stream equals the one from the whole
/// recording bit for bit.
#[derive(Debug, Clone, PartialEq)]
pub struct CorrelationSum {
    num_bins: usize,
    num_mics: usize,
    frames: usize,
    data: Vec<Complex<f64>>,
}

impl CorrelationSum {
    /// An empty sum for `num_bins` bins of `num_mics` × `num_mics`.
    pub fn new(num_bins: usize, num_mics: usize) -> Self {
        CorrelationSum {
            num_bins,
            num_mics,
            frames: 0,
            data: vec![Complex::new(0.0, 0.0); num_bins * num_mics * num_mics],
        }
    }

    /// Frames added so far.
    pub fn num_frames(&self) -> usize {
        self.frames
    }

    /// Add x xᴴ of frames `frames` of `spectra` (same bins and mics as the sum).
    pub fn add<T: Real>(&mut self, spectra: &crate::backend::Spectra<T>, frames: std::ops::Range<usize>) {
        let m = self.num_mics;
        debug_assert_eq!((spectra.num_bins, spectra.num_mics), (self.num_bins, m));
        let bin = |(b, k): (usize, &mut [Complex<f64>])| {
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
        };
        let mm = (m * m).max(1);
        // Each bin's sum in frame order either way: the same bits on one core or many.
        if frames.len() * m * m * self.num_bins >= 1 << 20 {
            use rayon::prelude::*;
            self.data.par_chunks_mut(mm).enumerate().for_each(bin);
        } else {
            self.data.chunks_mut(mm).enumerate().for_each(bin);
        }
        self.frames += frames.len();
    }

    /// K = the sum / frames, for bins starting at absolute bin `first_bin`; an error when
    /// no frame was added.
    pub fn finish(&self, first_bin: usize) -> Result<NoiseMatrices> {
        if self.frames == 0 {
            return Err(Error::TooShort("noise estimate: no frame".into()));
        }
        let scale = 1.0 / self.frames as f64;
        Ok(NoiseMatrices {
            num_mics: self.num_mics,
            first_bin,
            num_bins: self.num_bins,
            num_frames: self.frames,
            data: self.data.iter().map(|v| v * scale).collect(),
        })
    }
}

/// Estimate K from planar samples: x xᴴ averaged over the complete STFT frames that start
/// inside `range_s` (seconds; None = all; frames counted from the range's first sample),
/// for the config's used bins, in f64.
pub fn estimate(
    config: &LocalizeConfig,
    sample_rate_hz: u32,
    channels: &[Vec<f32>],
    range_s: Option<(f64, f64)>,
) -> Result<NoiseMatrices> {
    if sample_rate_hz != config.sample_rate_hz {
        return Err(Error::Mismatch(format!(
            "the noise audio is sampled at {} Hz but the analysis runs at {} Hz (convert it: --resample, resample=True in Python)",
            sample_rate_hz, config.sample_rate_hz
        )));
    }
    let len = channels.first().map_or(0, |c| c.len());
    let mut est =
        policy::RangeEstimate::new(config, channels.len(), range_s.unwrap_or((0.0, f64::INFINITY)))?;
    est.feed(0, channels, len);
    est.finish(len).map(|(k, _)| k)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::Spectra;

    /// A sum large enough to run over the bins on every core equals the same frames
    /// added one at a time (each small enough to run serially) bit for bit, and both
    /// equal x xᴴ summed in f64 by definition.
    #[test]
    fn a_parallel_sum_equals_the_serial_one_and_the_definition() {
        let (nf, nb, m) = (40, 30, 32);
        let mut sp = Spectra::<f32>::zeros(nf, nb, m);
        let mut x = 12345u64;
        for z in sp.data.iter_mut() {
            x = x
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let a = (x >> 40) as f32 / (1u64 << 24) as f32 - 0.5;
            let b = ((x >> 16) & 0xff_ffff) as f32 / (1u64 << 24) as f32 - 0.5;
            *z = Complex::new(a, b);
        }
        assert!(nf * m * m * nb >= 1 << 20, "the parallel path");
        let mut all = CorrelationSum::new(nb, m);
        all.add(&sp, 0..nf);
        let mut one = CorrelationSum::new(nb, m);
        for f in 0..nf {
            assert!(m * m * nb < 1 << 20, "the serial path");
            one.add(&sp, f..f + 1);
        }
        assert_eq!(all.data, one.data);
        assert_eq!((all.num_frames(), one.num_frames()), (nf, nf));
        for (b, i, j) in [(0, 0, 0), (7, 3, 30), (29, 31, 1)] {
            let mut want = Complex::new(0.0f64, 0.0);
            for f in 0..nf {
                let v = sp.frame_bin(f, b);
                want += Complex::new(v[i].re as f64, v[i].im as f64)
                    * Complex::new(v[j].re as f64, -v[j].im as f64);
            }
            assert!(
                (all.data[b * m * m + i * m + j] - want).norm() < 1e-12,
                "{b} {i} {j}"
            );
        }
    }
}
