//! The only orchestration: a stateful, causal stream engine. Batch localization is one use
//! of it (push the whole recording, then flush).
//!
//! ```text
//! push(block) ─► StftStream (sample ring) ─► FrameRing ─► WindowScheduler (due windows)
//!     ─► NoisePolicy (which K; hold while K is not known) ─► Backend::process (batches)
//!     ─► peaks ─► results ─► SourceTracker ─► IntervalExtender ─► Output
//! ```
//!
//! Contract (after rubato's): [`Engine::push`] takes blocks of any length and appends
//! every result whose window completed to the caller's [`Output`]; [`Engine::flush`] ends
//! the input and releases what was held; [`Engine::reset`] starts a new stream with the
//! same plan and backend. Results do not depend on how the input is cut into blocks: the
//! frames, the windows, the K estimates and (on the CPU) every value are those of the whole
//! recording, bit for bit. [`Engine::latency_frames`] says how many frames after a result's
//! frame c its window completes; [`Engine::samples_needed_next`] how many more samples
//! complete the next window.
//!
//! Memory stays bounded on any stream: the sample ring holds less than one frame plus
//! what a noise range still needs, the frame ring the frames of windows not yet run (and
//! the frames of a preceding-frames K); a large block is processed in pieces of
//! [`CHUNK_FRAMES`] frames.

use crate::audio::health::ChannelHealth;
use crate::backend::{Backend, BatchOutput, DeviceChoice, StageTimes, StreamId, WindowSpec};
use crate::correlation::onset::OnsetWeights;
use crate::correlation::WindowScheduler;
use crate::input::{Block, ChannelMap};
use crate::noise::policy::{InitialNoise, KSource, NoisePolicy, NoiseUpdate};
use crate::noise::NoiseMatrices;
use crate::plan::Plan;
use crate::real::Real;
use crate::stft::{FrameRing, Stft, StftStream};
use crate::tracking::{IntervalExtender, IntervalExtenderConfig, SourceTracker};
use crate::{Error, Result};
use std::collections::VecDeque;
use std::sync::Arc;

pub(crate) mod device;
mod group;
mod results;
mod types;
mod windows;

pub use device::make_backend;
pub use group::StreamGroup;
pub use results::{refine_source, source};
pub use types::{Localization, Output, SpectrumTable, StreamOptions, TrackingSpec};

/// Frames of input processed per step inside one [`Engine::push`].
pub const CHUNK_FRAMES: usize = 4096;

/// The stream engine for one array (see the [module docs](self)).
pub struct Engine<T: Real> {
    plan: Arc<Plan<T>>,
    /// None: a stream of a [`StreamGroup`], which runs its windows.
    backend: Option<Box<dyn Backend<T>>>,
    stft: StftStream<T>,
    ring: FrameRing<T>,
    scheduler: WindowScheduler,
    /// Windows complete but not yet run (held while K is not known), absolute starts.
    pending: VecDeque<WindowSpec>,
    noise: NoisePolicy,
    /// The K the plan holds now (None: a placeholder until the initial K is known).
    current: Option<KSource>,
    options: StreamOptions,
    tracker: Option<SourceTracker>,
    /// [`TrackingSpec::active_only`] as resolved.
    track_active_only: bool,
    extender: Option<IntervalExtender>,
    /// Spectrum rows of windows whose results the extender still holds: a row goes out
    /// with its result, so that an [`Output`]'s rows and results stay one to one.
    held_rows: Option<SpectrumTable>,
    /// Input channel of each microphone, once the first block told the channel count.
    map: Option<(usize, Arc<[usize]>)>,
    windows_run: usize,
    finished: bool,
    batch: BatchOutput,
    /// Absolute input sample of local sample 0 (moves forward at a gap, see
    /// [`Engine::skip`]).
    origin: u64,
    /// Checks of this stream's channels (dead, clipping, polarity-inverted), from its
    /// first push: notes once they can tell, and at flush.
    health: Option<ChannelHealth>,
    /// This stream's frames to the backend (fresh after a reset or a gap).
    stream: StreamId,
    /// Start of the last window run: its frames stay while windows overlap by more than
    /// half, so a backend's running correlation can subtract the frames that leave.
    last_start: Option<usize>,
    /// Whether a device error moves the stream to the CPU (device `auto`).
    cpu_fallback: bool,
    /// Onset weighting of the frames ([`crate::correlation::onset`]), when the plan's
    /// `onset_frames` asks for it.
    onset: Option<OnsetWeights>,
}

