//! The options `localize`, `listen` and `batch` share (array, analysis, noise, tracking,
//! outputs, device) and their translation into the library's [`LocalizerSpec`].

use super::sinks::LiveArgs;
use super::FormatArg;
use super::{
    AlgorithmArg, DenominatorArg, DeviceArg, NumeratorArg, PrecisionArg, SpectrumWeightArg, WindowFnArg,
    WindowTypeArg,
};
use anyhow::{anyhow, bail, Context};
use soundloc::array::freefield::DEFAULT_SPEED_OF_SOUND_M_S;
use soundloc::array::grid::GridSpec;
use soundloc::array::tf_cache::TfCache;
use soundloc::array::Geometry;
use soundloc::config::{Denominator, SpectrumWeight};
use soundloc::tracking::TrackerConfig;
use soundloc::{
    Algorithm, ArraySpec, LocalizeConfig, LocalizerSpec, NoiseSource, NoiseUpdate, TrackingSpec,
    WindowFunction, WindowType,
};
use std::path::PathBuf;

/// Analysis options shared by `localize` (HARK LocalizeMUSIC parameter names in brackets).
#[derive(clap::Args, Debug, Clone)]
pub struct AnalysisArgs {
    /// MUSIC_ALGORITHM. Unnamed: the room default without a noise source (sevd as
    /// NormMUSIC, subspace min(M/2, round(2√M)), refined), the robust gevd with one
    /// (subspace max(num-sources, M/2), refined). Named: exactly HARK's. Any case (HARK
    /// writes SEVD, GEVD, GSVD). NormMUSIC is sevd with --normalize-bins.
    #[arg(long, value_enum, ignore_case = true)]
    pub algorithm: Option<AlgorithmArg>,
    /// NUM_SOURCE: the number of sources (peaks reported and, in HARK, the signal subspace
    /// dimension; < number of mics).
    #[arg(long, default_value_t = 2)]
    pub num_sources: usize,
    /// MAXNUM_OUT_PEAKS: -1 = NUM_SOURCE, 0 = all peaks.
    #[arg(long, default_value_t = -1, allow_hyphen_values = true)]
    pub max_peaks: i64,
    /// WINDOW: frames per correlation matrix.
    #[arg(long, default_value_t = 50)]
    pub window: usize,
    /// WINDOW_TYPE.
    #[arg(long, value_enum, default_value = "future")]
    pub window_type: WindowTypeArg,
    /// PERIOD: one result every PERIOD frames.
    #[arg(long, default_value_t = 50)]
    pub period: usize,
    /// MIN_DEG: azimuth range kept, degrees. As HARK: an azimuth is wrapped into
    /// (MIN_DEG, MIN_DEG + 360] first, so MIN_DEG itself is left out (with -180 to -170,
    /// a peak at 180° = -180° is not kept; give -180.01).
    #[arg(long, default_value_t = -180.0, allow_hyphen_values = true)]
    pub min_deg: f64,
    /// MAX_DEG: azimuth range kept, degrees.
    #[arg(long, default_value_t = 180.0, allow_hyphen_values = true)]
    pub max_deg: f64,
    /// LOWER_BOUND_FREQUENCY, Hz.
    #[arg(long, default_value_t = 500.0)]
    pub lower_freq: f64,
    /// UPPER_BOUND_FREQUENCY, Hz (exclusive bin).
    #[arg(long, default_value_t = 2800.0)]
    pub upper_freq: f64,
    /// LENGTH: FFT length in samples [default: with --tf the zip's (512 for HARK's 16 kHz
    /// zips, 1536 for a tf make zip at 48 kHz; 512 for HGTF files); with --geometry 32 ms of the input's rate
    /// (512 at 16 kHz, 1536 at 48 kHz)].
    #[arg(long)]
    pub fft_length: Option<usize>,
    /// ADVANCE: hop in samples [default: with --tf nfft × 160/512 (HARK's 160 for 512);
    /// with --geometry 10 ms of the input's rate (160 at 16 kHz, 480 at 48 kHz)].
    #[arg(long)]
    pub hop: Option<usize>,
    /// STFT window function (MultiFFT WINDOW).
    #[arg(long, value_enum, default_value = "conj")]
    pub window_function: WindowFnArg,
    /// ENABLE_EIGENVALUE_WEIGHT.
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub eigenvalue_weight: bool,
    /// SPECTRUM_WEIGHT_TYPE.
    #[arg(long, value_enum, default_value = "uniform")]
    pub spectrum_weight: SpectrumWeightArg,
    /// Manual spectrum weights, one per used bin, comma-separated (overrides --spectrum-weight).
    #[arg(long, value_delimiter = ',')]
    pub spectrum_weights: Vec<f64>,
    /// MUSIC denominator.
    #[arg(long, value_enum, default_value = "squared")]
    pub denominator: DenominatorArg,
    /// Diagonal loading of K, relative to its mean diagonal (0 = none).
    #[arg(long, default_value_t = 0.0)]
    pub diagonal_loading: f64,
    /// Signal-subspace dimension of the decomposition when it should differ from
    /// --num-sources (reverberant rooms and large arrays need more than the talkers);
    /// default: --num-sources, as HARK, when an algorithm is named; unnamed,
    /// min(M/2, round(2√M)) in the room default and max(--num-sources, M/2) in the
    /// robust default.
    #[arg(long)]
    pub subspace_dim: Option<usize>,
    /// Per-bin normalisation (NormMUSIC): every bin's spectrum is scaled to a maximum of
    /// 1 before the bins are summed, so loud bins do not outvote the rest.
    /// Default: on in the room default (NormMUSIC), off otherwise.
    #[arg(long, overrides_with = "no_normalize_bins")]
    pub normalize_bins: bool,
    /// No per-bin normalisation, also in the room default (the powers of its SEVD, not
    /// NormMUSIC's bounded scale; for HARK's scale name --algorithm sevd).
    #[arg(long, overrides_with = "normalize_bins")]
    pub no_normalize_bins: bool,
    /// Sub-grid refinement: report each peak at the maximum of a quadratic fitted to the
    /// spectrum around it, not at the grid point. Default: on when no algorithm is named.
    #[arg(long, overrides_with = "no_refine")]
    pub refine: bool,
    /// No sub-grid refinement, also in the defaults (peaks at grid points).
    #[arg(long, overrides_with = "refine")]
    pub no_refine: bool,
    /// Coherence normalisation: the channels' gains come from the recording, not the TFs,
    /// so the microphones' gain mismatch cancels. SEVD: each window's R scaled to a unit
    /// diagonal, R_ij/√(R_ii R_jj), steering vectors reduced to their phases; textbook GEVD:
    /// the steering phases take K's channel levels as magnitudes (not for HARK's gsvd and
    /// gevd-hark). Default: on in the room default (no algorithm named, no noise source),
    /// off otherwise. With a noise source, turn it on for an uncalibrated array with
    /// geometric TFs (it costs anechoic accuracy on an array that matches its TFs).
    #[arg(long, overrides_with = "no_coherence")]
    pub coherence: bool,
    /// No coherence normalisation, also in the room default.
    #[arg(long, overrides_with = "coherence")]
    pub no_coherence: bool,
    /// The textbook GEVD's spectrum numerator: raw ‖a‖² (HARK-style spec §5; a loud noise
    /// source that K holds then shows as a peak at its own strength), whitened ‖a_w‖² =
    /// aᴴK⁻¹a (flattens it), or geometric ‖a‖·‖a_w‖. Default: geometric in the robust
    /// default (a noise source, no algorithm named), raw with --algorithm gevd.
    #[arg(long, value_enum)]
    pub numerator: Option<NumeratorArg>,
    /// Onset weighting: each frame of each bin enters the correlation with the weight
    /// ((r − 1)/r)² for r > 1, else 0, where r is how much louder the frame is than its
    /// average over about FRAMES frames before it: the whitened power xᴴK⁻¹x for gevd,
    /// gevd-hark and gsvd, else the mean over the microphones of each one's power against
    /// its own average (a channel's gain cancels). A talker's onsets count and the
    /// reverberation after them does not. 0 = off (HARK).
    /// Default: 10 when no algorithm is named (not with --noise-preceding), else 0.
    /// Not for srp-phat.
    #[arg(long, value_name = "FRAMES")]
    pub onset: Option<usize>,
    /// Approximate streaming mode (CPU): leading vectors tracked between windows, residual-
    /// checked; for large arrays at small --period and --num-sources; no source count.
    #[arg(long)]
    pub subspace_tracking: bool,
}

