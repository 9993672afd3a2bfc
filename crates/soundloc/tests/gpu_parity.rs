//! CUDA backend parity with the CPU reference (f64).
//!
//! Without a GPU every test prints `SKIPPED <test>: no CUDA device (<reason>)` and passes,
//! unless `SOUNDLOC_REQUIRE_GPU=1`, which turns that into a failure. With
//! `SOUNDLOC_CUDA_EMU_DIR=<dir>` (libraries from `scripts/build_cuda_emu.sh`) the same
//! backend runs over the CPU emulator of the kernels, on smaller problems.
//!
//! Figures (printed with `--nocapture`): RMS and max of the dB-spectrum difference against
//! the f64 CPU path over all windows and directions, and the share of windows whose peak
//! directions are identical, for the GPU (f32 and f64) and, as the yardstick, the f32 CPU
//! path.

use soundloc::array::freefield::{free_field, DEFAULT_SPEED_OF_SOUND_M_S};
use soundloc::array::{Geometry, Grid, TransferFunctions};
use soundloc::backend::cpu::CpuBackend;
use soundloc::backend::{cuda, Backend, BatchOutput, Job, Spectra, WindowSpec};
use soundloc::bench::{inputs, BenchConfig};
use soundloc::config::{Algorithm, Denominator, LocalizeConfig, WindowType};
use soundloc::correlation::schedule;
use soundloc::noise::estimate as estimate_noise;
use soundloc::noise::NoiseMatrices;
use soundloc::plan::Plan;
use soundloc::sim::{position_from_az_el, render, Scene, SceneSource, Signal};
use soundloc::stft::Stft;
use soundloc::Real;
use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;

#[derive(Clone)]
enum Mode {
    Device,
    Emulator(PathBuf),
}

impl Mode {
    fn is_emulator(&self) -> bool {
        matches!(self, Mode::Emulator(_))
    }
}

fn note(msg: &str) {
    let _ = writeln!(std::io::stderr(), "{msg}");
}

/// The device to test on, or None after printing why the test is skipped.
fn mode(test: &str) -> Option<Mode> {
    if let Ok(d) = std::env::var("SOUNDLOC_CUDA_EMU_DIR") {
        return Some(Mode::Emulator(PathBuf::from(d)));
    }
    match cuda::probe() {
        Ok(desc) => {
            note(&format!("{test}: {desc}"));
            Some(Mode::Device)
        }
        Err(reason) => {
            if std::env::var("SOUNDLOC_REQUIRE_GPU").as_deref() == Ok("1") {
                panic!("{test}: SOUNDLOC_REQUIRE_GPU=1 but no CUDA device ({reason})");
            }
            note(&format!("SKIPPED {test}: no CUDA device ({reason})"));
            None
        }
    }
}

fn gpu<T: Real>(mode: &Mode, plan: Arc<Plan<T>>) -> Box<dyn Backend<T>> {
    match mode {
        Mode::Device => cuda::new_backend(plan, 0, None).expect("CUDA backend"),
        Mode::Emulator(dir) => cuda::new_emulated_backend(plan, dir).expect("emulated CUDA backend"),
    }
}

/// dB spectra `[window][dir]` and peak lists of one run.
struct Run {
    db: Vec<f32>,
    peaks: Vec<Vec<usize>>,
    bin_weight: Vec<f32>,
    /// The estimated number of active sources per window (empty where not estimated).
    counts: Vec<u32>,
}

fn run<T: Real>(b: &mut dyn Backend<T>, spectra: &Spectra<T>, windows: &[WindowSpec], batch: usize) -> Run {
    let mut r = Run {
        db: Vec::new(),
        peaks: Vec::new(),
        bin_weight: Vec::new(),
        counts: Vec::new(),
    };
    let mut out = BatchOutput::default();
    for chunk in windows.chunks(batch.max(1)) {
        b.process(&[Job::once(spectra, chunk)], true, &mut out)
            .expect("process");
        assert_eq!(out.peaks.len(), chunk.len());
        r.db.extend_from_slice(&out.spectrum_db);
        r.bin_weight.extend_from_slice(&out.bin_weight);
        r.counts.extend_from_slice(&out.source_count);
        r.peaks.extend(
            out.peaks
                .iter()
                .map(|p| p.iter().map(|p| p.dir).collect::<Vec<_>>()),
        );
        // The reported peak power is the spectrum's value at that direction.
        let d = out.spectrum_db.len() / chunk.len();
        for (w, ps) in out.peaks.iter().enumerate() {
            for p in ps {
                let s = out.spectrum_db[w * d + p.dir] as f64;
                assert!(
                    (s - p.power_db).abs() <= 1e-4 * (1.0 + s.abs()),
                    "peak power {} vs spectrum {s}",
                    p.power_db
                );
            }
        }
    }
    r
}

