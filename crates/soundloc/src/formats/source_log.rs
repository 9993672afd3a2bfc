//! Source-location logs as HARK's `SaveSourceLocation` writes them and
//! `LoadSourceLocation` reads them: write from, and read back into,
//! [`LocalizationResult`]s.
//!
//! ## Text (HARK ≤ 2.0)
//! One line per result: `frame id x y z id x y z ...`, space separated, `\n` ended. `frame`
//! is the result's STFT frame index (HARK's frame count), `id` an integer, `x y z` the
//! direction vector. Writing uses Rust's shortest round-trip decimal form, so a written log
//! reads back to the same f64 values. Reading skips blank lines and lines starting with
//! `#`, and accepts any decimal or exponent float form (`%f`, `%e`, `%g`).
//!
//! ## XML (HARK ≥ 2.1; head and tail *inferred*, not checked against a HARK file)
//! ```text
//! <hark_xml version="1.3">
//!     <positions type="localization" frame="0" coordinate="cartesian">
//!         <position x="1" y="0" z="0" id="0"/>
//!     </positions>
//! </hark_xml>
//! ```
//! One `<positions>` per result, in order. The reader accepts any `type`, takes the frame
//! from `frame` (or `count`), requires `coordinate="cartesian"` when present, and reads
//! every `<position>` inside.
//!
//! ## What the formats do not hold
//! Both formats hold only frame, id and x, y, z. On reading:
//! - `azimuth_deg` = atan2(y, x) and `elevation_deg` = atan2(z, √(x²+y²)), in degrees;
//! - `power_db` is **NaN** (unknown; a [`crate::tracking::SourceTracker`] ignores NaN
//!   peaks, so do not re-track a loaded log — it already has ids);
//! - `grid_index` is 0 (the logs do not hold it; Python's `read_source_log` gives None);
//! - `time_s` = frame × `frame_period_s` (the caller's hop / sample rate, HARK's
//!   ADVANCE / SAMPLING_RATE, 160 / 16000 = 0.01 s by default).
//!
//! An untracked source (`id: None`) is written as id −1, and id −1 reads back as `None`.
//! Sources are written in the result's order (strongest first) and read back in file order.
//! Writers replace the file atomically ([`crate::output::atomic::AtomicFile`]);
//! [`SourceLogWriter`] writes one result at a time (a live run's log, a FIFO).

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::Path;

use crate::error::{Error, Result};
use crate::formats::xml;
use crate::output::atomic::write_atomically;
use crate::result::{LocalizationResult, Source};

/// The id written for a source without one.
pub const NO_ID: i64 = -1;

/// Which log format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SourceLogFormat {
    /// HARK ≤ 2.0 text, one line per result.
    Text,
    /// HARK ≥ 2.1 `hark_xml`.
    Xml,
}

fn id_out(s: &Source) -> i64 {
    s.id.unwrap_or(NO_ID)
}

fn id_in(id: i64) -> Option<i64> {
    (id != NO_ID).then_some(id)
}

/// A source read from a log: direction only (see the module docs for the other fields).
fn source_from_xyz(id: i64, x: f64, y: f64, z: f64) -> Source {
    let az = y.atan2(x).to_degrees();
    Source {
        id: id_in(id),
        grid_index: 0,
        azimuth_deg: if az <= -180.0 { az + 360.0 } else { az },
        elevation_deg: z.atan2((x * x + y * y).sqrt()).to_degrees(),
        x,
        y,
        z,
        power_db: f64::NAN,
        held: false,
    }
}

/// Writes a log one result at a time, as HARK's `SaveSourceLocation` does while it runs
/// (a live run's log grows as results come; a FIFO's reader sees each frame at once when
/// the caller flushes). [`SourceLogWriter::finish`] writes the XML tail.
#[derive(Debug)]
pub struct SourceLogWriter<W: std::io::Write> {
    w: W,
    format: SourceLogFormat,
    line: String,
}

impl<W: std::io::Write> SourceLogWriter<W> {
    /// A writer to `w`; the XML head is written now.
    pub fn new(mut w: W, format: SourceLogFormat) -> std::io::Result<Self> {
        if format == SourceLogFormat::Xml {
            w.write_all(XML_HEAD.as_bytes())?;
        }
        Ok(SourceLogWriter {
            w,
            format,
            line: String::new(),
        })
    }

