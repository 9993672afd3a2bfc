//! `soundloc bench --stream`: the stream engine as a live input drives it — 10 ms blocks
//! pushed one after another, PAST (causal) windows, PERIOD 1 by default — on the 8-mic ring
//! (72 directions) or the seed configuration (60 mics, 2522 directions, random transfer
//! functions and K as in [`super::inputs`]).
//!
//! Reported: the real-time factor (compute time / audio time), the results per second of
//! audio, and the latency from the arrival of a window's last sample (the block that holds
//! it is pushed) to its result (median, p99, max): on one engine a result is ready when the
//! push that completes its window returns.
//!
//! With `streams` > 1, that many streams (independent random audio) share one
//! [`StreamGroup`](crate::StreamGroup): every 10 ms tick pushes a block into each and one
//! `run` launches all their due windows together; the real-time factor is the compute time
//! of the ticks / the audio time of one stream (below 1: the device keeps every stream in
//! real time), the latency that of a tick (its last push to the end of its `run`).
//!
//! With `paced`, the audio arrives as it would from a sound card: block k is available
//! from (k + 1)·block/fs seconds after the start, and each push takes every block that has
//! arrived and not been pushed yet (at most [`CATCH_UP_S`] of audio), so a localizer that
//! falls behind runs the queued windows as one batch (what `soundloc localize -` and
//! `listen` do). Reported besides: the mean blocks per push and the largest backlog; the
//! latency runs from the arrival of a result's block to the end of its push.

use super::{gauss, random_noise, random_transfer_functions};
use crate::array::{freefield::free_field, Geometry, Grid};
use crate::backend::DeviceChoice;
use crate::config::{Algorithm, LocalizeConfig, Precision, WindowType};
use crate::input::{Block, CATCH_UP_S};
use crate::localizer::{Localizer, LocalizerSpec, NoiseSource};
use crate::{Output, Result};
use rand::SeedableRng;
use std::time::Instant;

/// Which array.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum StreamArray {
    /// 8-mic circle (r 3.65 cm), 5° ring grid (72 directions), free field.
    Ring8,
    /// The seed configuration: 60 mics, 2522-direction sphere, random unit-modulus TFs.
    Seed,
}

/// What to run.
#[derive(Debug, Clone, serde::Serialize)]
pub struct StreamBenchConfig {
    /// Array.
    pub array: StreamArray,
    /// Algorithm.
    pub algorithm: Algorithm,
    /// PERIOD in frames.
    pub period: usize,
    /// Seconds of audio pushed (after one second of warm-up).
    pub seconds: f64,
    /// Samples per channel per push.
    pub block: usize,
    /// Device.
    pub device: DeviceChoice,
    /// Precision.
    pub precision: Precision,
    /// Concurrent streams in one group (1: a single `Localizer`).
    pub streams: usize,
    /// The approximate mode ([`crate::subspace::tracking`]).
    pub subspace_tracking: bool,
    /// Audio arrives at real-time pace; queued blocks are pushed together (one stream).
    pub paced: bool,
}

/// Figures.
#[derive(Debug, Clone, serde::Serialize)]
pub struct StreamReport {
    /// What ran.
    pub config: StreamBenchConfig,
    /// Device description.
    pub device: String,
    /// Microphones, directions.
    pub num_mics: usize,
    /// Directions.
    pub num_dirs: usize,
    /// Results produced in the timed part.
    pub results: usize,
    /// Compute time / audio time.
    pub rtf: f64,
    /// Latency from a window's last sample to its result, ms: median.
    pub latency_ms_median: f64,
    /// p99.
    pub latency_ms_p99: f64,
    /// Max.
    pub latency_ms_max: f64,
    /// Stage split per result, ms (the STFT, scheduling, noise and tracking are the rest).
    pub stages_per_result: crate::backend::StageTimes,
    /// Paced runs: blocks per push, mean.
    pub blocks_per_push: Option<f64>,
    /// Paced runs: the largest backlog (arrived, not yet pushed) seen before a push, ms of
    /// audio.
    pub max_backlog_ms: Option<f64>,
}

