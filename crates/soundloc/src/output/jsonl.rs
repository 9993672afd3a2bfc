//! JSON lines: one JSON object per [`LocalizationResult`], one result per line.
//!
//! ```text
//! {"frame":50,"time_s":0.5,"sources":[{"id":3,"azimuth_deg":30.0,"elevation_deg":0.0,"x":0.866,"y":0.5,"z":0.0,"power_db":27.1,"grid_index":42}]}
//! ```
//!
//! `frame` is the result frame c, `time_s` = c·hop/fs in seconds, `sources` strongest
//! first; angles in degrees (azimuth = atan2(y, x) from +x toward +y, elevation from the
//! x-y plane), `power_db` = 10·log10(P̄ + 1). `id` is omitted for untracked sources;
//! `num_active` (the window's estimated number of active sources) where it was estimated.
//! Non-finite numbers are written as `null` (JSON has no NaN) and read back as NaN.
//! A result with no sources is written with `"sources":[]`.

use crate::result::{LocalizationResult, Source};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::io::{self, BufRead, Write};
use std::path::Path;

#[derive(Serialize)]
struct SourceOut {
    #[serde(skip_serializing_if = "Option::is_none")]
    id: Option<i64>,
    azimuth_deg: Option<f64>,
    elevation_deg: Option<f64>,
    x: Option<f64>,
    y: Option<f64>,
    z: Option<f64>,
    power_db: Option<f64>,
    grid_index: usize,
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    held: bool,
}

#[derive(Serialize)]
struct ResultOut {
    frame: usize,
    time_s: Option<f64>,
    sources: Vec<SourceOut>,
    #[serde(skip_serializing_if = "Option::is_none")]
    num_active: Option<usize>,
}

#[derive(Deserialize)]
struct SourceIn {
    #[serde(default)]
    id: Option<i64>,
    azimuth_deg: Option<f64>,
    elevation_deg: Option<f64>,
    x: Option<f64>,
    y: Option<f64>,
    z: Option<f64>,
    power_db: Option<f64>,
    grid_index: usize,
    #[serde(default)]
    held: bool,
}

#[derive(Deserialize)]
struct ResultIn {
    frame: usize,
    time_s: Option<f64>,
    sources: Vec<SourceIn>,
    #[serde(default)]
    num_active: Option<usize>,
}

