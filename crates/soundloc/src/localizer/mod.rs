//! The public face: a [`LocalizerSpec`] (plain, serde, every option) becomes a stateful
//! [`Localizer`] that streams. The CLI, the Python binding and the server only translate
//! their inputs into a spec; every rule lives here:
//!
//! - the algorithm: `sevd`, or the textbook `gevd` when a noise source or an online update
//!   is given and no algorithm is named (README "Which algorithm in noise");
//! - the array: a HARK transfer-function file, or free-field transfer functions from
//!   microphone positions and a grid; TF_CHANNEL_SELECTION, and the input channel map;
//! - the noise: a noise recording, a time range of the input, a HARK noise-CM file, or
//!   none (identity), mapped through the same channels; SEVD ignores K;
//! - the precision (f32 or f64), dispatched here once; the device.
//!
//! ```no_run
//! use soundloc::{Block, Localizer, LocalizerSpec, Output};
//! let mut loc = Localizer::new(&LocalizerSpec::from_tf("tamago_rectf.zip"))?;
//! let mut out = Output::default();
//! let block = vec![0.0f32; 8 * 1600]; // 100 ms of 8 interleaved channels
//! loc.push(Block::Interleaved { data: &block, channels: 8 }, &mut out)?;
//! loc.flush(&mut out)?;
//! # Ok::<(), soundloc::Error>(())
//! ```

use crate::array::freefield::{free_field, DEFAULT_SPEED_OF_SOUND_M_S};
use crate::array::grid::GridSpec;
use crate::array::tf_cache::TfCache;
use crate::array::{Geometry, Grid, TransferFunctions};
use crate::backend::{DeviceChoice, StageTimes};
use crate::config::{Algorithm, LocalizeConfig, Precision};
use crate::engine::{Engine, Localization, Output, TrackingSpec};
use crate::input::{Block, ChannelMap, RawMapping};
use crate::noise::policy::NoiseUpdate;
use crate::noise::NoiseMatrices;
use crate::{Error, Result};
use prepare::{engine, prepare};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Run `$e` on `$self.inner` whatever its precision: the `Inner` enum (F32 | F64) of the
/// module that calls it (an engine here, a stream group in `group.rs`).
macro_rules! dispatch {
    (mut $self:expr, $e:ident => $body:expr) => {
        match &mut $self.inner {
            Inner::F32($e) => $body,
            Inner::F64($e) => $body,
        }
    };
    ($self:expr, $e:ident => $body:expr) => {
        match &$self.inner {
            Inner::F32($e) => $body,
            Inner::F64($e) => $body,
        }
    };
}

mod defaults;
mod group;
mod prepare;
pub use defaults::{robust_subspace_dim, room_subspace_dim};
pub use group::LocalizerGroup;

/// Where the microphone positions and steering vectors come from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind", deny_unknown_fields)]
pub enum ArraySpec {
    /// A HARK transfer-function zip (harktool) or an old HGTF file (`*_loc.dat`).
    TransferFunctions {
        /// The file.
        path: PathBuf,
    },
    /// Free-field transfer functions (HARK's geometric convention) for microphone
    /// positions and a direction grid.
    FreeField {
        /// Microphone positions in metres, in channel order.
        mics: Vec<[f64; 3]>,
        /// The direction grid.
        grid: GridSpec,
        /// Distance of the grid points, metres.
        radius_m: f64,
        /// Speed of sound, m/s.
        speed_of_sound_m_s: f64,
    },
}

impl ArraySpec {
    /// The frame sizes (FFT length N, hop in samples) an analysis uses when none are given,
    /// for audio at `sample_rate_hz`:
    /// - free-field TFs: HARK's durations at that rate
    ///   ([`crate::config::frame_sizes_for_rate`]: 512 and 160 at 16 kHz, 1536 and 480 at
    ///   48 kHz);
    /// - a TF zip: the FFT length it was made for, with HARK's hop of 160/512 of it (512
    ///   and 160; 1536 and 480), so that a 48 kHz harktool zip needs no `--fft-length`;
    /// - otherwise (an old HGTF file, or a zip whose settings cannot be read: loading it
    ///   says why): HARK's 512 and 160.
    pub fn default_frame_sizes(&self, sample_rate_hz: u32) -> (usize, usize) {
        let hark = LocalizeConfig::default();
        match self {
            ArraySpec::FreeField { .. } => crate::config::frame_sizes_for_rate(sample_rate_hz),
            ArraySpec::TransferFunctions { path } if crate::formats::hark_zip::file_looks_like_zip(path) => {
                match crate::formats::tf_zip_read::read_tf_zip_config(path) {
                    Ok(c) if c.nfft >= 4 => {
                        let hop = ((c.nfft * hark.hop) as f64 / hark.nfft as f64).round() as usize;
                        (c.nfft, hop.max(1))
                    }
                    _ => (hark.nfft, hark.hop),
                }
            }
            ArraySpec::TransferFunctions { .. } => (hark.nfft, hark.hop),
        }
    }
}