type Setup = (
    LocalizeConfig,
    crate::array::TransferFunctions,
    crate::noise::NoiseMatrices,
);

fn setup(cfg: &StreamBenchConfig, rng: &mut rand::rngs::StdRng) -> Result<Setup> {
    let config = LocalizeConfig {
        algorithm: cfg.algorithm,
        window_type: WindowType::Past,
        period: cfg.period,
        subspace_tracking: cfg.subspace_tracking,
        ..LocalizeConfig::default()
    };
    let (tf, k) = match cfg.array {
        StreamArray::Ring8 => {
            let g = Geometry::circle(8, 0.0365, 0.0);
            let tf = free_field(
                &g,
                &Grid::ring(5.0, 0.0, 1.0),
                config.nfft,
                config.sample_rate_hz,
                config.bin_range(),
                343.0,
            )?;
            (tf, random_noise(rng, 8, config.bin_range()))
        }
        StreamArray::Seed => (
            random_transfer_functions(rng, &config, 60, 2522),
            random_noise(rng, 60, config.bin_range()),
        ),
    };
    Ok((config, tf, k))
}

/// Run it.
pub fn run(cfg: &StreamBenchConfig) -> Result<StreamReport> {
    if cfg.paced && cfg.streams > 1 {
        return Err(crate::Error::Config(
            "a paced stream benchmark runs one stream (--streams 1)".into(),
        ));
    }
    if cfg.streams > 1 {
        return match cfg.precision {
            Precision::F32 => run_group::<f32>(cfg),
            Precision::F64 => run_group::<f64>(cfg),
        };
    }
    let mut rng = rand::rngs::StdRng::seed_from_u64(1);
    let (config, tf, k) = setup(cfg, &mut rng)?;
    let m = tf.num_mics;
    let d = tf.num_dirs();
    let mut spec = LocalizerSpec::from_tf("(benchmark)");
    spec.analysis = config.clone();
    spec.algorithm = Some(cfg.algorithm);
    spec.noise = NoiseSource::None;
    spec.device = cfg.device;
    spec.precision = cfg.precision;
    let k = cfg.algorithm.uses_noise().then_some(k);
    let mut loc = Localizer::with_transfer_functions(&spec, tf, k)?;
    let fs = config.sample_rate_hz as f64;
    let block = cfg.block.max(1);
    let mut buf = vec![0f32; block * m];
    let mut out = Output::default();
    let mut fill = |buf: &mut Vec<f32>| {
        for v in buf.iter_mut() {
            *v = (1000.0 * gauss(&mut rng)) as f32;
        }
    };
    // Warm-up: one second (plan caches, kernel compilation, the first window).
    for _ in 0..(fs as usize).div_ceil(block) {
        fill(&mut buf);
        loc.push(
            Block::Interleaved {
                data: &buf,
                channels: m,
            },
            &mut out,
        )?;
    }
    out.results.clear();
    let before = loc.stage_times();
    let pushes = (cfg.seconds * fs / block as f64).ceil() as usize;
    if cfg.paced {
        let audio: Vec<f32> = (0..pushes * block * m)
            .map(|_| (1000.0 * gauss(&mut rng)) as f32)
            .collect();
        let p = paced(&mut loc, &audio, m, block, fs)?;
        let mut lat = p.latency_ms;
        lat.sort_by(f64::total_cmp);
        let q = |x: f64| quantile(&lat, x);
        return Ok(StreamReport {
            config: cfg.clone(),
            device: loc.device_name(),
            num_mics: m,
            num_dirs: d,
            results: lat.len(),
            rtf: p.compute_s / (pushes * block) as f64 * fs,
            latency_ms_median: q(0.5),
            latency_ms_p99: q(0.99),
            latency_ms_max: lat.last().copied().unwrap_or(f64::NAN),
            stages_per_result: per_result(loc.stage_times(), before, lat.len()),
            blocks_per_push: Some(pushes as f64 / p.pushes.max(1) as f64),
            max_backlog_ms: Some(p.max_backlog as f64 * block as f64 / fs * 1e3),
        });
    }
    let mut compute = 0.0;
    let mut lat = Vec::new();
    let mut results = 0;
    for _ in 0..pushes {
        fill(&mut buf);
        let t = Instant::now();
        loc.push(
            Block::Interleaved {
                data: &buf,
                channels: m,
            },
            &mut out,
        )?;
        let dt = t.elapsed().as_secs_f64();
        compute += dt;
        if !out.results.is_empty() {
            results += out.results.len();
            lat.extend(std::iter::repeat_n(dt * 1e3, out.results.len()));
            out.results.clear();
        }
    }
    lat.sort_by(f64::total_cmp);
    let stages = per_result(loc.stage_times(), before, results);
    let q = |p: f64| quantile(&lat, p);
    Ok(StreamReport {
        config: cfg.clone(),
        device: loc.device_name(),
        num_mics: m,
        num_dirs: d,
        results,
        rtf: compute / (pushes * block) as f64 * fs,
        latency_ms_median: q(0.5),
        latency_ms_p99: q(0.99),
        latency_ms_max: lat.last().copied().unwrap_or(f64::NAN),
        stages_per_result: stages,
        blocks_per_push: None,
        max_backlog_ms: None,
    })
}

