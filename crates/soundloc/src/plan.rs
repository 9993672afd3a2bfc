//! Plan once, run cheap: [`Plan`] validates a [`LocalizeConfig`] against the transfer
//! functions and the noise matrix, and precomputes everything that does not change
//! between windows:
//!
//! - the used bins k ∈ [⌊f_lo·N/fs⌋, ⌊f_hi·N/fs⌋) and the analysis window;
//! - the steering vectors a_{d,k} of the used bins, laid out `[bin][dir][mic]` so that one
//!   bin's D × M block feeds a GEMM, and their norms ‖a‖² = Re(aᴴa), `[bin][dir]` (for
//!   SRP-PHAT the phase-only ã = a/|a| elementwise, see [`crate::srp`]);
//! - the spectrum weights w_k;
//! - per bin, from K (in f64, once per K): K ← K / max|Re K_ij| (HARK's scaling), then the
//!   whitening matrix W_k of the algorithm (K⁻¹ for GSVD, L⁻¹ with K = L Lᴴ for GEVD,
//!   K^{-1/2} for GEVD-HARK), and for GEVD the whitened steering a_w = L⁻¹ a with ‖a_w‖²
//!   (and the spectrum's numerator from both when it is not the raw ‖a‖², [`crate::config::Numerator`]);
//! - the peak table (neighbours, azimuth mask, number of peaks out).
//!
//! After `Plan::new` a backend's per-batch calls fail only on shape or device errors.

use crate::array::{Grid, TransferFunctions};
use crate::audio::health::ClosePairs;
use crate::config::{Algorithm, Denominator, LocalizeConfig, SpectrumWeight};
use crate::lanes::{self, Planar};
use crate::noise::NoiseMatrices;
use crate::peaks::PeakTable;
use crate::real::{Real, C};
use crate::stft::window_function;
use crate::{Error, Result};
use faer::c64;
use rayon::prelude::*;
use std::ops::Range;
use std::sync::Arc;

mod singular;
mod whitening;
use whitening::whitening;

/// Noise-dependent precomputation (absent for SEVD).
#[derive(Debug, Clone, PartialEq)]
pub struct Whitening<T: Real> {
    /// W_k per used bin in f64, `[bin][i][j]` row-major M × M: the CPU and the GPU whiten
    /// R in double precision whatever T is.
    pub matrix64: Vec<c64>,
    /// GEVD only: whitened steering a_w = L⁻¹ a, `[bin][dir][mic]` (else empty). Shared
    /// by clones, and with the plan's own steering where K is the identity (a_w = a).
    pub steering: Arc<Vec<C<T>>>,
    /// GEVD only: ‖a_w‖², `[bin][dir]` (else empty); shared like `steering`.
    pub steering_norm2: Arc<Vec<T>>,
    /// GEVD with a [`crate::config::Numerator`] other than the raw ‖a‖²: the spectrum's numerator from
    /// ‖a‖² and ‖a_w‖², `[bin][dir]` (else empty). See [`Plan::numerator_norm2`].
    pub numerator_norm2: Vec<T>,
}

/// [`Whitening::numerator_norm2`] for `config` from the raw and whitened norms.
fn numerator_norm2<T: Real>(config: &LocalizeConfig, raw: &[T], w: &mut Whitening<T>) {
    w.numerator_norm2 = match (config.algorithm, config.numerator) {
        (Algorithm::Gevd, n) if !n.is_raw() => raw
            .iter()
            .zip(w.steering_norm2.iter())
            .map(|(&r, &aw)| T::of_f64(n.of(r.to_f64(), aw.to_f64())))
            .collect(),
        _ => Vec::new(),
    };
}