/// Where the noise correlation matrix K comes from.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind", deny_unknown_fields)]
pub enum NoiseSource {
    /// None: K = identity.
    #[default]
    None,
    /// A noise-only recording (WAV/FLAC), mapped through the same channels as the input.
    Recording {
        /// The file.
        path: PathBuf,
    },
    /// A time range of the input itself, seconds (results wait until it has arrived).
    Range {
        /// Start, seconds.
        start_s: f64,
        /// End, seconds.
        end_s: f64,
    },
    /// A HARK noise correlation file (CMSave text pair or zip).
    CorrelationFile {
        /// The file (the real part's file of a text pair).
        path: PathBuf,
    },
}

/// Everything a localization needs, as plain data (see the [module docs](self)).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LocalizerSpec {
    /// The array.
    pub array: ArraySpec,
    /// MUSIC_ALGORITHM; None = the defaults of [`LocalizerSpec::resolved_analysis`]: the room
    /// default (NormMUSIC) without a noise source, the robust GEVD with one.
    #[serde(default)]
    pub algorithm: Option<Algorithm>,
    /// The analysis parameters (HARK LocalizeMUSIC's); its `algorithm` is replaced by the
    /// resolved one and its `sample_rate_hz` by a transfer-function file's.
    #[serde(default)]
    pub analysis: LocalizeConfig,
    /// TF_CHANNEL_SELECTION (empty = all).
    #[serde(default)]
    pub channels: Vec<usize>,
    /// ChannelSelector: input channels kept first (empty = all).
    #[serde(default)]
    pub input_channels: Vec<usize>,
    /// The capture device's channel layout from the array file (an ODAS configuration's
    /// mapping), used when `input_channels` is empty ([`RawMapping`]).
    #[serde(default)]
    pub raw_mapping: Option<RawMapping>,
    /// Input channels (0-based, as the input checks name them) whose samples are negated:
    /// microphones wired with their polarity inverted. Applied to the input and to a
    /// noise recording; a noise-CM file is taken as it is.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub invert_channels: Vec<usize>,
    /// The noise matrix K.
    #[serde(default)]
    pub noise: NoiseSource,
    /// Online K updates (iGEVD / iGSVD).
    #[serde(default)]
    pub noise_update: NoiseUpdate,
    /// Tracking with ids (None = off).
    #[serde(default)]
    pub tracking: Option<TrackingSpec>,
    /// Compute precision.
    #[serde(default)]
    pub precision: Precision,
    /// Compute device.
    #[serde(default)]
    pub device: DeviceChoice,
    /// Produce the spectrum rows (for `.npy`, plots, live views).
    #[serde(default)]
    pub spectrum: bool,
    /// Where prepared transfer functions (the used bins of a TF zip) are cached.
    #[serde(default)]
    pub tf_cache: TfCache,
    /// Audio at another sampling rate than the analysis's (a 48 kHz sound card, a 16 kHz
    /// TF file) is converted ([`crate::audio::resample`]) instead of refused: the noise
    /// recording here, the input through [`Localizer::input_converter`].
    #[serde(default)]
    pub resample: bool,
    /// Coherence normalisation ([`LocalizeConfig::coherence`]): None = the default's choice
    /// (on in the room default, i.e. no algorithm named and no noise source; else
    /// `analysis.coherence`); Some(v) = v whatever the algorithm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coherence: Option<bool>,
    /// Sub-grid refinement ([`LocalizeConfig::refine`]): None = the default's choice (on
    /// when no algorithm is named; else `analysis.refine`); Some(v) = v whatever the
    /// algorithm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refine: Option<bool>,
    /// Per-bin normalisation ([`LocalizeConfig::normalize_bins`]): None = the default's
    /// choice (on in the room default, NormMUSIC; else `analysis.normalize_bins`);
    /// Some(v) = v whatever the algorithm (off in the room default: the powers of its
    /// SEVD, not NormMUSIC's bounded scale; HARK's scale needs the algorithm named).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normalize_bins: Option<bool>,
    /// The textbook GEVD's spectrum numerator ([`crate::config::Numerator`]): None = the
    /// default's choice (geometric in the robust default; else `analysis.numerator`);
    /// Some(n) = n (refused by the algorithms other than the textbook GEVD).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub numerator: Option<crate::config::Numerator>,
    /// Onset weighting ([`LocalizeConfig::onset_frames`]): None = the default's choice
    /// ([`ONSET_FRAMES`] when no algorithm is named and the noise matrix does not come
    /// from the frames before each window, else `analysis.onset_frames`); Some(n) = n,
    /// 0 = off.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub onset_frames: Option<usize>,
}

