//! Where K comes from while a stream is localized: the noise policy, a small state machine
//! the engine drives once per block.
//!
//! **The initial K** ([`InitialNoise`]) is given up front (a noise recording, a HARK
//! noise-CM file, matrices; `None` = identity), or estimated from a time range of the input
//! itself ([`InitialNoise::Range`]): x xᴴ averaged over the complete STFT frames inside the
//! range, counted from the range's first sample, in f64. While that range is still arriving
//! every window waits (the engine holds it and its frames), so a stream gives the same
//! results as the whole file; the wait is part of the stream's latency. A range that runs
//! past the end of the input is cut there, with a note.
//!
//! **Online updates** ([`NoiseUpdate`], iGEVD / iGSVD) follow the recording:
//!
//! - [`NoiseUpdate::Fixed`]: K never changes.
//! - [`NoiseUpdate::Segments`]: time ranges known to hold only noise (a push-to-talk gap, a
//!   voice-activity detector's silences). Segment i covers the STFT frames that lie
//!   entirely inside it: frame f (samples f·hop … f·hop + N − 1) with f·hop ≥ round(start·fs)
//!   and f·hop + N ≤ round(end·fs). Its K is **causal**: it is used from the first window
//!   whose last frame is at or after the segment's last frame on, and it replaces the K of
//!   every earlier segment (segments are not pooled, since the noise may have changed in
//!   between). Before the first segment completes, the initial K is used. A segment the
//!   input ends inside of (or before) is never used, with a note.
//! - [`NoiseUpdate::Preceding`]` { frames: F, gap: G }`: like HARK's delayed correlation
//!   maker, each window whose first frame is s uses K from the F frames s − G − F …
//!   s − G − 1. It suppresses whatever was already sounding a moment ago, so it finds
//!   sources that **start** against a changing background; a source that sounds through the
//!   preceding frames is whitened away with the noise. A window with fewer than G + F
//!   frames before it keeps the K in use.
//!
//! Each new K goes through the plan exactly like a K given up front (positive definite,
//! diagonal loading as configured); a failure names the segment or the frames. Online
//! updates need a noise-aware algorithm: SEVD ignores K, so a rule other than `Fixed` with
//! SEVD is a configuration error.

use super::{CorrelationSum, NoiseMatrices};
use crate::backend::WindowSpec;
use crate::config::LocalizeConfig;
use crate::real::Real;
use crate::stft::{FrameRing, Stft, StftStream};
use crate::{Error, Result};
use std::ops::Range;
use std::sync::Arc;

/// How K is updated while localizing (see the [module docs](self)).
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum NoiseUpdate {
    /// Keep the initial K.
    #[default]
    Fixed,
    /// Time ranges (start, end) in seconds that hold only noise; each segment's K is used
    /// once its frames are complete.
    Segments(Vec<(f64, f64)>),
    /// K from the `frames` frames ending `gap` frames before each window's first frame.
    Preceding {
        /// Number of frames averaged (F).
        frames: usize,
        /// Frames skipped between them and the window (G).
        gap: usize,
    },
}

/// The K a stream starts with.
#[derive(Debug, Clone, PartialEq)]
pub enum InitialNoise {
    /// Given up front (None = identity).
    Given(Option<NoiseMatrices>),
    /// Estimated from this time range of the input, (start, end) in seconds (end may be
    /// +∞: to the end of the input).
    Range(f64, f64),
}

/// Which K a window uses.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum KSource {
    /// The initial K.
    Initial,
    /// Segment i.
    Segment(usize),
    /// These absolute frames.
    Frames(Range<usize>),
}

/// K from a time range of a sample stream (see the [module docs](self)).
pub struct RangeEstimate {
    range_s: (f64, f64),
    fs: f64,
    s0: usize,
    /// Exclusive end sample (usize::MAX: to the end of the input).
    s1: usize,
    /// Absolute samples consumed so far.
    fed: usize,
    nfft: usize,
    stft: StftStream<f64>,
    ring: FrameRing<f64>,
    sum: CorrelationSum,
    first_bin: usize,
}