#[derive(Debug, Clone, Copy)]
struct Stats {
    rms_db: f64,
    max_db: f64,
    same_peaks: f64,
}

fn compare(a: &Run, reference: &Run) -> Stats {
    assert_eq!(a.db.len(), reference.db.len());
    assert!(a.db.iter().all(|v| v.is_finite()), "non-finite dB values");
    let mut s2 = 0.0;
    let mut mx = 0.0f64;
    for (x, y) in a.db.iter().zip(&reference.db) {
        let e = (*x as f64 - *y as f64).abs();
        s2 += e * e;
        mx = mx.max(e);
    }
    let same = a
        .peaks
        .iter()
        .zip(&reference.peaks)
        .filter(|(x, y)| x == y)
        .count();
    Stats {
        rms_db: (s2 / a.db.len() as f64).sqrt(),
        max_db: mx,
        same_peaks: same as f64 / a.peaks.len().max(1) as f64,
    }
}

fn report(what: &str, s: &Stats) {
    note(&format!(
        "  {what:<34} rms {:.3e} dB  max {:.3e} dB  identical peaks {:.1} %",
        s.rms_db,
        s.max_db,
        100.0 * s.same_peaks
    ));
}

/// Build f32 and f64 plans for `config` and `tf`.
fn plans(
    config: &LocalizeConfig,
    tf: &TransferFunctions,
    k: Option<&NoiseMatrices>,
) -> (Arc<Plan<f32>>, Arc<Plan<f64>>) {
    (
        Arc::new(Plan::<f32>::new(config, tf, k).expect("plan f32")),
        Arc::new(Plan::<f64>::new(config, tf, k).expect("plan f64")),
    )
}

/// A scene with two talkers, a rotor close to the array and sensor noise: its audio, the
/// free-field TFs of the grid and K from the rotor-only recording.
struct SceneData {
    audio: Vec<Vec<f32>>,
    tf: TransferFunctions,
    k: NoiseMatrices,
}

fn scene(geometry: Geometry, grid: Grid, seed: u64) -> SceneData {
    let fs = 16000;
    let rotor = SceneSource::new(position_from_az_el(160.0, 35.0, 0.6), Signal::Rotor).with_gain(0.15);
    let talkers = Scene {
        sources: vec![
            SceneSource::new(position_from_az_el(40.0, 0.0, 1.5), Signal::Speech),
            SceneSource::new(position_from_az_el(-95.0, 0.0, 1.2), Signal::WhiteNoise).with_gain(0.7),
            rotor.clone(),
        ],
        sensor_noise_std: 0.002,
        ..Scene::default()
    };
    let noise_only = Scene {
        sources: vec![rotor],
        sensor_noise_std: 0.002,
        ..Scene::default()
    };
    talkers.validate(&geometry, fs).expect("scene");
    let audio = render(&talkers, &geometry, fs, 1.2, seed).channels;
    let noise = render(&noise_only, &geometry, fs, 1.0, seed + 1).channels;
    // The STFT and band of every configuration below (their defaults).
    let base = scene_config(Algorithm::Sevd, 50, 10);
    let tf = free_field(
        &geometry,
        &grid,
        base.nfft,
        fs,
        base.bin_range(),
        DEFAULT_SPEED_OF_SOUND_M_S,
    )
    .unwrap();
    let k = estimate_noise(&base, fs, &noise, None).expect("noise");
    SceneData { audio, tf, k }
}

impl SceneData {
    /// parity_case on this scene with K, then the scene assertions (check_scene).
    fn check(&self, mode: &Mode, label: &str, config: &LocalizeConfig, gpu_batch: usize) {
        self.check_frames(mode, label, config, gpu_batch, false);
    }

