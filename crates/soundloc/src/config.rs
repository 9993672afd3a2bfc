//! What to compute: [`LocalizeConfig`], the typed, serialisable description of a
//! localization run, with HARK LocalizeMUSIC's parameter names in the docs and its defaults.
//!
//! A config is plain data (it can be logged, saved as TOML/JSON, and rebuilt on another
//! device). [`crate::plan::Plan::new`] validates it against the array and precomputes.

use serde::{Deserialize, Serialize};

/// Subspace decomposition (HARK's `MUSIC_ALGORITHM`). See `subspace/`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Algorithm {
    /// Standard eigenvalue decomposition of R (plain MUSIC; HARK's default).
    #[default]
    Sevd,
    /// Textbook generalized eigenproblem R e = λ K e (robust to coherent noise near the
    /// array; soundloc's default when a noise matrix is given).
    Gevd,
    /// HARK's GEVD: eigenvectors of K^{-1/2} R K^{-1/2}, used without back-transform.
    GevdHark,
    /// HARK's GSVD: left singular vectors of K^{-1} R (the seed paper's algorithm).
    Gsvd,
    /// Steered response power with the phase transform (SRP-PHAT, as ODAS,
    /// pyroomacoustics and SpeechBrain ship it): no subspace, no K. See [`crate::srp`].
    SrpPhat,
}

impl Algorithm {
    /// Whether this algorithm uses the noise correlation matrix K.
    pub fn uses_noise(self) -> bool {
        !matches!(self, Algorithm::Sevd | Algorithm::SrpPhat)
    }
    /// Whether this is a MUSIC variant (a subspace decomposition per bin).
    pub fn is_music(self) -> bool {
        !matches!(self, Algorithm::SrpPhat)
    }
    /// The name used on the command line and in outputs.
    pub fn name(self) -> &'static str {
        match self {
            Algorithm::Sevd => "sevd",
            Algorithm::Gevd => "gevd",
            Algorithm::GevdHark => "gevd-hark",
            Algorithm::Gsvd => "gsvd",
            Algorithm::SrpPhat => "srp-phat",
        }
    }
    /// The MUSIC variants, in a fixed order.
    pub const MUSIC: [Algorithm; 4] = [
        Algorithm::Sevd,
        Algorithm::Gevd,
        Algorithm::GevdHark,
        Algorithm::Gsvd,
    ];
    /// All algorithms, in a fixed order.
    pub const ALL: [Algorithm; 5] = [
        Algorithm::Sevd,
        Algorithm::Gevd,
        Algorithm::GevdHark,
        Algorithm::Gsvd,
        Algorithm::SrpPhat,
    ];
}

/// Which frames a correlation window covers relative to the result frame c
/// (HARK's `WINDOW_TYPE`). See [`crate::correlation`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum WindowType {
    /// The W frames ending at c (causal; what streaming uses).
    Past,
    /// Frames centred on c.
    Middle,
    /// Frames [c, c+W-1] (look-ahead; HARK's default).
    #[default]
    Future,
}

/// STFT analysis window (HARK MultiFFT `WINDOW`). See [`crate::stft`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum WindowFunction {
    /// HARK's CONJ window (default).
    #[default]
    Conj,
    /// Hamming.
    Hamming,
    /// Hann ("HANNING" in HARK).
    Hanning,
    /// No window.
    Rectangle,
}

/// Per-bin spectrum weight w_k (HARK's `SPECTRUM_WEIGHT_TYPE`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum SpectrumWeight {
    /// w_k = 1.
    #[default]
    Uniform,
    /// The A-weighting curve (IEC 61672) at each bin's centre frequency, as a linear gain.
    AWeighting,
    /// One weight per used bin, in bin order.
    Manual(Vec<f64>),
}

/// Denominator of the MUSIC spectrum.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Denominator {
    /// Σ |a^H e_m|² (HARK's code; default).
    #[default]
    Squared,
    /// Σ |a^H e_m| (as printed in the seed paper's equation 5).
    Unsquared,
}

