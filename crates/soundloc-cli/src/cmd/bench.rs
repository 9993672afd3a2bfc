//! `soundloc bench`: the seed-config benchmark.

use super::{AlgorithmArg, DeviceArg, PrecisionArg};
use soundloc::bench::{run as run_bench, BenchConfig, BenchReport};
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
#[command(group(clap::ArgGroup::new("stream_or_study").args(["stream", "accuracy", "e2e", "tracks"]).multiple(true)))]
#[command(group(clap::ArgGroup::new("study").args(["accuracy", "tracks"])))]
pub struct Args {
    /// Algorithms to run (repeatable; default: gsvd and gevd).
    #[arg(long = "algorithm", value_enum)]
    pub algorithms: Vec<AlgorithmArg>,
    /// Compute device: auto, cpu, cuda (GPU 0), cuda:all or cuda:N[,M...] (several GPUs
    /// share every batch of windows).
    #[arg(long, default_value = "auto")]
    pub device: DeviceArg,
    /// Precision.
    #[arg(long, value_enum, default_value = "f32")]
    pub precision: PrecisionArg,
    /// Microphones.
    #[arg(long, default_value_t = 60)]
    pub mics: usize,
    /// Directions (full-sphere grid).
    #[arg(long, default_value_t = 2522)]
    pub directions: usize,
    /// Correlation window W (frames).
    #[arg(long, default_value_t = 50)]
    pub window: usize,
    /// NUM_SOURCE.
    #[arg(long, default_value_t = 2)]
    pub num_sources: usize,
    /// NormMUSIC: normalise each bin's spectrum to a maximum of 1 before the bin sum.
    #[arg(long)]
    pub normalize_bins: bool,
    /// Coherence normalisation (`--coherence` of `localize`), kernel benchmark only.
    #[arg(long)]
    pub coherence: bool,
    /// Signal-subspace dimension when it should differ from --num-sources (the robust
    /// default uses max(--num-sources, M/2)).
    #[arg(long)]
    pub subspace_dim: Option<usize>,
    /// Windows per batch for the throughput figure.
    #[arg(long, default_value_t = 16)]
    pub batch: usize,
    /// Timed repeats (median).
    #[arg(long, default_value_t = 10)]
    pub repeats: usize,
    /// Print the reports as JSON (one object per line) instead of a table.
    #[arg(long)]
    pub json: bool,
    /// The stream engine as live input drives it (10 ms pushes, PAST windows): real-time
    /// factor and latency, on the 8-mic ring and the seed configuration.
    #[arg(long)]
    pub stream: bool,
    /// With --stream: PERIOD in frames.
    #[arg(long, default_value_t = 1, requires = "stream_or_study")]
    pub period: usize,
    /// With --stream: seconds of audio per run (after one second of warm-up).
    #[arg(long, default_value_t = 5.0, requires = "stream", conflicts_with_all = ["accuracy", "e2e"])]
    pub seconds: f64,
    /// With --stream: concurrent streams sharing one device (a stream group: every 10 ms
    /// tick pushes a block into each, their windows run in one launch). Repeatable.
    #[arg(long = "streams", default_values_t = [1usize], requires = "stream", conflicts_with_all = ["accuracy", "e2e"])]
    pub streams: Vec<usize>,
    /// With --stream: the approximate mode (subspace tracking between windows, CPU); also
    /// prints how far its results are from the exact path's on simulated scenes.
    #[arg(long, requires = "stream", conflicts_with_all = ["accuracy", "e2e"])]
    pub subspace_tracking: bool,
    /// With --stream: the audio arrives at real-time pace (10 ms blocks) and every push
    /// takes all blocks queued so far, as live input does when the localizer falls behind
    /// (one stream): does it keep up, with what latency and batches.
    #[arg(long, requires = "stream", conflicts_with_all = ["accuracy", "e2e"])]
    pub paced: bool,
    /// With --stream: which arrays (repeatable; default: both).
    #[arg(long = "array", value_enum, requires = "stream_or_study")]
    pub arrays: Vec<ArrayArg>,
    /// End to end: localize --input with --tf (a HARK TF zip) and print where the time
    /// goes (TF load, plan, read, engine with its stages, write), first with the TF cache
    /// off (read from the zip), then through the cache (the second of those hits it).
    #[arg(long, requires_all = ["tf", "input"], conflicts_with = "stream")]
    pub e2e: bool,
    /// With --e2e: the transfer functions (HARK TF zip or HGTF).
    #[arg(long, requires = "e2e", conflicts_with_all = ["stream", "accuracy"])]
    pub tf: Option<std::path::PathBuf>,
    /// With --e2e: the recording (WAV/FLAC).
    #[arg(long, requires = "e2e", conflicts_with_all = ["stream", "accuracy"])]
    pub input: Option<std::path::PathBuf>,
    /// With --e2e: noise-only time range of the input for K, START:END seconds.
    #[arg(long, default_value = "0:1", requires = "e2e", conflicts_with_all = ["stream", "accuracy"])]
    pub noise_range: String,
    /// The accuracy study: simulated scenes (anechoic and RT60 0.2–0.6 s rooms, 1–3
    /// talkers, SNR +20…−10 dB; drone rotors or room noise: --scene) localized by every
    /// algorithm and option; prints the
    /// hit rate within 5° per group of conditions (Markdown). Uses --array (ring8 or
    /// seed = the 60-mic sphere; default ring8), --period, --scenes, --split.
    #[arg(long, conflicts_with_all = ["stream", "e2e"])]
    pub accuracy: bool,
    /// With --accuracy: seeds per condition.
    #[arg(long, default_value_t = 2, requires = "study", conflicts_with_all = ["stream", "e2e"])]
    pub scenes: usize,
    /// With --accuracy: which seeds, the tuning split or the held-out test split.
    #[arg(long, value_enum, default_value = "test", requires = "study", conflicts_with_all = ["stream", "e2e"])]
    pub split: SplitArg,
    /// With --accuracy: only the conditions with at most this SNR (dB).
    #[arg(long, allow_negative_numbers = true, requires = "accuracy", conflicts_with_all = ["stream", "e2e"])]
    pub max_snr: Option<f64>,
    /// With --accuracy: only the conditions with at least this SNR (dB).
    #[arg(long, allow_negative_numbers = true, requires = "accuracy", conflicts_with_all = ["stream", "e2e"])]
    pub min_snr: Option<f64>,
    /// With --accuracy: only the variants whose name contains this text (repeatable).
    #[arg(long, requires = "accuracy", conflicts_with_all = ["stream", "e2e"])]
    pub variant: Vec<String>,
    /// With --accuracy: what else sounds besides the talkers — drone rotors 25 cm from
    /// the array (the GEVD family, K from the first second), or broadband sources spread
    /// over the room (the algorithms that need no noise recording).
    #[arg(long, value_enum, default_value = "drone", requires = "study", conflicts_with_all = ["stream", "e2e"])]
    pub scene: SceneArg,
    /// With --accuracy: render with an array that differs from its model, as a real array
    /// differs from its geometry or measured TFs: each microphone's position off by this
    /// much per axis (standard deviation, mm) ...
    #[arg(long, default_value_t = 0.0, requires = "accuracy", conflicts_with_all = ["stream", "e2e"])]
    pub position_error_mm: f64,
    /// ... and each channel's gain by this much (standard deviation, dB).
    #[arg(long, default_value_t = 0.0, requires = "accuracy", conflicts_with_all = ["stream", "e2e"])]
    pub gain_error_db: f64,
    /// Tracking with ids: 12 s scenes (each talker speaking 4–7 s; 1–2 talkers, RT60
    /// 0–0.6 s) through the defaults with tracking, the tracker's confirmation off and
    /// at W/2, W and 2W frames, with and without --preroll 50; prints the true ids per talker, the false ids per minute
    /// and the coverage of the talkers' speech. Uses --scene (drone or room), --split,
    /// --scenes, --period.
    #[arg(long, conflicts_with_all = ["stream", "e2e", "accuracy"])]
    pub tracks: bool,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneArg {
    /// Four rotors 0.25 m from the array.
    Drone,
    /// Six broadband sources spread over the room, no drone.
    Room,
    /// One point source in the room sounding throughout (K from the first second).
    Interferer,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplitArg {
    /// Seeds 0… (choose settings on these).
    Tune,
    /// Seeds 1,000,000… (report on these).
    Test,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArrayArg {
    /// 8-mic circle, 72 directions.
    Ring8,
    /// 60 mics, 2522 directions.
    Seed,
    /// 4-mic circle (3.2 cm, a ReSpeaker 4-mic array's), 72 directions: --accuracy only.
    Ring4,
}

fn run_stream(a: &Args, algs: &[AlgorithmArg]) -> anyhow::Result<ExitCode> {
    use soundloc::bench::stream::{run, StreamArray, StreamBenchConfig};
    let arrays = if a.arrays.is_empty() {
        vec![ArrayArg::Ring8, ArrayArg::Seed]
    } else {
        a.arrays.clone()
    };
    for arr in arrays {
        for (&alg, &streams) in algs
            .iter()
            .flat_map(|alg| a.streams.iter().map(move |s| (alg, s)))
        {
            let cfg = StreamBenchConfig {
                array: match arr {
                    ArrayArg::Ring8 => StreamArray::Ring8,
                    ArrayArg::Seed => StreamArray::Seed,
                    ArrayArg::Ring4 => anyhow::bail!("--array ring4 is for --accuracy only"),
                },
                algorithm: alg.into(),
                period: a.period,
                seconds: a.seconds,
                block: 160,
                device: a.device.into(),
                precision: match a.precision {
                    PrecisionArg::F32 => soundloc::Precision::F32,
                    PrecisionArg::F64 => soundloc::Precision::F64,
                },
                streams: streams.max(1),
                subspace_tracking: a.subspace_tracking,
                paced: a.paced,
            };
            let r = run(&cfg)?;
            if a.json {
                outln!("{}", serde_json::to_string(&r)?);
            } else {
                outln!(
                    "stream {:?} {} on {}: M={} D={} PERIOD {} ({:.0} results/s of audio), 10 ms pushes, {:.1} s, {} stream(s)",
                    cfg.array,
                    cfg.algorithm.name(),
                    r.device,
                    r.num_mics,
                    r.num_dirs,
                    cfg.period,
                    100.0 / cfg.period as f64,
                    cfg.seconds,
                    cfg.streams
                );
                outln!(
                    "  real-time factor {:.4} ({:.1}x real time); latency last sample -> result: median {:.2} ms, p99 {:.2} ms, max {:.2} ms",
                    r.rtf,
                    1.0 / r.rtf,
                    r.latency_ms_median,
                    r.latency_ms_p99,
                    r.latency_ms_max
                );
                if let (Some(b), Some(q)) = (r.blocks_per_push, r.max_backlog_ms) {
                    outln!(
                        "  paced at real time: {b:.2} blocks (10 ms each) per push on average, largest backlog {q:.0} ms of audio{}",
                        if r.rtf < 1.0 { "" } else { " (it did not keep up)" }
                    );
                }
                let s = &r.stages_per_result;
                outln!(
                    "  per result (ms): correlation {:.3}, decomposition {:.3}, spectrum {:.3}, peaks {:.3}; rest {:.3}",
                    s.correlation_ms,
                    s.decomposition_ms,
                    s.spectrum_ms,
                    s.peaks_ms,
                    r.rtf * 1e3 * cfg.period as f64 / 100.0 / cfg.streams as f64
                        - (s.correlation_ms + s.decomposition_ms + s.spectrum_ms + s.peaks_ms)
                );
            }
        }
        if a.subspace_tracking {
            let study = match arr {
                ArrayArg::Ring8 => soundloc::bench::accuracy::StudyArray::Ring8,
                ArrayArg::Seed => soundloc::bench::accuracy::StudyArray::Sphere60,
                ArrayArg::Ring4 => anyhow::bail!("--array ring4 is for --accuracy only"),
            };
            for &alg in algs {
                let g = soundloc::bench::tracking::agreement(study, alg.into(), a.period, 2_000_000, 2)?;
                if a.json {
                    outln!("{}", serde_json::to_string(&g)?);
                } else {
                    outln!(
                        "tracking vs exact, {:?} {} PERIOD {}: {} scenes (2 talkers, rotor noise, SNR 0 dB, RT60 0-0.6 s), {} windows",
                        g.array,
                        g.algorithm.name(),
                        g.period,
                        g.scenes,
                        g.windows
                    );
                    outln!(
                        "  spectrum difference: RMS {:.4} dB, p99 {:.4} dB, max {:.3} dB; same top peak {:.1}% of windows",
                        g.rms_db,
                        g.p99_db,
                        g.max_db,
                        100.0 * g.same_top_peak
                    );
                    outln!(
                        "  talker-windows within 5 deg: exact {:.1}%, tracked {:.1}%; decomposition {:.3} -> {:.3} ms per window; whole runs (TF, K, plan, engine) {:.2} -> {:.2} s",
                        100.0 * g.hits_exact,
                        100.0 * g.hits_tracked,
                        g.decomposition_ms_exact,
                        g.decomposition_ms_tracked,
                        g.seconds_exact,
                        g.seconds_tracked
                    );
                }
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn run_e2e(a: &Args, alg: AlgorithmArg) -> anyhow::Result<ExitCode> {
    use soundloc::array::tf_cache::TfCache;
    use soundloc::{ArraySpec, LocalizerSpec, NoiseSource};
    let (Some(tf), Some(input)) = (&a.tf, &a.input) else {
        anyhow::bail!("--e2e needs --tf and --input");
    };
    let (start_s, end_s) = super::run_args::parse_range(&a.noise_range)?;
    let mut spec = LocalizerSpec::with_array(ArraySpec::TransferFunctions { path: tf.clone() });
    spec.algorithm = Some(alg.into());
    spec.analysis.period = a.period;
    spec.analysis.window = a.window;
    spec.analysis.num_sources = a.num_sources;
    spec.noise = NoiseSource::Range { start_s, end_s };
    spec.device = a.device.into();
    spec.precision = match a.precision {
        PrecisionArg::F32 => soundloc::Precision::F32,
        PrecisionArg::F64 => soundloc::Precision::F64,
    };
    for (label, cache) in [
        ("from the zip", TfCache::Off),
        ("through the cache", TfCache::Default),
        ("through the cache", TfCache::Default),
    ] {
        let r = soundloc::bench::e2e::run(&spec, input, cache)?;
        if a.json {
            outln!("{}", serde_json::to_string(&r)?);
            continue;
        }
        let s = &r.stages;
        outln!(
            "e2e {} PERIOD {} on {}, TF {label}: {:.2} s of audio, {} results: total {:.0} ms",
            soundloc::Algorithm::from(alg).name(),
            a.period,
            r.device,
            r.audio_s,
            r.results,
            r.total_ms
        );
        outln!(
            "  TF load {:.0} ms, plan {:.0} ms, read {:.0} ms, engine {:.0} ms (stages: correlation {:.0}, decomposition {:.0}, spectrum {:.0}, peaks {:.0}), write {:.1} ms",
            r.tf_load_ms,
            r.plan_ms,
            r.read_ms,
            r.engine_ms,
            s.correlation_ms,
            s.decomposition_ms,
            s.spectrum_ms,
            s.peaks_ms,
            r.write_ms
        );
        if let Some(n) = &r.cache_note {
            outln!("  {n}");
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn run_tracks(a: &Args) -> anyhow::Result<ExitCode> {
    use soundloc::bench::accuracy::{StudyNoise, TEST_SEED0};
    use soundloc::bench::track_ids::{markdown, run, TrackVariant};
    let (noise, snrs) = match a.scene {
        SceneArg::Drone => (StudyNoise::Rotors, [0.0, -5.0]),
        SceneArg::Room => (StudyNoise::Room, [10.0, 0.0]),
        SceneArg::Interferer => anyhow::bail!("--tracks: --scene drone or room"),
    };
    let seed0 = match a.split {
        SplitArg::Tune => 0,
        SplitArg::Test => TEST_SEED0,
    };
    let w = soundloc::LocalizeConfig::default().window;
    let v = |name: String, confirm_frames: Option<usize>, preroll: usize| TrackVariant {
        name,
        confirm_frames,
        preroll,
    };
    let variants = [
        v("confirmation off (HARK)".into(), Some(0), 0),
        v(format!("confirm over {} frames (W/2)", w / 2), Some(w / 2), 0),
        v(format!("confirm over {w} frames (W)"), Some(w), 0),
        v(format!("confirm over {} frames (2W)", 2 * w), Some(2 * w), 0),
        v("the default".into(), None, 0),
        v("confirmation off, --preroll 50".into(), Some(0), 50),
        v("the default, --preroll 50".into(), None, 50),
    ];
    let t = std::time::Instant::now();
    let scores = run(noise, &snrs, a.period, seed0, a.scenes.max(1), &variants)?;
    outln!(
        "tracking study: Ring8, {noise:?} noise, SNR {snrs:?} dB, {:?} split, {} scene(s) per condition, PERIOD {}, {:.0} s",
        a.split,
        a.scenes.max(1),
        a.period,
        t.elapsed().as_secs_f64()
    );
    if a.json {
        outln!("{}", serde_json::to_string(&scores)?);
    } else {
        out!("{}", markdown(&scores));
    }
    Ok(ExitCode::SUCCESS)
}

fn run_accuracy(a: &Args) -> anyhow::Result<ExitCode> {
    use soundloc::bench::accuracy::{
        run, variants_for, variants_without_noise, SceneKind, StudyArray, StudyNoise, TEST_SEED0,
    };
    if a.scenes == 0 {
        anyhow::bail!("--scenes 0: give at least 1 seed per condition");
    }
    let array = match a.arrays.first() {
        Some(ArrayArg::Seed) => StudyArray::Sphere60,
        Some(ArrayArg::Ring4) => StudyArray::Ring4,
        _ => StudyArray::Ring8,
    };
    let seed0 = match a.split {
        SplitArg::Tune => 0,
        SplitArg::Test => TEST_SEED0,
    };
    let period = if a.period == 1 { 25 } else { a.period };
    let max_snr = a.max_snr.unwrap_or(f64::INFINITY);
    let min_snr = a.min_snr.unwrap_or(f64::NEG_INFINITY);
    let only = move |c: &soundloc::bench::accuracy::Condition| c.snr_db <= max_snr && c.snr_db >= min_snr;
    let (noise, all) = match a.scene {
        SceneArg::Drone => (StudyNoise::Rotors, variants_for(array, period)),
        SceneArg::Room => (StudyNoise::Room, variants_without_noise(array, period)),
        SceneArg::Interferer => (StudyNoise::Interferer, variants_for(array, period)),
    };
    let vs: Vec<_> = all
        .into_iter()
        .filter(|v| a.variant.is_empty() || a.variant.iter().any(|s| v.name.contains(s.as_str())))
        .collect();
    if vs.is_empty() {
        anyhow::bail!("--variant {:?}: no variant of the study matches", a.variant);
    }
    let t = std::time::Instant::now();
    if !(a.position_error_mm >= 0.0
        && a.position_error_mm <= 100.0
        && a.gain_error_db >= 0.0
        && a.gain_error_db <= 20.0)
    {
        anyhow::bail!("--position-error-mm must be within 0..100 and --gain-error-db within 0..20");
    }
    let kind = SceneKind {
        noise,
        position_error_m: a.position_error_mm * 1e-3,
        gain_error_db: a.gain_error_db,
    };
    let study = run(array, kind, &vs, seed0, a.scenes, 5.0, &only, &|n, total| {
        eprint!("\rscenes {n}/{total}");
    })?;
    eprintln!();
    outln!(
        "accuracy study: {array:?}, {noise:?} noise{}, {:?} split, {} scene(s) per condition, PERIOD {period}, {} results per variant, hit = a reported peak within 5° (as many peaks as talkers), {:.0} s",
        if a.position_error_mm > 0.0 || a.gain_error_db > 0.0 {
            format!(", array errors {} mm / {} dB", a.position_error_mm, a.gain_error_db)
        } else {
            String::new()
        },
        a.split,
        a.scenes,
        study.localizations,
        t.elapsed().as_secs_f64()
    );
    if a.json {
        outln!("{}", serde_json::to_string(&study)?);
    } else {
        out!("{}", study.markdown());
    }
    Ok(ExitCode::SUCCESS)
}

/// Sizes the benchmark can build on an ordinary machine (its random steering alone is
/// mics × directions × 73 bins complex values).
fn check_sizes(a: &Args) -> anyhow::Result<()> {
    use anyhow::bail;
    use soundloc::array::{MAX_DIRECTIONS, MAX_MICS};
    if !(2..=MAX_MICS).contains(&a.mics) {
        bail!(
            "--mics {}: must be between 2 and {MAX_MICS} (MUSIC needs a noise subspace)",
            a.mics
        );
    }
    if !(2..=MAX_DIRECTIONS).contains(&a.directions) {
        bail!(
            "--directions {}: must be between 2 and {MAX_DIRECTIONS}",
            a.directions
        );
    }
    const MAX_STEERING_BYTES: f64 = 4.0 * (1u64 << 30) as f64;
    let bytes = a.mics as f64 * a.directions as f64 * 73.0 * 8.0;
    if bytes > MAX_STEERING_BYTES {
        bail!(
            "--mics {} × --directions {}: {:.1} GiB of steering vectors, more than this benchmark builds (4 GiB)",
            a.mics,
            a.directions,
            bytes / (1u64 << 30) as f64
        );
    }
    for (v, what) in [
        (a.batch, "--batch"),
        (a.repeats, "--repeats"),
        (a.window, "--window"),
        (a.period, "--period"),
    ] {
        if v == 0 {
            bail!("{what} 0: must be at least 1");
        }
    }
    if let Some(&0) = a.streams.iter().find(|&&n| n == 0) {
        bail!("--streams 0: must be at least 1");
    }
    if !(a.seconds.is_finite() && a.seconds > 0.0 && a.seconds <= 3600.0) {
        bail!("--seconds {}: must be more than 0 and at most 3600", a.seconds);
    }
    Ok(())
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    check_sizes(&a)?;
    let algs = if a.algorithms.is_empty() {
        vec![AlgorithmArg::Gsvd, AlgorithmArg::Gevd]
    } else {
        a.algorithms.clone()
    };
    if a.coherence && (a.stream || a.e2e || a.accuracy) {
        anyhow::bail!(
            "--coherence applies to the kernel benchmark, not to --stream, --e2e or --accuracy \
             (the accuracy study has coherence variants of its own)"
        );
    }
    if a.stream {
        return run_stream(&a, &algs);
    }
    if a.e2e {
        return run_e2e(&a, algs[0]);
    }
    if a.accuracy {
        return run_accuracy(&a);
    }
    if a.tracks {
        return run_tracks(&a);
    }
    for alg in algs {
        let cfg = BenchConfig {
            algorithm: alg.into(),
            num_mics: a.mics,
            num_dirs: a.directions,
            window: a.window,
            num_sources: a.num_sources,
            normalize_bins: a.normalize_bins,
            coherence: a.coherence,
            subspace_dim: a.subspace_dim,
            batch: a.batch,
            repeats: a.repeats,
            device: a.device.into(),
        };
        let r = match a.precision {
            PrecisionArg::F32 => run_bench::<f32>(&cfg)?,
            PrecisionArg::F64 => run_bench::<f64>(&cfg)?,
        };
        if a.json {
            outln!("{}", serde_json::to_string(&r)?);
        } else {
            print_report(&r)?;
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn print_report(r: &BenchReport) -> anyhow::Result<()> {
    let c = &r.config;
    let s = &r.stages_per_localization;
    outln!(
        "{} on {} ({}): M={} bins={} D={} W={} Ns={}",
        c.algorithm.name(),
        r.device,
        r.precision,
        c.num_mics,
        r.num_bins,
        c.num_dirs,
        c.window,
        c.num_sources
    );
    outln!(
        "  ms per localization (one window, median)  {:>10.3}",
        r.ms_per_localization
    );
    outln!(
        "  localizations per second (batch of {:>3})  {:>10.1}",
        c.batch,
        r.localizations_per_s
    );
    outln!(
        "  ms compute per s of audio, PERIOD 50     {:>10.3}   (real-time factor {:.4})",
        r.ms_per_audio_s_period50,
        r.rtf_period50
    );
    outln!(
        "  ms compute per s of audio, PERIOD 1      {:>10.3}   (real-time factor {:.4})",
        r.ms_per_audio_s_period1,
        r.rtf_period1
    );
    outln!(
        "  stage split per localization (ms): correlation {:.3}, decomposition {:.3}, spectrum {:.3}, peaks {:.3}",
        s.correlation_ms, s.decomposition_ms, s.spectrum_ms, s.peaks_ms
    );
    Ok(())
}