    /// `check`, the frames marked [`Spectra::phased`] or not.
    fn check_frames(
        &self,
        mode: &Mode,
        label: &str,
        config: &LocalizeConfig,
        gpu_batch: usize,
        phased: bool,
    ) {
        let r = parity_case(
            mode,
            label,
            config,
            &self.tf,
            Some(&self.k),
            &self.audio,
            gpu_batch,
            phased,
        );
        check_scene(label, r);
    }
}

fn spectra<T: Real>(config: &LocalizeConfig, plan: &Plan<T>, audio: &[Vec<f32>]) -> Spectra<T> {
    Stft::<T>::new(config.nfft, config.hop, config.window_function, plan.bins.clone())
        .expect("stft")
        .process(audio)
        .expect("stft")
}

/// Run one configuration on the CPU (f64, f32) and the GPU (f32, f64), the frames marked
/// `phased` or not; returns (gpu f32, gpu f64, cpu f32) stats against cpu f64.
#[allow(clippy::too_many_arguments)]
fn parity_case(
    mode: &Mode,
    label: &str,
    config: &LocalizeConfig,
    tf: &TransferFunctions,
    k: Option<&NoiseMatrices>,
    audio: &[Vec<f32>],
    gpu_batch: usize,
    phased: bool,
) -> (Stats, Stats, Stats) {
    let (p32, p64) = plans(config, tf, k);
    let mut s32 = spectra(config, &p32, audio);
    let mut s64 = spectra(config, &p64, audio);
    (s32.phased, s64.phased) = (phased, phased);
    let windows = schedule(s64.num_frames, config.window, config.period, config.window_type);
    assert!(!windows.is_empty());
    let cpu64 = run(&mut CpuBackend::new(p64.clone()), &s64, &windows, 16);
    let cpu32 = run(&mut CpuBackend::new(p32.clone()), &s32, &windows, 16);
    let mut g32 = gpu(mode, p32.clone());
    let gpu32 = run(&mut *g32, &s32, &windows, gpu_batch);
    drop(g32);
    let mut g64 = gpu(mode, p64.clone());
    let gpu64 = run(&mut *g64, &s64, &windows, gpu_batch);
    let name = g64.device_name();
    drop(g64);
    // Eigenvalue weights g_k agree too.
    let mut bw = 0.0f64;
    for (a, b) in gpu64.bin_weight.iter().zip(&cpu64.bin_weight) {
        bw = bw.max((*a as f64 - *b as f64).abs() / (1e-30 + b.abs() as f64));
    }
    let (a, b, c) = (
        compare(&gpu32, &cpu64),
        compare(&gpu64, &cpu64),
        compare(&cpu32, &cpu64),
    );
    note(&format!(
        "{label}: {} windows, {} directions on {name}",
        windows.len(),
        p64.num_dirs
    ));
    report("gpu f32 vs cpu f64", &a);
    report("gpu f64 vs cpu f64", &b);
    report("cpu f32 vs cpu f64", &c);
    note(&format!(
        "  max relative bin-weight difference (gpu f64) {bw:.2e}"
    ));
    assert!(bw < 1e-6, "{label}: bin weights differ by {bw}");
    // The number of active sources (count.cu): on the tridiagonal path (squared
    // denominator, up to 64 microphones) in every window, the CPU's in nearly all (MDL is
    // an argmin: eigenvalues a rounding apart may tip a bin, rarely the median).
    let tridiagonal =
        config.counts_sources() && config.denominator == Denominator::Squared && p64.num_mics <= 64;
    assert_eq!(
        cpu64.counts.len(),
        if config.counts_sources() { windows.len() } else { 0 }
    );
    if tridiagonal {
        for (what, g) in [("gpu f32", &gpu32), ("gpu f64", &gpu64)] {
            assert_eq!(g.counts.len(), windows.len(), "{label}: {what} counts");
            let same = g.counts.iter().zip(&cpu64.counts).filter(|(x, y)| x == y).count();
            note(&format!(
                "  {what}: source count equal to the CPU's in {same} of {} windows",
                windows.len()
            ));
            assert!(
                same * 100 >= windows.len() * 95,
                "{label}: {what} counts {:?} vs CPU {:?}",
                g.counts,
                cpu64.counts
            );
        }
    }
    (a, b, c)
}