impl RangeEstimate {
    /// An estimate over `range_s` seconds of a `num_channels`-channel input.
    pub fn new(config: &LocalizeConfig, num_channels: usize, range_s: (f64, f64)) -> Result<Self> {
        let (a, b) = range_s;
        if !a.is_finite() || b.is_nan() || a < 0.0 || b <= a {
            return Err(Error::Config(format!(
                "noise range {a}:{b} s: need 0 <= start < end"
            )));
        }
        let fs = config.sample_rate_hz as f64;
        let bins = config.bin_range();
        let stft = Stft::<f64>::new(config.nfft, config.hop, config.window_function, bins.clone())?;
        let s1 = if b.is_finite() {
            (b * fs).round().min(usize::MAX as f64 / 2.0) as usize
        } else {
            usize::MAX
        };
        Ok(RangeEstimate {
            range_s,
            fs,
            s0: (a * fs).round().min(usize::MAX as f64 / 2.0) as usize,
            s1,
            fed: 0,
            nfft: config.nfft,
            stft: StftStream::new(stft, num_channels),
            ring: FrameRing::new(bins.len(), num_channels),
            sum: CorrelationSum::new(bins.len(), num_channels),
            first_bin: bins.start,
        })
    }

    /// The first absolute sample still needed from the input.
    pub fn needs_from(&self) -> usize {
        self.fed.max(self.s0)
    }

    /// Whether every sample of the range has been fed (`received` samples have arrived).
    pub fn complete(&self, received: usize) -> bool {
        received >= self.s1
    }

    /// Feed what has arrived: `buf` holds absolute samples `buf_start ..`, `received` in
    /// all (the samples from [`needs_from`](Self::needs_from) on must be held).
    pub fn feed(&mut self, buf_start: usize, buf: &[Vec<f32>], received: usize) {
        let from = self.needs_from();
        let to = received.min(self.s1);
        if to <= from || from < buf_start {
            return;
        }
        let (a, b) = (from - buf_start, to - buf_start);
        self.stft.append(to - from, |bufs| {
            for (v, ch) in bufs.iter_mut().zip(buf) {
                v.extend_from_slice(&ch[a..b]);
            }
        });
        self.stft.frames_into(&mut self.ring, usize::MAX);
        let n = self.ring.spectra().num_frames;
        self.sum.add(self.ring.spectra(), 0..n);
        self.ring.drop_before(self.ring.end());
        self.fed = to;
    }

    /// K from what was fed, the input having ended after `received` samples; with a note
    /// when the range ran past the end.
    pub fn finish(&self, received: usize) -> Result<(NoiseMatrices, Option<String>)> {
        let (a, b) = self.range_s;
        if self.s0 >= received {
            return Err(Error::TooShort(format!(
                "noise range {a}:{b} s starts after the end of the audio ({:.3} s)",
                received as f64 / self.fs
            )));
        }
        let got = received.min(self.s1) - self.s0;
        if self.sum.num_frames() == 0 {
            return Err(Error::TooShort(format!(
                "the noise segment has {got} samples, fewer than one {}-sample frame",
                self.nfft
            )));
        }
        let note = (self.s1 != usize::MAX && self.s1 > received).then(|| {
            format!(
                "noise range {a}:{b} s runs past the end of the input: K from {a}–{:.3} s",
                received as f64 / self.fs
            )
        });
        Ok((self.sum.finish(self.first_bin)?, note))
    }
}

/// One noise-only segment of [`NoiseUpdate::Segments`] while it arrives.
struct Segment {
    frames: Range<usize>,
    sum: CorrelationSum,
    /// K once every frame has arrived.
    k: Option<Arc<NoiseMatrices>>,
}