/// The defaults' onset-weighting memory in frames (0.1 s at HARK's 10 ms hop;
/// docs/accuracy.md, "Onset weighting").
pub const ONSET_FRAMES: usize = 10;

impl LocalizerSpec {
    /// Defaults with a transfer-function file.
    pub fn from_tf(path: impl Into<PathBuf>) -> Self {
        Self::with_array(ArraySpec::TransferFunctions { path: path.into() })
    }

    /// Defaults with free-field transfer functions for `mics` and `grid` (1 m, 343 m/s).
    pub fn free_field(mics: Vec<[f64; 3]>, grid: GridSpec) -> Self {
        Self::with_array(ArraySpec::FreeField {
            mics,
            grid,
            radius_m: 1.0,
            speed_of_sound_m_s: DEFAULT_SPEED_OF_SOUND_M_S,
        })
    }

    /// Which input channel feeds each microphone, for transfer functions of `tf_mics`
    /// microphones (before `channels` selects some): the input channels, the device
    /// layout and the TF channel selection of this spec, checked.
    pub fn channel_map(&self, tf_mics: usize) -> Result<ChannelMap> {
        if let Some(r) = &self.raw_mapping {
            r.validate(tf_mics)?;
        }
        Ok(ChannelMap {
            input_channels: self.input_channels.clone(),
            tf_channels: self.channels.clone(),
            full_mics: tf_mics,
            mics: if self.channels.is_empty() {
                tf_mics
            } else {
                self.channels.len()
            },
            raw: self.raw_mapping.clone(),
            inverted: self.invert_channels.clone(),
        })
    }

    /// Defaults with an array.
    pub fn with_array(array: ArraySpec) -> Self {
        LocalizerSpec {
            array,
            algorithm: None,
            analysis: LocalizeConfig::default(),
            channels: Vec::new(),
            input_channels: Vec::new(),
            raw_mapping: None,
            invert_channels: Vec::new(),
            noise: NoiseSource::None,
            noise_update: NoiseUpdate::Fixed,
            tracking: None,
            precision: Precision::F32,
            device: DeviceChoice::Auto,
            spectrum: false,
            tf_cache: TfCache::Default,
            resample: false,
            coherence: None,
            refine: None,
            normalize_bins: None,
            numerator: None,
            onset_frames: None,
        }
    }

    /// Load the transfer functions of the array for an analysis config: only the bins it
    /// uses (all bins when the file does not fit the config, so the plan says why).
    pub fn load_array(&self, config: &LocalizeConfig) -> Result<TransferFunctions> {
        Ok(self.load_array_noted(config)?.0)
    }