impl<T: Real> Engine<T> {
    /// An engine for `plan` (built with the initial K when it is given up front) on
    /// `backend`.
    pub fn new(plan: Arc<Plan<T>>, backend: Box<dyn Backend<T>>, options: StreamOptions) -> Result<Self> {
        let c = &plan.config;
        if options.channels.mics != plan.num_mics {
            return Err(Error::Mismatch(format!(
                "channel map gives {} microphones, the plan has {}",
                options.channels.mics, plan.num_mics
            )));
        }
        if let Some(t) = &options.tracking {
            t.tracker.validate()?;
        }
        let stft = Stft::new(c.nfft, c.hop, c.window_function, plan.bins.clone())?;
        let noise = NoisePolicy::new(
            c,
            plan.num_mics,
            options.initial_noise.clone(),
            options.noise_update.clone(),
        )?;
        let current = noise.initial().map(|_| KSource::Initial);
        if c.onset_frames > 0 && matches!(options.noise_update, NoiseUpdate::Preceding { .. }) {
            return Err(Error::Config(
                "onset weighting changes the frames that a noise matrix from the frames before each \
                 window (--noise-preceding) would be estimated from: use onset weighting 0 (--onset 0, onset_frames=0 in \
                 Python) with a noise update from preceding frames"
                    .into(),
            ));
        }
        let onset =
            (c.onset_frames > 0).then(|| OnsetWeights::new(c.onset_frames, plan.num_bins(), plan.num_mics));
        Ok(Engine {
            stft: StftStream::new(stft, plan.num_mics),
            ring: FrameRing::new(plan.num_bins(), plan.num_mics),
            scheduler: WindowScheduler::new(c.window, c.period, c.window_type),
            pending: VecDeque::new(),
            noise,
            current,
            tracker: options.tracking.map(|t| SourceTracker::new(t.tracker)),
            track_active_only: options.tracking.is_some_and(|t| t.active_only == Some(true)),
            extender: options.tracking.filter(|t| t.preroll > 0).map(|t| {
                IntervalExtender::new(IntervalExtenderConfig {
                    preroll_length: t.preroll,
                })
            }),
            held_rows: None,
            options,
            map: None,
            windows_run: 0,
            finished: false,
            batch: BatchOutput::default(),
            origin: 0,
            health: None,
            stream: StreamId::fresh(),
            last_start: None,
            cpu_fallback: false,
            onset,
            plan,
            backend: Some(backend),
        })
    }

    /// An engine with a fixed K (None = identity), no tracking and every input channel a
    /// microphone: what batch runs over known matrices need.
    pub fn with_fixed_noise(
        config: &crate::config::LocalizeConfig,
        tf: &crate::array::TransferFunctions,
        noise: Option<&NoiseMatrices>,
        device: DeviceChoice,
        want_spectrum: bool,
    ) -> Result<Self> {
        let plan = Arc::new(Plan::<T>::new(config, tf, noise)?);
        let backend = make_backend(plan.clone(), device, device::default_cache().as_deref())?;
        let options = StreamOptions {
            initial_noise: InitialNoise::Given(noise.cloned()),
            noise_update: NoiseUpdate::Fixed,
            tracking: None,
            channels: ChannelMap::identity(plan.num_mics),
            want_spectrum,
        };
        Engine::new(plan, backend, options)
    }

    /// A new stream starts: the backend may drop what it kept for the old one.
    fn new_stream_id(&mut self) {
        if let Some(b) = self.backend.as_mut() {
            b.forget(self.stream);
        }
        self.stream = StreamId::fresh();
        self.last_start = None;
    }

