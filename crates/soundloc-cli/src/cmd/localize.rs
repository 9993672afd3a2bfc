//! `soundloc localize`: localize sound sources in a recording.

use super::{AlgorithmArg, DeviceArg, PrecisionArg};
use anyhow::{anyhow, bail, Context};
use clap::ValueEnum;
use soundloc::array::freefield::{free_field, DEFAULT_SPEED_OF_SOUND_M_S};
use soundloc::array::grid::GridSpec;
use soundloc::array::{Geometry, TransferFunctions};
use soundloc::audio::{read_audio, Audio};
use soundloc::config::{Denominator, SpectrumWeight};
use soundloc::engine::{estimate_noise, Engine, Localization};
use soundloc::noise::NoiseMatrices;
use soundloc::online::{localize_online, NoiseUpdate};
use soundloc::output::plot::{plot_spectrum, SpectrumPlot};
use soundloc::output::{atomic::write_atomically, csv::CsvWriter, jsonl::JsonlWriter, npy::write_npy_f32};
use soundloc::tracking::{IntervalExtenderConfig, SourceTracker, TrackerConfig};
use soundloc::{Algorithm, LocalizationResult, LocalizeConfig, WindowFunction, WindowType};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(ValueEnum, Clone, Copy, Debug)]
pub enum FormatArg {
    /// One JSON object per result per line.
    Jsonl,
    /// One CSV row per source.
    Csv,
}

#[derive(ValueEnum, Clone, Copy, Debug)]
pub enum WindowTypeArg {
    /// The W frames ending at the result frame (causal).
    Past,
    /// Frames centred on the result frame.
    Middle,
    /// The W frames starting at the result frame (HARK default).
    Future,
}

#[derive(ValueEnum, Clone, Copy, Debug)]
pub enum WindowFnArg {
    /// HARK's CONJ window.
    Conj,
    /// Hamming.
    Hamming,
    /// Hann.
    Hanning,
    /// Rectangular.
    Rectangle,
}

#[derive(ValueEnum, Clone, Copy, Debug)]
pub enum SpectrumWeightArg {
    /// w_k = 1.
    Uniform,
    /// A-weighting curve.
    AWeighting,
}

#[derive(ValueEnum, Clone, Copy, Debug)]
pub enum DenominatorArg {
    /// Σ|aᴴe|² (HARK's code).
    Squared,
    /// Σ|aᴴe| (the paper's equation 5 as printed).
    Unsquared,
}