    /// [`LocalizerSpec::load_array`], with a note for the user: what the TF cache did,
    /// that the directions are seen from the microphones' centroid
    /// ([`Geometry::direction_frame`]), that a free-field grid's radius puts its points
    /// inside the array, or that the positions look like millimetres or centimetres.
    pub fn load_array_noted(&self, config: &LocalizeConfig) -> Result<(TransferFunctions, Option<String>)> {
        let used = config.bin_range();
        let note;
        let tf = match &self.array {
            ArraySpec::TransferFunctions { path } => {
                // Resampling runs the analysis at the file's rate, whatever the input's:
                // the bins to read are those of that rate (read from the zip's small
                // entries first).
                let mut config = config.clone();
                if self.resample && crate::formats::hark_zip::file_looks_like_zip(path) {
                    let c = crate::formats::tf_zip_read::read_tf_zip_config(path)?;
                    if c.nfft == config.nfft {
                        config.sample_rate_hz = c.sampling_rate_hz;
                    }
                }
                let used = config.bin_range();
                let (tf, outcome) = TransferFunctions::load_cached(
                    path,
                    Some((config.nfft, config.sample_rate_hz, used)),
                    &self.tf_cache,
                )?;
                return Ok((tf, outcome.note()));
            }
            ArraySpec::FreeField {
                mics,
                grid,
                radius_m,
                speed_of_sound_m_s,
            } => {
                grid.validate()?;
                // Before the TFs of every bin are built: a rate of GHz (a typo) would
                // make gigabytes of them, then fail at the STFT.
                if config.nfft > crate::stft::MAX_NFFT {
                    return Err(Error::Config(format!(
                        "the frame of {} samples at {} Hz exceeds the largest supported FFT length, {} \
                         (check the sample rate; or give --fft-length, nfft= in Python)",
                        config.nfft,
                        config.sample_rate_hz,
                        crate::stft::MAX_NFFT
                    )));
                }
                if !(radius_m.is_finite() && *radius_m > 0.0) {
                    return Err(Error::Config(format!(
                        "grid radius must be positive, got {radius_m} m"
                    )));
                }
                let (geometry, moved) = Geometry::new(mics.clone(), Path::new("microphone positions"))?
                    .direction_frame(*radius_m);
                let parts: Vec<String> = moved
                    .into_iter()
                    .chain(crate::array::freefield::free_field_notes(
                        &geometry,
                        *radius_m,
                        *speed_of_sound_m_s,
                    ))
                    .collect();
                note = (!parts.is_empty()).then(|| parts.join("; "));
                free_field(
                    &geometry,
                    &grid.build(*radius_m),
                    config.nfft,
                    config.sample_rate_hz,
                    if used.is_empty() {
                        0..config.nfft / 2 + 1
                    } else {
                        used
                    },
                    *speed_of_sound_m_s,
                )
            }
        }?;
        Ok((tf, note))
    }
}

enum Inner {
    F32(Engine<f32>),
    F64(Engine<f64>),
}

/// A stateful localizer for one array (see the [module docs](self) and
/// [`crate::engine`] for the streaming contract).
pub struct Localizer {
    inner: Inner,
    config: LocalizeConfig,
    grid: Grid,
    notes: Vec<String>,
    resample: bool,
}

impl Localizer {
    /// Build from a spec: loads the files it names, plans, picks the device.
    pub fn new(spec: &LocalizerSpec) -> Result<Self> {
        let (algorithm, _) = spec.resolved_algorithm();
        let config = LocalizeConfig {
            algorithm,
            ..spec.analysis.clone()
        };
        // The GPU's driver and context come up while the transfer functions load.
        // The guard (dropped on return, error or not) waits for it and gives its context
        // references back; a CUDA backend holds its own by then.
        let _warm = crate::engine::device::prewarm(spec.device, config.subspace_tracking);
        let (tf, note) = spec.load_array_noted(&config)?;
        tracing::debug!(
            "transfer functions ready: {} mics, {} directions{}",
            tf.num_mics,
            tf.grid.len(),
            note.as_deref().map(|n| format!(" ({n})")).unwrap_or_default()
        );
        let mut loc =
            Self::with_transfer_functions(spec, tf, None).map_err(|e| prepare::name_tf_file(spec, e))?;
        loc.notes.splice(0..0, note);
        Ok(loc)
    }

    /// Build with transfer functions (all microphones, before `spec.channels`) already in
    /// memory, and optionally K (`noise`, replacing `spec.noise`); `spec.array` is not
    /// read.
    pub fn with_transfer_functions(
        spec: &LocalizerSpec,
        tf: TransferFunctions,
        noise: Option<NoiseMatrices>,
    ) -> Result<Self> {
        let p = prepare(spec, tf, noise)?;
        let grid = p.tf.grid.clone();
        let inner = match spec.precision {
            Precision::F32 => Inner::F32(engine::<f32>(
                &p.config,
                &p.tf,
                spec,
                p.options,
                p.noise_file.as_deref(),
            )?),
            Precision::F64 => Inner::F64(engine::<f64>(
                &p.config,
                &p.tf,
                spec,
                p.options,
                p.noise_file.as_deref(),
            )?),
        };
        Ok(Localizer {
            inner,
            config: p.config,
            grid,
            notes: p.notes,
            resample: spec.resample,
        })
    }