/// Everything but the input: array, analysis, noise, tracking, outputs, device (shared by
/// `localize`, `listen` and `batch`).
#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// HARK transfer-function zip or old HGTF (*_loc.dat).
    #[arg(long, conflicts_with = "geometry")]
    pub tf: Option<PathBuf>,
    /// Microphone positions for free-field transfer functions: TOML (metres), or an ODAS
    /// configuration (*.cfg), whose mapping.map also picks the microphones among the
    /// device's raw.nChannels channels.
    #[arg(long)]
    pub geometry: Option<PathBuf>,
    /// Direction grid for --geometry: ring:STEP_DEG[:ELEV_DEG], sphere:N or hemisphere:N (the N directions above the horizontal plane, for planar arrays lying flat; with --tf the
    /// directions are the TF file's: an error).
    #[arg(long, default_value = "ring:5", conflicts_with = "tf")]
    pub grid: String,
    /// Distance of the grid points for --geometry (m), from the origin of the positions'
    /// frame (from the microphones' centroid when that origin lies outside the array).
    #[arg(long, default_value_t = 1.0, conflicts_with = "tf")]
    pub grid_radius: f64,
    /// Speed of sound for --geometry (m/s).
    #[arg(long, default_value_t = DEFAULT_SPEED_OF_SOUND_M_S, conflicts_with = "tf")]
    pub speed_of_sound: f64,
    /// Convert audio (the input and --noise) at another sampling rate than the transfer
    /// functions' to theirs (band-limited, no delay added), e.g. a 48 kHz sound card with a
    /// 16 kHz TF file; without it a different rate is an error. With --geometry (whose
    /// transfer functions are made at the input's rate) it converts a --noise recording.
    #[arg(long)]
    pub resample: bool,
    /// TF_CHANNEL_SELECTION: TF channels to use, comma-separated (0-based). Applied to the
    /// audio, a --noise recording and a --noise-cm file too when they have the TF's full
    /// channel count.
    #[arg(long, value_delimiter = ',')]
    pub channels: Vec<usize>,
    /// ChannelSelector: input channels to keep, comma-separated (0-based), applied to the
    /// recording and to --noise before anything else (e.g. drop a reference channel).
    #[arg(long, value_delimiter = ',')]
    pub input_channels: Vec<usize>,
    /// Input channels to negate, comma-separated (0-based, as the input checks name them):
    /// microphones wired with their polarity inverted. Applied to the recording and to
    /// --noise; a --noise-cm file is taken as it is.
    #[arg(long, value_delimiter = ',')]
    pub invert_channels: Vec<usize>,
    /// Noise-only recording for K.
    #[arg(long, conflicts_with_all = ["noise_range", "noise_cm"])]
    pub noise: Option<PathBuf>,
    /// Noise-only time range of the input for K, START:END in seconds.
    #[arg(long, conflicts_with = "noise_cm")]
    pub noise_range: Option<String>,
    /// Noise correlation matrix file (HARK text pair or zip).
    #[arg(long)]
    pub noise_cm: Option<PathBuf>,
    /// iGSVD/iGEVD: update K online from these noise-only segments of the input,
    /// START:END[,START:END...] seconds (each used once its frames are complete).
    #[arg(long, conflicts_with = "noise_preceding")]
    pub noise_segments: Option<String>,
    /// iGSVD/iGEVD: update K before each window from the FRAMES frames ending GAP frames
    /// before it (HARK's delayed correlation maker), FRAMES[:GAP].
    #[arg(long)]
    pub noise_preceding: Option<String>,
    #[command(flatten)]
    pub analysis: AnalysisArgs,
    /// Output format.
    #[arg(long, value_enum, default_value = "jsonl")]
    pub format: FormatArg,
    /// Write results here instead of stdout (`-o -`: stdout).
    #[arg(long, short = 'o')]
    pub output: Option<PathBuf>,
    /// Write the dB spectrum [result][direction] as .npy (plus FILE.json next to it, e.g. spec.npy.json, with times and directions).
    #[arg(long)]
    pub spectrum: Option<PathBuf>,
    /// Write a plot of the spectrum over time × azimuth (.png or .svg) at the end; what it
    /// draws is kept in bounded memory until then (15–45 MB by the grid: past 4 096–16 384
    /// results, neighbouring ones merge by their maximum, finer than the picture's pixels).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Track sources (HARK SourceTracker) and add ids.
    #[arg(long)]
    pub track: bool,
    /// SourceTracker THRESH (dB): peaks below are ignored.
    #[arg(long, requires = "track", default_value_t = 0.0, allow_hyphen_values = true)]
    pub thresh: f64,
    /// SourceTracker PAUSE_LENGTH, in tenths of an STFT frame as HARK's: a source without
    /// peaks is kept for PAUSE_LENGTH/10 frames (800: 80 frames, 0.8 s at hop 160 and
    /// 16 kHz), whatever --period.
    #[arg(long, requires = "track", default_value_t = 800.0)]
    pub pause_length: f64,
    /// SourceTracker MIN_SRC_INTERVAL (degrees).
    #[arg(long, requires = "track", default_value_t = 20.0)]
    pub min_src_interval: f64,
    /// SourceTracker MIN_ID.
    #[arg(long, requires = "track", default_value_t = 0)]
    pub min_id: i64,
    /// SourceIntervalExtender PREROLL_LENGTH (frames); 0 = off.
    #[arg(long, requires = "track", default_value_t = 0)]
    pub preroll: usize,
    /// Not in HARK: a new source gets its id only after it has been seen over this many
    /// STFT frames (tentative until then, each sighting within MIN_SRC_INTERVAL of the last
    /// and at most this many frames after it, or at the next result when --period is
    /// longer: then 1 … PERIOD all mean two consecutive results), so a peak of a few windows (a reflection, a
    /// noise burst) starts no track; 0 = at once, as HARK. Default: the window length
    /// (--window) when no --algorithm is named, 0 with a named algorithm.
    #[arg(long, value_name = "FRAMES", requires = "track")]
    pub confirm: Option<usize>,
    /// Each window feeds the tracker only its strongest num_active peaks (the source
    /// count's estimate): silence (num_active 0) starts no tracks, and one talker's second
    /// peak starts none either. Default: on in the room default (no algorithm, no noise
    /// source), whose powers do not tell silence or sidelobes from talkers; off otherwise
    /// (HARK).
    #[arg(long, requires = "track", overrides_with = "no_active_only")]
    pub active_only: bool,
    /// Every window feeds the tracker all its peaks, as HARK's SourceTracker (also in the
    /// room default).
    #[arg(long, requires = "track", overrides_with = "active_only")]
    pub no_active_only: bool,
    /// With --track: write the per-source summary (JSON) here: per id the first and last
    /// results carrying it (start_s, end_s), first_seen_s (when the tracker first saw the
    /// source, before confirming it), mean direction, max power, result count.
    #[arg(long)]
    pub summary: Option<PathBuf>,
    /// Write a HARK source-location log (text, HARK <= 2.0).
    #[arg(long)]
    pub log_text: Option<PathBuf>,
    /// Write a HARK source-location log (XML, HARK >= 2.1).
    #[arg(long)]
    pub log_xml: Option<PathBuf>,
    /// Send results to a HarkDataStreamSender receiver at HOST:PORT (SRC_INFO packets;
    /// retried while absent, never blocking).
    #[arg(long)]
    pub hark_stream: Option<String>,
    #[command(flatten)]
    pub live: LiveArgs,
    /// Compute device: auto, cpu, cuda (GPU 0), cuda:all or cuda:N[,M...] (several GPUs
    /// share every batch of windows).
    #[arg(long, default_value = "auto")]
    pub device: DeviceArg,
    /// Compute precision.
    #[arg(long, value_enum, default_value = "f32")]
    pub precision: PrecisionArg,
    /// Use no cache: read the TF zip itself, not the prepared-TF cache (which holds the
    /// used bins of zips read before, keyed by content), and compile the GPU kernels
    /// afresh instead of loading the images kept from earlier runs.
    #[arg(long)]
    pub no_cache: bool,
    /// The cache folder for prepared TFs and compiled GPU kernels (default:
    /// $SOUNDLOC_CACHE_DIR, else $XDG_CACHE_HOME/soundloc, else ~/.cache/soundloc).
    #[arg(long, conflicts_with = "no_cache")]
    pub cache_dir: Option<PathBuf>,
    /// No progress bar or notes on stderr; warnings (lost audio, a silent input, a dead or
    /// inverted channel) are still printed.
    #[arg(long, short = 'q')]
    pub quiet: bool,
}

