//! Where `localize` and `listen` put results. Result lines (JSON lines or CSV, on stdout or
//! `-o FILE`), the HARK source-location logs and the HARK network stream are written as
//! each window completes; stdout is flushed after every block, so a pipe sees each line
//! as soon as it exists; so are `-o`, the logs and the ODAS file outputs when they name a
//! FIFO or device. Files are written to a temporary file next to the target, renamed over
//! it only when the run succeeds. The summary is taken in as results come and written at
//! the end; the plot needs the whole run's results; the spectrum `.npy` is appended to its
//! temporary file as it comes and renamed at the end ([`super::spectrum_out`]). Every
//! output path is checked before localization starts.
//!
//! Live outputs never stall localization: the HARK stream and ODAS's SSL/SST messages go
//! through reconnecting senders that drop (and count) what a missing receiver cannot take,
//! and the browser view ([`crate::serve`]) drops per client.

use crate::serve::LiveServer;
use soundloc::output::live;
use soundloc::output::odas::{self, SstSlots};

pub use super::live_out::LiveArgs;
use super::live_out::{odas_target, report, OdasOut, NET_GRACE};
use super::localize::{note, FormatArg};
use super::run_args::RunArgs;
use super::spectrum_out::{spectrum_sidecar, SpectrumSink};
use anyhow::{bail, Context};
use soundloc::formats::source_log::{SourceLogFormat, SourceLogWriter};
use soundloc::output::atomic::{write_atomically, AtomicFile};
use soundloc::output::hark_stream::HarkStreamSender;
use soundloc::output::plot::plot_spectrum;
use soundloc::output::plot_keep::PlotKeep;
use soundloc::output::{csv::CsvWriter, jsonl::JsonlWriter};
use soundloc::{LocalizationResult, Localizer, Output};
use std::io::Write;
use std::path::{Path, PathBuf};

enum Lines<W: Write> {
    Jsonl(JsonlWriter<W>),
    Csv(CsvWriter<W>),
}

impl<W: Write> Lines<W> {
    fn new(format: FormatArg, w: W) -> std::io::Result<Self> {
        Ok(match format {
            FormatArg::Jsonl => Lines::Jsonl(JsonlWriter::new(w)),
            FormatArg::Csv => Lines::Csv(CsvWriter::new(w)?),
        })
    }
    fn write(&mut self, r: &LocalizationResult) -> std::io::Result<()> {
        match self {
            Lines::Jsonl(j) => j.write(r),
            Lines::Csv(c) => c.write(r),
        }
    }
    fn flush(&mut self) -> std::io::Result<()> {
        match self {
            Lines::Jsonl(j) => j.flush(),
            Lines::Csv(c) => c.flush(),
        }
    }
    fn into_inner(self) -> W {
        match self {
            Lines::Jsonl(j) => j.into_inner(),
            Lines::Csv(c) => c.into_inner(),
        }
    }
}

/// How far the run is, for the live view's status line.
#[derive(Debug, Clone, Copy, Default)]
pub struct Progress {
    /// Audio localized, s.
    pub audio_s: f64,
    /// Compute time so far, s.
    pub compute_s: f64,
    /// Compute time of the last block, s.
    pub last_compute_s: f64,
    /// Live input dropped while behind, s.
    pub lost_s: f64,
}

enum Dest {
    Stdout(Lines<std::io::Stdout>),
    /// `-o FILE`; `true` when FILE is a FIFO or device, written in place and flushed after
    /// every block as stdout is (a reader follows it live).
    File(Lines<AtomicFile>, PathBuf, bool),
    /// Stdout, after its reader closed it while other outputs were still being written.
    Closed,
}

/// Stdout's reader closed it (`soundloc … | head -1`): the reader's choice, so the run
/// ends with success ([`crate::main`] looks for this in an error's chain). A closed pipe
/// or FIFO given as a file (`-o`, `--odas-ssl`, …) is an error like any other.
#[derive(Debug)]
pub struct StdoutClosed;

impl std::fmt::Display for StdoutClosed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("stdout was closed by its reader")
    }
}

impl std::error::Error for StdoutClosed {}

/// An error writing results to stdout: [`StdoutClosed`] for a closed pipe.
pub fn stdout_error(e: std::io::Error) -> anyhow::Error {
    if e.kind() == std::io::ErrorKind::BrokenPipe {
        anyhow::Error::new(StdoutClosed)
    } else {
        anyhow::Error::new(e).context("writing results to stdout")
    }
}

