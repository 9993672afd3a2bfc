//! The seed-config benchmark (`soundloc bench`, `benches/seed.rs`).
//!
//! Work: the seed paper's configuration — GSVD-MUSIC (or any algorithm), M = 60 mics,
//! 73 bins (500–2800 Hz at N = 512, fs = 16 kHz), W = 50 frames, 2522 directions (full
//! sphere), NUM_SOURCE = 2 — on random-but-valid inputs: complex Gaussian STFT frames,
//! unit-modulus random-phase transfer functions, and a Hermitian positive-definite K built
//! like the PyTorch peer's (Nᴴ N / 4M + 0.1 I). Reported, as `shared/bench/README.md` asks:
//! ms per localization (one window, median), localizations per second (batched), ms of
//! compute per second of audio at PERIOD 50 and PERIOD 1 (2 and 100 localizations per
//! second of audio at hop 160), the real-time factor, and the stage split.

pub mod accuracy;
pub mod e2e;
pub mod stream;
pub mod track_ids;
pub mod tracking;

use crate::array::{Grid, TransferFunctions};
use crate::backend::{BatchOutput, DeviceChoice, Job, Spectra, StageTimes, WindowSpec};
use crate::config::{Algorithm, LocalizeConfig};
use crate::engine::make_backend;
use crate::noise::NoiseMatrices;
use crate::plan::Plan;
use crate::real::{Real, C};
use crate::Result;
use num_complex::Complex;
use rand::{Rng, SeedableRng};
use std::sync::Arc;
use std::time::Instant;

/// What to benchmark.
#[derive(Debug, Clone, serde::Serialize)]
pub struct BenchConfig {
    /// Decomposition.
    pub algorithm: Algorithm,
    /// Microphones M.
    pub num_mics: usize,
    /// Directions D (full-sphere grid).
    pub num_dirs: usize,
    /// Correlation window W in frames.
    pub window: usize,
    /// NUM_SOURCE.
    pub num_sources: usize,
    /// NormMUSIC's per-bin normalisation.
    pub normalize_bins: bool,
    /// Coherence normalisation (`LocalizeConfig::coherence`).
    pub coherence: bool,
    /// Signal-subspace dimension when it differs from `num_sources` (None: the same).
    pub subspace_dim: Option<usize>,
    /// Windows per batch for the throughput figure.
    pub batch: usize,
    /// Timed repeats (median taken).
    pub repeats: usize,
    /// Device.
    pub device: DeviceChoice,
}

impl Default for BenchConfig {
    fn default() -> Self {
        BenchConfig {
            algorithm: Algorithm::Gsvd,
            num_mics: 60,
            num_dirs: 2522,
            window: 50,
            num_sources: 2,
            normalize_bins: false,
            coherence: false,
            subspace_dim: None,
            batch: 16,
            repeats: 10,
            device: DeviceChoice::Cpu,
        }
    }
}

/// Benchmark figures.
#[derive(Debug, Clone, serde::Serialize)]
pub struct BenchReport {
    /// What ran.
    pub config: BenchConfig,
    /// Compute precision.
    pub precision: &'static str,
    /// Device description.
    pub device: String,
    /// Used bins.
    pub num_bins: usize,
    /// Median ms for one window (latency).
    pub ms_per_localization: f64,
    /// Median ms for a batch of `config.batch` windows.
    pub batch_ms: f64,
    /// Batched throughput.
    pub localizations_per_s: f64,
    /// Compute per second of audio at PERIOD 50 (2 localizations / s).
    pub ms_per_audio_s_period50: f64,
    /// Compute per second of audio at PERIOD 1 (100 localizations / s).
    pub ms_per_audio_s_period1: f64,
    /// Real-time factor at PERIOD 50 (compute time / audio time; < 1 is faster than real time).
    pub rtf_period50: f64,
    /// Real-time factor at PERIOD 1.
    pub rtf_period1: f64,
    /// Stage split per localization, ms (from the batched runs).
    pub stages_per_localization: StageTimes,
}

/// Random-but-valid inputs for the seed configuration.
pub struct BenchInputs<T: Real> {
    /// The plan.
    pub plan: Arc<Plan<T>>,
    /// STFT frames for `batch` non-overlapping windows.
    pub spectra: Spectra<T>,
    /// The windows.
    pub windows: Vec<WindowSpec>,
}

/// Build the inputs (deterministic, seed 1).
pub fn inputs<T: Real>(cfg: &BenchConfig) -> Result<BenchInputs<T>> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(1);
    let config = LocalizeConfig {
        algorithm: cfg.algorithm,
        window: cfg.window,
        period: cfg.window,
        num_sources: cfg.num_sources,
        normalize_bins: cfg.normalize_bins,
        coherence: cfg.coherence,
        subspace_dim: cfg.subspace_dim,
        ..Default::default()
    };
    let bins = config.bin_range();
    let (m, d) = (cfg.num_mics, cfg.num_dirs);
    let tf = random_transfer_functions(&mut rng, &config, m, d);
    let noise = random_noise(&mut rng, m, bins.clone());
    let plan = Arc::new(Plan::<T>::new(&config, &tf, Some(&noise))?);
    let nw = cfg.batch.max(1);
    let nf = nw * cfg.window;
    let mut spectra = Spectra::<T>::zeros(nf, bins.len(), m);
    for z in spectra.data.iter_mut() {
        *z = C::new(T::of_f64(gauss(&mut rng)), T::of_f64(gauss(&mut rng)));
    }
    let windows = (0..nw)
        .map(|i| WindowSpec {
            frame: i * cfg.window,
            start: i * cfg.window,
            len: cfg.window,
        })
        .collect();
    Ok(BenchInputs {
        plan,
        spectra,
        windows,
    })
}

