//! `soundloc tf`: inspect HARK transfer-function files, make geometric ones.

use anyhow::bail;
use clap::{Subcommand, ValueEnum};
use soundloc::array::freefield::{free_field, DEFAULT_SPEED_OF_SOUND_M_S};
use soundloc::array::grid::GridSpec;
use soundloc::array::{Geometry, TransferFunctions};
use soundloc::formats::hark_zip::write_tf_zip;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub command: TfCommand,
}

#[derive(Subcommand, Debug)]
pub enum TfCommand {
    /// Describe a transfer-function file: HARK TF zip (HARK >= 2.1) or HGTF `*_loc.dat`.
    Inspect(InspectArgs),
    /// Write a geometric (free-field) HARK TF zip for an array and a direction grid, like
    /// harktool's geometric TFs (all N/2+1 bins).
    #[command(allow_negative_numbers = true)]
    Make(MakeArgs),
}

#[derive(clap::Args, Debug)]
pub struct InspectArgs {
    /// The TF file (zip or HGTF).
    pub file: PathBuf,
    /// Print JSON (one object) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Read and check every matrix of a TF zip (by default only its structure and first
    /// matrix are read; every matrix is checked to exist).
    #[arg(long)]
    pub verify: bool,
}

/// Built-in arrays.
#[derive(ValueEnum, Clone, Copy, Debug)]
pub enum BuiltinArray {
    /// 8 mics on a circle of radius 3.65 cm in the x-y plane (TAMAGO-03-like).
    Circle8,
    /// 60 mics spread over a sphere of radius 10 cm (Fibonacci lattice).
    Sphere60,
}

impl BuiltinArray {
    fn geometry(self) -> Geometry {
        match self {
            BuiltinArray::Circle8 => Geometry::circle(8, 0.0365, 0.0),
            BuiltinArray::Sphere60 => Geometry::sphere(60, 0.1),
        }
    }
}

#[derive(clap::Args, Debug)]
#[command(group(clap::ArgGroup::new("array").required(true).args(["geometry", "builtin"])))]
pub struct MakeArgs {
    /// Array geometry: TOML (`mics = [[x, y, z], ...]`, metres, channel order) or an ODAS
    /// configuration (*.cfg: general.mics, in its order).
    #[arg(long)]
    pub geometry: Option<PathBuf>,
    /// A built-in array instead of a geometry file.
    #[arg(long, value_enum)]
    pub builtin: Option<BuiltinArray>,
    /// Directions: ring:STEP_DEG[:ELEV_DEG], sphere:N or hemisphere:N (the upper half; e.g. ring:5, ring:5:16.7, sphere:2522, hemisphere:1261).
    #[arg(long)]
    pub grid: GridSpec,
    /// Distance of the grid points (the modelled sources) from the origin of the
    /// positions' frame (from the microphones' centroid when that origin lies outside the
    /// array), metres.
    #[arg(long = "grid-radius", default_value_t = 1.0, alias = "radius")]
    pub radius: f64,
    /// FFT length N (the zip holds N/2+1 bins). Default: 32 ms at the sampling rate, as
    /// `localize --geometry` uses (HARK's 512 at 16 kHz, 1536 at 48 kHz).
    #[arg(long)]
    pub fft_length: Option<usize>,
    /// Sampling rate, Hz.
    #[arg(long, default_value_t = 16000)]
    pub sample_rate: u32,
    /// Speed of sound, m/s.
    #[arg(long, default_value_t = DEFAULT_SPEED_OF_SOUND_M_S)]
    pub speed_of_sound: f64,
    /// Output zip.
    #[arg(short, long)]
    pub output: PathBuf,
    /// No summary of what was written, no notes (as `localize -q`).
    #[arg(long, short = 'q')]
    pub quiet: bool,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    match a.command {
        TfCommand::Inspect(a) => inspect(a),
        TfCommand::Make(a) => make(a),
    }
}

fn inspect(a: InspectArgs) -> anyhow::Result<ExitCode> {
    let quick = !a.verify
        && std::fs::File::open(&a.file)
            .and_then(|mut f| {
                let mut h = [0u8; 4];
                std::io::Read::read_exact(&mut f, &mut h).map(|_| h)
            })
            .is_ok_and(|h| soundloc::formats::hark_zip::looks_like_zip(&h));
    let summary = if quick {
        soundloc::formats::hark_zip::inspect_tf_zip(&a.file)?
    } else {
        TransferFunctions::load(&a.file)?.summary()
    };
    if a.json {
        let mut v = serde_json::to_value(&summary)?;
        if let Some(o) = v.as_object_mut() {
            o.insert("file".into(), a.file.display().to_string().into());
            o.insert("verified".into(), (!quick).into());
        }
        outln!("{v}");
    } else {
        outln!("file             {}", a.file.display());
        out!("{summary}");
        if quick {
            outln!("verified         no: the zip's directory and XML only (--verify reads every value)");
        } else {
            outln!("verified         yes: every value read (CRC, sizes, finite numbers)");
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn make(a: MakeArgs) -> anyhow::Result<ExitCode> {
    soundloc::output::atomic::check_output_path(&a.output, "-o")?;
    if let Some(g) = &a.geometry {
        soundloc::output::atomic::check_outputs(&[(&a.output, "-o")], &[(g, "--geometry")])?;
    }
    if !(a.radius.is_finite() && a.radius > 0.0) {
        bail!("--grid-radius {}: must be a positive number of metres", a.radius);
    }
    let (geometry, moved) = match (&a.geometry, a.builtin) {
        (Some(p), _) => Geometry::load(p)?,
        (None, Some(b)) => b.geometry(),
        (None, None) => bail!("give --geometry FILE or --builtin"),
    }
    .direction_frame(a.radius);
    // Warnings print under -q too, as localize's do.
    let notes = soundloc::array::freefield::free_field_notes(&geometry, a.radius, a.speed_of_sound);
    for n in moved.into_iter().chain(notes) {
        if !a.quiet || n.starts_with("warning:") {
            eprintln!("soundloc: {n}");
        }
    }
    let grid = a.grid.build(a.radius);
    let nfft = a
        .fft_length
        .unwrap_or(soundloc::config::frame_sizes_for_rate(a.sample_rate).0);
    let bins = 0..nfft / 2 + 1;
    let tf = free_field(&geometry, &grid, nfft, a.sample_rate, bins, a.speed_of_sound)?;
    write_tf_zip(&tf, &a.output)?;
    if a.quiet {
        return Ok(ExitCode::SUCCESS);
    }
    outln!(
        "wrote {}: {} mics, {} directions ({}, {} m), {} bins (nfft {}, {} Hz)",
        a.output.display(),
        tf.num_mics,
        tf.num_dirs(),
        a.grid,
        a.radius,
        tf.num_bins,
        tf.nfft,
        tf.sample_rate_hz
    );
    Ok(ExitCode::SUCCESS)
}