/// The run's outputs.
pub struct Sinks {
    dest: Dest,
    hark: Option<HarkStreamSender>,
    view: Option<LiveServer>,
    ssl: Option<OdasOut>,
    sst: Option<(OdasOut, SstSlots)>,
    quiet: bool,
    /// What `--plot` draws, in bounded memory.
    keep: Option<PlotKeep>,
    /// `--summary`, taken in as results come.
    summary: Option<soundloc::tracking::Summarizer>,
    /// `--log-text`, `--log-xml`: written as results come.
    logs: Vec<(SourceLogWriter<AtomicFile>, PathBuf)>,
    /// `--spectrum`.
    spectrum: SpectrumSink,
    count: usize,
    pots: usize,
    /// Tracking is on: SSL gets the windows' own peaks ([`Output::peaks`]).
    tracking: bool,
}

fn status(p: &Progress, finished: bool) -> live::Status {
    live::Status {
        audio_s: p.audio_s,
        rtf: if p.audio_s > 0.0 {
            p.compute_s / p.audio_s
        } else {
            0.0
        },
        compute_ms: p.last_compute_s * 1e3,
        lost_s: p.lost_s,
        view_dropped: 0,
        finished,
    }
}

impl Sinks {
    /// Check every output path before anything is computed: its folder exists, it is not
    /// a folder, and it replaces neither an input (`input`: the recording's path, if any,
    /// and the run's other files) nor another output.
    /// For an input that waits for its sender (`tcp-listen:`): the live outputs'
    /// addresses are checked now (the view's port can be bound, the receivers' hosts
    /// resolve), so that a mistake is not found only once the sender has connected, its
    /// audio then lost.
    pub fn check_addresses(a: &RunArgs) -> anyhow::Result<()> {
        use std::net::ToSocketAddrs;
        if let Some(v) = &a.live.serve {
            // Not LiveServer::bind: its accept thread would keep the port for the run.
            LiveServer::check(&serve_address(v))?;
        }
        let mut peers = Vec::new();
        if let Some(h) = &a.hark_stream {
            peers.push(("--hark-stream", soundloc::output::hark_stream::peer_address(h)?));
        }
        for (v, what) in [(&a.live.odas_ssl, "ODAS SSL"), (&a.live.odas_sst, "ODAS SST")] {
            if let Some(addr) = v.as_deref().map(|v| odas_target(v, what)).transpose()?.flatten() {
                peers.push((what, addr.to_string()));
            }
        }
        for (what, p) in peers {
            p.to_socket_addrs()
                .with_context(|| format!("{what} {p}: cannot resolve the receiver's address"))?;
        }
        Ok(())
    }