/// A validated, precomputed localization plan. Shared (`Arc`) by the engine and a backend.
#[derive(Debug, Clone)]
pub struct Plan<T: Real> {
    /// The configuration it was built from.
    pub config: LocalizeConfig,
    /// Number of microphones M.
    pub num_mics: usize,
    /// Number of directions D.
    pub num_dirs: usize,
    /// Used absolute FFT bins.
    pub bins: Range<usize>,
    /// The direction grid.
    pub grid: Grid,
    /// Analysis window, N samples.
    pub window: Vec<T>,
    /// a_{d,k}, `[bin][dir][mic]`. Shared (not copied) by the plans a K update makes.
    pub steering: Arc<Vec<C<T>>>,
    /// ‖a_{d,k}‖², `[bin][dir]`. Shared like `steering`.
    pub steering_norm2: Arc<Vec<T>>,
    /// Spectrum weight w_k per used bin.
    pub weights: Vec<T>,
    /// Whitening for GEVD / GEVD-HARK / GSVD.
    pub whitening: Option<Whitening<T>>,
    /// Peak search table.
    pub peak_table: PeakTable,
    /// Small arrays (M ≤ [`lanes::MAX_MICS`]): the denominator's steering vectors
    /// ([`Plan::denominator_steering`]) in planar form for the CPU's spectrum kernels,
    /// derived at construction and by [`Plan::with_noise`] (a plan's steering, whitening
    /// and algorithm are not changed after construction).
    pub(crate) planar: Option<Arc<Planar<T>>>,
    /// a_r − a_i of every value of [`Plan::denominator_steering`] for the CPU's AVX-512
    /// spectrum kernel (`projections::steering_sums`; bins × D × M f32, 44 MB at the seed
    /// config, half the steering's size), formed on its first use (GPU runs never pay for
    /// it; the first CPU call waits for it) and anew by [`Plan::with_noise`] for GEVD. A
    /// clone whose steering, whitening or algorithm is changed by hand keeps the old sums
    /// (as it keeps `planar`): build a new plan instead.
    pub(crate) steering_sums: Arc<std::sync::OnceLock<Vec<f32>>>,
    /// The input checks' close microphone pairs and band edge
    /// ([`crate::audio::health::close_pairs`] at the lowest used bin), formed on the first
    /// stream's first push and shared by every stream of the plan.
    pub(crate) close_pairs: Arc<std::sync::OnceLock<Option<ClosePairs>>>,
    /// The gains check's expected relative channel powers ([`Plan::expected_levels`]),
    /// formed on first use and shared like `close_pairs`.
    pub(crate) expected_levels: Arc<std::sync::OnceLock<Vec<f64>>>,
    /// The source count's floor relative to each bin's largest value
    /// ([`crate::subspace::count::model_floor`], from the TFs' microphone positions).
    pub count_floor: f64,
    /// The source count's independent snapshots per frame of a window: hop/N_fft
    /// (overlapping frames), times [`crate::correlation::onset::snapshot_fraction`] with
    /// onset weighting. MDL's N = max(1, round(W × this)) on the CPU and the GPU.
    pub count_snapshots_per_frame: f64,
}

impl<T: Real> Plan<T> {
    /// The input checks' close pairs (formed once, see the field).
    pub fn close_pairs(&self) -> Option<ClosePairs> {
        self.close_pairs
            .get_or_init(|| {
                let (m, d) = (self.num_mics, self.num_dirs);
                let c = &self.config;
                let bin_hz = c.sample_rate_hz as f64 / c.nfft as f64;
                // The lowest used bin above DC.
                let first = usize::from(self.bins.start == 0);
                let f0 = (self.bins.start + first) as f64 * bin_hz;
                self.steering
                    .get(first * d * m..(first + 1) * d * m)
                    .and_then(|st| {
                        crate::audio::health::close_pairs(st, m, first, self.bins.len(), f0, bin_hz)
                    })
            })
            .clone()
    }

    /// E_m = Σ over the used bins and directions of |a_{d,k,m}|² per microphone (any
    /// common scale): the channel powers a far sound field gives relative to each other,
    /// for the input checks' gains check ([`crate::audio::health::gains`]). Formed once.
    pub fn expected_levels(&self) -> Vec<f64> {
        self.expected_levels
            .get_or_init(|| {
                let m = self.num_mics;
                let mut e = vec![0.0f64; m];
                for a in self.steering.chunks_exact(m) {
                    for (s, z) in e.iter_mut().zip(a) {
                        let (re, im) = (z.re.to_f64(), z.im.to_f64());
                        *s += re * re + im * im;
                    }
                }
                e
            })
            .clone()
    }

    /// Whether the input checks look at the channels' gains: the textbook GEVD (the
    /// robust default) without coherence normalisation, whose whitened steering is the
    /// most sensitive to gains the transfer functions do not have.
    pub fn gains_matter(&self) -> bool {
        self.config.algorithm == Algorithm::Gevd && !self.config.coherence
    }

