//! `--spectrum FILE.npy` (with its `FILE.npy.json` sidecar) and the table `--plot` needs.
//!
//! The `.npy` is written as the results come (rows appended to the temporary file, the
//! shape put into its header at the end, then renamed into place), so an hour's spectrum
//! on a fine grid never sits in memory; only `--plot`, which draws the whole run, and a
//! target that cannot seek (a FIFO, /dev/stdout) keep the table.

use anyhow::Context;
use soundloc::engine::SpectrumTable;
use soundloc::output::atomic::{write_atomically, AtomicFile};
use soundloc::output::npy::{write_npy_f32, NpyRowWriter};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The spectrum outputs of a run.
pub struct SpectrumSink {
    /// `--spectrum`.
    path: Option<PathBuf>,
    /// Keep the whole table (a target that cannot seek, written at the end).
    keep_table: bool,
    /// Write the `.npy` as the rows come (a plain file).
    stream: bool,
    table: Option<SpectrumTable>,
    /// The `.npy` being written, opened at the first rows.
    streamed: Option<NpyRowWriter<AtomicFile>>,
    frames: Vec<usize>,
    times_s: Vec<f64>,
}

impl SpectrumSink {
    /// For `--spectrum path`.
    pub fn new(path: Option<&Path>) -> Self {
        // A device, FIFO or socket is written in place and cannot seek.
        let special = path.is_some_and(|p| std::fs::metadata(p).is_ok_and(|m| !m.is_file()));
        SpectrumSink {
            path: path.map(Path::to_path_buf),
            keep_table: special,
            stream: path.is_some() && !special,
            table: None,
            streamed: None,
            frames: Vec::new(),
            times_s: Vec::new(),
        }
    }

    /// Whether the run's spectrum is needed at all.
    pub fn wanted(&self) -> bool {
        self.path.is_some() || self.keep_table
    }

    /// Take the next rows.
    pub fn take(&mut self, t: SpectrumTable) -> anyhow::Result<()> {
        if let Some(p) = self.path.as_ref().filter(|_| self.stream) {
            if self.streamed.is_none() {
                let f = AtomicFile::create(p)?;
                self.streamed = Some(
                    NpyRowWriter::new(f, t.num_dirs)
                        .with_context(|| format!("{}: writing the spectrum", p.display()))?,
                );
            }
            if let Some(w) = &mut self.streamed {
                w.push(&t.db)
                    .with_context(|| format!("{}: writing the spectrum", p.display()))?;
            }
            self.frames.extend_from_slice(&t.frames);
            self.times_s.extend_from_slice(&t.times_s);
        }
        if self.keep_table {
            match &mut self.table {
                Some(all) => all.append(t),
                None => self.table = Some(t),
            }
        }
        Ok(())
    }

    /// Write the `.npy` (finishing a streamed one) and its sidecar; `az`/`el` the grid's
    /// directions. Nothing when no result came.
    pub fn finish(
        self,
        az: &[f64],
        el: &[f64],
        config: &soundloc::LocalizeConfig,
        quiet: bool,
    ) -> anyhow::Result<()> {
        let Some(path) = &self.path else {
            return Ok(());
        };
        let (rows, frames, times_s) = if let Some(w) = self.streamed {
            let rows = w.rows();
            let mut f = w
                .finish()
                .with_context(|| format!("{}: writing the spectrum", path.display()))?;
            f.flush()
                .with_context(|| format!("{}: writing the spectrum", path.display()))?;
            f.commit()?;
            (rows, self.frames, self.times_s)
        } else if let Some(t) = &self.table {
            let rows = t.frames.len();
            write_atomically(path, |w| write_npy_f32(w, rows, t.num_dirs, &t.db))?;
            (rows, t.frames.clone(), t.times_s.clone())
        } else {
            return Ok(());
        };
        let algorithm = config.algorithm;
        let what = if algorithm.is_music() {
            "MUSIC spectrum"
        } else {
            "steered response power (SRP-PHAT)"
        };
        let meta = serde_json::json!({
            "description": format!("dB {what} 10*log10(P+1), {} summed over the bins, rows = results, columns = directions", config.label()),
            "algorithm": algorithm.name(),
            "analysis": config.label(),
            "shape": [rows, az.len()],
            "frames": frames,
            "times_s": times_s,
            "azimuth_deg": az,
            "elevation_deg": el,
        });
        write_atomically(spectrum_sidecar(path), |w| {
            serde_json::to_writer(&mut *w, &meta)?;
            writeln!(w)
        })?;
        super::localize::note(quiet, &format!("spectrum written to {}", path.display()));
        Ok(())
    }
}

/// The spectrum's metadata file: `FILE.json` next to `FILE` (e.g. `spec.npy.json`).
pub fn spectrum_sidecar(path: &Path) -> PathBuf {
    let mut side = path.as_os_str().to_owned();
    side.push(".json");
    PathBuf::from(side)
}