fn fin(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

fn nan(v: Option<f64>) -> f64 {
    v.unwrap_or(f64::NAN)
}

/// The JSON line for `result`, without the trailing newline.
pub fn to_json_line(result: &LocalizationResult) -> String {
    let out = ResultOut {
        frame: result.frame,
        time_s: fin(result.time_s),
        sources: result
            .sources
            .iter()
            .map(|s| SourceOut {
                id: s.id,
                azimuth_deg: fin(s.azimuth_deg),
                elevation_deg: fin(s.elevation_deg),
                x: fin(s.x),
                y: fin(s.y),
                z: fin(s.z),
                power_db: fin(s.power_db),
                grid_index: s.grid_index,
                held: s.held,
            })
            .collect(),
        num_active: result.num_active,
    };
    // Serialising plain structs of numbers cannot fail.
    serde_json::to_string(&out).unwrap_or_default()
}

/// Parse one JSON line back into a result.
pub fn from_json_line(line: &str) -> std::result::Result<LocalizationResult, serde_json::Error> {
    let r: ResultIn = serde_json::from_str(line)?;
    Ok(LocalizationResult {
        num_active: r.num_active,
        frame: r.frame,
        time_s: nan(r.time_s),
        sources: r
            .sources
            .into_iter()
            .map(|s| Source {
                id: s.id,
                grid_index: s.grid_index,
                azimuth_deg: nan(s.azimuth_deg),
                elevation_deg: nan(s.elevation_deg),
                x: nan(s.x),
                y: nan(s.y),
                z: nan(s.z),
                power_db: nan(s.power_db),
                held: s.held,
            })
            .collect(),
    })
}

/// Writes results as JSON lines to any [`Write`]; each line goes out in one `write_all`,
/// so a line-buffered stream (stdout, a pipe) never shows half a line.
#[derive(Debug)]
pub struct JsonlWriter<W: Write> {
    inner: W,
    line: String,
}

impl<W: Write> JsonlWriter<W> {
    /// Wrap a writer.
    pub fn new(inner: W) -> Self {
        JsonlWriter {
            inner,
            line: String::new(),
        }
    }
    /// Write one result as one line.
    pub fn write(&mut self, result: &LocalizationResult) -> io::Result<()> {
        self.line.clear();
        self.line.push_str(&to_json_line(result));
        self.line.push('\n');
        self.inner.write_all(self.line.as_bytes())
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

/// Write `results` to `path` as JSON lines, atomically.
pub fn write_jsonl_file(path: impl AsRef<Path>, results: &[LocalizationResult]) -> Result<()> {
    super::atomic::write_atomically(path, |f| JsonlWriter::new(f).write_all(results))
}

/// Read JSON lines from `reader`; `name` is used in error messages (`name: line 3: ...`).
/// Blank lines are skipped.
pub fn read_jsonl<R: BufRead>(reader: R, name: &Path) -> Result<Vec<LocalizationResult>> {
    let mut out = Vec::new();
    for (i, line) in reader.lines().enumerate() {
        let line = line.map_err(|e| Error::io(name, e))?;
        if line.trim().is_empty() {
            continue;
        }
        let r = from_json_line(&line).map_err(|e| Error::format(name, format!("line {}: {e}", i + 1)))?;
        out.push(r);
    }
    Ok(out)
}

/// Read a JSON-lines file written by [`write_jsonl_file`] or [`JsonlWriter`].
pub fn read_jsonl_file(path: impl AsRef<Path>) -> Result<Vec<LocalizationResult>> {
    let path = path.as_ref();
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    read_jsonl(io::BufReader::new(f), path)
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn sample_results() -> Vec<LocalizationResult> {
        vec![
            LocalizationResult {
                num_active: None,
                frame: 0,
                time_s: 0.0,
                sources: vec![
                    Source {
                        id: Some(3),
                        grid_index: 6,
                        azimuth_deg: 30.0,
                        elevation_deg: 0.0,
                        x: 0.8660254037844387,
                        y: 0.5,
                        z: 0.0,
                        power_db: 27.125,
                        held: false,
                    },
                    Source {
                        id: None,
                        grid_index: 60,
                        azimuth_deg: -60.0,
                        elevation_deg: 10.0,
                        x: 0.1,
                        y: -0.2,
                        z: 0.3,
                        power_db: 12.5,
                        held: false,
                    },
                ],
            },
            LocalizationResult {
                num_active: Some(2),
                frame: 50,
                time_s: 0.5,
                sources: vec![],
            },
        ]
    }

    #[test]
    fn line_format_and_field_order() {
        let r = &sample_results()[0];
        let line = to_json_line(r);
        assert!(line.starts_with(
            "{\"frame\":0,\"time_s\":0.0,\"sources\":[{\"id\":3,\"azimuth_deg\":30.0,\"elevation_deg\":0.0,\"x\":0.8660254037844387,\"y\":0.5,\"z\":0.0,\"power_db\":27.125,\"grid_index\":6}"
        ), "{line}");
        // No id key when untracked.
        assert!(line.contains("{\"azimuth_deg\":-60.0"), "{line}");
        assert_eq!(
            to_json_line(&sample_results()[1]),
            "{\"frame\":50,\"time_s\":0.5,\"sources\":[],\"num_active\":2}"
        );
    }

    #[test]
    fn round_trip_through_writer_and_reader() {
        let results = sample_results();
        let mut w = JsonlWriter::new(Vec::new());
        w.write_all(&results).unwrap();
        let bytes = w.into_inner();
        let text = String::from_utf8(bytes.clone()).unwrap();
        assert_eq!(text.lines().count(), 2);
        let back = read_jsonl(&bytes[..], Path::new("mem")).unwrap();
        assert_eq!(back, results);
    }

    #[test]
    fn file_round_trip_and_error_names_line() {
        let d = std::env::temp_dir().join(format!("soundloc-jsonl-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let p = d.join("r.jsonl");
        write_jsonl_file(&p, &sample_results()).unwrap();
        assert_eq!(read_jsonl_file(&p).unwrap(), sample_results());
        std::fs::write(&p, "{\"frame\":0,\"time_s\":0.0,\"sources\":[]}\n{oops}\n").unwrap();
        let e = read_jsonl_file(&p).unwrap_err().to_string();
        assert!(e.contains("r.jsonl") && e.contains("line 2"), "{e}");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn floats_round_trip_bit_exactly() {
        let mut r = sample_results()[0].clone();
        let awkward = [119.99999999999999, 0.1 + 0.2, 1e-300, -2.5e17, f64::MIN_POSITIVE];
        for (i, v) in awkward.iter().enumerate() {
            r.time_s = *v;
            r.sources[0].azimuth_deg = -v;
            r.sources[1].power_db = v * (i as f64 + 1.0);
            assert_eq!(from_json_line(&to_json_line(&r)).unwrap(), r);
        }
    }

    #[test]
    fn non_finite_becomes_null_and_nan() {
        let mut r = sample_results()[0].clone();
        r.sources[0].power_db = f64::NEG_INFINITY;
        let line = to_json_line(&r);
        assert!(line.contains("\"power_db\":null"), "{line}");
        let back = from_json_line(&line).unwrap();
        assert!(back.sources[0].power_db.is_nan());
    }
}