    /// Validate and precompute. `noise` is K (None = identity) and is ignored by SEVD.
    pub fn new(
        config: &LocalizeConfig,
        tf: &TransferFunctions,
        noise: Option<&NoiseMatrices>,
    ) -> Result<Self> {
        validate_config(config)?;
        let m = tf.num_mics;
        let d = tf.num_dirs();
        // MUSIC resolves fewer sources than microphones (HARK ties its signal subspace to
        // NUM_SOURCE); SRP-PHAT has no subspace, its num_sources is only a peak count.
        let subspace = config.algorithm.is_music();
        if m < 2 {
            return Err(Error::Config(format!(
                "{m} microphone{}: localization needs at least 2 (--channels, channels= in Python, selects \
                 the transfer functions' microphones used)",
                if m == 1 { "" } else { "s" }
            )));
        }
        if config.num_sources == 0 || (subspace && config.num_sources >= m) {
            return Err(Error::Config(if subspace {
                format!(
                    "num-sources (num_sources= in Python) must be between 1 and M-1 = {} for {} \
                     microphones with {}, got {} (MUSIC resolves fewer sources than \
                     microphones; srp-phat reports any number of peaks)",
                    m.saturating_sub(1),
                    m,
                    config.algorithm.name(),
                    config.num_sources
                )
            } else {
                format!(
                    "num-sources (num_sources= in Python) must be at least 1, got {}",
                    config.num_sources
                )
            }));
        }
        if let Some(ns) = config.subspace_dim {
            if ns == 0 || ns >= m {
                return Err(Error::Config(format!(
                    "subspace-dim must be between 1 and M-1 = {} for {} microphones, got {ns}",
                    m.saturating_sub(1),
                    m
                )));
            }
        }
        if tf.nfft != config.nfft {
            return Err(Error::Mismatch(format!(
                "transfer functions are for a {}-point FFT but the analysis uses {} (set --fft-length {n}, nfft={n} in Python)",
                tf.nfft,
                config.nfft,
                n = tf.nfft
            )));
        }
        if tf.sample_rate_hz != config.sample_rate_hz {
            return Err(Error::Mismatch(format!(
                "transfer functions are for {} Hz but the analysis runs at {} Hz",
                tf.sample_rate_hz, config.sample_rate_hz
            )));
        }
        let bins = config.bin_range();
        if bins.is_empty() || bins == (0..1) {
            let step = config.sample_rate_hz as f64 / config.nfft as f64;
            let what = if bins.is_empty() {
                "no frequency bin".to_string()
            } else {
                "only bin 0 (0 Hz, which carries no direction)".to_string()
            };
            return Err(Error::Config(format!(
                "{what} between {} Hz and {} Hz at N = {}, fs = {} Hz: bins are {step} Hz apart, and the \
                 band uses bins k from floor(lower·N/fs) up to, not including, floor(upper·N/fs) (HARK's \
                 rule); widen the band or lengthen the FFT",
                config.lower_freq_hz, config.upper_freq_hz, config.nfft, config.sample_rate_hz
            )));
        }
        if bins.start < tf.first_bin || bins.end > tf.first_bin + tf.num_bins {
            return Err(Error::Mismatch(format!(
                "the analysis uses bins {}..{} but the transfer functions hold bins {}..{}",
                bins.start,
                bins.end,
                tf.first_bin,
                tf.first_bin + tf.num_bins
            )));
        }
        if d == 0 {
            return Err(Error::Config("the direction grid is empty".into()));
        }
        let nb = bins.len();
        // Steering [bin][dir][mic] and norms.
        let mut steering = vec![C::new(T::zero(), T::zero()); nb * d * m];
        let mut norm2 = vec![T::zero(); nb * d];
        // SRP-PHAT, and MUSIC on coherence matrices, steer with the phase alone: ã = a/|a|.
        let phase_only = config.algorithm == Algorithm::SrpPhat || config.coherence;
        steering
            .par_chunks_mut(d * m)
            .zip(norm2.par_chunks_mut(d))
            .enumerate()
            .for_each(|(b, (s, n2))| {
                let bin = bins.start + b;
                for dir in 0..d {
                    let mut acc = 0.0f64;
                    for mic in 0..m {
                        let a = tf.get(dir, mic, bin);
                        let (mut re, mut im) = (a.re as f64, a.im as f64);
                        if phase_only {
                            let n = re.hypot(im);
                            (re, im) = if n > 0.0 && n.is_finite() {
                                (re / n, im / n)
                            } else {
                                (0.0, 0.0)
                            };
                        }
                        acc += re * re + im * im;
                        s[dir * m + mic] = C::new(T::of_f64(re), T::of_f64(im));
                    }
                    n2[dir] = T::of_f64(acc);
                }
            });
        if steering.iter().any(|z| !(z.re.is_finite() && z.im.is_finite())) {
            return Err(Error::Numerical {
                stage: "plan",
                message: "transfer functions contain non-finite values".into(),
            });
        }
        if let Some(dir) = (0..d).find(|&dir| (0..nb).all(|b| norm2[b * d + dir] == T::zero())) {
            return Err(Error::Numerical {
                stage: "plan",
                message: format!("transfer function of direction {dir} is zero in every used bin"),
            });
        }
        let weights = spectrum_weights::<T>(config, &bins)?;
        let (steering, norm2) = (Arc::new(steering), Arc::new(norm2));
        let whitening = if config.algorithm.uses_noise() {
            let identity;
            let k = match noise {
                Some(k) => k,
                None => {
                    identity = NoiseMatrices::identity(m, bins.clone());
                    &identity
                }
            };
            // Without K, a_w = a: the plan's own steering serves (bit for bit; with
            // coherence normalisation its norms are those of the unrounded phase-only
            // values, a rounding apart, so the whitened ones are computed).
            let shared = (noise.is_none() && !config.coherence).then_some((&steering, &norm2));
            let mut w = whitening(config, k, &bins, m, d, &steering, shared)?;
            numerator_norm2(config, &norm2, &mut w);
            Some(w)
        } else {
            None
        };
        let peak_table = PeakTable::new(&tf.grid, config)?;
        let mut plan = Plan {
            config: config.clone(),
            num_mics: m,
            num_dirs: d,
            bins,
            grid: tf.grid.clone(),
            window: window_function::<T>(config.window_function, config.nfft),
            steering,
            steering_norm2: norm2,
            weights,
            whitening,
            peak_table,
            planar: None,
            steering_sums: Default::default(),
            close_pairs: Default::default(),
            expected_levels: Default::default(),
            // Positions that are not an array (HARK's sample zips hold placeholders, several
            // microphones at one point) are not used.
            count_floor: crate::subspace::count::model_floor(
                crate::array::Geometry::new(tf.mic_positions.clone(), std::path::Path::new("TF"))
                    .ok()
                    .filter(|g| g.num_mics() == m)
                    .map(|g| g.aperture_m()),
                config.sample_rate_hz,
                config.nfft,
            ),
            count_snapshots_per_frame: Self::snapshots_per_frame(config, m),
        };
        plan.planar = plan.planar_steering();
        Ok(plan)
    }

