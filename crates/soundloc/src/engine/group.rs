//! Many streams, one device: the windows that several arrays' streams complete go to the
//! backend together, in one launch (after NVIDIA DeepStream's `nvstreammux`: batch N
//! sources per launch). One process can so serve many arrays — a GPU's throughput comes
//! from batches, and one PERIOD-1 stream hands it one window at a time.
//!
//! The streams share one plan (the array, the grid, the algorithm and one fixed noise
//! matrix K) and one backend. Each keeps its own state: samples, frames, windows,
//! tracker; results do not depend on which other streams are in the group or how the
//! windows are batched (on the CPU, bit for bit).
//!
//! ```text
//! push(i, block) ─► stream i: STFT, due windows wait ──┐
//! push(j, block) ─► stream j: …                        ├─► run ─► one Backend::process
//!                                                      ┘        ─► results per stream
//! ```

use super::{make_backend, Engine, Output, StreamOptions};
use crate::backend::{Backend, BatchOutput, DeviceChoice, Job, StageTimes, WindowSpec};
use crate::input::Block;
use crate::noise::policy::{InitialNoise, NoiseUpdate};
use crate::plan::Plan;
use crate::real::Real;
use crate::{Error, Result};
use std::sync::Arc;

/// Streams sharing a plan and a backend (see the [module docs](self)).
pub struct StreamGroup<T: Real> {
    plan: Arc<Plan<T>>,
    backend: Box<dyn Backend<T>>,
    streams: Vec<Engine<T>>,
    batch: BatchOutput,
}

impl<T: Real> StreamGroup<T> {
    /// An empty group on `device` for `plan` (which holds the K every stream uses).
    pub fn new(plan: Arc<Plan<T>>, device: DeviceChoice) -> Result<Self> {
        let backend = make_backend(plan.clone(), device, super::device::default_cache().as_deref())?;
        Ok(Self::with_backend(plan, backend))
    }

    /// An empty group on a backend built for `plan`.
    pub fn with_backend(plan: Arc<Plan<T>>, backend: Box<dyn Backend<T>>) -> Self {
        StreamGroup {
            plan,
            backend,
            streams: Vec::new(),
            batch: BatchOutput::default(),
        }
    }

    /// Add a stream; returns its index. Its noise must be the plan's fixed K (given up
    /// front, never updated): windows of one launch share one K.
    pub fn add(&mut self, options: StreamOptions) -> Result<usize> {
        if !matches!(options.initial_noise, InitialNoise::Given(_))
            || options.noise_update != NoiseUpdate::Fixed
        {
            return Err(Error::Config(
                "a stream group shares one fixed noise matrix K: give it up front, without online updates"
                    .into(),
            ));
        }
        let mut e = Engine::new(self.plan.clone(), Box::new(NoBackend), options)?;
        e.backend = None;
        self.streams.push(e);
        Ok(self.streams.len() - 1)
    }

    /// Number of streams.
    pub fn len(&self) -> usize {
        self.streams.len()
    }

    /// Whether the group has no stream.
    pub fn is_empty(&self) -> bool {
        self.streams.is_empty()
    }

    /// Stream `i` (its latency, samples needed, sample format checks).
    pub fn stream(&self, i: usize) -> Result<&Engine<T>> {
        self.streams
            .get(i)
            .ok_or_else(|| Error::Config(format!("no stream {i} in a group of {}", self.streams.len())))
    }

    fn stream_mut(&mut self, i: usize) -> Result<&mut Engine<T>> {
        let n = self.streams.len();
        self.streams
            .get_mut(i)
            .ok_or_else(|| Error::Config(format!("no stream {i} in a group of {n}")))
    }

    /// The backend's device description.
    pub fn device_name(&self) -> String {
        self.backend.device_name()
    }

    /// Stage times of the shared backend.
    pub fn stage_times(&self) -> StageTimes {
        self.backend.stage_times()
    }

    /// Push a block into stream `i`: its windows wait for [`run`](Self::run). Notes go
    /// to `out`.
    pub fn push(&mut self, i: usize, block: Block<'_>, out: &mut Output) -> Result<()> {
        self.stream_mut(i)?.push(block, out)
    }