impl AnalysisArgs {
    /// The typed config (the algorithm resolved by the caller); frame sizes not given are
    /// the array's ([`soundloc::ArraySpec::default_frame_sizes`], asked only then: for a TF
    /// zip it reads the zip's settings).
    pub fn config(&self, algorithm: Algorithm, sample_rate_hz: u32, array: &ArraySpec) -> LocalizeConfig {
        let (nfft, hop) = match (self.fft_length, self.hop) {
            (Some(n), Some(h)) => (n, h),
            (n, h) => {
                let d = array.default_frame_sizes(sample_rate_hz);
                (n.unwrap_or(d.0), h.unwrap_or(d.1))
            }
        };
        LocalizeConfig {
            algorithm,
            nfft,
            hop,
            sample_rate_hz,
            window_function: match self.window_function {
                WindowFnArg::Conj => WindowFunction::Conj,
                WindowFnArg::Hamming => WindowFunction::Hamming,
                WindowFnArg::Hanning => WindowFunction::Hanning,
                WindowFnArg::Rectangle => WindowFunction::Rectangle,
            },
            window: self.window,
            window_type: match self.window_type {
                WindowTypeArg::Past => WindowType::Past,
                WindowTypeArg::Middle => WindowType::Middle,
                WindowTypeArg::Future => WindowType::Future,
            },
            period: self.period,
            num_sources: self.num_sources,
            subspace_dim: self.subspace_dim,
            max_peaks: self.max_peaks,
            min_deg: self.min_deg,
            max_deg: self.max_deg,
            lower_freq_hz: self.lower_freq,
            upper_freq_hz: self.upper_freq,
            spectrum_weight: if !self.spectrum_weights.is_empty() {
                SpectrumWeight::Manual(self.spectrum_weights.clone())
            } else {
                match self.spectrum_weight {
                    SpectrumWeightArg::Uniform => SpectrumWeight::Uniform,
                    SpectrumWeightArg::AWeighting => SpectrumWeight::AWeighting,
                }
            },
            eigenvalue_weight: self.eigenvalue_weight,
            denominator: match self.denominator {
                DenominatorArg::Squared => Denominator::Squared,
                DenominatorArg::Unsquared => Denominator::Unsquared,
            },
            diagonal_loading: self.diagonal_loading,
            normalize_bins: self.normalize_bins,
            refine: self.refine,
            // The spec's `coherence` and `numerator` carry the choices (None: the default's).
            coherence: false,
            numerator: Default::default(),
            subspace_tracking: self.subspace_tracking,
            // The spec's `onset_frames` carries the choice (None: the default's).
            onset_frames: 0,
        }
    }
}