    /// [`Plan::count_snapshots_per_frame`] for `config` on `num_mics` microphones.
    fn snapshots_per_frame(config: &LocalizeConfig, num_mics: usize) -> f64 {
        let overlap = config.hop.min(config.nfft) as f64 / config.nfft as f64;
        if config.onset_frames == 0 {
            return overlap;
        }
        let whitened = config.algorithm.uses_noise();
        overlap * crate::correlation::onset::snapshot_fraction(config.onset_frames, num_mics, whitened)
    }

    /// The same plan with a new noise matrix K (online K updates: iGSVD / iGEVD). Only the
    /// noise part (whitening, and for GEVD the whitened steering) is computed; the steering
    /// vectors and their norms are shared with `self`, not copied.
    pub fn with_noise(&self, noise: &NoiseMatrices) -> Result<Self> {
        let mut p = self.clone();
        if self.config.algorithm.uses_noise() {
            let mut w = whitening(
                &self.config,
                noise,
                &self.bins,
                self.num_mics,
                self.num_dirs,
                &self.steering,
                None,
            )?;
            numerator_norm2(&self.config, &self.steering_norm2, &mut w);
            p.whitening = Some(w);
            if self.config.algorithm == Algorithm::Gevd {
                // Its denominator reads the whitened steering.
                p.planar = p.planar_steering();
                p.steering_sums = Default::default();
            }
        }
        Ok(p)
    }

    /// Number of used bins.
    pub fn num_bins(&self) -> usize {
        self.bins.len()
    }

    /// The steering vectors and norms the spectrum's denominator uses: the whitened ones
    /// for the textbook GEVD, the raw ones otherwise. `[bin][dir][mic]`, `[bin][dir]`.
    pub fn denominator_steering(&self) -> (&[C<T>], &[T]) {
        match (&self.whitening, self.config.algorithm) {
            (Some(w), Algorithm::Gevd) => (&w.steering[..], &w.steering_norm2[..]),
            _ => (&self.steering[..], &self.steering_norm2[..]),
        }
    }

