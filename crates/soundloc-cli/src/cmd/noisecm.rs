//! `soundloc noisecm`: make and inspect HARK noise correlation matrices (CMSave / CMLoad).

use anyhow::Context;
use clap::{Subcommand, ValueEnum};
use soundloc::audio::read_audio;
use soundloc::formats::noise_cm::{text_pair_paths, Expected, NoiseCm};
use soundloc::WindowFunction;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub command: NoiseCmCommand,
}

#[derive(Subcommand, Debug)]
pub enum NoiseCmCommand {
    /// Estimate K (x xᴴ averaged over the noise frames, every bin 0..=N/2) from a
    /// noise-only recording and write it as HARK reads it.
    #[command(allow_negative_numbers = true)]
    Make(MakeArgs),
    /// Describe a noise correlation file: channels, bins, per-bin trace and conditioning.
    Inspect(InspectArgs),
}

/// Output format of `noisecm make`.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum CmFormat {
    /// HARK <= 2.0 text pair (real and imaginary part files).
    Text,
    /// HARK >= 2.1 zip.
    Zip,
}

/// STFT analysis window (HARK MultiFFT WINDOW).
#[derive(ValueEnum, Clone, Copy, Debug)]
pub enum WindowArg {
    /// HARK's CONJ window.
    Conj,
    /// Hamming.
    Hamming,
    /// Hann.
    Hanning,
    /// Rectangular.
    Rectangle,
}

impl From<WindowArg> for WindowFunction {
    fn from(w: WindowArg) -> Self {
        match w {
            WindowArg::Conj => Self::Conj,
            WindowArg::Hamming => Self::Hamming,
            WindowArg::Hanning => Self::Hanning,
            WindowArg::Rectangle => Self::Rectangle,
        }
    }
}

#[derive(clap::Args, Debug)]
pub struct MakeArgs {
    /// Noise-only recording (WAV or FLAC).
    pub input: PathBuf,
    /// Output. Text: the pair's name (`K` → K_r, K_i; `noise_r.dat` → noise_r.dat,
    /// noise_i.dat); zip: the zip file.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Time range of the input to average, START:END in seconds (default: all).
    #[arg(long, value_parser = parse_range)]
    pub range: Option<(f64, f64)>,
    /// Output format (default: zip when the output ends in .zip, else text).
    #[arg(long, value_enum)]
    pub format: Option<CmFormat>,
    /// FFT length N (LENGTH) [default: 32 ms of the recording's rate, as `localize
    /// --geometry` and `tf make`: 512 at 16 kHz, 1536 at 48 kHz]. It must be the
    /// localization's: the file records the bins, not the rate.
    #[arg(long)]
    pub fft_length: Option<usize>,
    /// Frame advance in samples (ADVANCE) [default: 10 ms of the recording's rate: 160 at
    /// 16 kHz, 480 at 48 kHz].
    #[arg(long)]
    pub hop: Option<usize>,
    /// Analysis window function (WINDOW), as `localize --window-function`.
    #[arg(long, value_enum, default_value = "conj", alias = "window")]
    pub window_function: WindowArg,
    /// Input channels to use, comma-separated (0-based; default: all), as `localize
    /// --input-channels`.
    #[arg(long, value_delimiter = ',', alias = "channels")]
    pub input_channels: Vec<usize>,
    /// Input channels to negate, comma-separated (0-based), as `localize
    /// --invert-channels`: K then matches a localization with the same option.
    #[arg(long, value_delimiter = ',')]
    pub invert_channels: Vec<usize>,
    /// No summary of what was written (warnings stay), as `localize -q`.
    #[arg(long, short = 'q')]
    pub quiet: bool,
}

#[derive(clap::Args, Debug)]
pub struct InspectArgs {
    /// A zip, or the real-part file of a text pair (the imaginary one is found by name),
    /// or both as REAL,IMAG.
    pub file: PathBuf,
    /// Print JSON (one object, with every bin) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also print one line per bin.
    #[arg(long)]
    pub bins: bool,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    match a.command {
        NoiseCmCommand::Make(a) => make(a),
        NoiseCmCommand::Inspect(a) => inspect(a),
    }
}

/// START:END in seconds, 0 <= START < END.
fn parse_range(s: &str) -> Result<(f64, f64), String> {
    let bad = || format!("{s:?}: expected START:END in seconds with 0 <= START < END, e.g. 0:1.5");
    let (a, b) = s.split_once(':').ok_or_else(bad)?;
    let a: f64 = a.trim().parse().map_err(|_| bad())?;
    let b: f64 = b.trim().parse().map_err(|_| bad())?;
    if !(a.is_finite() && b.is_finite() && a >= 0.0 && b > a) {
        return Err(bad());
    }
    Ok((a, b))
}

