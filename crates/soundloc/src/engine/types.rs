//! What the stream engine takes and gives: stream options, outputs, spectrum rows.

use crate::backend::StageTimes;
use crate::input::ChannelMap;
use crate::noise::policy::{InitialNoise, NoiseUpdate};
use crate::result::LocalizationResult;
use crate::tracking::TrackerConfig;

/// The broadband spectrum of every result, dB, `[result][dir]`.
#[derive(Debug, Clone, PartialEq)]
pub struct SpectrumTable {
    /// Result frame c of each row.
    pub frames: Vec<usize>,
    /// Time of each row in seconds.
    pub times_s: Vec<f64>,
    /// Number of directions (columns).
    pub num_dirs: usize,
    /// 10·log10(P̄ + 1), `[result][dir]`.
    pub db: Vec<f32>,
    /// Number of used bins.
    pub num_bins: usize,
    /// g_k (eigenvalue weight, or 1) per result and used bin, `[result][bin]`.
    pub bin_weight: Vec<f32>,
}

impl SpectrumTable {
    pub(super) fn empty(num_dirs: usize, num_bins: usize) -> Self {
        SpectrumTable {
            frames: Vec::new(),
            times_s: Vec::new(),
            num_dirs,
            db: Vec::new(),
            num_bins,
            bin_weight: Vec::new(),
        }
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Whether the table has no rows.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Remove the first `n` rows (at most all) and return them as a table.
    pub(super) fn take_front(&mut self, n: usize) -> SpectrumTable {
        let n = n.min(self.len());
        SpectrumTable {
            frames: self.frames.drain(..n).collect(),
            times_s: self.times_s.drain(..n).collect(),
            num_dirs: self.num_dirs,
            db: self.db.drain(..n * self.num_dirs).collect(),
            num_bins: self.num_bins,
            bin_weight: self.bin_weight.drain(..n * self.num_bins).collect(),
        }
    }

    /// Append another table's rows.
    pub fn append(&mut self, other: SpectrumTable) {
        self.frames.extend(other.frames);
        self.times_s.extend(other.times_s);
        self.db.extend(other.db);
        self.bin_weight.extend(other.bin_weight);
    }
}

/// What `push` and `flush` append to: results in time order, spectrum rows (one per
/// window, in window order, when the engine was asked for spectra) and notes for the user
/// (a noise range cut at the end of the input, an unused segment).
#[derive(Debug, Clone, Default)]
#[non_exhaustive]
pub struct Output {
    /// Results, in increasing frame order.
    pub results: Vec<LocalizationResult>,
    /// Each window's own peaks before the tracker (ODAS's "potential sources", its SSL
    /// stream), in time order and as soon as the window ran — collected only where the
    /// caller asks by setting `Some` (as `spectrum`) and tracking is on; without tracking
    /// `results` are those peaks.
    pub peaks: Option<Vec<LocalizationResult>>,
    /// Spectrum rows, when asked for.
    pub spectrum: Option<SpectrumTable>,
    /// Things the user should know.
    pub notes: Vec<String>,
    /// With tracking, the ids given since the last output and when the tracker first saw
    /// each source (before confirming it): what [`crate::tracking::Summarizer::started`]
    /// takes. They come as the ids are given, ahead of `preroll`'s delayed results.
    pub track_starts: Vec<crate::tracking::TrackStart>,
}

impl Output {
    /// Take everything out, leaving it empty.
    pub fn take(&mut self) -> Output {
        std::mem::take(self)
    }
}

/// Everything one batch localization produces.
#[derive(Debug, Clone)]
pub struct Localization {
    /// One result per correlation window, in time order.
    pub results: Vec<LocalizationResult>,
    /// With tracking, every id given and when the tracker first saw its source
    /// ([`crate::tracking::summarize_with_starts`]).
    pub track_starts: Vec<crate::tracking::TrackStart>,
    /// The spectrum, when asked for.
    pub spectrum: Option<SpectrumTable>,
    /// Notes for the user.
    pub notes: Vec<String>,
    /// The device that computed it.
    pub device: String,
    /// Time per stage in ms.
    pub stage_times: StageTimes,
}

/// Tracking options: HARK's SourceTracker and SourceIntervalExtender.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrackingSpec {
    /// SourceTracker parameters.
    pub tracker: TrackerConfig,
    /// SourceIntervalExtender PREROLL_LENGTH in frames (0 = off; delays results by it).
    pub preroll: usize,
    /// Whether each window feeds the tracker only its strongest `num_active` peaks (the
    /// source count's estimate): windows judged noise-only feed none, so that silence
    /// starts no tracks and lets tracks end (their PAUSE_LENGTH still runs), and one
    /// talker's window does not feed its second, noise or sidelobe, peak; a window
    /// without an estimate feeds its peaks. None: the default, on in the room
    /// default (no algorithm named, no noise source: NormMUSIC's powers do not tell
    /// silence from a talker, so THRESH cannot), off otherwise (HARK's SourceTracker
    /// sees every window).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub active_only: Option<bool>,
}

/// How a stream is run (beside the plan): noise policy, tracking, channel map, spectra.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamOptions {
    /// The K the stream starts with.
    pub initial_noise: InitialNoise,
    /// Online K updates.
    pub noise_update: NoiseUpdate,
    /// Tracking (None = off).
    pub tracking: Option<TrackingSpec>,
    /// Input channels → microphones.
    pub channels: ChannelMap,
    /// Produce spectrum rows.
    pub want_spectrum: bool,
}
