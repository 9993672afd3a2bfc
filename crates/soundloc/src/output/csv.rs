//! CSV: one row per localized source, and one per result without sources.
//!
//! ```text
//! frame,time_s,rank,id,azimuth_deg,elevation_deg,x,y,z,power_db,grid_index,held,num_active
//! 50,0.5,0,3,30,0,0.8660254037844386,0.5,0,27.1,42,,1
//! 60,0.6,0,3,30,0,0.8660254037844386,0.5,0,27.1,42,1,0
//! 70,0.7,,,,,,,,,,,0
//! ```
//!
//! `rank` is the 0-based position of the source in its result (0 = strongest); `id` is
//! empty for untracked sources; `held` is `1` for a tracked source carried through its
//! pause (PAUSE_LENGTH) without being observed in that window, at its last direction and
//! power, and empty otherwise; `num_active` is the window's estimated number of active
//! sources where it was estimated (`--active-only`, the room and robust defaults' count),
//! empty otherwise. A result with no sources gives one row with only `frame`, `time_s` and
//! `num_active`, so every window computed is in the file (a silent one included). Angles in
//! degrees, `time_s` in seconds, `power_db` = 10·log10(P̄ + 1). Numbers use Rust's
//! shortest round-trip formatting; non-finite values are written as `NaN`, `inf`, `-inf`.

use crate::result::LocalizationResult;
use crate::Result;
use std::io::{self, Write};
use std::path::Path;

/// The header line (without newline).
pub const CSV_HEADER: &str =
    "frame,time_s,rank,id,azimuth_deg,elevation_deg,x,y,z,power_db,grid_index,held,num_active";

/// Writes results as CSV to any [`Write`]: the header on creation, then one row per source
/// (one with empty source fields for a result without sources).
#[derive(Debug)]
pub struct CsvWriter<W: Write> {
    inner: W,
    buf: String,
}

impl<W: Write> CsvWriter<W> {
    /// Wrap a writer and write the header line.
    pub fn new(mut inner: W) -> io::Result<Self> {
        inner.write_all(CSV_HEADER.as_bytes())?;
        inner.write_all(b"\n")?;
        Ok(CsvWriter {
            inner,
            buf: String::new(),
        })
    }

    /// Write the rows of one result (one with empty source fields when it has no
    /// sources), in one `write_all`.
    pub fn write(&mut self, result: &LocalizationResult) -> io::Result<()> {
        use std::fmt::Write as _;
        self.buf.clear();
        let active = result.num_active.map(|n| n.to_string()).unwrap_or_default();
        if result.sources.is_empty() {
            let _ = writeln!(self.buf, "{},{},,,,,,,,,,,{active}", result.frame, result.time_s);
        }
        for (rank, s) in result.sources.iter().enumerate() {
            let id = s.id.map(|i| i.to_string()).unwrap_or_default();
            // Writing to a String cannot fail.
            let _ = writeln!(
                self.buf,
                "{},{},{},{},{},{},{},{},{},{},{},{},{active}",
                result.frame,
                result.time_s,
                rank,
                id,
                s.azimuth_deg,
                s.elevation_deg,
                s.x,
                s.y,
                s.z,
                s.power_db,
                s.grid_index,
                if s.held { "1" } else { "" }
            );
        }
        self.inner.write_all(self.buf.as_bytes())
    }

    /// Write several results.
    pub fn write_all(&mut self, results: &[LocalizationResult]) -> io::Result<()> {
        results.iter().try_for_each(|r| self.write(r))
    }

    /// Flush the underlying writer.
    pub fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }

    /// The underlying writer.
    pub fn into_inner(self) -> W {
        self.inner
    }
}

/// Write `results` to `path` as CSV, atomically.
pub fn write_csv_file(path: impl AsRef<Path>, results: &[LocalizationResult]) -> Result<()> {
    super::atomic::write_atomically(path, |f| CsvWriter::new(f)?.write_all(results))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::result::Source;

    fn src(id: Option<i64>, az: f64, p: f64, gi: usize) -> Source {
        Source {
            id,
            grid_index: gi,
            azimuth_deg: az,
            elevation_deg: 0.0,
            x: 1.0,
            y: 0.0,
            z: 0.0,
            power_db: p,
            held: false,
        }
    }

    #[test]
    fn header_rows_and_empty_results() {
        let results = vec![
            LocalizationResult {
                num_active: None,
                frame: 0,
                time_s: 0.0,
                sources: vec![],
            },
            LocalizationResult {
                num_active: Some(0),
                frame: 10,
                time_s: 0.1,
                sources: vec![],
            },
            LocalizationResult {
                num_active: None,
                frame: 50,
                time_s: 0.5,
                sources: vec![src(Some(7), 30.0, 27.5, 6), src(None, -90.5, 12.25, 54)],
            },
            LocalizationResult {
                num_active: Some(1),
                frame: 60,
                time_s: 0.6,
                sources: vec![Source {
                    held: true,
                    ..src(Some(7), 30.0, 27.5, 6)
                }],
            },
        ];
        let mut w = CsvWriter::new(Vec::new()).unwrap();
        w.write_all(&results).unwrap();
        let text = String::from_utf8(w.into_inner()).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines,
            vec![
                CSV_HEADER,
                "0,0,,,,,,,,,,,",
                "10,0.1,,,,,,,,,,,0",
                "50,0.5,0,7,30,0,1,0,0,27.5,6,,",
                "50,0.5,1,,-90.5,0,1,0,0,12.25,54,,",
                "60,0.6,0,7,30,0,1,0,0,27.5,6,1,1",
            ]
        );
    }

    #[test]
    fn file_is_written() {
        let d = std::env::temp_dir().join(format!("soundloc-csv-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let p = d.join("r.csv");
        write_csv_file(&p, &[]).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), format!("{CSV_HEADER}\n"));
        std::fs::remove_dir_all(&d).unwrap();
    }
}