struct Paced {
    compute_s: f64,
    latency_ms: Vec<f64>,
    pushes: usize,
    max_backlog: usize,
}

/// Push `audio` (interleaved, `m` channels) as it arrives at real-time pace in blocks of
/// `block` samples, each push taking every block queued (at most [`CATCH_UP_S`]).
fn paced(loc: &mut Localizer, audio: &[f32], m: usize, block: usize, fs: f64) -> Result<Paced> {
    let n = audio.len() / (block * m);
    let dt = block as f64 / fs;
    let cap = ((CATCH_UP_S * fs) as usize / block).max(1);
    let mut out = Output::default();
    let mut p = Paced {
        compute_s: 0.0,
        latency_ms: Vec::new(),
        pushes: 0,
        max_backlog: 0,
    };
    let start = Instant::now();
    let mut next = 0;
    while next < n {
        let arrived = ((start.elapsed().as_secs_f64() / dt) as usize).min(n);
        if arrived <= next {
            let due = (next + 1) as f64 * dt - start.elapsed().as_secs_f64();
            if due > 0.0 {
                std::thread::sleep(std::time::Duration::from_secs_f64(due));
            }
            continue;
        }
        p.max_backlog = p.max_backlog.max(arrived - next);
        let take = (arrived - next).min(cap);
        let t = Instant::now();
        loc.push(
            Block::Interleaved {
                data: &audio[next * block * m..(next + take) * block * m],
                channels: m,
            },
            &mut out,
        )?;
        p.compute_s += t.elapsed().as_secs_f64();
        let done = start.elapsed().as_secs_f64();
        // Result q of this push completes with block next + q (one window per block at
        // PERIOD = block; otherwise an approximation), never later than the last one.
        for q in 0..out.results.len() {
            let b = (next + q).min(next + take - 1);
            p.latency_ms.push((done - (b + 1) as f64 * dt) * 1e3);
        }
        out.results.clear();
        p.pushes += 1;
        next += take;
    }
    Ok(p)
}