    /// The spectrum's numerator `[bin][dir]`: ‖a‖² (spec §5), or for the textbook GEVD with
    /// another [`crate::config::Numerator`] its value from ‖a‖² and ‖a_w‖².
    pub fn numerator_norm2(&self) -> &[T] {
        match &self.whitening {
            Some(w) if !w.numerator_norm2.is_empty() => &w.numerator_norm2,
            _ => &self.steering_norm2,
        }
    }

    /// The planar copy of [`Plan::denominator_steering`] for small arrays, None above
    /// [`lanes::MAX_MICS`].
    fn planar_steering(&self) -> Option<Arc<Planar<T>>> {
        (self.num_mics <= lanes::MAX_MICS).then(|| {
            Arc::new(Planar::new(
                self.denominator_steering().0,
                self.num_dirs,
                self.num_mics,
            ))
        })
    }

    /// W_k of used bin `b` in f64 (row-major M × M), as the decompositions use it (CPU and
    /// GPU whiten in double whatever T is).
    pub fn whitening_matrix64(&self, b: usize) -> Option<&[c64]> {
        let mm = self.num_mics * self.num_mics;
        self.whitening.as_ref().map(|w| &w.matrix64[b * mm..(b + 1) * mm])
    }

    /// Centre frequency of used bin `b` in Hz.
    pub fn bin_hz(&self, b: usize) -> f64 {
        (self.bins.start + b) as f64 * self.config.sample_rate_hz as f64 / self.config.nfft as f64
    }
}

fn validate_config(c: &LocalizeConfig) -> Result<()> {
    let bad = |m: String| Err(Error::Config(m));
    if c.nfft < 4 {
        return bad(format!("fft length must be at least 4, got {}", c.nfft));
    }
    if c.hop == 0 {
        return bad("hop must be at least 1 sample".into());
    }
    if c.window == 0 {
        return bad("window (frames per correlation) must be at least 1".into());
    }
    if c.period == 0 {
        return bad("period must be at least 1 frame".into());
    }
    if c.coherence && matches!(c.algorithm, Algorithm::Gsvd | Algorithm::GevdHark) {
        return bad(format!(
            "coherence normalisation is defined for sevd and the textbook gevd, not for HARK's {} \
             (its spectrum uses the raw steering vectors against K⁻¹-weighted ones); drop --coherence \
             or use --algorithm gevd",
            c.algorithm.name()
        ));
    }
    if c.algorithm == Algorithm::SrpPhat {
        // SRP-PHAT has no subspace and no denominator, and its phase transform already
        // removes the channels' gains: these would change nothing. (The eigenvalue weight
        // is on by default everywhere, so SRP-PHAT ignores it rather than refuse it.)
        let unused: Vec<&str> = [
            (c.subspace_dim.is_some(), "--subspace-dim (subspace_dim=)"),
            (c.coherence, "--coherence (coherence=True)"),
            (c.denominator != Denominator::Squared, "--denominator"),
        ]
        .into_iter()
        .filter_map(|(given, name)| given.then_some(name))
        .collect();
        if !unused.is_empty() {
            return bad(format!(
                "srp-phat has no signal subspace or MUSIC denominator, and its phase transform already \
                 removes the channels' gains: {} would change nothing; drop it or name a MUSIC algorithm",
                unused.join(", ")
            ));
        }
    }
    if !c.numerator.is_raw() && c.algorithm != Algorithm::Gevd {
        return bad(format!(
            "the {} numerator is defined for the textbook gevd (K whitens its steering \
             vectors), not for {}, whose spectrum uses ‖a‖²: drop the numerator (--numerator, \
             numerator= in Python), or give a noise source (the robust default) or name the \
             textbook gevd (--algorithm gevd)",
            c.numerator.name(),
            c.algorithm.name()
        ));
    }
    if c.max_peaks < -1 {
        return bad(format!(
            "max-peaks must be -1 (= num-sources), 0 (all peaks) or a positive count, got {}",
            c.max_peaks
        ));
    }
    if c.sample_rate_hz == 0 {
        return bad("sample rate must be positive".into());
    }
    if !(c.lower_freq_hz.is_finite() && c.upper_freq_hz.is_finite())
        || c.lower_freq_hz < 0.0
        || c.upper_freq_hz <= c.lower_freq_hz
    {
        return bad(format!(
            "frequency range must satisfy 0 <= lower < upper, got {} .. {} Hz",
            c.lower_freq_hz, c.upper_freq_hz
        ));
    }
    if !(c.min_deg.is_finite() && c.max_deg.is_finite()) || c.min_deg > c.max_deg {
        return bad(format!(
            "azimuth range must satisfy min-deg <= max-deg, got {} .. {}",
            c.min_deg, c.max_deg
        ));
    }
    if !(c.diagonal_loading >= 0.0 && c.diagonal_loading.is_finite()) {
        return bad(format!(
            "diagonal loading must be >= 0, got {}",
            c.diagonal_loading
        ));
    }
    if c.onset_frames > 0 && c.algorithm == Algorithm::SrpPhat {
        return bad(
            "onset weighting is not defined for srp-phat: its phase transform reduces every frame to \
             its phase and would discard the weights (use onset 0, or a MUSIC algorithm)"
                .into(),
        );
    }
    if c.subspace_tracking {
        if !c.algorithm.is_music() {
            return bad(format!(
                "subspace tracking needs a MUSIC algorithm; {} has no subspace",
                c.algorithm.name()
            ));
        }
        if c.denominator == crate::config::Denominator::Unsquared {
            return bad("subspace tracking needs the squared denominator (the unsquared one sums over every noise vector)".into());
        }
    }
    Ok(())
}