/// Analysis options shared by `localize` (HARK LocalizeMUSIC parameter names in brackets).
#[derive(clap::Args, Debug, Clone)]
pub struct AnalysisArgs {
    /// MUSIC_ALGORITHM. Default: sevd, or gevd when a noise source is given.
    #[arg(long, value_enum)]
    pub algorithm: Option<AlgorithmArg>,
    /// NUM_SOURCE: signal subspace dimension (< number of mics).
    #[arg(long, default_value_t = 2)]
    pub num_sources: usize,
    /// MAXNUM_OUT_PEAKS: -1 = NUM_SOURCE, 0 = all peaks.
    #[arg(long, default_value_t = -1, allow_hyphen_values = true)]
    pub max_peaks: i64,
    /// WINDOW: frames per correlation matrix.
    #[arg(long, default_value_t = 50)]
    pub window: usize,
    /// WINDOW_TYPE.
    #[arg(long, value_enum, default_value = "future")]
    pub window_type: WindowTypeArg,
    /// PERIOD: one result every PERIOD frames.
    #[arg(long, default_value_t = 50)]
    pub period: usize,
    /// MIN_DEG: azimuth range kept, degrees.
    #[arg(long, default_value_t = -180.0, allow_hyphen_values = true)]
    pub min_deg: f64,
    /// MAX_DEG: azimuth range kept, degrees.
    #[arg(long, default_value_t = 180.0, allow_hyphen_values = true)]
    pub max_deg: f64,
    /// LOWER_BOUND_FREQUENCY, Hz.
    #[arg(long, default_value_t = 500.0)]
    pub lower_freq: f64,
    /// UPPER_BOUND_FREQUENCY, Hz (exclusive bin).
    #[arg(long, default_value_t = 2800.0)]
    pub upper_freq: f64,
    /// LENGTH: FFT length in samples.
    #[arg(long, default_value_t = 512)]
    pub fft_length: usize,
    /// ADVANCE: hop in samples.
    #[arg(long, default_value_t = 160)]
    pub hop: usize,
    /// STFT window function (MultiFFT WINDOW).
    #[arg(long, value_enum, default_value = "conj")]
    pub window_function: WindowFnArg,
    /// ENABLE_EIGENVALUE_WEIGHT.
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub eigenvalue_weight: bool,
    /// SPECTRUM_WEIGHT_TYPE.
    #[arg(long, value_enum, default_value = "uniform")]
    pub spectrum_weight: SpectrumWeightArg,
    /// Manual spectrum weights, one per used bin, comma-separated (overrides --spectrum-weight).
    #[arg(long, value_delimiter = ',')]
    pub spectrum_weights: Vec<f64>,
    /// MUSIC denominator.
    #[arg(long, value_enum, default_value = "squared")]
    pub denominator: DenominatorArg,
    /// Diagonal loading of K, relative to its mean diagonal (0 = none).
    #[arg(long, default_value_t = 0.0)]
    pub diagonal_loading: f64,
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Input recording (WAV 16/24/32-bit int or 32-bit float, or FLAC).
    pub input: PathBuf,
    /// HARK transfer-function zip or old HGTF (*_loc.dat).
    #[arg(long, conflicts_with = "geometry")]
    pub tf: Option<PathBuf>,
    /// Microphone positions (TOML, metres) for free-field transfer functions.
    #[arg(long)]
    pub geometry: Option<PathBuf>,
    /// Direction grid for --geometry: ring:STEP_DEG[:ELEV_DEG] or sphere:N.
    #[arg(long, default_value = "ring:5")]
    pub grid: String,
    /// Distance of the grid points for --geometry (m).
    #[arg(long, default_value_t = 1.0)]
    pub grid_radius: f64,
    /// Speed of sound for --geometry (m/s).
    #[arg(long, default_value_t = DEFAULT_SPEED_OF_SOUND_M_S)]
    pub speed_of_sound: f64,
    /// TF_CHANNEL_SELECTION: TF channels to use, comma-separated (0-based). Applied to the
    /// audio too when it has the TF's full channel count.
    #[arg(long, value_delimiter = ',')]
    pub channels: Vec<usize>,
    /// ChannelSelector: input channels to keep, comma-separated (0-based), applied to the
    /// recording and to --noise before anything else (e.g. drop a reference channel).
    #[arg(long, value_delimiter = ',')]
    pub input_channels: Vec<usize>,
    /// Noise-only recording for K.
    #[arg(long, conflicts_with_all = ["noise_range", "noise_cm"])]
    pub noise: Option<PathBuf>,
    /// Noise-only time range of the input for K, START:END in seconds.
    #[arg(long, conflicts_with = "noise_cm")]
    pub noise_range: Option<String>,
    /// Noise correlation matrix file (HARK text pair or zip).
    #[arg(long)]
    pub noise_cm: Option<PathBuf>,
    /// iGSVD/iGEVD: update K online from these noise-only segments of the input,
    /// START:END[,START:END...] seconds (each used once its frames are complete).
    #[arg(long, conflicts_with = "noise_preceding")]
    pub noise_segments: Option<String>,
    /// iGSVD/iGEVD: update K before each window from the FRAMES frames ending GAP frames
    /// before it (HARK's delayed correlation maker), FRAMES[:GAP].
    #[arg(long)]
    pub noise_preceding: Option<String>,
    #[command(flatten)]
    pub analysis: AnalysisArgs,
    /// Output format.
    #[arg(long, value_enum, default_value = "jsonl")]
    pub format: FormatArg,
    /// Write results here instead of stdout.
    #[arg(long, short = 'o')]
    pub output: Option<PathBuf>,
    /// Write the dB spectrum [result][direction] as .npy (plus FILE.json with times and directions).
    #[arg(long)]
    pub spectrum: Option<PathBuf>,
    /// Write a plot of the spectrum over time × azimuth (.png or .svg).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Track sources (HARK SourceTracker) and add ids.
    #[arg(long)]
    pub track: bool,
    /// SourceTracker THRESH (dB): peaks below are ignored.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub thresh: f64,
    /// SourceTracker PAUSE_LENGTH.
    #[arg(long, default_value_t = 800.0)]
    pub pause_length: f64,
    /// SourceTracker MIN_SRC_INTERVAL (degrees).
    #[arg(long, default_value_t = 20.0)]
    pub min_src_interval: f64,
    /// SourceTracker MIN_ID.
    #[arg(long, default_value_t = 0)]
    pub min_id: i64,
    /// SourceIntervalExtender PREROLL_LENGTH (frames); 0 = off.
    #[arg(long, default_value_t = 0)]
    pub preroll: usize,
    /// With --track: write the per-source summary (JSON) here.
    #[arg(long)]
    pub summary: Option<PathBuf>,
    /// Write a HARK source-location log (text, HARK <= 2.0).
    #[arg(long)]
    pub log_text: Option<PathBuf>,
    /// Write a HARK source-location log (XML, HARK >= 2.1).
    #[arg(long)]
    pub log_xml: Option<PathBuf>,
    /// Send results to a HarkDataStreamSender receiver at HOST:PORT (SRC_INFO packets).
    #[arg(long)]
    pub hark_stream: Option<String>,
    /// Compute device.
    #[arg(long, value_enum, default_value = "auto")]
    pub device: DeviceArg,
    /// Compute precision.
    #[arg(long, value_enum, default_value = "f32")]
    pub precision: PrecisionArg,
    /// No progress bar or notes on stderr.
    #[arg(long, short = 'q')]
    pub quiet: bool,
}