/// The stream's noise state (see the [module docs](self)).
pub(crate) struct NoisePolicy {
    update: NoiseUpdate,
    initial_range: Option<RangeEstimate>,
    /// The initial K once known (None = identity).
    initial: Option<Option<NoiseMatrices>>,
    initial_given: InitialNoise,
    segments: Vec<Segment>,
    last_preceding: KSource,
    /// Some window had its preceding frames (NoiseUpdate::Preceding).
    preceding_used: bool,
    first_bin: usize,
    fs: f64,
    num_bins: usize,
    num_mics: usize,
}

impl NoisePolicy {
    /// The policy for a stream of `num_mics` channels.
    pub fn new(
        config: &LocalizeConfig,
        num_mics: usize,
        initial: InitialNoise,
        update: NoiseUpdate,
    ) -> Result<Self> {
        if !matches!(update, NoiseUpdate::Fixed) && !config.algorithm.uses_noise() {
            return Err(Error::Config(format!(
                "online noise updates need a noise-aware algorithm (gevd, gevd-hark or gsvd); {} ignores K",
                config.algorithm.name()
            )));
        }
        if let NoiseUpdate::Preceding { frames: 0, .. } = update {
            return Err(Error::Config(
                "preceding-frames noise update: needs at least one frame".into(),
            ));
        }
        let bins = config.bin_range();
        let (hop, nfft, fs) = (config.hop, config.nfft, config.sample_rate_hz as f64);
        let segments = match &update {
            NoiseUpdate::Segments(s) => s
                .iter()
                .enumerate()
                .map(|(i, &(a, b))| {
                    segment_frames(i, a, b, nfft, hop, fs).map(|frames| Segment {
                        frames,
                        sum: CorrelationSum::new(bins.len(), num_mics),
                        k: None,
                    })
                })
                .collect::<Result<Vec<_>>>()?,
            _ => Vec::new(),
        };
        let mut p = NoisePolicy {
            update,
            initial_range: None,
            initial: None,
            initial_given: initial,
            segments,
            last_preceding: KSource::Initial,
            preceding_used: false,
            first_bin: bins.start,
            fs,
            num_bins: bins.len(),
            num_mics,
        };
        p.start(config)?;
        Ok(p)
    }

    fn start(&mut self, config: &LocalizeConfig) -> Result<()> {
        match &self.initial_given {
            InitialNoise::Given(k) => self.initial = Some(k.clone()),
            InitialNoise::Range(a, b) => {
                self.initial = None;
                self.initial_range = Some(RangeEstimate::new(config, self.num_mics, (*a, *b))?);
            }
        }
        Ok(())
    }

    /// The initial K when it is known: Some(None) is the identity.
    pub fn initial(&self) -> Option<&Option<NoiseMatrices>> {
        self.initial.as_ref()
    }

    /// One K for the whole stream (the initial one, once known): no segments, no
    /// preceding frames.
    pub fn fixed(&self) -> bool {
        matches!(self.update, NoiseUpdate::Fixed)
    }

    /// Replace the initial K (kept across resets).
    pub fn set_initial(&mut self, k: NoiseMatrices) {
        self.initial_given = InitialNoise::Given(Some(k.clone()));
        self.initial = Some(Some(k));
        self.initial_range = None;
    }

    /// Forget the stream: segments and a range estimate start again.
    pub fn reset(&mut self, config: &LocalizeConfig) -> Result<()> {
        for s in &mut self.segments {
            s.sum = CorrelationSum::new(self.num_bins, self.num_mics);
            s.k = None;
        }
        self.last_preceding = KSource::Initial;
        self.preceding_used = false;
        self.start(config)
    }

    /// The first absolute input sample the policy still needs.
    pub fn keep_samples_from(&self) -> usize {
        self.initial_range
            .as_ref()
            .map_or(usize::MAX, RangeEstimate::needs_from)
    }

