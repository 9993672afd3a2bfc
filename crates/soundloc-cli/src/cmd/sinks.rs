//! Where `localize` and `listen` put results. Result lines (JSON lines or CSV, on stdout or
//! `-o FILE`) and the HARK network stream are written as each window completes; stdout is
//! flushed after every block, so a pipe sees each line as soon as it exists. `-o` writes a
//! temporary file next to the target and renames it over the target only when the run
//! succeeds. Outputs that need the whole run (summary, HARK logs, the spectrum `.npy`, the
//! plot) are written at the end. Every output path is checked before localization starts.

use super::localize::{FormatArg, RunArgs};
use anyhow::{bail, Context};
use soundloc::output::atomic::{write_atomically, AtomicFile};
use soundloc::output::hark_stream::HarkStreamSender;
use soundloc::output::plot::{plot_spectrum, SpectrumPlot};
use soundloc::output::{csv::CsvWriter, jsonl::JsonlWriter, npy::write_npy_f32};
use soundloc::{LocalizationResult, Localizer, Output, SpectrumTable};
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

enum Dest {
    Stdout(Lines<std::io::Stdout>),
    File(Lines<AtomicFile>, PathBuf),
}

/// The run's outputs.
pub struct Sinks {
    dest: Dest,
    hark: Option<HarkStreamSender>,
    /// Every result, when an end-of-run output needs them.
    keep: Option<Vec<LocalizationResult>>,
    spectrum: Option<SpectrumTable>,
    count: usize,
}

fn check_dir(p: &Path, what: &str) -> anyhow::Result<()> {
    if let Some(d) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
        if !d.is_dir() {
            bail!(
                "{}: {what}: the directory {} does not exist",
                p.display(),
                d.display()
            );
        }
    }
    Ok(())
}

impl Sinks {
    /// Check every output path before anything is computed.
    pub fn check_paths(a: &RunArgs) -> anyhow::Result<()> {
        for (p, what) in [
            (&a.output, "--output"),
            (&a.spectrum, "--spectrum"),
            (&a.plot, "--plot"),
            (&a.summary, "--summary"),
            (&a.log_text, "--log-text"),
            (&a.log_xml, "--log-xml"),
        ] {
            if let Some(p) = p {
                check_dir(p, what)?;
            }
        }
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
        Ok(())
    }

    /// Open the streaming outputs (the `-o` temporary file, the HARK stream connection).
    pub fn open(a: &RunArgs, loc: &Localizer) -> anyhow::Result<Self> {
        let dest = match &a.output {
            Some(p) => Dest::File(Lines::new(a.format, AtomicFile::create(p)?)?, p.clone()),
            None => {
                Dest::Stdout(Lines::new(a.format, std::io::stdout()).context("writing results to stdout")?)
            }
        };
        let hark = match &a.hark_stream {
            Some(addr) => Some(HarkStreamSender::connect(addr, loc.config().hop as i32)?),
            None => None,
        };
        let keep_all = a.summary.is_some() || a.log_text.is_some() || a.log_xml.is_some() || a.plot.is_some();
        Ok(Sinks {
            dest,
            hark,
            keep: keep_all.then(Vec::new),
            spectrum: None,
            count: 0,
        })
    }

    /// Results written so far.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Write what `out` holds now and empty it.
    pub fn emit(&mut self, out: &mut Output, _loc: &Localizer) -> anyhow::Result<()> {
        let results = std::mem::take(&mut out.results);
        if let Some(t) = out.spectrum.take() {
            match &mut self.spectrum {
                Some(all) => all.append(t),
                None => self.spectrum = Some(t),
            }
        }
        if results.is_empty() {
            return Ok(());
        }
        match &mut self.dest {
            Dest::Stdout(l) => {
                for r in &results {
                    l.write(r).context("writing results to stdout")?;
                }
                l.flush().context("writing results to stdout")?;
            }
            Dest::File(l, p) => {
                for r in &results {
                    l.write(r)
                        .with_context(|| format!("{}: writing results", p.display()))?;
                }
            }
        }
        if let Some(h) = &mut self.hark {
            for r in &results {
                h.send(r, r.frame as i32)?;
            }
        }
        self.count += results.len();
        if let Some(k) = &mut self.keep {
            k.extend(results);
        }
        Ok(())
    }

    /// The end-of-run outputs, then the `-o` file is renamed into place.
    pub fn finish(self, a: &RunArgs, loc: &Localizer, title: &str) -> anyhow::Result<()> {
        let results = self.keep.unwrap_or_default();
        if let Some(p) = &a.summary {
            let s = soundloc::tracking::summarize(&results);
            write_atomically(p, |w| {
                serde_json::to_writer_pretty(&mut *w, &s)?;
                writeln!(w)
            })?;
        }
        use soundloc::formats::source_log::{write, SourceLogFormat};
        if let Some(p) = &a.log_text {
            write(p, &results, SourceLogFormat::Text)?;
        }
        if let Some(p) = &a.log_xml {
            write(p, &results, SourceLogFormat::Xml)?;
        }
        let grid = loc.grid();
        let az: Vec<f64> = (0..grid.len()).map(|d| grid.azimuth_deg(d)).collect();
        let el: Vec<f64> = (0..grid.len()).map(|d| grid.elevation_deg(d)).collect();
        if let Some(table) = &self.spectrum {
            if let Some(p) = &a.spectrum {
                write_spectrum(p, table, &az, &el)?;
                super::localize::note(a.quiet, &format!("spectrum written to {}", p.display()));
            }
            if let Some(p) = &a.plot {
                let plot = SpectrumPlot {
                    times_s: table.times_s.clone(),
                    azimuth_deg: az.clone(),
                    elevation_deg: el.clone(),
                    db: table.db.clone(),
                    peaks: results
                        .iter()
                        .map(|r| r.sources.iter().map(|s| (s.azimuth_deg, s.power_db)).collect())
                        .collect(),
                    truth_azimuths_deg: Vec::new(),
                    title: title.to_string(),
                };
                plot_spectrum(p, &plot)?;
                super::localize::note(a.quiet, &format!("plot written to {}", p.display()));
            }
        }
        if let Dest::File(l, p) = self.dest {
            let mut f = l.into_inner();
            f.flush()
                .with_context(|| format!("{}: writing results", p.display()))?;
            f.commit()?;
        }
        Ok(())
    }
}

fn write_spectrum(path: &Path, table: &SpectrumTable, az: &[f64], el: &[f64]) -> anyhow::Result<()> {
    let rows = table.frames.len();
    write_atomically(path, |w| write_npy_f32(w, rows, table.num_dirs, &table.db))?;
    let meta = serde_json::json!({
        "description": "dB MUSIC spectrum 10*log10(P+1), rows = results, columns = directions",
        "shape": [rows, table.num_dirs],
        "frames": table.frames,
        "times_s": table.times_s,
        "azimuth_deg": az,
        "elevation_deg": el,
    });
    let mut side = path.as_os_str().to_owned();
    side.push(".json");
    write_atomically(PathBuf::from(side), |w| {
        serde_json::to_writer(&mut *w, &meta)?;
        writeln!(w)
    })?;
    Ok(())
}