/// Unit-modulus random-phase transfer functions of `m` mics for a `d`-point sphere, over
/// the config's used bins.
pub(crate) fn random_transfer_functions(
    rng: &mut impl Rng,
    config: &LocalizeConfig,
    m: usize,
    d: usize,
) -> TransferFunctions {
    let bins = config.bin_range();
    let mut data = Vec::with_capacity(d * m * bins.len());
    for _ in 0..d * m * bins.len() {
        let ph: f32 = rng.gen_range(0.0..std::f32::consts::TAU);
        data.push(Complex::new(ph.cos(), ph.sin()));
    }
    TransferFunctions {
        nfft: config.nfft,
        sample_rate_hz: config.sample_rate_hz,
        grid: Grid::sphere(d, 1.0),
        mic_positions: vec![[0.0; 3]; m],
        num_mics: m,
        first_bin: bins.start,
        num_bins: bins.len(),
        data,
    }
}

pub(crate) fn gauss(rng: &mut impl Rng) -> f64 {
    // Box–Muller.
    let u1: f64 = rng.gen_range(f64::EPSILON..1.0);
    let u2: f64 = rng.gen_range(0.0..1.0);
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// K = Nᴴ N / (4M) + 0.1 I per bin, N a 4M × M complex Gaussian matrix.
pub(crate) fn random_noise(rng: &mut impl Rng, m: usize, bins: std::ops::Range<usize>) -> NoiseMatrices {
    let mut k = NoiseMatrices::identity(m, bins.clone());
    for b in 0..bins.len() {
        let n: Vec<Complex<f64>> = (0..4 * m * m)
            .map(|_| Complex::new(gauss(rng), gauss(rng)))
            .collect();
        let kb = &mut k.data[b * m * m..(b + 1) * m * m];
        for i in 0..m {
            for j in 0..m {
                let mut acc = Complex::new(0.0, 0.0);
                for r in 0..4 * m {
                    acc += n[r * m + i].conj() * n[r * m + j];
                }
                kb[i * m + j] = acc / (4 * m) as f64 + if i == j { 0.1 } else { 0.0 };
            }
        }
    }
    k
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Run the benchmark.
pub fn run<T: Real>(cfg: &BenchConfig) -> Result<BenchReport> {
    let inp = inputs::<T>(cfg)?;
    let mut backend = make_backend(
        inp.plan.clone(),
        cfg.device,
        crate::engine::device::default_cache().as_deref(),
    )?;
    let mut out = BatchOutput::default();
    let one = &inp.windows[..1];
    // Warm-up (module load, kernel compile, allocation).
    backend.process(&[Job::once(&inp.spectra, one)], false, &mut out)?;
    backend.process(&[Job::once(&inp.spectra, &inp.windows)], false, &mut out)?;
    let reps = cfg.repeats.max(1);
    let mut t1 = Vec::with_capacity(reps);
    for _ in 0..reps {
        let t = Instant::now();
        backend.process(&[Job::once(&inp.spectra, one)], false, &mut out)?;
        t1.push(t.elapsed().as_secs_f64() * 1e3);
    }
    backend.reset_stage_times();
    let mut tb = Vec::with_capacity(reps);
    for _ in 0..reps {
        let t = Instant::now();
        backend.process(&[Job::once(&inp.spectra, &inp.windows)], false, &mut out)?;
        tb.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let st = backend.stage_times();
    let n = (reps * inp.windows.len()) as f64;
    let stages = StageTimes {
        correlation_ms: st.correlation_ms / n,
        decomposition_ms: st.decomposition_ms / n,
        spectrum_ms: st.spectrum_ms / n,
        peaks_ms: st.peaks_ms / n,
    };
    let one_ms = median(t1);
    let batch_ms = median(tb);
    let per_loc_batched = batch_ms / inp.windows.len() as f64;
    let loc_per_s = 1e3 / per_loc_batched;
    // Hop 160 at 16 kHz = 100 frames/s: PERIOD 50 → 2 results/s, PERIOD 1 → 100 results/s.
    let p50 = 2.0 * per_loc_batched.min(one_ms);
    let p1 = 100.0 * per_loc_batched;
    Ok(BenchReport {
        config: cfg.clone(),
        precision: T::NAME,
        device: backend.device_name(),
        num_bins: inp.plan.num_bins(),
        ms_per_localization: one_ms,
        batch_ms,
        localizations_per_s: loc_per_s,
        ms_per_audio_s_period50: p50,
        ms_per_audio_s_period1: p1,
        rtf_period50: p50 / 1e3,
        rtf_period1: p1 / 1e3,
        stages_per_localization: stages,
    })
}