    /// On a device error (a GPU that fails mid-run), go on with the CPU backend instead of
    /// failing: the batch that failed runs again on the CPU, so no result is lost or
    /// repeated, and a note says so. What `device = auto` asks for.
    pub fn set_cpu_fallback(&mut self, on: bool) {
        self.cpu_fallback = on;
    }

    /// The plan (holding the K in use now).
    pub fn plan(&self) -> &Plan<T> {
        &self.plan
    }

    /// The backend's device description.
    pub fn device_name(&self) -> String {
        self.backend
            .as_ref()
            .map_or_else(|| "a stream group's device".into(), |b| b.device_name())
    }

    /// Stage times since the start (or the last reset).
    pub fn stage_times(&self) -> StageTimes {
        self.backend.as_ref().map(|b| b.stage_times()).unwrap_or_default()
    }

    /// Frames between a result's frame c and the last frame of its window: W − 1 for
    /// FUTURE, ⌊W/2⌋ for MIDDLE, 0 for PAST. A result is out once the N samples of that
    /// last frame have arrived (plus, at the start of a stream whose K comes from a time
    /// range of it, until the range has arrived).
    pub fn latency_frames(&self) -> usize {
        self.scheduler.latency_frames()
    }

    /// Frames a result then waits in the interval extender (`preroll` P > 0): until the
    /// first result at or past its frame + P, ⌈P / PERIOD⌉ · PERIOD; 0 without one.
    pub fn preroll_hold_frames(&self) -> usize {
        let period = self.plan.config.period.max(1);
        self.extender.as_ref().map_or(0, |_| {
            self.options
                .tracking
                .map_or(0, |t| t.preroll.div_ceil(period) * period)
        })
    }

    /// Samples per channel still needed before the next window completes (≥ 1).
    pub fn samples_needed_next(&self) -> usize {
        let c = &self.plan.config;
        let need = self.scheduler.next_last_frame() * c.hop + c.nfft;
        need.saturating_sub(self.stft.samples_received()).max(1)
    }

    /// Samples per channel received since the start (or the last reset).
    pub fn samples_received(&self) -> usize {
        self.stft.samples_received()
    }

    /// Time of local STFT frame `frame` in seconds (its first sample): frame·hop/fs after
    /// the start of the stream (plus the samples before and in gaps).
    pub fn frame_time(&self, frame: usize) -> f64 {
        (self.origin as f64 + (frame * self.plan.config.hop) as f64) / self.plan.config.sample_rate_hz as f64
    }

    /// The frame number reported for local frame `frame`: frames counted from the start of
    /// the stream (after a gap, from its first sample, ⌊origin/hop⌋ + frame).
    fn report_frame(&self, frame: usize) -> usize {
        (self.origin / self.plan.config.hop as u64) as usize + frame
    }

    /// A gap in the input: `samples` samples per channel were lost (a live source that
    /// fell behind dropped them). The stream goes on after the gap as if it started there:
    /// windows that would span the gap are skipped (the count is in the note), result
    /// times stay true (`time_s` counts the lost samples), the tracker and the K in use
    /// are kept; a noise estimate still arriving is finished with what it had.
    pub fn skip(&mut self, samples: u64, out: &mut Output) -> Result<()> {
        self.restart_after(
            samples,
            out,
            "of audio lost",
            "(the input came faster than it was handled)",
        )
    }

    /// A pause in the input: `samples` samples per channel of time passed with no audio
    /// at all (a listening input between one sender and the next). Handled as a
    /// [`skip`](Self::skip), with a note that says what happened.
    pub fn pause(&mut self, samples: u64, out: &mut Output) -> Result<()> {
        self.restart_after(samples, out, "without input", "(between two senders)")
    }