impl AnalysisArgs {
    /// The typed config (the algorithm resolved by the caller).
    pub fn config(&self, algorithm: Algorithm, sample_rate_hz: u32) -> LocalizeConfig {
        LocalizeConfig {
            algorithm,
            nfft: self.fft_length,
            hop: self.hop,
            sample_rate_hz,
            window_function: match self.window_function {
                WindowFnArg::Conj => WindowFunction::Conj,
                WindowFnArg::Hamming => WindowFunction::Hamming,
                WindowFnArg::Hanning => WindowFunction::Hanning,
                WindowFnArg::Rectangle => WindowFunction::Rectangle,
            },
            window: self.window,
            window_type: match self.window_type {
                WindowTypeArg::Past => WindowType::Past,
                WindowTypeArg::Middle => WindowType::Middle,
                WindowTypeArg::Future => WindowType::Future,
            },
            period: self.period,
            num_sources: self.num_sources,
            max_peaks: self.max_peaks,
            min_deg: self.min_deg,
            max_deg: self.max_deg,
            lower_freq_hz: self.lower_freq,
            upper_freq_hz: self.upper_freq,
            spectrum_weight: if !self.spectrum_weights.is_empty() {
                SpectrumWeight::Manual(self.spectrum_weights.clone())
            } else {
                match self.spectrum_weight {
                    SpectrumWeightArg::Uniform => SpectrumWeight::Uniform,
                    SpectrumWeightArg::AWeighting => SpectrumWeight::AWeighting,
                }
            },
            eigenvalue_weight: self.eigenvalue_weight,
            denominator: match self.denominator {
                DenominatorArg::Squared => Denominator::Squared,
                DenominatorArg::Unsquared => Denominator::Unsquared,
            },
            diagonal_loading: self.diagonal_loading,
        }
    }
}

/// The online noise-update rule from --noise-segments / --noise-preceding.
fn noise_update(a: &Args) -> anyhow::Result<NoiseUpdate> {
    if let Some(s) = &a.noise_segments {
        let segs = s
            .split(',')
            .map(parse_range)
            .collect::<anyhow::Result<Vec<_>>>()?;
        return Ok(NoiseUpdate::Segments(segs));
    }
    if let Some(s) = &a.noise_preceding {
        let (f, g) = s.split_once(':').unwrap_or((s, "0"));
        let bad = || format!("--noise-preceding {s:?}: expected FRAMES[:GAP]");
        let frames: usize = f.trim().parse().with_context(bad)?;
        let gap: usize = g.trim().parse().with_context(bad)?;
        if frames == 0 {
            bail!("--noise-preceding {s:?}: FRAMES must be at least 1");
        }
        return Ok(NoiseUpdate::Preceding { frames, gap });
    }
    Ok(NoiseUpdate::Fixed)
}