    /// Frames (absolute) that windows starting at or after `next_start` will need for
    /// their K.
    pub fn keep_frames_from(&self, next_start: usize) -> usize {
        match self.update {
            NoiseUpdate::Preceding { frames, gap } => next_start.saturating_sub(frames + gap),
            _ => next_start,
        }
    }

    /// New samples have arrived (`buf` holds absolute samples `buf_start ..`).
    pub fn observe_samples(
        &mut self,
        buf_start: usize,
        buf: &[Vec<f32>],
        received: usize,
    ) -> Result<Vec<String>> {
        let mut notes = Vec::new();
        if let Some(r) = &mut self.initial_range {
            r.feed(buf_start, buf, received);
            if r.complete(received) {
                let (k, note) = r.finish(received)?;
                notes.extend(note);
                self.initial = Some(Some(k));
                self.initial_range = None;
            }
        }
        Ok(notes)
    }

    /// New frames `new` (absolute) have arrived in `ring`.
    pub fn observe_frames<T: Real>(&mut self, ring: &FrameRing<T>, new: Range<usize>) -> Result<()> {
        for (i, s) in self.segments.iter_mut().enumerate() {
            let a = s.frames.start.max(new.start);
            let b = s.frames.end.min(new.end);
            if a < b {
                s.sum.add(ring.spectra(), a - ring.first()..b - ring.first());
                if b == s.frames.end {
                    let k = s
                        .sum
                        .finish(self.first_bin)
                        .map_err(|e| Error::Mismatch(format!("noise segment {i}: {e}")))?;
                    s.k = Some(Arc::new(k));
                }
            }
        }
        Ok(())
    }

    /// The input ended after `received` samples and `frames` frames: finish a range
    /// estimate that was still arriving; notes for segments that never completed.
    pub fn finish(&mut self, received: usize, frames: usize) -> Result<Vec<String>> {
        let mut notes = Vec::new();
        if let Some(r) = self.initial_range.take() {
            let (k, note) = r.finish(received)?;
            notes.extend(note);
            self.initial = Some(Some(k));
        }
        if let NoiseUpdate::Preceding { frames: f, gap } = self.update {
            if !self.preceding_used {
                notes.push(format!(
                    "warning: no window had {f} noise frames {gap} frames before it (the input has {frames} frames): K was never updated from preceding frames"
                ));
            }
        }
        if let NoiseUpdate::Segments(v) = &self.update {
            for (i, s) in self.segments.iter().enumerate() {
                if s.k.is_none() && s.frames.end != usize::MAX && s.frames.end > frames {
                    notes.push(format!(
                        "noise segment {i} ({}–{} s) does not end before the input does ({:.3} s): not used",
                        v[i].0,
                        v[i].1,
                        received as f64 / self.fs
                    ));
                }
            }
        }
        Ok(notes)
    }

    /// A gap in the input after `received` samples and `frames` frames (the engine starts
    /// counting again after it): a range estimate still arriving is finished with what it
    /// had; segments not complete are dropped; preceding frames start again.
    pub fn on_gap(&mut self, received: usize, frames: usize) -> Result<Vec<String>> {
        let mut notes = Vec::new();
        if let Some(r) = self.initial_range.take() {
            let (k, note) = r.finish(received)?;
            notes.extend(note);
            self.initial = Some(Some(k));
        }
        // The latest complete segment stays in use for every later window; the others
        // (and those cut by the gap) are never used again.
        let latest = self
            .segments
            .iter()
            .enumerate()
            .filter(|(_, s)| s.k.is_some() && s.frames.end <= frames)
            .max_by_key(|(_, s)| s.frames.end)
            .map(|(i, _)| i);
        let mut cut = 0;
        for (i, s) in self.segments.iter_mut().enumerate() {
            if Some(i) == latest {
                s.frames = 0..1;
            } else {
                cut += usize::from(s.k.is_none());
                s.frames = usize::MAX..usize::MAX;
            }
        }
        if cut > 0 {
            notes.push(format!("{cut} noise segments cut by the gap are not used"));
        }
        self.last_preceding = KSource::Initial;
        Ok(notes)
    }