    pub fn check_paths(a: &RunArgs, input: Option<&Path>) -> anyhow::Result<()> {
        let sidecar = a.spectrum.as_deref().map(spectrum_sidecar);
        let l = &a.live;
        let odas_files = [(&l.odas_ssl, "--odas-ssl"), (&l.odas_sst, "--odas-sst")];
        let mut outputs: Vec<(&Path, &str)> = Vec::new();
        for (p, what) in [
            (a.output.as_deref().filter(|p| !is_stdout(p)), "--output"),
            (a.spectrum.as_deref(), "--spectrum"),
            (sidecar.as_deref(), "--spectrum's .json"),
            (a.plot.as_deref(), "--plot"),
            (a.summary.as_deref(), "--summary"),
            (a.log_text.as_deref(), "--log-text"),
            (a.log_xml.as_deref(), "--log-xml"),
        ]
        .into_iter()
        .chain(
            odas_files
                .iter()
                .map(|(v, what)| {
                    let file = match v.as_deref() {
                        Some(v) => odas_target(v, what)?.is_none().then_some(v),
                        None => None,
                    };
                    Ok((file.map(Path::new), *what))
                })
                .collect::<anyhow::Result<Vec<_>>>()?,
        ) {
            if let Some(p) = p {
                soundloc::output::atomic::check_output_path(p, what)?;
                outputs.push((p, what));
            }
        }
        // Outputs written by name, not as a stream: a pipe or device cannot take them
        // (the others write one there directly, e.g. `-o /dev/stdout`).
        for (p, what) in [
            (
                a.spectrum.as_deref(),
                "--spectrum (two files: the .npy and its .json)",
            ),
            (a.plot.as_deref(), "--plot (an image written by name)"),
        ] {
            if let Some(p) = p.filter(|p| std::fs::metadata(p).is_ok_and(|m| !m.is_file())) {
                bail!(
                    "{}: {what}: not a regular file (a pipe or device); name a file",
                    p.display()
                );
            }
        }
        // A noise-CM text pair is two files (the imaginary one found by name).
        let cm_files = a
            .noise_cm
            .as_deref()
            .map(soundloc::formats::noise_cm::NoiseCm::files_read)
            .unwrap_or_default();
        let inputs: Vec<(&Path, &str)> = [
            (input, "the recording"),
            (a.tf.as_deref(), "--tf"),
            (a.geometry.as_deref(), "--geometry"),
            (a.noise.as_deref(), "--noise"),
        ]
        .into_iter()
        .filter_map(|(p, w)| p.map(|p| (p, w)))
        .chain(cm_files.iter().map(|p| (p.as_path(), "--noise-cm")))
        .collect();
        soundloc::output::atomic::check_outputs(&outputs, &inputs)?;
        if let Some(p) = &a.plot {
            let ext = p
                .extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase);
            if !matches!(ext.as_deref(), Some("png" | "svg")) {
                bail!(
                    "{}: --plot writes PNG or SVG: name the file .png or .svg",
                    p.display()
                );
            }
        }
        if a.summary.is_some() && !a.track {
            bail!("--summary needs --track");
        }
        if l.odas_sst.is_some() && !a.track {
            bail!("--odas-sst needs --track (SST messages carry tracked sources)");
        }
        for (n, what) in [(l.odas_pots, "--odas-pots"), (l.odas_tracks, "--odas-tracks")] {
            if !(1..=64).contains(&n) {
                bail!("{what} must be 1..=64, got {n}");
            }
        }
        Ok(())
    }

    /// Open the streaming outputs (the `-o` temporary file, the HARK stream connection).
    pub fn open(a: &RunArgs, loc: &Localizer, source: &str) -> anyhow::Result<Self> {
        let dest = match a.output.as_ref().filter(|p| !is_stdout(p)) {
            Some(p) => {
                let f = AtomicFile::create(p)?;
                let live = f.is_special();
                Dest::File(Lines::new(a.format, f)?, p.clone(), live)
            }
            None => Dest::Stdout(Lines::new(a.format, std::io::stdout()).map_err(stdout_error)?),
        };
        let hark = match &a.hark_stream {
            Some(addr) => Some(HarkStreamSender::connect(addr, loc.config().hop as i32)?),
            None => None,
        };
        let keep_all = a.plot.is_some();
        let mut logs = Vec::new();
        for (p, format) in [
            (&a.log_text, SourceLogFormat::Text),
            (&a.log_xml, SourceLogFormat::Xml),
        ] {
            if let Some(p) = p {
                let w = SourceLogWriter::new(AtomicFile::create(p)?, format)
                    .with_context(|| format!("{}: writing the source-location log", p.display()))?;
                logs.push((w, p.clone()));
            }
        }
        let l = &a.live;
        let ssl = l
            .odas_ssl
            .as_deref()
            .map(|v| OdasOut::open(v, "ODAS SSL"))
            .transpose()?;
        let sst = match l.odas_sst.as_deref() {
            Some(v) => Some((OdasOut::open(v, "ODAS SST")?, SstSlots::new(l.odas_tracks))),
            None => None,
        };
        let period = loc.config().period;
        if (ssl.is_some() || sst.is_some()) && period != 1 {
            super::localize::note(
                a.quiet,
                &format!(
                    "ODAS messages go out once per result, every {period} hops here; ODAS sends one \
                     per hop and odas_web expects consecutive time stamps (it logs \"Frame skipped\" \
                     and plots every 20th message): --period 1 for ODAS's rate"
                ),
            );
        }
        let peaks = loc.config().peaks_out();
        if ssl.is_some() && peaks < l.odas_pots {
            let (pots, rest) = (l.odas_pots, l.odas_pots - peaks);
            super::localize::note(
                a.quiet,
                &format!(
                    "ODAS SSL messages carry {pots} potential sources (--odas-pots), each result \
                     at most {peaks} peaks (--max-peaks, or --num-sources when not given): the \
                     other {rest} are zeros (E 0). --max-peaks {pots} fills them with the next \
                     peaks where a window has that many (every output then reports them); \
                     --odas-pots {peaks} leaves them out"
                ),
            );
        }
        let view = match &l.serve {
            Some(addr) => {
                let v = LiveServer::bind(&serve_address(addr), &l.serve_host)?;
                let c = loc.config();
                let grid = loc.grid();
                let az: Vec<f64> = (0..grid.len()).map(|d| grid.azimuth_deg(d)).collect();
                let el: Vec<f64> = (0..grid.len()).map(|d| grid.elevation_deg(d)).collect();
                let fs = c.sample_rate_hz as f64;
                let info = live::RunInfo {
                    source: source.to_string(),
                    algorithm: c.algorithm.name().to_string(),
                    label: c.label(),
                    device: loc.device_name(),
                    sample_rate_hz: c.sample_rate_hz,
                    hop: c.hop,
                    latency_ms: ((loc.latency_frames() + loc.preroll_hold_frames()) * c.hop + c.nfft) as f64
                        / fs
                        * 1e3,
                };
                v.hello(live::hello(&info, &az, &el));
                // Always said, even with --quiet: the user needs the address.
                let at = v.local_addr();
                if at.ip().is_unspecified() {
                    eprintln!(
                        "soundloc: live view at http://{at}/ (every interface: http://127.0.0.1:{p}/ on this \
                         machine, http://<its address>:{p}/ from others)",
                        p = at.port()
                    );
                } else {
                    eprintln!("soundloc: live view at http://{at}/");
                }
                Some(v)
            }
            None => None,
        };
        Ok(Sinks {
            dest,
            hark,
            view,
            ssl,
            sst,
            quiet: a.quiet,
            keep: keep_all.then(|| PlotKeep::new(loc.grid().len())),
            summary: a.summary.is_some().then(Default::default),
            logs,
            spectrum: SpectrumSink::new(a.spectrum.as_deref()),
            count: 0,
            pots: a.live.odas_pots,
            tracking: a.track,
        })
    }

    /// Whether anything but the result lines is being written (files at the end, ODAS,
    /// the HARK stream, the live view).
    fn other_outputs(&self) -> bool {
        self.keep.is_some()
            || self.summary.is_some()
            || !self.logs.is_empty()
            || self.spectrum.wanted()
            || self.ssl.is_some()
            || self.sst.is_some()
            || self.hark.is_some()
            || self.view.is_some()
    }

    /// Results written so far.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Prepare `out` for the stream: ask for the windows' own peaks where SSL needs them
    /// beside the tracks.
    pub fn arm(&self, out: &mut Output) {
        if self.tracking && self.ssl.is_some() {
            out.peaks = Some(Vec::new());
        }
    }

    /// Write what `out` holds now and empty it.
    pub fn emit(&mut self, out: &mut Output, progress: &Progress) -> anyhow::Result<()> {
        let results = std::mem::take(&mut out.results);
        let starts = std::mem::take(&mut out.track_starts);
        // ODAS's SSL carries each window's own peaks (potential sources), its SST the tracks.
        let peaks = out.peaks.as_mut().map(std::mem::take).unwrap_or_default();
        let pots = if self.tracking { &peaks } else { &results };
        let table = out.spectrum.take();
        if let Some(v) = &mut self.view {
            // Spectrum rows and results are both in frame order: one forward cursor.
            let mut row = 0;
            for r in &results {
                let spectrum = match &table {
                    Some(t) if v.spectrum_due(r.time_s) => {
                        while row < t.frames.len() && t.frames[row] < r.frame {
                            row += 1;
                        }
                        let d = t.num_dirs;
                        (t.frames.get(row) == Some(&r.frame))
                            .then(|| live::spectrum(r.frame, r.time_s, &t.db[row * d..(row + 1) * d]))
                    }
                    _ => None,
                };
                v.result(live::result(r), spectrum);
            }
            v.status(status(progress, false), false);
        }
        if let (Some(k), Some(t)) = (&mut self.keep, &table) {
            k.add_rows(t);
        }
        if let Some(t) = table.filter(|_| self.spectrum.wanted()) {
            self.spectrum.take(t)?;
        }
        let mut notes = Vec::new();
        if let Some(h) = &self.hark {
            notes.extend(h.net().take_notes());
        }
        for o in self.ssl.iter().chain(self.sst.iter().map(|s| &s.0)) {
            notes.extend(o.notes());
        }
        for n in notes {
            note(self.quiet, &n);
        }
        let mut text = String::new();
        if let Some(o) = &mut self.ssl {
            for r in pots {
                text.clear();
                odas::write_ssl(r, self.pots, &mut text);
                o.write(&text)?;
            }
        }
        // The tracker's first sightings come as ids are given, ahead of `--preroll`'s
        // delayed results: taken in whether or not this output has results.
        if let Some(s) = &mut self.summary {
            starts.iter().for_each(|t| s.started(t));
        }
        if results.is_empty() {
            return Ok(());
        }
        match &mut self.dest {
            Dest::Stdout(l) => {
                let written = results
                    .iter()
                    .try_for_each(|r| l.write(r))
                    .and_then(|_| l.flush());
                match written.map_err(stdout_error) {
                    // With other outputs the run goes on for them.
                    Err(e) if e.is::<StdoutClosed>() && self.other_outputs() => {
                        note(
                            self.quiet,
                            "stdout was closed by its reader: results are no longer printed; the other \
                             outputs are still written",
                        );
                        self.dest = Dest::Closed;
                    }
                    r => r?,
                }
            }
            Dest::Closed => {}
            Dest::File(l, p, live) => {
                for r in &results {
                    l.write(r)
                        .with_context(|| format!("{}: writing results", p.display()))?;
                }
                if *live {
                    l.flush()
                        .with_context(|| format!("{}: writing results", p.display()))?;
                }
            }
        }
        if let Some(h) = &mut self.hark {
            for r in &results {
                h.send(r, r.frame as i32)?;
            }
        }
        for r in &results {
            if let Some((o, slots)) = &mut self.sst {
                text.clear();
                slots.write(r, &mut text);
                o.write(&text)?;
            }
        }
        for (w, p) in &mut self.logs {
            let written = results.iter().try_for_each(|r| w.write(r)).and_then(|_| {
                if w.get_mut().is_special() {
                    w.get_mut().flush()
                } else {
                    Ok(())
                }
            });
            written.with_context(|| format!("{}: writing the source-location log", p.display()))?;
        }
        if let Some(s) = &mut self.summary {
            results.iter().for_each(|r| s.add(r));
        }
        self.count += results.len();
        if let Some(k) = &mut self.keep {
            k.add_results(&results);
        }
        Ok(())
    }

    /// The live view, to keep serving after the other outputs are finished.
    pub fn take_view(&mut self) -> Option<LiveServer> {
        self.view.take()
    }

    /// The live view's status message for `p`.
    pub fn status(p: &Progress, finished: bool) -> live::Status {
        status(p, finished)
    }

    /// The end-of-run outputs, then the `-o` file is renamed into place.
    pub fn finish(mut self, a: &RunArgs, loc: &Localizer, title: &str) -> anyhow::Result<()> {
        // The network outputs wind down together: each has NET_GRACE from now.
        if let Some(h) = &mut self.hark {
            h.close(NET_GRACE);
        }
        for o in [self.ssl.as_mut(), self.sst.as_mut().map(|s| &mut s.0)]
            .into_iter()
            .flatten()
        {
            if let OdasOut::Net(n) = o {
                n.close(NET_GRACE);
            }
        }
        if let Some(h) = self.hark {
            let peer = h.peer().to_string();
            let (stats, notes) = h.finish_noted(NET_GRACE);
            for m in notes {
                note(a.quiet, &m);
            }
            report(a.quiet, "HARK stream", &peer, stats);
        }
        if let Some(o) = self.ssl {
            o.finish(a.quiet)?;
        }
        if let Some((o, _)) = self.sst {
            o.finish(a.quiet)?;
        }
        if let (Some(p), Some(s)) = (&a.summary, self.summary) {
            let s = s.finish();
            write_atomically(p, |w| {
                serde_json::to_writer_pretty(&mut *w, &s)?;
                writeln!(w)
            })?;
        }
        for (w, p) in self.logs {
            let f = w
                .finish()
                .and_then(|mut f| f.flush().map(|_| f))
                .with_context(|| format!("{}: writing the source-location log", p.display()))?;
            f.commit()?;
        }
        let grid = loc.grid();
        let az: Vec<f64> = (0..grid.len()).map(|d| grid.azimuth_deg(d)).collect();
        let el: Vec<f64> = (0..grid.len()).map(|d| grid.elevation_deg(d)).collect();
        if let (Some(p), Some(k)) = (&a.plot, self.keep) {
            if !k.is_empty() {
                plot_spectrum(p, &k.plot(az.clone(), el.clone(), title.to_string()))?;
                super::localize::note(a.quiet, &format!("plot written to {}", p.display()));
            }
        }
        self.spectrum.finish(&az, &el, loc.config(), a.quiet)?;
        if let Dest::File(l, p, _) = self.dest {
            let mut f = l.into_inner();
            f.flush()
                .with_context(|| format!("{}: writing results", p.display()))?;
            f.commit()?;
        }
        Ok(())
    }
}

/// The live view's listening address for `--serve V`: a bare port means loopback.
fn serve_address(v: &str) -> String {
    if v.bytes().all(|b| b.is_ascii_digit()) {
        format!("127.0.0.1:{v}")
    } else {
        v.to_string()
    }
}

/// `-o -`: the results on stdout, as without `-o`.
pub fn is_stdout(p: &Path) -> bool {
    p.as_os_str() == "-"
}
