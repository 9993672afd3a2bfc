//! Many arrays, one device, from one spec: a [`LocalizerGroup`] is a
//! [`StreamGroup`](crate::StreamGroup) built the way a [`Localizer`](super::Localizer) is —
//! the same spec, the same rules (algorithm, channel map, noise, precision, device) — for
//! N streams that share the plan. Each stream keeps its own samples, windows and tracker;
//! the windows they complete go to the backend together (one GPU launch for all arrays).
//!
//! The streams share one fixed K, so the noise must be given up front (a noise recording,
//! a HARK noise-CM file, matrices) — a time range of each stream's own input, or online
//! updates, would give every stream its own K and is refused.
//!
//! ```no_run
//! use soundloc::{Block, LocalizerGroup, LocalizerSpec, Output};
//! let mut g = LocalizerGroup::new(&LocalizerSpec::from_tf("tamago_rectf.zip"), 4)?;
//! let blocks = vec![vec![0.0f32; 8 * 160]; 4]; // 10 ms of 8 channels for each array
//! let views: Vec<Block> = blocks.iter().map(|b| Block::Interleaved { data: b, channels: 8 }).collect();
//! let mut outs = vec![Output::default(); 4];
//! g.push_all(&views, &mut outs)?; // outs[i]: the results array i's block completed
//! # Ok::<(), soundloc::Error>(())
//! ```

use super::prepare::{plan_for, prepare};
use super::LocalizerSpec;
use crate::array::{Grid, TransferFunctions};
use crate::backend::StageTimes;
use crate::config::{LocalizeConfig, Precision};
use crate::engine::{make_backend, Output, StreamGroup, StreamOptions};
use crate::input::Block;
use crate::noise::policy::{InitialNoise, NoiseUpdate};
use crate::noise::NoiseMatrices;
use crate::{Error, Result};
use std::sync::Arc;

enum Inner {
    F32(StreamGroup<f32>),
    F64(StreamGroup<f64>),
}

/// Streams of several arrays of one kind, localized together (see the [module docs](self)).
pub struct LocalizerGroup {
    inner: Inner,
    options: StreamOptions,
    config: LocalizeConfig,
    grid: Grid,
    notes: Vec<String>,
}

impl LocalizerGroup {
    /// `streams` streams from a spec: loads the files it names, plans once, picks the device.
    pub fn new(spec: &LocalizerSpec, streams: usize) -> Result<Self> {
        let (algorithm, _) = spec.resolved_algorithm();
        let config = LocalizeConfig {
            algorithm,
            ..spec.analysis.clone()
        };
        // As Localizer::new: the GPU comes up while the transfer functions load.
        let _warm = crate::engine::device::prewarm(spec.device, config.subspace_tracking);
        let (tf, note) = spec.load_array_noted(&config)?;
        let mut g = Self::with_transfer_functions(spec, tf, None, streams)
            .map_err(|e| super::prepare::name_tf_file(spec, e))?;
        g.notes.splice(0..0, note);
        Ok(g)
    }

    /// As [`Localizer::with_transfer_functions`](super::Localizer::with_transfer_functions),
    /// for `streams` streams.
    pub fn with_transfer_functions(
        spec: &LocalizerSpec,
        tf: TransferFunctions,
        noise: Option<NoiseMatrices>,
        streams: usize,
    ) -> Result<Self> {
        let p = prepare(spec, tf, noise)?;
        let k = match (&p.options.initial_noise, &p.options.noise_update) {
            (InitialNoise::Given(k), NoiseUpdate::Fixed) => k.clone(),
            _ => return Err(Error::Config(
                "streams of a group share one fixed noise matrix K: give it up front (a noise recording, \
                     a noise-CM file or matrices), not as a time range of the input or with online updates"
                    .into(),
            )),
        };
        // Compiled GPU kernels are kept where the prepared TFs are (none with the cache off).
        let cache = spec.tf_cache.dir();
        let inner = match spec.precision {
            Precision::F32 => {
                let plan = Arc::new(plan_for::<f32>(
                    &p.config,
                    &p.tf,
                    k.as_ref(),
                    p.noise_file.as_deref(),
                )?);
                let backend = make_backend(plan.clone(), spec.device, cache.as_deref())?;
                Inner::F32(StreamGroup::with_backend(plan, backend))
            }
            Precision::F64 => {
                let plan = Arc::new(plan_for::<f64>(
                    &p.config,
                    &p.tf,
                    k.as_ref(),
                    p.noise_file.as_deref(),
                )?);
                let backend = make_backend(plan.clone(), spec.device, cache.as_deref())?;
                Inner::F64(StreamGroup::with_backend(plan, backend))
            }
        };
        let mut g = LocalizerGroup {
            inner,
            options: p.options,
            config: p.config,
            grid: p.tf.grid.clone(),
            notes: p.notes,
        };
        for _ in 0..streams {
            g.add_stream()?;
        }
        Ok(g)
    }

    /// Add a stream like the others; returns its index.
    pub fn add_stream(&mut self) -> Result<usize> {
        let o = self.options.clone();
        dispatch!(mut self, g => g.add(o))
    }

    /// Number of streams.
    pub fn len(&self) -> usize {
        dispatch!(self, g => g.len())
    }

    /// Whether the group has no stream.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
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

    /// Microphones per array (after the channel map).
    pub fn num_mics(&self) -> usize {
        self.options.channels.mics
    }

    /// The device description.
    pub fn device_name(&self) -> String {
        dispatch!(self, g => g.device_name())
    }

    /// Stage times of the shared backend.
    pub fn stage_times(&self) -> StageTimes {
        dispatch!(self, g => g.stage_times())
    }

    /// See [`Engine::check_input`](crate::engine::Engine::check_input) (the same for every stream).
    pub fn check_input(&self, sample_rate_hz: u32, channels: usize) -> Result<()> {
        dispatch!(self, g => match g.stream(0) {
            Ok(s) => s.check_input(sample_rate_hz, channels),
            Err(_) => Ok(()),
        })
    }

    /// Frames between a result's frame and the last frame of its window.
    pub fn latency_frames(&self) -> usize {
        dispatch!(self, g => g.stream(0).map_or(0, |s| s.latency_frames()))
    }

    /// Samples per channel stream `i` still needs before its next result.
    pub fn samples_needed_next(&self, i: usize) -> Result<usize> {
        dispatch!(self, g => g.stream(i).map(|s| s.samples_needed_next()))
    }

    /// Push a block into stream `i`; its windows wait for [`run`](Self::run).
    pub fn push(&mut self, i: usize, block: Block<'_>, out: &mut Output) -> Result<()> {
        dispatch!(mut self, g => g.push(i, block, out))
    }

    /// One block per stream, then one run: `outs[i]` gets stream i's results.
    pub fn push_all(&mut self, blocks: &[Block<'_>], outs: &mut [Output]) -> Result<()> {
        dispatch!(mut self, g => g.push_all(blocks, outs))
    }

    /// Run every waiting window of every stream (one entry of `outs` per stream).
    pub fn run(&mut self, outs: &mut [Output]) -> Result<()> {
        dispatch!(mut self, g => g.run(outs))
    }

    /// End stream `i`'s input: its last windows and delayed results go to `outs[i]`.
    pub fn flush(&mut self, i: usize, outs: &mut [Output]) -> Result<()> {
        dispatch!(mut self, g => g.flush(i, outs))
    }

    /// Start stream `i` again.
    pub fn reset(&mut self, i: usize) -> Result<()> {
        dispatch!(mut self, g => g.reset(i))
    }
}