fn scene_config(algorithm: Algorithm, window: usize, period: usize) -> LocalizeConfig {
    LocalizeConfig {
        algorithm,
        window,
        period,
        num_sources: 2,
        ..Default::default()
    }
}

fn check_scene(label: &str, r: (Stats, Stats, Stats)) {
    let (g32, g64, c32) = r;
    assert_eq!(
        g32.same_peaks, 1.0,
        "{label}: GPU f32 peaks differ from the f64 reference"
    );
    assert_eq!(
        g64.same_peaks, 1.0,
        "{label}: GPU f64 peaks differ from the f64 reference"
    );
    assert!(g64.rms_db < 1e-6, "{label}: GPU f64 spectrum differs: {g64:?}");
    assert!(
        g32.rms_db <= 1.5 * c32.rms_db + 1e-6,
        "{label}: GPU f32 rms {:.3e} dB worse than the CPU f32 path's {:.3e} dB",
        g32.rms_db,
        c32.rms_db
    );
}

#[test]
fn probe_reports_or_explains() {
    match cuda::probe() {
        Ok(s) => note(&format!("probe: {s}")),
        Err(e) => {
            assert!(!e.is_empty());
            note(&format!("probe: no CUDA ({e})"));
        }
    }
}

#[test]
fn kernels_compile_with_nvrtc() {
    if !cuda::nvrtc_available() {
        note("SKIPPED kernels_compile_with_nvrtc: libnvrtc not found (pip's nvidia-cuda-nvrtc on LD_LIBRARY_PATH enables it)");
        return;
    }
    let t = std::time::Instant::now();
    let r = cuda::nvrtc_compile_all("sm_90").unwrap_or_else(|e| panic!("{e}"));
    note(&format!(
        "kernels_compile_with_nvrtc: {r:?} in {:.1} s",
        t.elapsed().as_secs_f64()
    ));
    assert_eq!(r.len(), 8);
}

#[test]
fn scene_ring_array_every_algorithm() {
    let Some(mode) = mode("scene_ring_array_every_algorithm") else {
        return;
    };
    let sd = scene(Geometry::circle(8, 0.0365, 0.0), Grid::ring(5.0, 0.0, 1.0), 7);
    for alg in Algorithm::MUSIC {
        let cfg = scene_config(alg, 50, 10);
        sd.check(&mode, &format!("ring8 {}", alg.name()), &cfg, 4);
    }
    // Unsquared denominator (all noise vectors), and other window types / PERIOD 1.
    for alg in [Algorithm::Sevd, Algorithm::Gsvd, Algorithm::Gevd] {
        let cfg = LocalizeConfig {
            denominator: Denominator::Unsquared,
            ..scene_config(alg, 50, 10)
        };
        sd.check(&mode, &format!("ring8 {} unsquared", alg.name()), &cfg, 4);
    }
    // Fewer frames than microphones (rank-deficient R; the Jacobi kernel uses its factor form).
    for alg in Algorithm::MUSIC {
        let cfg = scene_config(alg, 6, 9);
        sd.check(&mode, &format!("ring8 {} W6 (W < M)", alg.name()), &cfg, 5);
    }
    let cfg = LocalizeConfig {
        window_type: WindowType::Past,
        eigenvalue_weight: false,
        ..scene_config(Algorithm::Gevd, 30, 1)
    };
    sd.check(&mode, "ring8 gevd past W30 P1 no-eigw", &cfg, 64);
    let cfg = LocalizeConfig {
        window_type: WindowType::Middle,
        max_peaks: 0,
        ..scene_config(Algorithm::Sevd, 25, 7)
    };
    sd.check(&mode, "ring8 sevd middle W25 P7 all peaks", &cfg, 3);
}

