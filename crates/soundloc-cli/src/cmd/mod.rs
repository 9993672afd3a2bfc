//! Subcommands.

/// `print!` to stdout that returns the error instead of panicking: a closed pipe
/// (`soundloc tf inspect … | head -1`) becomes [`sinks::StdoutClosed`] (a quiet success),
/// anything else (`> /dev/full`) an error naming stdout. Use inside a function returning
/// `anyhow::Result`.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        write!(std::io::stdout().lock(), $($arg)*).map_err($crate::cmd::sinks::stdout_error)?;
    }};
}

/// `println!` as [`out!`] does `print!`.
macro_rules! outln {
    () => { out!("\n") };
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout().lock(), $($arg)*).map_err($crate::cmd::sinks::stdout_error)?;
    }};
}

pub mod batch;
pub mod bench;
pub mod demo;
pub mod input;
pub mod listen;
mod live_out;
pub mod localize;
pub mod noisecm;
pub mod run_args;
mod senders;
pub mod sinks;
pub mod spectrum_out;
pub mod tf;

use clap::{Parser, Subcommand, ValueEnum};
use std::process::ExitCode;

/// MUSIC sound source localization for microphone arrays (SEVD / GEVD / GSVD), CPU and CUDA.
#[derive(Parser, Debug)]
#[command(name = "soundloc", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Simulated scenes with known answers, localized by every algorithm (no files needed).
    Demo(demo::Args),
    /// Localize sound sources in a recording, on standard input or from a TCP peer.
    #[command(allow_negative_numbers = true)]
    Localize(Box<localize::Args>),
    /// Localize many recordings, one result file each (a list or --manifest; --shard K/N;
    /// a rerun skips what is done).
    #[command(allow_negative_numbers = true, mut_args(batch::hide_per_input_options))]
    Batch(Box<batch::Args>),
    /// Localize a live microphone array (built with the `capture` feature).
    #[command(allow_negative_numbers = true)]
    Listen(Box<listen::Args>),
    /// Benchmark the seed configuration (GSVD, 60 mics, 73 bins, W 50, 2522 directions).
    Bench(Box<bench::Args>),
    /// Transfer functions: inspect HARK TF files, make geometric ones.
    #[command(allow_negative_numbers = true)]
    Tf(tf::Args),
    /// Noise correlation matrices (HARK CMSave/CMLoad files): make from a recording, inspect.
    #[command(allow_negative_numbers = true)]
    Noisecm(noisecm::Args),
    /// Developers: compile the kernel bundle embedded in the binary (needs NVRTC).
    #[command(hide = true)]
    CudaPrebuild(PrebuildArgs),
}

/// `soundloc cuda-prebuild`.
#[derive(clap::Args, Debug)]
pub struct PrebuildArgs {
    /// Target architecture.
    #[arg(long, default_value = "sm_90")]
    arch: String,
    /// The bundle to write (kernels/prebuilt/sm_XY.bin).
    #[arg(short, long)]
    output: std::path::PathBuf,
}

fn prebuild(a: PrebuildArgs) -> anyhow::Result<ExitCode> {
    let t = std::time::Instant::now();
    let bundle = soundloc::backend::cuda::nvrtc_prebuild(&a.arch).map_err(anyhow::Error::msg)?;
    soundloc::output::atomic::write_atomically(&a.output, |f| std::io::Write::write_all(f, &bundle))?;
    eprintln!(
        "soundloc: {} ({} bytes) in {:.1} s",
        a.output.display(),
        bundle.len(),
        t.elapsed().as_secs_f64()
    );
    Ok(ExitCode::SUCCESS)
}

/// `--device`: auto, cpu, cuda (GPU 0), cuda:all or cuda:N[,M...] (several GPUs share the
/// work).
#[derive(Clone, Copy, Debug, Default)]
pub struct DeviceArg(pub soundloc::backend::DeviceChoice);

impl std::str::FromStr for DeviceArg {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        s.parse()
            .map(DeviceArg)
            .map_err(|e: soundloc::Error| e.to_string())
    }
}

impl From<DeviceArg> for soundloc::backend::DeviceChoice {
    fn from(d: DeviceArg) -> Self {
        d.0
    }
}

/// Compute precision.
#[derive(ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PrecisionArg {
    /// Single precision (as HARK; default).
    #[default]
    F32,
    /// Double precision (reference).
    F64,
}

/// MUSIC algorithm.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum AlgorithmArg {
    /// Standard eigendecomposition of R (plain MUSIC; HARK's default).
    Sevd,
    /// Textbook generalized eigenvectors R e = λ K e (robust in coherent noise).
    Gevd,
    /// HARK's GEVD (eigenvectors of K^-1/2 R K^-1/2, no back-transform).
    GevdHark,
    /// HARK's GSVD (left singular vectors of K^-1 R; the seed paper's algorithm).
    Gsvd,
    /// Steered response power with the phase transform (no subspace, no noise matrix).
    SrpPhat,
}

impl From<AlgorithmArg> for soundloc::Algorithm {
    fn from(a: AlgorithmArg) -> Self {
        match a {
            AlgorithmArg::Sevd => Self::Sevd,
            AlgorithmArg::Gevd => Self::Gevd,
            AlgorithmArg::GevdHark => Self::GevdHark,
            AlgorithmArg::Gsvd => Self::Gsvd,
            AlgorithmArg::SrpPhat => Self::SrpPhat,
        }
    }
}

pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Bench(a) => bench::run(*a),
        Command::Demo(a) => demo::run(a),
        Command::Localize(a) => localize::run(*a),
        Command::Batch(a) => batch::run(*a),
        Command::Listen(a) => listen::run(*a),
        Command::Tf(a) => tf::run(a),
        Command::Noisecm(a) => noisecm::run(a),
        Command::CudaPrebuild(a) => prebuild(a),
    }
}

// Value enums of `localize`'s analysis and output options.

#[derive(ValueEnum, Clone, Copy, Debug)]
pub enum FormatArg {
    /// One JSON object per result per line.
    Jsonl,
    /// One CSV row per source (and one per window without sources).
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

/// `--numerator`.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum NumeratorArg {
    /// ‖a‖² (spec §5).
    Raw,
    /// ‖a_w‖² = aᴴK⁻¹a.
    Whitened,
    /// ‖a‖·‖a_w‖.
    Geometric,
}

impl From<NumeratorArg> for soundloc::config::Numerator {
    fn from(n: NumeratorArg) -> Self {
        match n {
            NumeratorArg::Raw => Self::Raw,
            NumeratorArg::Whitened => Self::Whitened,
            NumeratorArg::Geometric => Self::Geometric,
        }
    }
}

#[derive(ValueEnum, Clone, Copy, Debug)]
pub enum DenominatorArg {
    /// Σ|aᴴe|² (HARK's code).
    Squared,
    /// Σ|aᴴe| (the paper's equation 5 as printed).
    Unsquared,
}