/// The online noise-update rule from --noise-segments / --noise-preceding.
fn noise_update(a: &RunArgs) -> anyhow::Result<NoiseUpdate> {
    if let Some(s) = &a.noise_segments {
        let segs = s
            .split(',')
            .map(|r| parse_range_of("--noise-segments: segment", r))
            .collect::<anyhow::Result<Vec<_>>>()?;
        return Ok(NoiseUpdate::Segments(segs));
    }
    if let Some(s) = &a.noise_preceding {
        let (f, g) = s.split_once(':').unwrap_or((s, "0"));
        let bad = || format!("--noise-preceding {s:?}: expected FRAMES[:GAP]");
        let frames: usize = f.trim().parse().with_context(bad)?;
        let gap: usize = g.trim().parse().with_context(bad)?;
        if frames == 0 {
            bail!("--noise-preceding {s:?}: FRAMES must be at least 1");
        }
        return Ok(NoiseUpdate::Preceding { frames, gap });
    }
    Ok(NoiseUpdate::Fixed)
}

/// Parse `START:END` seconds (a noise range).
pub fn parse_range(s: &str) -> anyhow::Result<(f64, f64)> {
    parse_range_of("noise range", s)
}

/// Parse `START:END` seconds; errors name it as `what`.
pub fn parse_range_of(what: &str, s: &str) -> anyhow::Result<(f64, f64)> {
    let (a, b) = s
        .split_once(':')
        .ok_or_else(|| anyhow!("{what} {s:?}: expected START:END in seconds, e.g. 0:1.5"))?;
    let a: f64 = a
        .trim()
        .parse()
        .with_context(|| format!("{what} {s:?}: bad start"))?;
    let b: f64 = b
        .trim()
        .parse()
        .with_context(|| format!("{what} {s:?}: bad end"))?;
    if !(a >= 0.0 && b > a) {
        bail!("{what} {s:?}: need 0 <= START < END");
    }
    Ok((a, b))
}