/// SRP-PHAT (phase-transformed correlation, no decomposition), NormMUSIC (per-bin
/// normalised spectra, two spectrum passes) and coherence normalisation on the GPU
/// against the CPU reference.
#[test]
fn srp_phat_and_normmusic_on_the_gpu() {
    let Some(mode) = mode("srp_phat_and_normmusic_on_the_gpu") else {
        return;
    };
    let sd = scene(Geometry::circle(8, 0.0365, 0.0), Grid::ring(5.0, 0.0, 1.0), 7);
    let norm = |alg| LocalizeConfig {
        normalize_bins: true,
        ..scene_config(alg, 50, 10)
    };
    sd.check(
        &mode,
        "ring8 srp-phat",
        &scene_config(Algorithm::SrpPhat, 50, 10),
        4,
    );
    sd.check(&mode, "ring8 srp-phat normalised", &norm(Algorithm::SrpPhat), 4);
    // Frames marked as transformed already (soundloc.doa's factor of a long window):
    // summed as they are, on both devices. They are not unit-modulus here, so a backend
    // that transformed them again would differ from the CPU's by dB.
    sd.check_frames(
        &mode,
        "ring8 srp-phat, frames phased",
        &scene_config(Algorithm::SrpPhat, 50, 10),
        4,
        true,
    );
    sd.check(&mode, "ring8 normmusic sevd", &norm(Algorithm::Sevd), 4);
    sd.check(&mode, "ring8 normmusic gevd", &norm(Algorithm::Gevd), 3);
    // Coherence normalisation (a kernel of its own after the correlation): the room
    // default's form, and with K.
    let coh = |alg, dim| LocalizeConfig {
        coherence: true,
        subspace_dim: Some(dim),
        refine: true,
        ..norm(alg)
    };
    sd.check(
        &mode,
        "ring8 room default (coherence)",
        &coh(Algorithm::Sevd, 4),
        4,
    );
    sd.check(&mode, "ring8 gevd coherence", &coh(Algorithm::Gevd, 4), 3);
    let whitened = LocalizeConfig {
        numerator: soundloc::config::Numerator::Whitened,
        ..scene_config(Algorithm::Gevd, 50, 10)
    };
    sd.check(&mode, "ring8 gevd whitened numerator", &whitened, 3);
    let (mics, dirs) = if mode.is_emulator() { (12, 150) } else { (60, 2522) };
    let sd = scene(Geometry::sphere(mics, 0.1), Grid::sphere(dirs, 1.0), 11);
    sd.check(
        &mode,
        &format!("sphere{mics} srp-phat"),
        &scene_config(Algorithm::SrpPhat, 50, 25),
        8,
    );
    sd.check(
        &mode,
        &format!("sphere{mics} normmusic gevd"),
        &norm(Algorithm::Gevd),
        8,
    );
    // Fewer frames than microphones (W = 50 < 60; W = 8 < 12 in the emulator): the factor
    // form, which rebuilds R from the raw frames, would be chosen without coherence.
    let (dim, window) = if mode.is_emulator() { (3, 8) } else { (15, 50) };
    sd.check(
        &mode,
        &format!("sphere{mics} room default (coherence, subspace {dim}, W {window})"),
        &LocalizeConfig {
            window,
            ..coh(Algorithm::Sevd, dim)
        },
        8,
    );
}

#[test]
fn scene_sphere_array_60_mics() {
    let Some(mode) = mode("scene_sphere_array_60_mics") else {
        return;
    };
    let (mics, dirs) = if mode.is_emulator() { (16, 200) } else { (60, 2522) };
    let sd = scene(Geometry::sphere(mics, 0.1), Grid::sphere(dirs, 1.0), 11);
    for alg in Algorithm::MUSIC {
        let cfg = scene_config(alg, 50, 25);
        sd.check(&mode, &format!("sphere{mics} {}", alg.name()), &cfg, 8);
    }
    // The robust default's signal subspace (M/2 vectors; 12 of 16 in the emulator, more
    // values than the eigensolver block has warps): its last vectors lie among the
    // noise-floor eigenvalues, close together (the eigensolver before 2026-11-27 was
    // 8e-4 dB off on this scene's SEVD). Not GSVD: its H = A Aᴴ squares the condition
    // number, and vectors that deep are rounding there (docs/gpu.md).
    let dim = if mode.is_emulator() { 12 } else { mics / 2 };
    for alg in [Algorithm::Sevd, Algorithm::Gevd] {
        let cfg = LocalizeConfig {
            subspace_dim: Some(dim),
            ..scene_config(alg, 50, 25)
        };
        sd.check(
            &mode,
            &format!("sphere{mics} {} subspace {dim}", alg.name()),
            &cfg,
            8,
        );
    }
    // The robust default as it runs: refined, the geometric numerator ‖a‖·‖a_w‖ (read by
    // the GPU's spectrum from the plan like the raw ‖a‖²).
    let cfg = LocalizeConfig {
        subspace_dim: Some(dim),
        refine: true,
        numerator: soundloc::config::Numerator::Geometric,
        ..scene_config(Algorithm::Gevd, 50, 25)
    };
    sd.check(
        &mode,
        &format!("sphere{mics} robust default (subspace {dim}, geometric numerator)"),
        &cfg,
        8,
    );
}