/// w_k per used bin.
/// The highest power (dB) a per-bin normalised spectrum (NormMUSIC, `normalize_bins`) can
/// reach: every bin's maximum is its weight w_k, so P̄ ≤ Σ_k w_k and the reported power
/// 10·log10(P̄ + 1) ≤ 10·log10(Σ_k w_k + 1). `None` when the bins are not normalised
/// (the plain MUSIC spectrum has no such bound).
pub fn normalized_power_ceiling_db(c: &LocalizeConfig) -> Result<Option<f64>> {
    if !(c.normalize_bins && c.algorithm.is_music()) {
        return Ok(None);
    }
    let w: Vec<f64> = spectrum_weights(c, &c.bin_range())?;
    Ok(Some(10.0 * (w.iter().sum::<f64>() + 1.0).log10()))
}

fn spectrum_weights<T: Real>(c: &LocalizeConfig, bins: &Range<usize>) -> Result<Vec<T>> {
    let hz = |k: usize| k as f64 * c.sample_rate_hz as f64 / c.nfft as f64;
    Ok(match &c.spectrum_weight {
        SpectrumWeight::Uniform => vec![T::one(); bins.len()],
        SpectrumWeight::AWeighting => bins.clone().map(|k| T::of_f64(a_weighting_gain(hz(k)))).collect(),
        SpectrumWeight::Manual(w) => {
            if w.len() != bins.len() {
                return Err(Error::Config(format!(
                    "manual spectrum weights: {} values given, {} bins used ({}..{})",
                    w.len(),
                    bins.len(),
                    bins.start,
                    bins.end
                )));
            }
            if let Some(i) = w.iter().position(|x| !x.is_finite() || *x < 0.0) {
                return Err(Error::Config(format!(
                    "manual spectrum weight {i} is {}, must be finite and >= 0",
                    w[i]
                )));
            }
            if w.iter().all(|&x| x == 0.0) {
                return Err(Error::Config(format!(
                    "manual spectrum weights are all zero: no bin of {}..{} would count, and the spectrum would be flat",
                    bins.start, bins.end
                )));
            }
            w.iter().map(|&x| T::of_f64(x)).collect()
        }
    })
}

/// A-weighting (IEC 61672) as a linear amplitude gain at `f` Hz: 10^(A(f)/20) with
/// A(f) = 20·log10(R_A(f)) + 2.00 dB.
pub fn a_weighting_gain(f: f64) -> f64 {
    let f2 = f * f;
    let ra = 12194.0f64.powi(2) * f2 * f2
        / ((f2 + 20.6f64.powi(2))
            * ((f2 + 107.7f64.powi(2)) * (f2 + 737.9f64.powi(2))).sqrt()
            * (f2 + 12194.0f64.powi(2)));
    if ra <= 0.0 {
        return 0.0;
    }
    10f64.powf((20.0 * ra.log10() + 2.0) / 20.0)
}

#[cfg(test)]
mod tests;