    /// One result: a text line, or one `<positions>` element.
    pub fn write(&mut self, r: &LocalizationResult) -> std::io::Result<()> {
        self.line.clear();
        push_frame(&mut self.line, r, self.format);
        self.w.write_all(self.line.as_bytes())
    }

    /// The underlying writer, e.g. to flush it after a block of results.
    pub fn get_mut(&mut self) -> &mut W {
        &mut self.w
    }

    /// Ends the log (the XML tail) and returns the writer, not flushed.
    pub fn finish(mut self) -> std::io::Result<W> {
        if self.format == SourceLogFormat::Xml {
            self.w.write_all(XML_TAIL.as_bytes())?;
        }
        Ok(self.w)
    }
}

/// Appends one result's text line or `<positions>` element to `s`.
fn push_frame(s: &mut String, r: &LocalizationResult, format: SourceLogFormat) {
    match format {
        SourceLogFormat::Text => {
            let _ = write!(s, "{}", r.frame);
            for src in &r.sources {
                let _ = write!(s, " {} {} {} {}", id_out(src), src.x, src.y, src.z);
            }
            s.push('\n');
        }
        SourceLogFormat::Xml => {
            let _ = writeln!(
                s,
                "    <positions type=\"localization\" frame=\"{}\" coordinate=\"cartesian\">",
                r.frame
            );
            for src in &r.sources {
                let _ = writeln!(
                    s,
                    "        <position x=\"{}\" y=\"{}\" z=\"{}\" id=\"{}\"/>",
                    src.x,
                    src.y,
                    src.z,
                    id_out(src)
                );
            }
            s.push_str("    </positions>\n");
        }
    }
}

const XML_HEAD: &str = "<hark_xml version=\"1.3\">\n";
const XML_TAIL: &str = "</hark_xml>\n";

/// The whole log of `results` as a string.
fn to_string(results: &[LocalizationResult], format: SourceLogFormat) -> String {
    let xml = format == SourceLogFormat::Xml;
    let mut s = String::from(if xml { XML_HEAD } else { "" });
    for r in results {
        push_frame(&mut s, r, format);
    }
    if xml {
        s.push_str(XML_TAIL);
    }
    s
}

/// The text log as a string.
pub fn to_text(results: &[LocalizationResult]) -> String {
    to_string(results, SourceLogFormat::Text)
}

/// The XML log as a string.
pub fn to_xml(results: &[LocalizationResult]) -> String {
    to_string(results, SourceLogFormat::Xml)
}

/// Writes `results` to `path` in `format`, atomically.
pub fn write(path: &Path, results: &[LocalizationResult], format: SourceLogFormat) -> Result<()> {
    let text = to_string(results, format);
    write_atomically(path, |f| f.write_all(text.as_bytes()))
}

/// Writes the HARK ≤ 2.0 text log.
pub fn write_text(path: &Path, results: &[LocalizationResult]) -> Result<()> {
    write(path, results, SourceLogFormat::Text)
}

/// Writes the HARK ≥ 2.1 XML log.
pub fn write_xml(path: &Path, results: &[LocalizationResult]) -> Result<()> {
    write(path, results, SourceLogFormat::Xml)
}

fn parse_finite(tok: &str, what: &str, path: &Path, line: usize) -> Result<f64> {
    match tok.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(Error::format(
            path,
            format!("line {line}: {what} is not finite: {tok:?}"),
        )),
        Err(_) => Err(Error::format(
            path,
            format!("line {line}: {what} is not a number: {tok:?}"),
        )),
    }
}