    fn restart_after(&mut self, samples: u64, out: &mut Output, what: &str, why: &str) -> Result<()> {
        if self.finished {
            return Err(Error::State(
                "skip after flush: call reset to start a new stream".into(),
            ));
        }
        let received = self.stft.samples_received() as u64;
        let fs = self.plan.config.sample_rate_hz as f64;
        let held = self.pending.len();
        out.notes
            .extend(self.noise.on_gap(received as usize, self.ring.end())?);
        let at = (self.origin + received) as f64 / fs;
        self.origin += received + samples;
        self.stft.reset();
        self.ring.reset();
        self.scheduler.reset();
        self.pending.clear();
        if let Some(o) = &mut self.onset {
            o.reset();
        }
        // A tentative track is not confirmed across frames that were never analysed.
        if let Some(t) = &mut self.tracker {
            t.drop_tentative();
        }
        self.new_stream_id();
        out.notes.push(format!(
            "input gap: {:.3} s {what} at {at:.3} s {why}; windows across it skipped{}",
            samples as f64 / fs,
            if held > 0 {
                format!(", {held} held windows dropped")
            } else {
                String::new()
            }
        ));
        Ok(())
    }

    /// Check an input's format before streaming it: its sample rate and channel count.
    pub fn check_input(&self, sample_rate_hz: u32, channels: usize) -> Result<()> {
        if sample_rate_hz != self.plan.config.sample_rate_hz {
            return Err(Error::Mismatch(format!(
                "sampled at {} Hz, but the transfer functions are for {} Hz (the resample option converts it: --resample, resample=True)",
                sample_rate_hz, self.plan.config.sample_rate_hz
            )));
        }
        self.options.channels.resolve(channels).map(|_| ())
    }

    /// Replace the initial noise matrix K now (an update from outside the stream, e.g. a
    /// noise estimate of the caller's own); it is used from the next window on, until an
    /// online update picks another, and kept across [`reset`](Self::reset).
    pub fn set_noise(&mut self, noise: &NoiseMatrices) -> Result<()> {
        self.install(noise)?;
        self.noise.set_initial(noise.clone());
        self.current = Some(KSource::Initial);
        Ok(())
    }

    fn install(&mut self, noise: &NoiseMatrices) -> Result<()> {
        let Some(backend) = self.backend.as_mut() else {
            return Err(Error::Config(
                "the streams of a group share its noise matrix K: it cannot change for one of them".into(),
            ));
        };
        let plan = Arc::new(self.plan.with_noise(noise)?);
        backend.set_plan(plan.clone())?;
        self.plan = plan;
        Ok(())
    }

    /// Push a block of any length; results of windows it completes are appended to `out`.
    pub fn push(&mut self, block: Block<'_>, out: &mut Output) -> Result<()> {
        let (idx, len) = self.check(&block)?;
        self.take(block, idx, len, out)
    }

    /// [`push`](Self::push) after [`check`](Self::check) said `idx`, `len` for `block`.
    pub(crate) fn take(
        &mut self,
        block: Block<'_>,
        idx: Arc<[usize]>,
        len: usize,
        out: &mut Output,
    ) -> Result<()> {
        if self.map.is_none() {
            self.map = Some((block.channels(), idx.clone()));
        }
        // With a CPU backend the rest runs on a thread of the pool: the parallel stages of
        // a small push then start from inside it, so the caller hands off once per push
        // instead of once per stage, and not at all where it is a worker itself
        // (`crate::pool`; `Backend::runs_on_pool` says why not for devices).
        let r = if self.backend.as_ref().is_some_and(|b| b.runs_on_pool()) {
            rayon::scope(|_| self.push_checked(&block, &idx, len, out))
        } else {
            self.push_checked(&block, &idx, len, out)
        };
        self.keep_spectrum(out);
        r
    }

    /// Where the stream keeps the spectrum, `out` has a table even when no window ran
    /// (zero rows), so that every output of the stream has one and they join as they
    /// are.
    pub(crate) fn keep_spectrum(&self, out: &mut Output) {
        if self.options.want_spectrum {
            out.spectrum
                .get_or_insert_with(|| SpectrumTable::empty(self.plan.num_dirs, self.plan.num_bins()));
        }
    }