/// Parse `START:END` seconds.
pub fn parse_range(s: &str) -> anyhow::Result<(f64, f64)> {
    let (a, b) = s
        .split_once(':')
        .ok_or_else(|| anyhow!("noise range {s:?}: expected START:END in seconds, e.g. 0:1.5"))?;
    let a: f64 = a
        .trim()
        .parse()
        .with_context(|| format!("noise range {s:?}: bad start"))?;
    let b: f64 = b
        .trim()
        .parse()
        .with_context(|| format!("noise range {s:?}: bad end"))?;
    if !(a >= 0.0 && b > a) {
        bail!("noise range {s:?}: need 0 <= START < END");
    }
    Ok((a, b))
}

fn note(quiet: bool, msg: &str) {
    if !quiet {
        eprintln!("soundloc: {msg}");
    }
}

/// Load the TFs from --tf or --geometry/--grid, apply --channels.
fn transfer_functions(a: &Args, config: &LocalizeConfig) -> anyhow::Result<TransferFunctions> {
    let tf = match (&a.tf, &a.geometry) {
        (Some(p), _) => TransferFunctions::load(p)?,
        (None, Some(g)) => {
            let geometry = Geometry::load(g)?;
            let spec: GridSpec = a.grid.parse()?;
            let grid = spec.build(a.grid_radius);
            free_field(
                &geometry,
                &grid,
                config.nfft,
                config.sample_rate_hz,
                0..config.nfft / 2 + 1,
                a.speed_of_sound,
            )?
        }
        (None, None) => bail!(
            "no transfer functions: give --tf FILE (HARK TF zip or *_loc.dat) or --geometry array.toml --grid ring:5"
        ),
    };
    Ok(if a.channels.is_empty() {
        tf
    } else {
        tf.select_channels(&a.channels)?
    })
}

/// Apply --input-channels (HARK's ChannelSelector).
fn pick_input_channels(audio: Audio, keep: &[usize], what: &Path) -> anyhow::Result<Audio> {
    if keep.is_empty() {
        return Ok(audio);
    }
    audio
        .select_channels(keep)
        .with_context(|| format!("{}: --input-channels", what.display()))
}