    /// One block for every stream (`blocks[i]` into stream i, the streams' STFTs in
    /// parallel on the CPU's cores), then [`run`](Self::run): the tick of a server that
    /// receives all its arrays' audio in step.
    pub fn push_all(&mut self, blocks: &[Block<'_>], outs: &mut [Output]) -> Result<()> {
        use rayon::prelude::*;
        if blocks.len() != self.streams.len() || outs.len() != self.streams.len() {
            return Err(Error::Config(format!(
                "{} blocks and {} outputs for {} streams",
                blocks.len(),
                outs.len(),
                self.streams.len()
            )));
        }
        // Every block is checked (in parallel) before any is taken: a rejected call leaves
        // every stream as it was, and the error names the first bad stream.
        let checks: Vec<Result<_>> = self
            .streams
            .par_iter_mut() // (a stream is Send, not Sync)
            .zip(blocks.par_iter())
            .map(|(s, b)| s.check(b))
            .collect();
        let mut checked = Vec::with_capacity(blocks.len());
        for (i, c) in checks.into_iter().enumerate() {
            checked.push(c.map_err(|e| match e {
                Error::Numerical { stage, message } => Error::Numerical {
                    stage,
                    message: format!("stream {i}: {message}"),
                },
                e => Error::Mismatch(format!("stream {i}: {e}")),
            })?);
        }
        self.streams
            .par_iter_mut()
            .zip(blocks.par_iter())
            .zip(checked.into_par_iter())
            .zip(outs.par_iter_mut())
            .try_for_each(|(((s, b), (idx, len)), o)| s.take(*b, idx, len, o))?;
        self.run(outs)
    }

    /// Run every waiting window of every stream, in launches of up to the backend's batch
    /// size; stream i's results are appended to `outs[i]` (`outs` has one entry per
    /// stream).
    pub fn run(&mut self, outs: &mut [Output]) -> Result<()> {
        if outs.len() != self.streams.len() {
            return Err(Error::Config(format!(
                "{} outputs for {} streams",
                outs.len(),
                self.streams.len()
            )));
        }
        let cap = self.backend.max_windows_per_batch().max(1);
        loop {
            // Up to `cap` windows, oldest streams first, each stream's in order.
            let mut take: Vec<(usize, Vec<WindowSpec>)> = Vec::new();
            let mut n = 0;
            for (i, s) in self.streams.iter_mut().enumerate() {
                if n == cap {
                    break;
                }
                let k = s.pending.len().min(cap - n);
                if k > 0 {
                    take.push((i, s.pending.drain(..k).collect()));
                    n += k;
                }
            }
            if take.is_empty() {
                for (s, o) in self.streams.iter().zip(outs.iter_mut()) {
                    s.keep_spectrum(o);
                }
                return Ok(());
            }
            // Onset weighting, each stream's frames by its own state: the streams in
            // parallel (each stream appears once in `take`).
            {
                use rayon::prelude::*;
                let mut windows: Vec<Option<&[WindowSpec]>> = vec![None; self.streams.len()];
                for (i, w) in &take {
                    windows[*i] = Some(w);
                }
                self.streams
                    .par_iter_mut()
                    .zip(windows.into_par_iter())
                    .for_each(|(s, w)| {
                        if let Some(w) = w {
                            s.weigh_frames(w);
                        }
                    });
            }
            let want = self.streams.iter().any(|s| s.wants_spectrum());
            let jobs: Vec<Job<'_, T>> = take.iter().map(|(i, w)| self.streams[*i].job(w)).collect();
            self.backend.process(&jobs, want, &mut self.batch)?;
            let mut at = 0;
            for (i, w) in &take {
                self.streams[*i].deliver(w, &self.batch, at, &mut outs[*i])?;
                at += w.len();
            }
            // Frames of windows that ran are no longer needed.
            for (i, _) in &take {
                self.streams[*i].release_frames();
            }
        }
    }

    /// End stream `i`'s input: its last windows run (with whatever else waits), then its
    /// tracker's delayed results and notes go to `outs[i]`.
    pub fn flush(&mut self, i: usize, outs: &mut [Output]) -> Result<()> {
        let s = self.stream_mut(i)?;
        if s.finished {
            return Ok(());
        }
        let out = outs
            .get_mut(i)
            .ok_or_else(|| Error::Config(format!("no output for stream {i}")))?;
        s.end_input(out)?;
        self.run(outs)?;
        self.streams[i].finish(&mut outs[i])
    }

    /// Start stream `i` again (see [`Engine::reset`]).
    pub fn reset(&mut self, i: usize) -> Result<()> {
        let old = self.stream(i)?.stream;
        self.backend.forget(old);
        self.stream_mut(i)?.reset()
    }
}

/// Stands in while a group's stream is built; never runs.
struct NoBackend;

impl<T: Real> Backend<T> for NoBackend {
    fn device_name(&self) -> String {
        "none".into()
    }
    fn max_windows_per_batch(&self) -> usize {
        1
    }
    fn process(&mut self, _: &[Job<'_, T>], _: bool, _: &mut BatchOutput) -> Result<()> {
        Err(Error::Config(
            "a group's stream runs its windows through the group".into(),
        ))
    }
    fn set_plan(&mut self, _: Arc<Plan<T>>) -> Result<()> {
        Ok(())
    }
    fn stage_times(&self) -> StageTimes {
        StageTimes::default()
    }
    fn reset_stage_times(&mut self) {}
}