    /// [`push`](Self::push)'s checks of `block`, which change nothing: the stream must be
    /// open, the channel count the earlier blocks' (or one the options can map), every
    /// sample finite and within what the precision's correlations hold. Returns the
    /// channels to take and the block's length.
    pub(crate) fn check(&self, block: &Block<'_>) -> Result<(Arc<[usize]>, usize)> {
        if self.finished {
            return Err(Error::State(
                "push after the end of the stream (flush, or localize of a whole recording): call reset to start a new stream".into(),
            ));
        }
        let len = block.samples()?;
        let n_in = block.channels();
        let idx = match &self.map {
            Some((n, idx)) if *n == n_in => idx.clone(),
            Some((n, _)) => {
                return Err(Error::Mismatch(format!(
                    "audio block has {n_in} channels, earlier blocks had {n}"
                )))
            }
            None => self.options.channels.resolve(n_in)?.into(),
        };
        // The whole block is checked before any of it is taken: a rejected push leaves
        // the stream as it was.
        let bad = |v: f32| v.is_nan() | (v.abs() > T::MAX_SAMPLE);
        if let Some((i, c)) = block.find(&idx, bad) {
            let v = block.at(i, c);
            let what = if v.is_nan() {
                "NaN".to_string()
            } else if v.is_infinite() {
                "infinite".to_string()
            } else {
                format!(
                    "{v:e}, beyond what {} correlation matrices hold (|x| <= {:e}; use --precision f64, precision=\"f64\" in Python, or scale the input)",
                    T::NAME,
                    T::MAX_SAMPLE
                )
            };
            return Err(Error::numerical(
                "audio",
                format!(
                    "sample {} of input channel {c} is {what} (0-based)",
                    self.stft.samples_received() + i
                ),
            ));
        }
        Ok((idx, len))
    }

    /// [`push`](Self::push) after the checks: `len` samples of `block`, channels `idx`.
    fn push_checked(&mut self, block: &Block<'_>, idx: &[usize], len: usize, out: &mut Output) -> Result<()> {
        let step = CHUNK_FRAMES * self.plan.config.hop;
        let mut pos = 0;
        while pos < len {
            let n = step.min(len - pos);
            let first = self.stft.samples_received();
            let map = &self.options.channels;
            self.stft.append(n, |bufs| {
                block.extend_channels(idx, pos..pos + n, bufs);
                map.invert_last(idx, bufs, n);
            });
            let (buf_start, buf) = self.stft.buffered();
            let health = self.health.get_or_insert_with(|| {
                let h = ChannelHealth::new(
                    idx.to_vec(),
                    self.plan.config.sample_rate_hz as f64,
                    self.plan.config.hop,
                    self.plan.close_pairs(),
                );
                if self.plan.gains_matter() {
                    h.with_gain_check(self.plan.expected_levels())
                } else {
                    h
                }
            });
            let tails: Vec<&[f32]> = buf.iter().map(|ch| &ch[first - buf_start..]).collect();
            health.observe(&tails);
            out.notes.extend(health.notes(false));
            let notes = self.noise.observe_samples(buf_start, buf, first + n)?;
            out.notes.extend(notes);
            self.advance(out)?;
            pos += n;
        }
        Ok(())
    }

    /// End of input: release held windows (finishing a noise range that ran past the end)
    /// and the tracker's delayed results. An error when the whole stream gave no window.
    /// Call [`reset`](Self::reset) before pushing again.
    pub fn flush(&mut self, out: &mut Output) -> Result<()> {
        if self.finished {
            return Ok(());
        }
        self.end_input(out)?;
        self.run_pending(out)?;
        self.finish(out)
    }

    /// First half of [`flush`](Self::flush): no more input; windows held for a noise
    /// range that ran past the end become runnable.
    fn end_input(&mut self, out: &mut Output) -> Result<()> {
        self.finished = true;
        let notes = self.noise.finish(self.stft.samples_received(), self.ring.end())?;
        out.notes.extend(notes);
        Ok(())
    }