fn make(a: MakeArgs) -> anyhow::Result<ExitCode> {
    let ext_is = |names: &[&str]| {
        a.output
            .extension()
            .is_some_and(|e| names.iter().any(|x| e.eq_ignore_ascii_case(x)))
    };
    let zip_name = ext_is(&["zip"]);
    if a.format == Some(CmFormat::Text) && zip_name {
        anyhow::bail!(
            "{}: --format text writes a pair of text files, not a zip: name them without .zip (-o K gives K_r and K_i) or use --format zip",
            a.output.display()
        );
    }
    if ext_is(&["wav", "flac"]) {
        anyhow::bail!(
            "{}: -o names the noise matrix, not audio: give a name such as K (the text pair K_r, K_i) or K.zip",
            a.output.display()
        );
    }
    let format = a
        .format
        .unwrap_or(if zip_name { CmFormat::Zip } else { CmFormat::Text });
    let (re, im) = text_pair_paths(&a.output);
    let outs: Vec<(&std::path::Path, &str)> = if format == CmFormat::Text {
        vec![(&re, "-o (real part)"), (&im, "-o (imaginary part)")]
    } else {
        vec![(&a.output, "-o")]
    };
    // The name given (a text pair's stem too: a folder there is a mistake) and the files.
    soundloc::output::atomic::check_output_path(&a.output, "-o")?;
    for (p, what) in &outs {
        soundloc::output::atomic::check_output_path(p, what)?;
    }
    soundloc::output::atomic::check_outputs(&outs, &[(&a.input, "the recording")])?;
    let audio = read_audio(&a.input)?;
    let kept = match a.input_channels.len() {
        0 => audio.num_channels(),
        k => k,
    };
    let map = soundloc::input::ChannelMap {
        input_channels: a.input_channels.clone(),
        inverted: a.invert_channels.clone(),
        ..soundloc::input::ChannelMap::identity(kept)
    };
    let idx = map
        .resolve(audio.num_channels())
        .with_context(|| format!("{}: --input-channels / --invert-channels", a.input.display()))?;
    let mut audio = audio
        .select_channels(&idx)
        .with_context(|| format!("{}: --input-channels", a.input.display()))?;
    map.invert(&idx, &mut audio.channels);
    let fs = audio.sample_rate_hz;
    let (nfft, hop) = soundloc::config::frame_sizes_for_rate(fs);
    let (nfft, hop) = (a.fft_length.unwrap_or(nfft), a.hop.unwrap_or(hop));
    // The input checks `localize` makes (a dead, constant or clipping channel), which also
    // explain a K that is not positive definite.
    let mut health = soundloc::audio::health::ChannelHealth::new(idx.clone(), fs as f64, hop, None);
    health.observe(&audio.channels.iter().map(Vec::as_slice).collect::<Vec<_>>());
    let warnings = health.notes(true);
    for w in &warnings {
        eprintln!("soundloc: {}: {w}", a.input.display());
    }
    let (cm, frames) = NoiseCm::estimate(&audio.channels, fs, nfft, hop, a.window_function.into(), a.range)
        .with_context(|| format!("{}", a.input.display()))?;
    let shape = format!(
        "{} channels, {} bins (nfft {} at {fs} Hz, {:.2} Hz apart; the file does not record the rate: use it with transfer functions of {fs} Hz and nfft {}), {} frames of {}",
        cm.num_mics,
        cm.num_bins(),
        cm.nfft,
        fs as f64 / cm.nfft as f64,
        cm.nfft,
        frames,
        a.input.display()
    );
    match format {
        CmFormat::Text => {
            cm.write_text_pair(&re, &im)?;
            if !a.quiet {
                outln!(
                    "wrote {} (real part) and {} (imaginary part): {shape}",
                    re.display(),
                    im.display()
                );
            }
        }
        CmFormat::Zip => {
            cm.write_zip(&a.output)?;
            if !a.quiet {
                outln!(
                    "wrote {}: {shape}; single precision, as HARK's zips (a text pair keeps full precision)",
                    a.output.display()
                );
            }
        }
    }
    let s = cm.summary();
    if s.not_positive_definite > 0 {
        let why = if warnings.is_empty() {
            "use more noise frames or diagonal loading (or look for two channels carrying the same signal)"
        } else {
            "see the channel warnings above (a dead or constant channel has no noise of its own); otherwise use more noise frames or diagonal loading"
        };
        eprintln!(
            "soundloc: warning: K is not positive definite in {} of {} bins ({} frames for {} channels): \
             GEVD/GSVD will reject it; {why}",
            s.not_positive_definite, s.num_bins, frames, cm.num_mics
        );
    }
    Ok(ExitCode::SUCCESS)
}

fn inspect(a: InspectArgs) -> anyhow::Result<ExitCode> {
    let cm = NoiseCm::load(&a.file, Expected::default())?;
    let s = cm.summary();
    if a.json {
        let mut v = serde_json::to_value(&s)?;
        if let Some(o) = v.as_object_mut() {
            o.insert("file".into(), a.file.display().to_string().into());
        }
        outln!("{v}");
        return Ok(ExitCode::SUCCESS);
    }
    outln!("file             {}", a.file.display());
    out!("{s}");
    if a.bins {
        outln!(
            "{:>5} {:>12} {:>12} {:>12} {:>12}",
            "bin",
            "trace",
            "min eig",
            "max eig",
            "condition"
        );
        for (k, b) in s.bins.iter().enumerate() {
            outln!(
                "{k:>5} {:>12.4e} {:>12.4e} {:>12.4e} {:>12.4e}",
                b.trace,
                b.min_eigenvalue,
                b.max_eigenvalue,
                b.condition
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}