    /// Notes from building (the algorithm chosen, K ignored…).
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// Put `note` ahead of the notes from building: what a caller that read the array
    /// itself (a binding's arrays) has to say about it.
    pub fn prepend_note(&mut self, note: String) {
        self.notes.insert(0, note);
    }

    /// The resolved analysis parameters (algorithm, sample rate).
    pub fn config(&self) -> &LocalizeConfig {
        &self.config
    }

    /// The direction grid (columns of the spectrum, `grid_index` of sources).
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// Microphones (channels after the channel map).
    pub fn num_mics(&self) -> usize {
        dispatch!(self, e => e.plan().num_mics)
    }

    /// The device description.
    pub fn device_name(&self) -> String {
        dispatch!(self, e => e.device_name())
    }

    /// Stage times since the start (or the last reset).
    pub fn stage_times(&self) -> StageTimes {
        dispatch!(self, e => e.stage_times())
    }

    /// See [`Engine::check_input`].
    pub fn check_input(&self, sample_rate_hz: u32, channels: usize) -> Result<()> {
        dispatch!(self, e => e.check_input(sample_rate_hz, channels))
    }

    /// How audio of `sample_rate_hz` and `channels` reaches this localizer: `None` when it
    /// can be pushed as it is, a converter to the analysis rate when the rates differ and
    /// the spec allows resampling, otherwise the error of [`Localizer::check_input`]
    /// (which names both rates and the `resample` option).
    pub fn input_converter(
        &self,
        sample_rate_hz: u32,
        channels: usize,
    ) -> Result<Option<crate::audio::resample::Resampler>> {
        let fs = self.config.sample_rate_hz;
        if sample_rate_hz == fs || !self.resample {
            self.check_input(sample_rate_hz, channels)?;
            return Ok(None);
        }
        self.check_input(fs, channels)?;
        crate::audio::resample::Resampler::new(sample_rate_hz, fs, channels).map(Some)
    }

    /// See [`Engine::push`].
    pub fn push(&mut self, block: Block<'_>, out: &mut Output) -> Result<()> {
        dispatch!(mut self, e => e.push(block, out))
    }

    /// [`Localizer::push`]'s checks of `block` (an open stream, the channel count, finite
    /// samples within range), which change nothing: a caller that pushes a block in
    /// pieces checks it whole first, so a bad sample late in it leaves the stream as it
    /// was, as one push would.
    pub fn check_block(&self, block: &Block<'_>) -> Result<()> {
        dispatch!(self, e => e.check(block).map(|_| ()))
    }

    /// See [`Engine::flush`].
    pub fn flush(&mut self, out: &mut Output) -> Result<()> {
        dispatch!(mut self, e => e.flush(out))
    }

    /// See [`Engine::reset`].
    pub fn reset(&mut self) -> Result<()> {
        dispatch!(mut self, e => e.reset())
    }

    /// See [`Engine::skip`].
    pub fn skip(&mut self, samples: u64, out: &mut Output) -> Result<()> {
        dispatch!(mut self, e => e.skip(samples, out))
    }

    /// See [`Engine::pause`].
    pub fn pause(&mut self, samples: u64, out: &mut Output) -> Result<()> {
        dispatch!(mut self, e => e.pause(samples, out))
    }

    /// See [`Engine::set_noise`].
    pub fn set_noise(&mut self, noise: &NoiseMatrices) -> Result<()> {
        dispatch!(mut self, e => e.set_noise(noise))
    }

    /// See [`Engine::latency_frames`].
    pub fn latency_frames(&self) -> usize {
        dispatch!(self, e => e.latency_frames())
    }

    /// See [`Engine::preroll_hold_frames`].
    pub fn preroll_hold_frames(&self) -> usize {
        dispatch!(self, e => e.preroll_hold_frames())
    }

    /// See [`Engine::samples_needed_next`].
    pub fn samples_needed_next(&self) -> usize {
        dispatch!(self, e => e.samples_needed_next())
    }

    /// See [`Engine::samples_received`].
    pub fn samples_received(&self) -> usize {
        dispatch!(self, e => e.samples_received())
    }

    /// Batch: push planar channels whole, then flush.
    pub fn localize(&mut self, channels: &[Vec<f32>]) -> Result<Localization> {
        dispatch!(mut self, e => e.localize(channels))
    }
}

#[cfg(test)]
mod tests;