/// Numerator of the textbook GEVD's MUSIC spectrum P_k(d) = num / ‖P_n a_w‖² (the other
/// algorithms use ‖a‖², spec §5). Where no talker is, ‖P_n a_w‖² ≈ ‖a_w‖², so the raw
/// ‖a‖² leaves the noise's own directional power ‖a‖²/aᴴK⁻¹a (its MVDR spectrum) in the
/// spectrum: a loud noise source that K describes stands out as a peak. ‖a_w‖² flattens
/// it (the whitened domain's plain MUSIC); ‖a‖·‖a_w‖ keeps half of it (in dB). Measured
/// in docs/accuracy.md ("The spectrum's numerator").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Numerator {
    /// ‖a‖², the raw steering vector's squared norm (spec §5; the default of `gevd`).
    #[default]
    Raw,
    /// ‖a_w‖² = aᴴK⁻¹a.
    Whitened,
    /// ‖a‖·‖a_w‖, the geometric mean of the two (the robust default's).
    Geometric,
}

impl Numerator {
    /// Whether this is spec §5's ‖a‖².
    pub fn is_raw(&self) -> bool {
        *self == Numerator::Raw
    }

    /// Its name on the command line and in Python.
    pub fn name(&self) -> &'static str {
        match self {
            Numerator::Raw => "raw",
            Numerator::Whitened => "whitened",
            Numerator::Geometric => "geometric",
        }
    }

    /// The numerator from ‖a‖² (`raw`) and ‖a_w‖² (`whitened`).
    pub fn of(&self, raw: f64, whitened: f64) -> f64 {
        match self {
            Numerator::Raw => raw,
            Numerator::Whitened => whitened,
            Numerator::Geometric => (raw * whitened).sqrt(),
        }
    }
}

/// Compute precision: single (as HARK; default) or double (the reference).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Precision {
    /// f32.
    #[default]
    F32,
    /// f64.
    F64,
}