/// Apply --channels to audio that has the TF's full channel count.
fn select_audio(audio: Audio, channels: &[usize], full_mics: usize, what: &Path) -> anyhow::Result<Audio> {
    if channels.is_empty() || audio.num_channels() == channels.len() {
        return Ok(audio);
    }
    if audio.num_channels() == full_mics {
        return Ok(audio.select_channels(channels)?);
    }
    bail!(
        "{}: has {} channels; --channels selects {} of the transfer functions' {}",
        what.display(),
        audio.num_channels(),
        channels.len(),
        full_mics
    )
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let audio = pick_input_channels(read_audio(&a.input)?, &a.input_channels, &a.input)?;
    let update = noise_update(&a)?;
    let noise_given = a.noise.is_some()
        || a.noise_range.is_some()
        || a.noise_cm.is_some()
        || !matches!(update, NoiseUpdate::Fixed);
    let algorithm: Algorithm = match a.analysis.algorithm {
        Some(x) => x.into(),
        None if noise_given => {
            note(
                a.quiet,
                "a noise source was given: using the textbook GEVD (choose with --algorithm)",
            );
            Algorithm::Gevd
        }
        None => Algorithm::Sevd,
    };
    if algorithm.uses_noise() && !noise_given {
        note(
            a.quiet,
            &format!("{} without a noise source: K = identity", algorithm.name()),
        );
    }
    let config = a.analysis.config(algorithm, audio.sample_rate_hz);
    let tf = transfer_functions(&a, &config)?;
    let config = LocalizeConfig {
        sample_rate_hz: tf.sample_rate_hz,
        ..config
    };
    let full_mics = if a.channels.is_empty() {
        tf.num_mics
    } else {
        // The TF before selection had at least max(channel)+1 mics; the audio must match it.
        a.channels.iter().max().map_or(0, |m| m + 1).max(tf.num_mics)
    };
    let full_mics = if let Some(p) = &a.tf {
        TransferFunctions::load(p)
            .map(|t| t.num_mics)
            .unwrap_or(full_mics)
    } else if let Some(g) = &a.geometry {
        Geometry::load(g).map(|g| g.num_mics()).unwrap_or(full_mics)
    } else {
        full_mics
    };
    let audio = select_audio(audio, &a.channels, full_mics, &a.input)?;
    if audio.sample_rate_hz != tf.sample_rate_hz {
        bail!(
            "{}: sampled at {} Hz, but the transfer functions are for {} Hz",
            a.input.display(),
            audio.sample_rate_hz,
            tf.sample_rate_hz
        );
    }
    if audio.num_channels() != tf.num_mics {
        bail!(
            "{}: has {} channels, but the transfer functions have {} microphones (select with --channels)",
            a.input.display(),
            audio.num_channels(),
            tf.num_mics
        );
    }
    let noise: Option<NoiseMatrices> = if !algorithm.uses_noise() {
        None
    } else if let Some(p) = &a.noise {
        let n = pick_input_channels(read_audio(p)?, &a.input_channels, p)?;
        let n = select_audio(n, &a.channels, full_mics, p)?;
        if n.num_channels() != tf.num_mics {
            bail!(
                "{}: noise recording has {} channels, the transfer functions {}",
                p.display(),
                n.num_channels(),
                tf.num_mics
            );
        }
        Some(
            estimate_noise(&config, n.sample_rate_hz, &n.channels, None)
                .with_context(|| format!("{}", p.display()))?,
        )
    } else if let Some(r) = &a.noise_range {
        let range = parse_range(r)?;
        Some(
            estimate_noise(&config, audio.sample_rate_hz, &audio.channels, Some(range))
                .with_context(|| format!("{}: --noise-range {r}", a.input.display()))?,
        )
    } else if let Some(p) = &a.noise_cm {
        Some(crate::cmd::noise_cm_for(p, &config, tf.num_mics)?)
    } else {
        None
    };

    let show_progress = !a.quiet && audio.duration_s() > 3.0;
    let want_spectrum = a.spectrum.is_some() || a.plot.is_some();
    let run = match a.precision {
        PrecisionArg::F32 => localize::<f32>(
            &config,
            &tf,
            noise.as_ref(),
            a.device,
            &audio,
            &update,
            want_spectrum,
            show_progress,
        )?,
        PrecisionArg::F64 => localize::<f64>(
            &config,
            &tf,
            noise.as_ref(),
            a.device,
            &audio,
            &update,
            want_spectrum,
            show_progress,
        )?,
    };
    note(
        a.quiet,
        &format!(
            "{} results from {:.2} s of {}-channel audio, {} on {}",
            run.results.len(),
            audio.duration_s(),
            audio.num_channels(),
            algorithm.name(),
            run.device
        ),
    );
    let mut results = run.results.clone();
    if a.track {
        let cfg = TrackerConfig {
            thresh_db: a.thresh,
            pause_length: a.pause_length,
            min_src_interval_deg: a.min_src_interval,
            min_id: a.min_id,
        };
        cfg.validate()?;
        let mut tracker = SourceTracker::new(cfg);
        results = results.iter().map(|r| tracker.update(r)).collect();
        if a.preroll > 0 {
            results = soundloc::tracking::extend(
                &results,
                IntervalExtenderConfig {
                    preroll_length: a.preroll,
                },
            );
        }
        if let Some(p) = &a.summary {
            let s = soundloc::tracking::summarize(&results);
            write_atomically(p, |w| {
                serde_json::to_writer_pretty(&mut *w, &s)?;
                writeln!(w)
            })?;
        }
    } else if a.summary.is_some() {
        bail!("--summary needs --track");
    }
    write_results(&a, &results)?;
    if let Some(p) = &a.log_text {
        soundloc::formats::source_log::write(
            p,
            &results,
            soundloc::formats::source_log::SourceLogFormat::Text,
        )?;
    }
    if let Some(p) = &a.log_xml {
        soundloc::formats::source_log::write(
            p,
            &results,
            soundloc::formats::source_log::SourceLogFormat::Xml,
        )?;
    }
    if let Some(addr) = &a.hark_stream {
        let mut s = soundloc::output::hark_stream::HarkStreamSender::connect(addr, config.hop as i32)?;
        for r in &results {
            s.send(r, r.frame as i32)?;
        }
    }
    if let Some(table) = &run.spectrum {
        if let Some(p) = &a.spectrum {
            write_spectrum(p, table, &tf)?;
            note(a.quiet, &format!("spectrum written to {}", p.display()));
        }
        if let Some(p) = &a.plot {
            let plot = SpectrumPlot {
                times_s: table.times_s.clone(),
                azimuth_deg: (0..tf.num_dirs()).map(|d| tf.grid.azimuth_deg(d)).collect(),
                elevation_deg: (0..tf.num_dirs()).map(|d| tf.grid.elevation_deg(d)).collect(),
                db: table.db.clone(),
                peaks: results
                    .iter()
                    .map(|r| r.sources.iter().map(|s| (s.azimuth_deg, s.power_db)).collect())
                    .collect(),
                truth_azimuths_deg: Vec::new(),
                title: format!(
                    "{} — {} MUSIC, {}",
                    a.input
                        .file_name()
                        .map(|s| s.to_string_lossy().into_owned())
                        .unwrap_or_default(),
                    algorithm.name(),
                    run.device
                ),
            };
            plot_spectrum(p, &plot)?;
            note(a.quiet, &format!("plot written to {}", p.display()));
        }
    }
    Ok(ExitCode::SUCCESS)
}