#[test]
fn seed_config_random_data_every_algorithm() {
    let Some(mode) = mode("seed_config_random_data_every_algorithm") else {
        return;
    };
    for alg in Algorithm::MUSIC {
        let env = |k: &str, d: usize| std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d);
        let cfg = if mode.is_emulator() {
            BenchConfig {
                algorithm: alg,
                num_mics: env("SOUNDLOC_EMU_MICS", 10),
                num_dirs: env("SOUNDLOC_EMU_DIRS", 300),
                window: env("SOUNDLOC_EMU_WINDOW", 20),
                batch: env("SOUNDLOC_EMU_BATCH", 3),
                ..Default::default()
            }
        } else {
            BenchConfig {
                algorithm: alg,
                batch: 24,
                ..Default::default()
            }
        };
        let i64_ = inputs::<f64>(&cfg).expect("inputs f64");
        let i32_ = inputs::<f32>(&cfg).expect("inputs f32");
        let cpu64 = run(
            &mut CpuBackend::new(i64_.plan.clone()),
            &i64_.spectra,
            &i64_.windows,
            8,
        );
        let cpu32 = run(
            &mut CpuBackend::new(i32_.plan.clone()),
            &i32_.spectra,
            &i32_.windows,
            8,
        );
        let mut g = gpu(&mode, i32_.plan.clone());
        let gpu32 = run(&mut *g, &i32_.spectra, &i32_.windows, cfg.batch);
        drop(g);
        let mut g = gpu(&mode, i64_.plan.clone());
        let gpu64 = run(&mut *g, &i64_.spectra, &i64_.windows, 5);
        drop(g);
        let (a, b, c) = (
            compare(&gpu32, &cpu64),
            compare(&gpu64, &cpu64),
            compare(&cpu32, &cpu64),
        );
        note(&format!(
            "seed config {} (M={} D={} W={} Ns={}), {} windows:",
            alg.name(),
            cfg.num_mics,
            cfg.num_dirs,
            cfg.window,
            cfg.num_sources,
            cpu64.peaks.len()
        ));
        report("gpu f32 vs cpu f64", &a);
        report("gpu f64 vs cpu f64", &b);
        report("cpu f32 vs cpu f64", &c);
        assert!(b.rms_db < 1e-6, "{}: GPU f64 differs: {b:?}", alg.name());
        assert!(b.same_peaks == 1.0, "{}: GPU f64 peaks differ", alg.name());
        assert!(
            a.rms_db <= 1.5 * c.rms_db + 1e-6,
            "{}: GPU f32 rms {:.3e} dB worse than the CPU f32 path's {:.3e} dB",
            alg.name(),
            a.rms_db,
            c.rms_db
        );
    }
}