/// Everything that defines a localization run. Defaults are HARK LocalizeMUSIC's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LocalizeConfig {
    /// `MUSIC_ALGORITHM`.
    pub algorithm: Algorithm,
    /// FFT length N in samples (`LENGTH`, 512).
    pub nfft: usize,
    /// Frame advance in samples (`ADVANCE`, 160).
    pub hop: usize,
    /// Sampling rate in Hz (`SAMPLING_RATE`, 16000).
    pub sample_rate_hz: u32,
    /// Analysis window function (MultiFFT `WINDOW`, CONJ).
    pub window_function: WindowFunction,
    /// Correlation window W in frames (`WINDOW`, 50).
    pub window: usize,
    /// `WINDOW_TYPE` (FUTURE).
    pub window_type: WindowType,
    /// One result every `period` frames (`PERIOD`, 50).
    pub period: usize,
    /// Signal subspace dimension Ns (`NUM_SOURCE`, 2); must be < number of mics.
    pub num_sources: usize,
    /// Signal-subspace dimension used by the decomposition when it should differ from
    /// `num_sources` (reverberation and residual noise take more than one dimension per
    /// talker); `None` = `num_sources`, as HARK ties them.
    pub subspace_dim: Option<usize>,
    /// Peaks reported per result (`MAXNUM_OUT_PEAKS`): -1 = `num_sources`, 0 = all.
    pub max_peaks: i64,
    /// Azimuth range kept, in degrees (`MIN_DEG`, -180).
    pub min_deg: f64,
    /// Azimuth range kept, in degrees (`MAX_DEG`, 180).
    pub max_deg: f64,
    /// Lowest frequency used in Hz (`LOWER_BOUND_FREQUENCY`, 500).
    pub lower_freq_hz: f64,
    /// Frequency bound in Hz, exclusive bin (`UPPER_BOUND_FREQUENCY`, 2800).
    pub upper_freq_hz: f64,
    /// `SPECTRUM_WEIGHT_TYPE`.
    pub spectrum_weight: SpectrumWeight,
    /// `ENABLE_EIGENVALUE_WEIGHT` (true): weight each bin by √(largest eigenvalue).
    pub eigenvalue_weight: bool,
    /// Squared (default) or unsquared denominator.
    pub denominator: Denominator,
    /// Diagonal loading added to K (relative to its mean diagonal) before it is used;
    /// 0 = none, and a K that is not positive definite is an error.
    pub diagonal_loading: f64,
    /// Per-bin normalisation (NormMUSIC, Salvati et al. 2014, as pyroomacoustics'
    /// `NormMUSIC`): each bin's pseudo-spectrum is divided by its maximum over the
    /// directions before the bins are summed, so every bin votes with weight w_k (the
    /// eigenvalue weight g_k cancels). Off in HARK.
    pub normalize_bins: bool,
    /// Sub-grid refinement of every peak (see [`crate::peaks::refine`]): the reported
    /// direction is the maximum of a quadratic fitted to the dB spectrum at the peak and
    /// its grid neighbours, within one grid step. Off in HARK (grid directions only).
    pub refine: bool,
    /// Coherence normalisation (off in HARK): the channels' gains are taken from the
    /// recording, not from the transfer functions, so an array whose microphones are
    /// louder or quieter than its TFs say (real ones differ by ±1 dB and more) gives the
    /// results of a matched one. The steering vectors are reduced to their phases
    /// a_m/|a_m|, and
    /// - SEVD: every window's R_k is replaced by its coherence matrix D^{-1/2} R_k
    ///   D^{-1/2}, D = diag(R_k) (R̃_ij = R_ij / √(R_ii R_jj), unit diagonal; a silent
    ///   channel keeps a zero row and column), in which each channel's gain cancels;
    /// - the textbook GEVD: R and K stay as they are (the whitening stays exact) and the
    ///   steering vectors take the magnitudes of K's channel levels, √(K_mm / geometric mean of K_jj) —
    ///   with K = G K₀ G that is the gain G times the noise field's own level pattern.
    ///
    /// It discards the level differences that measured TFs hold (the array's own shadow).
    /// Refused for HARK's GSVD and GEVD; ignored by SRP-PHAT, whose phase transform already
    /// discards gains.
    pub coherence: bool,
    /// The textbook GEVD's spectrum numerator ([`Numerator`]; spec §5's ‖a‖² unless set).
    /// The other algorithms refuse any other. Left out of JSON when raw.
    #[serde(skip_serializing_if = "Numerator::is_raw")]
    pub numerator: Numerator,
    /// Approximate mode for streams (see [`crate::subspace::tracking`]): each window's
    /// leading vectors by warm-started subspace iteration from the previous window's,
    /// checked by their residual, with an exact decomposition at the start, on every
    /// failed check and once per ⌈W / PERIOD⌉ windows. Pays off at small PERIOD and small
    /// `signal_dim`; CPU only; no source count. Off (exact) by default.
    pub subspace_tracking: bool,
    /// Onset weighting of the correlation ([`crate::correlation::onset`]): the memory T in
    /// frames of each bin's recent average power; a frame enters R with the weight
    /// w = ((r − 1)/r)² for r > 1, else 0, r its power against that average (whitened by
    /// K for the noise-aware algorithms, per microphone otherwise), so a talker's onsets
    /// count and the reverberation after them does not. 0 = off (HARK); the defaults
    /// without a named algorithm use 10 (docs/accuracy.md, "Onset weighting"). Refused
    /// for SRP-PHAT, whose phase transform would discard the weights. Left out of JSON
    /// when 0.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub onset_frames: usize,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

impl Default for LocalizeConfig {
    fn default() -> Self {
        LocalizeConfig {
            algorithm: Algorithm::Sevd,
            nfft: 512,
            hop: 160,
            sample_rate_hz: 16000,
            window_function: WindowFunction::Conj,
            window: 50,
            window_type: WindowType::Future,
            period: 50,
            num_sources: 2,
            subspace_dim: None,
            max_peaks: -1,
            min_deg: -180.0,
            max_deg: 180.0,
            lower_freq_hz: 500.0,
            upper_freq_hz: 2800.0,
            spectrum_weight: SpectrumWeight::Uniform,
            eigenvalue_weight: true,
            denominator: Denominator::Squared,
            diagonal_loading: 0.0,
            normalize_bins: false,
            refine: false,
            coherence: false,
            numerator: Numerator::Raw,
            subspace_tracking: false,
            onset_frames: 0,
        }
    }
}