    /// Second half of [`flush`](Self::flush), once every window ran: the tracker's delayed
    /// results, warnings about the input, an error when no window ran at all.
    fn finish(&mut self, out: &mut Output) -> Result<()> {
        self.keep_spectrum(out);
        if let Some(e) = &mut self.extender {
            out.results.extend(e.finish());
        }
        if let Some(held) = self.held_rows.take() {
            out.spectrum
                .get_or_insert_with(|| SpectrumTable::empty(held.num_dirs, held.num_bins))
                .append(held);
        }
        if let Some(h) = &mut self.health {
            out.notes.extend(h.notes(true));
        }
        let unconfirmed = self
            .tracker
            .as_ref()
            .and_then(|t| Some((t.none_confirmed()?, t.config().confirm_frames.unwrap_or(0))));
        if let Some((n, confirm)) = unconfirmed {
            let c = &self.plan.config;
            out.notes.push(format!(
                "tracking: {n} new source(s) seen, none confirmed, so no source was output: a new source is \
                 confirmed when a peak within MIN_SRC_INTERVAL is seen again {confirm} frames ({:.2} s) after its \
                 first sighting, each sighting within that time of the last; lower --confirm \
                 (tracker_confirm_frames= in Python; 0: HARK's tracker, an id at the first sighting)",
                confirm as f64 * c.hop as f64 / c.sample_rate_hz as f64
            ));
        }
        if self.windows_run == 0 {
            let c = &self.plan.config;
            let len = self.stft.samples_received();
            // The first result's window (with PAST it is at frame PERIOD, with MIDDLE it
            // ends ⌊W/2⌋ after its frame).
            let (frame, start) = self.scheduler.next_window();
            let last = self.scheduler.next_last_frame();
            let need = c.nfft + last * c.hop;
            let fs = c.sample_rate_hz as f64;
            return Err(Error::NoWindow(format!(
                "the audio has {len} samples ({:.3} s); the first result (frame {frame}, its window of {} frames \
                 being frames {start}–{last}) needs at least {need} ({:.3} s)",
                len as f64 / fs,
                c.window,
                need as f64 / fs
            )));
        }
        Ok(())
    }

    /// Start a new stream: samples, frames, windows, noise estimates and tracks are
    /// forgotten; the plan, the backend and the initial K stay.
    pub fn reset(&mut self) -> Result<()> {
        self.stft.reset();
        self.ring.reset();
        if let Some(o) = &mut self.onset {
            o.reset();
        }
        self.scheduler.reset();
        self.pending.clear();
        self.noise.reset(&self.plan.config.clone())?;
        if let Some(t) = &mut self.tracker {
            t.reset();
        }
        if let Some(e) = &mut self.extender {
            e.reset();
        }
        self.held_rows = None;
        self.map = None;
        self.windows_run = 0;
        self.finished = false;
        self.origin = 0;
        self.health = None;
        self.new_stream_id();
        if let Some(b) = self.backend.as_mut() {
            b.reset_stage_times();
        }
        if self.noise.initial().is_some() && self.current != Some(KSource::Initial) {
            let (k, _) = self.noise.matrices(&KSource::Initial, &self.ring, 0)?;
            self.install(&k)?;
            self.current = Some(KSource::Initial);
        } else if self.noise.initial().is_none() {
            self.current = None;
        }
        Ok(())
    }

    /// Batch: push planar channels whole, then flush.
    pub fn localize(&mut self, channels: &[Vec<f32>]) -> Result<Localization> {
        let mut out = Output::default();
        self.push(Block::Planar(channels), &mut out)?;
        self.flush(&mut out)?;
        Ok(Localization {
            results: out.results,
            track_starts: out.track_starts,
            spectrum: out.spectrum,
            notes: out.notes,
            device: self.device_name(),
            stage_times: self.stage_times(),
        })
    }
}

impl<T: Real> Drop for Engine<T> {
    fn drop(&mut self) {
        if let Some(b) = self.backend.as_mut() {
            b.forget(self.stream);
        }
    }
}

#[cfg(test)]
mod tests;