/// `streams` streams in one group, pushed tick by tick.
fn run_group<T: crate::real::Real>(cfg: &StreamBenchConfig) -> Result<StreamReport> {
    use crate::engine::StreamOptions;
    use crate::noise::policy::{InitialNoise, NoiseUpdate};
    let mut rng = rand::rngs::StdRng::seed_from_u64(1);
    let (config, tf, k) = setup(cfg, &mut rng)?;
    let k = cfg.algorithm.uses_noise().then_some(k);
    let plan = std::sync::Arc::new(crate::plan::Plan::<T>::new(&config, &tf, k.as_ref())?);
    let mut group = crate::StreamGroup::new(plan, cfg.device)?;
    let m = tf.num_mics;
    let n = cfg.streams;
    for _ in 0..n {
        group.add(StreamOptions {
            initial_noise: InitialNoise::Given(k.clone()),
            noise_update: NoiseUpdate::Fixed,
            tracking: None,
            channels: crate::input::ChannelMap::identity(m),
            want_spectrum: false,
        })?;
    }
    let fs = config.sample_rate_hz as f64;
    let block = cfg.block.max(1);
    // Pre-generated audio, one buffer per stream, reused tick after tick.
    let bufs: Vec<Vec<f32>> = (0..n)
        .map(|_| {
            (0..block * m)
                .map(|_| (1000.0 * gauss(&mut rng)) as f32)
                .collect()
        })
        .collect();
    let mut outs = vec![Output::default(); n];
    let blocks: Vec<Block<'_>> = bufs
        .iter()
        .map(|b| Block::Interleaved { data: b, channels: m })
        .collect();
    let tick = |group: &mut crate::StreamGroup<T>, outs: &mut [Output]| group.push_all(&blocks, outs);
    for _ in 0..(fs as usize).div_ceil(block) {
        tick(&mut group, &mut outs)?;
    }
    for o in outs.iter_mut() {
        o.results.clear();
    }
    let before = group.stage_times();
    let ticks = (cfg.seconds * fs / block as f64).ceil() as usize;
    let mut lat = Vec::with_capacity(ticks);
    for _ in 0..ticks {
        let t = Instant::now();
        tick(&mut group, &mut outs)?;
        lat.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let compute: f64 = lat.iter().sum::<f64>() / 1e3;
    let results: usize = outs.iter().map(|o| o.results.len()).sum();
    lat.sort_by(f64::total_cmp);
    let q = |p: f64| quantile(&lat, p);
    Ok(StreamReport {
        config: cfg.clone(),
        device: group.device_name(),
        num_mics: m,
        num_dirs: tf.num_dirs(),
        results,
        rtf: compute / (ticks * block) as f64 * fs,
        latency_ms_median: q(0.5),
        latency_ms_p99: q(0.99),
        latency_ms_max: lat.last().copied().unwrap_or(f64::NAN),
        stages_per_result: per_result(group.stage_times(), before, results),
        blocks_per_push: None,
        max_backlog_ms: None,
    })
}

/// Stage times since `before`, per result.
fn per_result(
    now: crate::backend::StageTimes,
    before: crate::backend::StageTimes,
    results: usize,
) -> crate::backend::StageTimes {
    let n = results.max(1) as f64;
    crate::backend::StageTimes {
        correlation_ms: (now.correlation_ms - before.correlation_ms) / n,
        decomposition_ms: (now.decomposition_ms - before.decomposition_ms) / n,
        spectrum_ms: (now.spectrum_ms - before.spectrum_ms) / n,
        peaks_ms: (now.peaks_ms - before.peaks_ms) / n,
    }
}

/// The `p` quantile of sorted values (NaN when empty).
fn quantile(sorted: &[f64], p: f64) -> f64 {
    sorted
        .get(((sorted.len() as f64 - 1.0) * p).round() as usize)
        .copied()
        .unwrap_or(f64::NAN)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Paced at real time, every 10 ms block still gives its PERIOD-1 result (none lost or
    /// doubled however blocks are grouped into catch-up pushes), each no earlier than its
    /// block arrived; unpaced, the same count.
    #[test]
    fn a_paced_stream_gives_one_result_per_block() {
        let mut cfg = StreamBenchConfig {
            array: StreamArray::Ring8,
            algorithm: Algorithm::Gevd,
            period: 1,
            seconds: 0.5,
            block: 160,
            device: DeviceChoice::Cpu,
            precision: Precision::F32,
            streams: 1,
            subspace_tracking: false,
            paced: true,
        };
        let p = run(&cfg).unwrap();
        assert_eq!(p.results, 50, "one result per 10 ms block");
        assert!(p.latency_ms_median >= 0.0 && p.latency_ms_max < 1e4, "{p:?}");
        let b = p.blocks_per_push.unwrap();
        assert!((1.0..=50.0).contains(&b), "{b}");
        cfg.paced = false;
        assert_eq!(run(&cfg).unwrap().results, 50);
        cfg.paced = true;
        cfg.streams = 2;
        assert!(run(&cfg).is_err(), "paced runs one stream");
    }
}
