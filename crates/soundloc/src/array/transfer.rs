//! Transfer functions a_{d,k}: for each direction d and frequency bin k, the complex
//! response of every microphone (the steering vector of MUSIC).

use super::Grid;
use num_complex::Complex;

/// Transfer functions for a set of directions, microphones and bins.
///
/// `data` is laid out `[direction][mic][bin - first_bin]` (row-major), complex f32 as HARK
/// stores them. Bins are those of an `nfft`-point FFT at `sample_rate_hz`; a file holds all
/// `nfft/2 + 1`, a computed set may hold only the bins the analysis uses.
#[derive(Debug, Clone, PartialEq)]
pub struct TransferFunctions {
    /// FFT length the TFs are defined for.
    pub nfft: usize,
    /// Sampling rate in Hz.
    pub sample_rate_hz: u32,
    /// Directions.
    pub grid: Grid,
    /// Microphone positions in metres as given by the source (may be placeholders in
    /// vendor files: never trust them over the TF data).
    pub mic_positions: Vec<[f64; 3]>,
    /// Number of microphones.
    pub num_mics: usize,
    /// First bin held in `data`.
    pub first_bin: usize,
    /// Number of bins held in `data`.
    pub num_bins: usize,
    /// `[direction][mic][bin - first_bin]`.
    pub data: Vec<Complex<f32>>,
}

impl TransferFunctions {
    /// Number of directions.
    pub fn num_dirs(&self) -> usize {
        self.grid.len()
    }
    /// Range of bins held.
    pub fn bins(&self) -> std::ops::Range<usize> {
        self.first_bin..self.first_bin + self.num_bins
    }
    /// a_{dir,bin}[mic]. `bin` is an absolute FFT bin index; panics if not held.
    #[inline]
    pub fn get(&self, dir: usize, mic: usize, bin: usize) -> Complex<f32> {
        debug_assert!(self.bins().contains(&bin));
        self.data[(dir * self.num_mics + mic) * self.num_bins + (bin - self.first_bin)]
    }
}