#[allow(clippy::too_many_arguments)]
fn localize<T: soundloc::Real>(
    config: &LocalizeConfig,
    tf: &TransferFunctions,
    noise: Option<&NoiseMatrices>,
    device: DeviceArg,
    audio: &Audio,
    update: &NoiseUpdate,
    want_spectrum: bool,
    progress: bool,
) -> anyhow::Result<Localization> {
    let mut engine = Engine::<T>::new(config, tf, noise, device.into())?;
    let bar = progress.then(|| {
        let b = indicatif::ProgressBar::new(0);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} localizing [{bar:40}] {pos}/{len} windows {eta}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    });
    let mut cb = |done: usize, total: usize| {
        if let Some(b) = &bar {
            b.set_length(total as u64);
            b.set_position(done as u64);
        }
    };
    let run = if matches!(update, NoiseUpdate::Fixed) {
        engine.localize_samples(audio.sample_rate_hz, &audio.channels, want_spectrum, &mut cb)?
    } else {
        let spectra = engine.spectra(audio.sample_rate_hz, &audio.channels)?;
        localize_online(&mut engine, &spectra, update, want_spectrum, &mut cb)?
    };
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    Ok(run)
}

fn write_results(a: &Args, results: &[LocalizationResult]) -> anyhow::Result<()> {
    let emit = |w: &mut dyn Write| -> std::io::Result<()> {
        match a.format {
            FormatArg::Jsonl => {
                let mut j = JsonlWriter::new(w);
                j.write_all(results)?;
                j.flush()
            }
            FormatArg::Csv => {
                let mut c = CsvWriter::new(w)?;
                c.write_all(results)?;
                c.flush()
            }
        }
    };
    match &a.output {
        Some(p) => write_atomically(p, |w| emit(w))?,
        None => {
            let stdout = std::io::stdout();
            let mut lock = stdout.lock();
            emit(&mut lock).context("writing results to stdout")?;
        }
    }
    Ok(())
}

fn write_spectrum(
    path: &Path,
    table: &soundloc::engine::SpectrumTable,
    tf: &TransferFunctions,
) -> anyhow::Result<()> {
    let rows = table.frames.len();
    write_atomically(path, |w| write_npy_f32(w, rows, table.num_dirs, &table.db))?;
    let meta = serde_json::json!({
        "description": "dB MUSIC spectrum 10*log10(P+1), rows = results, columns = directions",
        "shape": [rows, table.num_dirs],
        "frames": table.frames,
        "times_s": table.times_s,
        "azimuth_deg": (0..tf.num_dirs()).map(|d| tf.grid.azimuth_deg(d)).collect::<Vec<_>>(),
        "elevation_deg": (0..tf.num_dirs()).map(|d| tf.grid.elevation_deg(d)).collect::<Vec<_>>(),
    });
    let mut side = path.as_os_str().to_owned();
    side.push(".json");
    write_atomically(PathBuf::from(side), |w| {
        serde_json::to_writer(&mut *w, &meta)?;
        writeln!(w)
    })?;
    Ok(())
}
