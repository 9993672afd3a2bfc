//! `soundloc localize`: localize sound sources in a recording.

use super::input::{spawn_reader, InputArgs, Msg};
use super::run_args::RunArgs;
use super::sinks::{Progress, Sinks};
pub use super::FormatArg;
use anyhow::{anyhow, bail};
use soundloc::audio::AudioFormat;
use soundloc::{Block, Localizer, LocalizerSpec, Output};
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

/// `soundloc localize`: an input, and what to do with it.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub run: RunArgs,
}

/// A note on stderr; with `--quiet` only warnings (lost audio, a silent input, a dead
/// channel: what makes the results wrong or incomplete).
pub fn note(quiet: bool, msg: &str) {
    if !quiet || msg.starts_with("warning:") {
        eprintln!("soundloc: {msg}");
    }
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    Sinks::check_paths(&args.run, Some(Path::new(&args.input.input)))?;
    // A busy or malformed --serve port, or a receiver that does not resolve, is said before
    // the transfer functions load (and, for tcp-listen:, before a sender connects).
    Sinks::check_addresses(&args.run)?;
    let mut ready = None;
    if args.input.input.starts_with("tcp-listen:") {
        // What can be checked before a sender connects is checked now: an error after it
        // connected would throw its audio away. The addresses were checked above; the
        // transfer functions (and K) are loaded where the rate is known (a raw input's --rate, or a TF file's own), and a raw
        // input's channels are checked against the array. The localizer is kept for the
        // run when the sender's audio asks for the same one.
        let spec = args.run.spec(args.input.rate.unwrap_or(16000))?;
        if let (Some(rate), Some(channels)) = (args.input.rate, args.input.raw_channels) {
            let loc = Localizer::new(&spec)?;
            loc.input_converter(rate, channels)
                .map_err(|e| anyhow!("{}: {e}", args.input.input))?;
            ready = Some((spec, loc));
        } else if args.run.tf.is_some() {
            ready = Some((spec.clone(), Localizer::new(&spec)?));
        }
    }
    let input = args.input.open(args.run.quiet)?;
    let (fmt, rx) = spawn_reader(
        input.source,
        input.live,
        &args.input,
        args.run.live.serve.is_some(),
    );
    drive(&args.run, &input.name, input.live, fmt, rx, ready)
}