impl RunArgs {
    /// The library spec these arguments describe, for an input sampled at `rate_hz`.
    pub fn spec(&self, rate_hz: u32) -> anyhow::Result<LocalizerSpec> {
        let mut raw_mapping = None;
        let array = match (&self.tf, &self.geometry) {
            (Some(p), _) => ArraySpec::TransferFunctions { path: p.clone() },
            (None, Some(g)) => ArraySpec::FreeField {
                mics: {
                    let (geometry, mapping) = Geometry::load_with_mapping(g)?;
                    raw_mapping = mapping;
                    geometry.mics
                },
                grid: self.grid.parse::<GridSpec>()?,
                radius_m: self.grid_radius,
                speed_of_sound_m_s: self.speed_of_sound,
            },
            (None, None) => bail!(
                "no transfer functions: give --tf FILE (HARK TF zip or *_loc.dat) or --geometry array.toml --grid ring:5"
            ),
        };
        if self.resample && self.geometry.is_some() && self.noise.is_none() {
            bail!(
                "--resample with --geometry converts only a --noise recording (free-field transfer functions \
                 are made at the input's rate), and none is given: drop --resample"
            );
        }
        let noise = if let Some(p) = &self.noise {
            NoiseSource::Recording { path: p.clone() }
        } else if let Some(r) = &self.noise_range {
            let (start_s, end_s) = parse_range(r)?;
            NoiseSource::Range { start_s, end_s }
        } else if let Some(p) = &self.noise_cm {
            NoiseSource::CorrelationFile { path: p.clone() }
        } else {
            NoiseSource::None
        };
        let tracking = if self.track {
            let tracker = TrackerConfig {
                thresh_db: self.thresh,
                pause_length: self.pause_length,
                min_src_interval_deg: self.min_src_interval,
                min_id: self.min_id,
                confirm_frames: self.confirm,
            };
            tracker.validate()?;
            Some(TrackingSpec {
                tracker,
                preroll: self.preroll,
                active_only: choice(self.active_only, self.no_active_only),
            })
        } else {
            if self.summary.is_some() {
                bail!("--summary needs --track");
            }
            None
        };
        Ok(LocalizerSpec {
            algorithm: self.analysis.algorithm.map(Into::into),
            analysis: self.analysis.config(Algorithm::Sevd, rate_hz, &array),
            array,
            channels: self.channels.clone(),
            input_channels: self.input_channels.clone(),
            invert_channels: self.invert_channels.clone(),
            raw_mapping,
            noise,
            noise_update: noise_update(self)?,
            tracking,
            precision: match self.precision {
                PrecisionArg::F32 => soundloc::Precision::F32,
                PrecisionArg::F64 => soundloc::Precision::F64,
            },
            device: self.device.into(),
            spectrum: self.spectrum.is_some() || self.plot.is_some() || self.live.serve.is_some(),
            tf_cache: match (&self.cache_dir, self.no_cache) {
                (_, true) => TfCache::Off,
                (Some(d), _) => TfCache::Dir(d.clone()),
                (None, false) => TfCache::Default,
            },
            resample: self.resample,
            // None: the default's choice.
            coherence: choice(self.analysis.coherence, self.analysis.no_coherence),
            refine: choice(self.analysis.refine, self.analysis.no_refine),
            normalize_bins: choice(self.analysis.normalize_bins, self.analysis.no_normalize_bins),
            numerator: self.analysis.numerator.map(Into::into),
            onset_frames: self.analysis.onset,
        })
    }
}

/// A `--X` / `--no-X` pair: Some(true), Some(false), or None (the default's choice).
fn choice(on: bool, off: bool) -> Option<bool> {
    match (on, off) {
        (true, _) => Some(true),
        (_, true) => Some(false),
        _ => None,
    }
}