    /// The K source of window `w`, or None while the initial K is not known yet.
    pub fn choose(&mut self, w: &WindowSpec) -> Option<KSource> {
        self.initial.as_ref()?;
        Some(match self.update {
            NoiseUpdate::Fixed => KSource::Initial,
            NoiseUpdate::Segments(_) => {
                let last = w.start + w.len - 1;
                // The latest-ending segment complete by the window's last frame.
                self.segments
                    .iter()
                    .enumerate()
                    .filter(|(_, s)| s.k.is_some() && s.frames.end.saturating_sub(1) <= last)
                    .max_by_key(|(_, s)| s.frames.end)
                    .map_or(KSource::Initial, |(i, _)| KSource::Segment(i))
            }
            NoiseUpdate::Preceding { frames, gap } => {
                if let Some(s0) = w.start.checked_sub(gap + frames) {
                    self.last_preceding = KSource::Frames(s0..s0 + frames);
                    self.preceding_used = true;
                }
                self.last_preceding.clone()
            }
        })
    }

    /// K of `src`, and what it is (for messages). `ring` must hold the frames of a
    /// [`KSource::Frames`].
    pub fn matrices<T: Real>(
        &self,
        src: &KSource,
        ring: &FrameRing<T>,
        window_frame: usize,
    ) -> Result<(NoiseMatrices, String)> {
        match src {
            KSource::Initial => {
                let k = match self.initial.as_ref() {
                    Some(Some(k)) => k.clone(),
                    _ => {
                        NoiseMatrices::identity(self.num_mics, self.first_bin..self.first_bin + self.num_bins)
                    }
                };
                Ok((k, "the initial noise matrix".into()))
            }
            KSource::Segment(i) => {
                let s = &self.segments[*i];
                let what = match &self.update {
                    NoiseUpdate::Segments(v) => format!(
                        "noise segment {i} ({}–{} s, frames {}..{})",
                        v[*i].0, v[*i].1, s.frames.start, s.frames.end
                    ),
                    _ => format!("noise segment {i}"),
                };
                let k =
                    s.k.as_deref()
                        .cloned()
                        .ok_or_else(|| Error::Mismatch(format!("{what}: not complete")))?;
                Ok((k, what))
            }
            KSource::Frames(f) => {
                let what = format!(
                    "noise from frames {}..{} (before the window at frame {window_frame})",
                    f.start, f.end
                );
                let first = ring.first();
                if f.start < first || f.end > ring.end() {
                    return Err(Error::Mismatch(format!("{what}: frames no longer held")));
                }
                let k = NoiseMatrices::from_spectra(
                    ring.spectra(),
                    self.first_bin,
                    f.start - first..f.end - first,
                )
                .map_err(|e| Error::Mismatch(format!("{what}: {e}")))?;
                Ok((k, what))
            }
        }
    }
}

/// The frames segment i covers (see the module docs); an error when it is not a valid
/// range or holds no complete frame.
fn segment_frames(i: usize, a: f64, b: f64, nfft: usize, hop: usize, fs: f64) -> Result<Range<usize>> {
    if !(a.is_finite() && b.is_finite() && a >= 0.0 && b > a) {
        return Err(Error::Config(format!(
            "noise segment {i} ({a}–{b} s): need 0 <= start < end"
        )));
    }
    let s0 = (a * fs).round() as usize;
    let s1 = (b * fs).round() as usize;
    let first = s0.div_ceil(hop);
    let end = if s1 >= nfft { (s1 - nfft) / hop + 1 } else { 0 };
    if first >= end {
        return Err(Error::TooShort(format!(
            "noise segment {i} ({a}–{b} s) holds no complete {nfft}-sample frame"
        )));
    }
    Ok(first..end)
}

#[cfg(test)]
mod tests;
