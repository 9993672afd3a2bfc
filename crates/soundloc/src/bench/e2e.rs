//! End-to-end benchmark (`soundloc bench --e2e`): one whole localization of a recording
//! with a TF file, split into what a user waits for — transfer functions (from the zip or
//! the prepared-TF cache), the plan (steering layout, whitening, backend), reading and
//! decoding the audio, the stream engine (STFT, scheduling, noise, and the backend's
//! stages), and writing the results (JSON lines, to memory).

use crate::array::tf_cache::TfCache;
use crate::audio::open_source;
use crate::backend::StageTimes;
use crate::engine::Output;
use crate::input::Block;
use crate::localizer::{Localizer, LocalizerSpec};
use crate::output::jsonl::JsonlWriter;
use crate::{Error, Result};
use std::path::Path;
use std::time::Instant;

/// Where the time of one end-to-end run went.
#[derive(Debug, Clone, serde::Serialize)]
pub struct E2eReport {
    /// The TF cache setting of this run (`off`, or the folder).
    pub cache: String,
    /// What the cache did (note), if anything.
    pub cache_note: Option<String>,
    /// Loading the transfer functions, ms.
    pub tf_load_ms: f64,
    /// Planning (steering layout, weights, backend set-up), ms.
    pub plan_ms: f64,
    /// Reading and decoding the audio, ms.
    pub read_ms: f64,
    /// The stream engine (STFT, windows, noise, backend stages), ms.
    pub engine_ms: f64,
    /// Of `engine_ms`, the backend's stages.
    pub stages: StageTimes,
    /// Writing the results as JSON lines (to memory), ms.
    pub write_ms: f64,
    /// Everything, ms.
    pub total_ms: f64,
    /// Seconds of audio.
    pub audio_s: f64,
    /// Results.
    pub results: usize,
    /// The device.
    pub device: String,
}

/// Localize `input` with `spec` once, timing each part; `cache` replaces `spec.tf_cache`.
pub fn run(spec: &LocalizerSpec, input: &Path, cache: TfCache) -> Result<E2eReport> {
    let t_all = Instant::now();
    let mut spec = spec.clone();
    spec.tf_cache = cache.clone();
    let mut src = open_source(input)?;
    let fmt = src.format();
    let (algorithm, _) = spec.resolved_algorithm();
    let mut config = spec.analysis.clone();
    config.algorithm = algorithm;
    config.sample_rate_hz = fmt.sample_rate_hz;
    spec.analysis.sample_rate_hz = fmt.sample_rate_hz;
    let t = Instant::now();
    // As Localizer::new: the GPU comes up while the TFs load.
    let warm = crate::engine::device::prewarm(spec.device, config.subspace_tracking);
    let (tf, cache_note) = spec.load_array_noted(&config)?;
    let tf_load_ms = t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let mut loc = Localizer::with_transfer_functions(&spec, tf, None)?;
    drop(warm);
    let plan_ms = t.elapsed().as_secs_f64() * 1e3;
    loc.check_input(fmt.sample_rate_hz, fmt.channels)
        .map_err(|e| Error::format(input, e.to_string()))?;
    let (mut read_ms, mut engine_ms) = (0.0, 0.0);
    let mut out = Output::default();
    let mut buf = Vec::new();
    let mut frames = 0u64;
    loop {
        let t = Instant::now();
        let n = src.read_interleaved(1 << 15, &mut buf)?;
        read_ms += t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        if n == 0 {
            loc.flush(&mut out)?;
            engine_ms += t.elapsed().as_secs_f64() * 1e3;
            break;
        }
        frames += n as u64;
        loc.push(
            Block::Interleaved {
                data: &buf,
                channels: fmt.channels,
            },
            &mut out,
        )?;
        engine_ms += t.elapsed().as_secs_f64() * 1e3;
    }
    let t = Instant::now();
    let mut w = JsonlWriter::new(Vec::new());
    w.write_all(&out.results)
        .map_err(|e| Error::io("results (memory)", e))?;
    let bytes = w.into_inner();
    let write_ms = t.elapsed().as_secs_f64() * 1e3;
    std::hint::black_box(bytes);
    Ok(E2eReport {
        cache: cache.dir().map_or("off".into(), |d| d.display().to_string()),
        cache_note,
        tf_load_ms,
        plan_ms,
        read_ms,
        engine_ms,
        stages: loc.stage_times(),
        write_ms,
        total_ms: t_all.elapsed().as_secs_f64() * 1e3,
        audio_s: frames as f64 / fmt.sample_rate_hz as f64,
        results: out.results.len(),
        device: loc.device_name(),
    })
}