/// The stream engine on the GPU: pushes of random sizes (PAST windows, PERIOD 1, textbook
/// GEVD with K from the first half second, replaced by a noise segment's K mid-stream) equal
/// the GPU's own whole-file run, and agree with the f64 CPU stream.
#[test]
fn streaming_on_the_gpu_equals_its_batch_run_and_the_cpu() {
    use rand::{Rng, SeedableRng};
    use soundloc::engine::{Engine, Output, StreamOptions};
    use soundloc::noise::policy::{InitialNoise, NoiseUpdate};
    use soundloc::{Block, ChannelMap};
    let Some(mode) = mode("streaming_on_the_gpu_equals_its_batch_run_and_the_cpu") else {
        return;
    };
    let scene = soundloc::demo::ring8_drone(-5.0, 21).unwrap();
    let audio = scene.render();
    let secs = if mode.is_emulator() { 2.2 } else { 3.0 };
    let channels: Vec<Vec<f32>> = audio
        .channels
        .iter()
        .map(|c| c[..(secs * 16000.0) as usize].to_vec())
        .collect();
    let config = LocalizeConfig {
        algorithm: Algorithm::Gevd,
        window_type: WindowType::Past,
        period: if mode.is_emulator() { 10 } else { 1 },
        ..LocalizeConfig::default()
    };
    let tf = scene.transfer_functions(&config).unwrap();
    let options = StreamOptions {
        initial_noise: InitialNoise::Range(0.0, 0.5),
        noise_update: NoiseUpdate::Segments(vec![(0.4, 0.95)]),
        tracking: None,
        channels: ChannelMap::identity(8),
        want_spectrum: true,
    };
    fn engine<T: Real>(
        mode: Option<&Mode>,
        config: &LocalizeConfig,
        tf: &TransferFunctions,
        options: &StreamOptions,
    ) -> Engine<T> {
        let plan = Arc::new(Plan::<T>::new(config, tf, None).unwrap());
        let backend: Box<dyn Backend<T>> = match mode {
            Some(m) => gpu(m, plan.clone()),
            None => Box::new(CpuBackend::new(plan.clone())),
        };
        Engine::new(plan, backend, options.clone()).unwrap()
    }
    let whole = engine::<f32>(Some(&mode), &config, &tf, &options)
        .localize(&channels)
        .unwrap();
    let mut e = engine::<f32>(Some(&mode), &config, &tf, &options);
    let mut out = Output::default();
    let mut rng = rand::rngs::StdRng::seed_from_u64(4);
    let mut pos = 0;
    let len = channels[0].len();
    while pos < len {
        let n = rng.gen_range(1..4000).min(len - pos);
        let part: Vec<Vec<f32>> = channels.iter().map(|c| c[pos..pos + n].to_vec()).collect();
        e.push(Block::Planar(&part), &mut out).unwrap();
        pos += n;
    }
    e.flush(&mut out).unwrap();
    assert_eq!(out.results.len(), whole.results.len());
    let peaks = |r: &[soundloc::LocalizationResult]| -> Vec<Vec<usize>> {
        r.iter()
            .map(|x| x.sources.iter().map(|s| s.grid_index).collect())
            .collect()
    };
    assert_eq!(
        peaks(&out.results),
        peaks(&whole.results),
        "GPU stream vs GPU whole file"
    );
    let (a, b) = (
        &out.spectrum.as_ref().unwrap().db,
        &whole.spectrum.as_ref().unwrap().db,
    );
    let max_diff = a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max);
    assert!(max_diff < 1e-3, "GPU stream vs GPU whole file: {max_diff} dB");
    let cpu = engine::<f64>(None, &config, &tf, &options)
        .localize(&channels)
        .unwrap();
    let c = &cpu.spectrum.as_ref().unwrap().db;
    let rms = (a
        .iter()
        .zip(c)
        .map(|(x, y)| ((x - y) as f64).powi(2))
        .sum::<f64>()
        / a.len() as f64)
        .sqrt();
    // Peaks are compared once the talkers fill the window (they start at 1 s; a PAST
    // window is 0.5 s): before, the whitened spectrum is flat and its maxima move with
    // rounding (spec §9).
    let talk: Vec<usize> = (0..out.results.len())
        .filter(|&i| out.results[i].time_s >= 1.5)
        .collect();
    let (g, c64) = (peaks(&out.results), peaks(&cpu.results));
    let same = talk.iter().filter(|&&i| g[i] == c64[i]).count();
    note(&format!(
        "stream on GPU: {} windows, vs GPU batch max {max_diff:.2e} dB, vs CPU f64 RMS {rms:.2e} dB, identical peaks {same}/{} with talkers",
        out.results.len(),
        talk.len()
    ));
    assert!(rms < 0.05, "vs CPU f64: RMS {rms} dB");
    assert!(!talk.is_empty() && same == talk.len(), "{same} of {}", talk.len());
}