/// Parses a text log (`path` only names the file in errors).
pub fn parse_text(text: &str, path: &Path, frame_period_s: f64) -> Result<Vec<LocalizationResult>> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let toks: Vec<&str> = t.split_whitespace().collect();
        let frame: usize = toks[0].parse().map_err(|_| {
            Error::format(
                path,
                format!(
                    "line {n}: frame count is not a non-negative integer: {:?}",
                    toks[0]
                ),
            )
        })?;
        let rest = &toks[1..];
        if !rest.len().is_multiple_of(4) {
            return Err(Error::format(
                path,
                format!(
                    "line {n}: expected groups of 4 values (id x y z) after the frame count, found {} values",
                    rest.len()
                ),
            ));
        }
        let mut sources = Vec::with_capacity(rest.len() / 4);
        for (k, g) in rest.chunks_exact(4).enumerate() {
            let id: i64 = g[0].parse().map_err(|_| {
                Error::format(
                    path,
                    format!("line {n}: source {k}: id is not an integer: {:?}", g[0]),
                )
            })?;
            let x = parse_finite(g[1], &format!("source {k}: x"), path, n)?;
            let y = parse_finite(g[2], &format!("source {k}: y"), path, n)?;
            let z = parse_finite(g[3], &format!("source {k}: z"), path, n)?;
            sources.push(source_from_xyz(id, x, y, z));
        }
        out.push(LocalizationResult {
            num_active: None,
            frame,
            time_s: frame as f64 * frame_period_s,
            sources,
        });
    }
    Ok(out)
}

/// Parses an XML log (`path` only names the file in errors).
pub fn parse_xml(text: &str, path: &Path, frame_period_s: f64) -> Result<Vec<LocalizationResult>> {
    let doc = xml::parse_file_text(text, path)?;
    let root = doc
        .find("hark_xml")
        .ok_or_else(|| Error::format(path, "no <hark_xml> element"))?;
    let mut out = Vec::new();
    for (b, block) in root.find_all("positions").into_iter().enumerate() {
        let ctx = |m: String| Error::format(path, format!("<positions> #{b}: {m}"));
        if let Some(c) = block.attr("coordinate") {
            if c != "cartesian" {
                return Err(ctx(format!(
                    "coordinate {c:?} is not supported (only \"cartesian\")"
                )));
            }
        }
        let fstr = block
            .attr("frame")
            .or_else(|| block.attr("count"))
            .ok_or_else(|| ctx("no frame attribute".into()))?;
        let frame: usize = fstr
            .trim()
            .parse()
            .map_err(|_| ctx(format!("frame is not a non-negative integer: {fstr:?}")))?;
        let mut sources = Vec::new();
        for (k, p) in block.children_named("position").enumerate() {
            let get = |name: &str| -> Result<f64> {
                let v = p
                    .attr(name)
                    .ok_or_else(|| ctx(format!("frame {frame}: <position> #{k}: missing {name}")))?;
                match v.trim().parse::<f64>() {
                    Ok(x) if x.is_finite() => Ok(x),
                    _ => Err(ctx(format!(
                        "frame {frame}: <position> #{k}: {name} is not a finite number: {v:?}"
                    ))),
                }
            };
            let (x, y, z) = (get("x")?, get("y")?, get("z")?);
            let id = match p.attr("id") {
                None => NO_ID,
                Some(v) => v.trim().parse::<i64>().map_err(|_| {
                    ctx(format!(
                        "frame {frame}: <position> #{k}: id is not an integer: {v:?}"
                    ))
                })?,
            };
            sources.push(source_from_xyz(id, x, y, z));
        }
        out.push(LocalizationResult {
            num_active: None,
            frame,
            time_s: frame as f64 * frame_period_s,
            sources,
        });
    }
    Ok(out)
}

/// The format of log content: XML when the first non-blank character is `<`, else text.
pub fn detect(text: &str) -> SourceLogFormat {
    if text.trim_start_matches('\u{feff}').trim_start().starts_with('<') {
        SourceLogFormat::Xml
    } else {
        SourceLogFormat::Text
    }
}

/// Reads a log of either format (by content, see [`detect`]). `frame_period_s` sets
/// `time_s` = frame × frame_period_s.
pub fn read(path: &Path, frame_period_s: f64) -> Result<Vec<LocalizationResult>> {
    let text = super::read_text_bounded(path, super::MAX_SOURCE_LOG_BYTES, "source-location log")?;
    match detect(&text) {
        SourceLogFormat::Text => parse_text(&text, path, frame_period_s),
        SourceLogFormat::Xml => parse_xml(&text, path, frame_period_s),
    }
}