/// HARK's `LENGTH` 512 and `ADVANCE` 160, which are samples at 16 kHz, as the durations
/// they are there (32 ms, 10 ms) at `sample_rate_hz`: (the even FFT length nearest
/// 0.032·fs, the hop nearest 0.01·fs), at least (4, 1) — 1536 and 480 at 48 kHz, 1412
/// and 441 at 44.1 kHz. The free-field default when no frame sizes are given: with 512
/// samples at 48 kHz the window of 50 frames covers 0.17 s instead of 0.5 s, and a
/// user-style sweep (pyroomacoustics rooms, 2026-12-01) lost 12–24 points of
/// talker-windows against the same audio at 16 kHz, which these sizes gave back.
pub fn frame_sizes_for_rate(sample_rate_hz: u32) -> (usize, usize) {
    let fs = sample_rate_hz as f64;
    let nfft = ((0.032 * fs / 2.0).round() as usize * 2).max(4);
    let hop = ((0.01 * fs).round() as usize).max(1);
    (nfft, hop)
}

impl LocalizeConfig {
    /// The used bins: k from ⌊lower·N/fs⌋ up to but not including ⌊upper·N/fs⌋.
    pub fn bin_range(&self) -> std::ops::Range<usize> {
        let n = self.nfft as f64;
        let fs = self.sample_rate_hz as f64;
        let lo = (self.lower_freq_hz * n / fs).floor().max(0.0) as usize;
        let hi = (self.upper_freq_hz * n / fs).floor().max(0.0) as usize;
        lo..hi.min(self.nfft / 2 + 1)
    }
    /// The signal-subspace dimension Ns the decomposition uses.
    pub fn signal_dim(&self) -> usize {
        self.subspace_dim.unwrap_or(self.num_sources)
    }
    /// What runs, for people: the algorithm's name ("normmusic" for the SEVD with every
    /// bin normalised), then the signal subspace when it differs from `num_sources`, and
    /// "coherence" and "refined" (e.g. "normmusic (subspace 4, coherence, refined)" for the
    /// room default on 8 mics).
    pub fn label(&self) -> String {
        let mut s = match (self.algorithm, self.normalize_bins && self.algorithm.is_music()) {
            (Algorithm::Sevd, true) => "normmusic".to_string(),
            (a, true) => format!("{} normalised", a.name()),
            (a, false) => a.name().to_string(),
        };
        let mut with = Vec::new();
        if self.algorithm.is_music() && self.signal_dim() != self.num_sources {
            with.push(format!("subspace {}", self.signal_dim()));
        }
        if self.coherence && self.algorithm.is_music() {
            with.push("coherence".to_string());
        }
        if !self.numerator.is_raw() {
            with.push(format!("{} numerator", self.numerator.name()));
        }
        if self.refine {
            with.push("refined".to_string());
        }
        if !with.is_empty() {
            s += &format!(" ({})", with.join(", "));
        }
        s
    }
    /// Whether the number of active sources is estimated (`num_active`): for the MUSIC
    /// family, not in the approximate mode (it keeps only the tracked values).
    pub fn counts_sources(&self) -> bool {
        self.algorithm.is_music() && !self.subspace_tracking
    }
    /// Whether every window's R is replaced by its coherence matrix: [`Self::coherence`]
    /// with the SEVD (the textbook GEVD takes the gains from K instead).
    pub fn normalizes_r(&self) -> bool {
        self.coherence && self.algorithm == Algorithm::Sevd
    }
    /// Peaks reported per result after resolving `max_peaks` (usize::MAX = all).
    pub fn peaks_out(&self) -> usize {
        match self.max_peaks {
            x if x < 0 => self.num_sources,
            0 => usize::MAX,
            x => x as usize,
        }
    }
}

#[cfg(test)]
mod tests {
    /// HARK's sizes at 16 kHz, their durations elsewhere.
    #[test]
    fn frame_sizes_keep_harks_durations() {
        assert_eq!(super::frame_sizes_for_rate(16000), (512, 160));
        assert_eq!(super::frame_sizes_for_rate(48000), (1536, 480));
        assert_eq!(super::frame_sizes_for_rate(44100), (1412, 441));
        assert_eq!(super::frame_sizes_for_rate(8000), (256, 80));
        assert_eq!(super::frame_sizes_for_rate(1), (4, 1));
    }

    use super::*;
    #[test]
    fn default_bins_are_16_to_88() {
        let c = LocalizeConfig::default();
        assert_eq!(c.bin_range(), 16..89);
        assert_eq!(c.bin_range().len(), 73);
    }
}