/// Localize what the reader sends, writing results as they complete. `ready`: a
/// localizer already built, used if its spec is the one this input needs.
pub fn drive(
    a: &RunArgs,
    name: &Path,
    live: bool,
    fmt: AudioFormat,
    rx: super::input::Queue,
    ready: Option<(LocalizerSpec, Localizer)>,
) -> anyhow::Result<ExitCode> {
    let spec = a.spec(fmt.sample_rate_hz)?;
    tracing::debug!("localizer: setting up");
    // (A pre-built localizer for another spec is dropped here, before the new one is built.)
    let mut loc = match ready.filter(|(s, _)| *s == spec) {
        Some((_, loc)) => loc,
        None => Localizer::new(&spec)?,
    };
    tracing::debug!("localizer ready");
    // Set-up notes (the algorithm run, the TF cache) once per process: `batch` sets up
    // one localizer per recording.
    static SEEN: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());
    for n in loc.notes() {
        let mut seen = SEEN.lock().unwrap_or_else(|e| e.into_inner());
        if !seen.contains(n) {
            seen.push(n.clone());
            note(a.quiet, n);
        }
    }
    let mut resampler = loc
        .input_converter(fmt.sample_rate_hz, fmt.channels)
        .map_err(|e| anyhow!("{}: {e}", name.display()))?;
    let in_rate = fmt.sample_rate_hz;
    let fmt = match &resampler {
        Some(r) => {
            note(
                a.quiet,
                &format!(
                    "{}: resampling {} Hz to the transfer functions' {} Hz",
                    name.display(),
                    r.rate_in(),
                    r.rate_out()
                ),
            );
            AudioFormat {
                sample_rate_hz: r.rate_out(),
                total_frames: fmt.total_frames.map(|n| r.output_frames(n)),
                ..fmt
            }
        }
        None => fmt,
    };
    let mut converted = Vec::new();
    let fs = fmt.sample_rate_hz as f64;
    if live {
        let c = loc.config();
        let hold = loc.preroll_hold_frames();
        let delay = loc.latency_frames() + hold;
        note(
            a.quiet,
            &format!(
                "streaming from {}: a result is out {} frames ({:.0} ms) after its frame starts, plus one frame of {} samples{}",
                name.display(),
                delay,
                delay as f64 * c.hop as f64 / fs * 1e3,
                c.nfft,
                if hold > 0 {
                    format!(" (of which {hold} frames --preroll's wait)")
                } else {
                    String::new()
                }
            ),
        );
    }
    if live && a.plot.is_some() {
        let keep = soundloc::output::plot_keep::PlotKeep::new(loc.grid().len());
        note(
            a.quiet,
            &format!(
                "--plot is written when this live session ends; until then it keeps at most about {:.0} MB (past {} results, neighbouring ones merge by their maximum, finer than the picture's pixels)",
                (keep.max_groups() * (loc.grid().len() * 4 + 600)) as f64 / 1e6,
                keep.max_groups()
            ),
        );
    }
    let mut sinks = Sinks::open(a, &loc, &name.display().to_string())?;
    let total = fmt.total_frames.unwrap_or(0);
    let bar = (!a.quiet && !live && total as f64 / fs > 3.0).then(|| {
        let b = indicatif::ProgressBar::new(total);
        b.set_style(
            indicatif::ProgressStyle::with_template("{spinner} localizing [{bar:40}] {percent}% {eta}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    });
    let nch = fmt.channels;
    let mut out = Output::default();
    sinks.arm(&mut out);
    let (mut audio_frames, mut lost_frames, mut gaps) = (0u64, 0u64, 0usize);
    let mut progress = Progress::default();
    let mut next_report = 10.0;
    let ctx = |e: soundloc::Error| anyhow!("{}: {e}", name.display());
    // Queued blocks arrive at the input's rate.
    let catch_up = (soundloc::input::CATCH_UP_S * in_rate as f64) as usize * nch;
    let mut held: Option<Msg> = None;
    loop {
        let msg = match held.take() {
            Some(m) => m,
            None => rx
                .recv()
                .map_err(|_| anyhow!("{}: the reader stopped", name.display()))?,
        };
        let t = Instant::now();
        let (mut data, gap, end, pause) = match msg {
            Msg::Block { data, gap } => (data, gap, false, 0),
            Msg::End { gap } => (Vec::new(), gap, true, 0),
            Msg::Pause { lost, frames } => (Vec::new(), lost, false, frames),
            Msg::Failed(e) => return Err(e.into()),
            Msg::Note(n) => {
                note(a.quiet, &n);
                continue;
            }
            Msg::LikeAFile(n) => {
                // A file being piped: no progress lines of a live session from now on.
                note(a.quiet, &n);
                next_report = f64::INFINITY;
                continue;
            }
        };
        if live && !end {
            super::input::catch_up(&rx, &mut data, catch_up, &mut held);
        }
        let (mut gap, mut pause) = (gap, pause);
        if let Some(r) = &mut resampler {
            // Before a gap or the end the converter's last samples go in; a gap becomes
            // the output frames that keep later samples at their true times.
            converted.clear();
            if gap > 0 {
                gap = r.gap(gap, &mut converted).map_err(ctx)?;
            }
            if pause > 0 {
                pause = r.gap(pause, &mut converted).map_err(ctx)?;
            }
            if end {
                r.finish(&mut converted).map_err(ctx)?;
            }
            if !converted.is_empty() {
                let block = Block::Interleaved {
                    data: &converted,
                    channels: nch,
                };
                loc.push(block, &mut out).map_err(ctx)?;
                audio_frames += (converted.len() / nch) as u64;
            }
            if !end {
                converted.clear();
                r.process(&data, &mut converted).map_err(ctx)?;
                std::mem::swap(&mut data, &mut converted);
            }
        }
        if gap > 0 {
            loc.skip(gap, &mut out).map_err(ctx)?;
            lost_frames += gap;
            gaps += 1;
        }
        if pause > 0 {
            loc.pause(pause, &mut out).map_err(ctx)?;
        }
        if end {
            match loc.flush(&mut out) {
                // A live session stopped before its first window: no results, no error
                // (a recording that short stays one).
                Err(soundloc::Error::NoWindow(m)) if super::input::interrupted() => {
                    note(a.quiet, &format!("no results: {m}"))
                }
                r => r.map_err(ctx)?,
            }
        } else if !data.is_empty() {
            loc.push(
                Block::Interleaved {
                    data: &data,
                    channels: nch,
                },
                &mut out,
            )
            .map_err(ctx)?;
            audio_frames += (data.len() / nch) as u64;
        }
        let dt = t.elapsed().as_secs_f64();
        progress.compute_s += dt;
        progress.last_compute_s = dt;
        progress.audio_s = audio_frames as f64 / fs;
        progress.lost_s = lost_frames as f64 / fs;
        for n in out.notes.drain(..) {
            note(a.quiet, &n);
        }
        sinks.emit(&mut out, &progress)?;
        if let Some(b) = &bar {
            b.set_position(audio_frames);
        }
        let audio_s = audio_frames as f64 / fs;
        if live && audio_s >= next_report {
            next_report += 10.0;
            note(
                a.quiet,
                &format!(
                    "{audio_s:.1} s localized, real-time factor {:.3} (compute / audio){}",
                    progress.compute_s / audio_s,
                    if lost_frames > 0 {
                        format!(", {:.2} s lost in {gaps} gaps", lost_frames as f64 / fs)
                    } else {
                        String::new()
                    }
                ),
            );
        }
        if end {
            break;
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    if audio_frames == 0 {
        bail!("{}: no audio frames (zero samples)", name.display());
    }
    let audio_s = audio_frames as f64 / fs;
    tracing::debug!(
        "input done: {audio_s:.2} s of audio, {:.3} s in the engine ({:?})",
        progress.compute_s,
        loc.stage_times()
    );
    // The microphones analysed, when a selection keeps fewer than the input has.
    let mics = loc.num_mics();
    let channels = if mics < nch {
        format!("{nch}-channel audio ({mics} microphones used)")
    } else {
        format!("{nch}-channel audio")
    };
    note(
        a.quiet,
        &format!(
            "{} results from {:.2} s of {channels}, {} on {} (real-time factor {:.4})",
            sinks.count(),
            audio_s,
            loc.config().label(),
            loc.device_name(),
            progress.compute_s / audio_s
        ),
    );
    if lost_frames > 0 {
        let rtf = progress.compute_s / audio_s;
        // Computing at well under real time, the run was held up elsewhere: by what reads
        // its outputs (a pipe that is read slowly blocks every write).
        let why = if rtf < 0.5 {
            format!(
                "the input came faster than it was handled; the localization itself ran at a real-time \
                 factor of {rtf:.3}: writing the results held it up, e.g. a slow reader of stdout or of a FIFO"
            )
        } else {
            "the input came faster than it was localized".to_string()
        };
        note(
            a.quiet,
            &format!(
                "warning: {:.2} s of audio lost in {gaps} gaps ({why})",
                lost_frames as f64 / fs
            ),
        );
    }
    let title = format!(
        "{} — {}, {}",
        name.file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        loc.config().label(),
        loc.device_name()
    );
    let view = sinks.take_view();
    sinks.finish(a, &loc, &title)?;
    tracing::debug!("outputs written");
    drop(loc);
    tracing::debug!("localizer released");
    // Ended by Ctrl-C (or SIGTERM, SIGHUP): the view goes with the run, as it was asked.
    if let Some(mut v) = view.filter(|_| !super::input::interrupted()) {
        v.status(Sinks::status(&progress, true), true);
        note(
            a.quiet,
            &format!(
                "the input has ended; the live view stays at http://{}/ until Ctrl-C",
                v.local_addr()
            ),
        );
        super::input::wait_for_ctrl_c();
    }
    Ok(ExitCode::SUCCESS)
}
