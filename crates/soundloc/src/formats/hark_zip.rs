//! HARK's zip container (HARK ≥ 2.1, libharkio3): transfer functions, and the generic
//! pieces for other payloads (noise correlation matrices use the same container).
//!
//! A transfer-function zip, as HARKTOOL5 writes it (entry order of tamago_geotf.zip):
//!
//! ```text
//! transferFunction/
//! transferFunction/whatisthis.txt          "transfer function"
//! transferFunction/microphones.xml         <positions type="microphone" coordinate="cartesian">
//! transferFunction/source.xml              <config> + <positions type="soundsource"> + <neighbors>
//! transferFunction/localization/
//! transferFunction/separation/
//! transferFunction/localization/tf00000.mat   complex M × (N/2+1), rows = mics
//! transferFunction/separation/tf00000.mat     (for geometric TFs: complex conjugate)
//! ... one pair per direction id
//! ```
//!
//! Reading: the root folder is wherever `whatisthis.txt` is; positions are ordered by
//! their `id` attribute (document order when absent); `coordinate="polar"` positions are
//! read from `azimuth`/`elevation` (degrees) and `radius` (metres, default 1) — that
//! variant's attribute names are inferred, no real file was available. `<neighbors>`
//! lists each point first, then its neighbours; the point itself is dropped. The grid is
//! [`GridKind::Ring`](crate::array::GridKind::Ring) when all points share one elevation (±0.5°), step around the circle
//! by equal steps, and the table is exactly left/right; otherwise
//! [`GridKind::Irregular`](crate::array::GridKind::Irregular) with the stored table (or, with no table, the 6 nearest).
//! The separation TFs are not read. Placeholder microphone positions (tamago_rectf.zip
//! has them) are kept as found.
//!
//! Writing ([`write_tf_zip`]) reproduces that layout; positions are written with Rust's
//! shortest round-trip formatting, so reading back gives identical numbers. The zip is
//! written to a temporary file in the same folder and renamed into place.

use crate::array::TransferFunctions;
use crate::formats::hark_mat::{write_mat, MatData};
use crate::formats::xml::Element;
use crate::formats::zip_archive::ZipReader;
use crate::output::atomic::AtomicFile;
use crate::{Error, Result};
use std::collections::BTreeMap;
use std::io::{Seek, Write};
use std::path::{Path, PathBuf};

/// Root folder of a transfer-function zip.
pub const TF_ROOT: &str = "transferFunction";
/// `whatisthis.txt` content of a transfer-function zip.
pub const TF_WHATISTHIS: &str = "transfer function";
/// `whatisthis.txt` content of a noise correlation-matrix zip.
pub const CM_WHATISTHIS: &str = "correlation matrix";
pub use super::tf_zip_read::{inspect_tf_zip, read_tf_zip, read_tf_zip_bins};
pub use super::zip_archive::{MAX_ENTRY_BYTES, MAX_RATIO, MAX_TOTAL_BYTES};

/// True when `bytes` start like a zip archive (`PK\x03\x04`, or `PK\x05\x06` for an
/// empty one).
pub fn looks_like_zip(bytes: &[u8]) -> bool {
    bytes.starts_with(b"PK\x03\x04") || bytes.starts_with(b"PK\x05\x06")
}

/// True when the file at `path` starts like a zip archive (false when it cannot be read:
/// the reader that follows reports why).
pub fn file_looks_like_zip(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 4];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && looks_like_zip(&head)
}

/// The path used in error messages for entry `entry` of zip `zip`:
/// `tf.zip: transferFunction/localization/tf00003.mat`.
pub fn entry_path(zip: &Path, entry: &str) -> PathBuf {
    PathBuf::from(format!("{}: {}", zip.display(), entry))
}

/// Read every file entry of a zip into memory, keyed by entry name (directories
/// skipped). Truncated or corrupt archives (bad central directory, CRC mismatch,
/// unsupported compression) are errors naming the file and, where known, the entry.
pub fn read_zip_entries(path: &Path) -> Result<BTreeMap<String, Vec<u8>>> {
    read_zip_entries_where(path, |_| true)
}

/// [`read_zip_entries`] for the entries whose name `keep` accepts. Bounded by what the
/// archive can hold: no entry over [`MAX_ENTRY_BYTES`], no more than [`MAX_TOTAL_BYTES`]
/// in all, no entry over 1 MiB that inflates more than [`MAX_RATIO`] times its compressed
/// size (a zip bomb), and an entry never inflates past the size its header declares.
pub fn read_zip_entries_where(path: &Path, keep: impl Fn(&str) -> bool) -> Result<BTreeMap<String, Vec<u8>>> {
    let mut zr = ZipReader::open(path)?;
    let names: Vec<String> = zr.names().into_iter().filter(|n| keep(n)).collect();
    zr.check_total(names.iter().map(String::as_str))?;
    let mut out = BTreeMap::new();
    for n in names {
        let b = zr.read(&n)?;
        out.insert(n, b);
    }
    Ok(out)
}

/// Write a zip holding `entries` in the given order (names ending in `/` are folders,
/// their bytes ignored; files are deflated). Written atomically ([`AtomicFile`]): on error
/// `path` is untouched. A device, FIFO or socket is written in place (the zip is built in
/// memory first, since it cannot seek), never replaced.
pub fn write_zip_entries(path: &Path, entries: &[(String, Vec<u8>)]) -> Result<()> {
    // Errors name the file asked for, not the hidden temporary one.
    let zerr = |e: zip::result::ZipError| match e {
        zip::result::ZipError::Io(e) => Error::io(path, e),
        e => Error::io(path, std::io::Error::other(e.to_string())),
    };
    let mut out = AtomicFile::create(path)?;
    if out.is_special() {
        let buf = zip_into(std::io::Cursor::new(Vec::new()), entries).map_err(zerr)?;
        out.write_all(buf.get_ref()).map_err(|e| Error::io(path, e))?;
    } else {
        zip_into(&mut out, entries).map_err(zerr)?;
    }
    out.commit()
}

/// The zip of `entries` written to `w` (see [`write_zip_entries`]).
fn zip_into<W: Write + Seek>(w: W, entries: &[(String, Vec<u8>)]) -> zip::result::ZipResult<W> {
    let mut w = zip::ZipWriter::new(w);
    let opts = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
    for (name, bytes) in entries {
        if name.ends_with('/') {
            w.add_directory(name.as_str(), opts)?;
        } else {
            w.start_file(name.as_str(), opts)?;
            w.write_all(bytes)?;
        }
    }
    w.finish()
}

/// Find the container's root folder (with trailing `/`, e.g. `transferFunction/`) and
/// its trimmed `whatisthis.txt` text. Error when no `whatisthis.txt` exists.
pub fn container_root(entries: &BTreeMap<String, Vec<u8>>, path: &Path) -> Result<(String, String)> {
    let mut found: Vec<&String> = entries
        .keys()
        .filter(|k| k.rsplit('/').next() == Some("whatisthis.txt"))
        .collect();
    found.sort_by_key(|k| k.len());
    let key = found.first().ok_or_else(|| {
        Error::format(
            path,
            "no whatisthis.txt: not a HARK zip (expected transferFunction/whatisthis.txt)",
        )
    })?;
    let root = &key[..key.len() - "whatisthis.txt".len()];
    let text = String::from_utf8_lossy(&entries[*key]).trim().to_string();
    Ok((root.to_string(), text))
}

/// The text of entry `name`, or an error naming the zip and the missing entry.
pub fn entry_text<'a>(
    entries: &'a BTreeMap<String, Vec<u8>>,
    name: &str,
    path: &Path,
) -> Result<std::borrow::Cow<'a, str>> {
    let b = entries
        .get(name)
        .ok_or_else(|| Error::format(path, format!("missing entry {name}")))?;
    Ok(String::from_utf8_lossy(b))
}

/// The `<config>` block of `source.xml`.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct HarkConfig {
    /// `<comment>`.
    pub comment: String,
    /// `<SynchronousAverage>`.
    pub synchronous_average: i64,
    /// `<TSPpath>`.
    pub tsp_path: String,
    /// `<TSPOffset>`.
    pub tsp_offset: i64,
    /// `<PeakSearch from to>`.
    pub peak_search: (i64, i64),
    /// `<nfft>`: FFT length.
    pub nfft: usize,
    /// `<samplingRate>`: Hz.
    pub sampling_rate_hz: u32,
    /// `<signalMax>`.
    pub signal_max: i64,
    /// `<TSPLength>`.
    pub tsp_length: i64,
}

impl HarkConfig {
    /// A config for computed TFs (HARKTOOL5's defaults for the measurement fields).
    pub fn new(nfft: usize, sampling_rate_hz: u32, comment: &str) -> Self {
        HarkConfig {
            comment: comment.to_string(),
            synchronous_average: 16,
            tsp_path: String::new(),
            tsp_offset: 16384,
            peak_search: (0, 0),
            nfft,
            sampling_rate_hz,
            signal_max: 32768,
            tsp_length: 16384,
        }
    }

    /// Read from the document holding `<config>`; `nfft` and `samplingRate` are
    /// required, the other fields default as in [`HarkConfig::new`].
    pub fn from_xml(doc: &Element, path: &Path) -> Result<Self> {
        let cfg = doc
            .find("config")
            .ok_or_else(|| Error::format(path, "no <config> element"))?;
        let text = |n: &str| cfg.child(n).map(|e| e.text_trimmed().to_string());
        let int = |n: &str, default: i64| -> Result<i64> {
            match text(n) {
                None => Ok(default),
                Some(t) if t.is_empty() => Ok(default),
                Some(t) => t.parse::<i64>().map_err(|_| {
                    Error::format(path, format!("<config><{n}>: expected an integer, found {t:?}"))
                }),
            }
        };
        let nfft = int("nfft", -1)?;
        if nfft < 2 {
            return Err(Error::format(path, "<config><nfft> missing or smaller than 2"));
        }
        let fs = int("samplingRate", -1)?;
        if fs <= 0 || fs > u32::MAX as i64 {
            return Err(Error::format(
                path,
                "<config><samplingRate> missing or not a positive integer (Hz)",
            ));
        }
        let mut c = HarkConfig::new(nfft as usize, fs as u32, "");
        c.comment = text("comment").unwrap_or_default();
        c.tsp_path = text("TSPpath").unwrap_or_default();
        c.synchronous_average = int("SynchronousAverage", c.synchronous_average)?;
        c.tsp_offset = int("TSPOffset", c.tsp_offset)?;
        c.signal_max = int("signalMax", c.signal_max)?;
        c.tsp_length = int("TSPLength", c.tsp_length)?;
        if let Some(ps) = cfg.child("PeakSearch") {
            let a = |n: &str| ps.attr(n).and_then(|v| v.trim().parse::<i64>().ok()).unwrap_or(0);
            c.peak_search = (a("from"), a("to"));
        }
        Ok(c)
    }

    /// The `<config>` element, children in HARKTOOL5's order.
    pub fn to_element(&self) -> Element {
        Element::new("config")
            .with_child(Element::new("comment").with_text(&self.comment))
            .with_child(Element::new("SynchronousAverage").with_text(self.synchronous_average.to_string()))
            .with_child(Element::new("TSPpath").with_text(&self.tsp_path))
            .with_child(Element::new("TSPOffset").with_text(self.tsp_offset.to_string()))
            .with_child(
                Element::new("PeakSearch")
                    .with_attr("from", self.peak_search.0.to_string())
                    .with_attr("to", self.peak_search.1.to_string()),
            )
            .with_child(Element::new("nfft").with_text(self.nfft.to_string()))
            .with_child(Element::new("samplingRate").with_text(self.sampling_rate_hz.to_string()))
            .with_child(Element::new("signalMax").with_text(self.signal_max.to_string()))
            .with_child(Element::new("TSPLength").with_text(self.tsp_length.to_string()))
    }
}

fn parse_f64(el: &Element, name: &str, i: usize, path: &Path) -> Result<Option<f64>> {
    match el.attr(name) {
        None => Ok(None),
        Some(v) => match v.trim().parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(Some(x)),
            _ => Err(Error::format(
                path,
                format!("position {i}: {name}={v:?} is not a finite number"),
            )),
        },
    }
}

/// The positions of the first `<positions>` element whose `type` is `kind`
/// (`microphone`, `soundsource`; any `<positions>` when `kind` is empty), ordered by id.
/// Cartesian x/y/z (metres), or polar azimuth/elevation (degrees) and radius (metres,
/// default 1) when `coordinate="polar"`. Ids must be 0..n−1, each once. Returns `None`
/// when there is no such `<positions>` element.
pub fn read_positions(doc: &Element, kind: &str, path: &Path) -> Result<Option<Vec<[f64; 3]>>> {
    let Some(ps) = doc
        .find_all("positions")
        .into_iter()
        .find(|p| kind.is_empty() || p.attr("type") == Some(kind))
    else {
        return Ok(None);
    };
    let polar = ps
        .attr("coordinate")
        .is_some_and(|c| c.trim().eq_ignore_ascii_case("polar"));
    let items: Vec<&Element> = ps.children_named("position").collect();
    let n = items.len();
    let mut out: Vec<Option<[f64; 3]>> = vec![None; n];
    for (k, el) in items.iter().enumerate() {
        let id = match el.attr("id") {
            None => k,
            Some(v) => match v.trim().parse::<usize>() {
                Ok(id) if id < n => id,
                _ => {
                    return Err(Error::format(
                        path,
                        format!("<position> #{k}: id={v:?} is not in 0..{n}"),
                    ))
                }
            },
        };
        let p = if polar {
            let az = parse_f64(el, "azimuth", id, path)?;
            let elv = parse_f64(el, "elevation", id, path)?;
            let r = parse_f64(el, "radius", id, path)?.unwrap_or(1.0);
            let (Some(az), Some(elv)) = (az, elv) else {
                return Err(Error::format(
                    path,
                    format!("position {id}: polar position needs azimuth and elevation"),
                ));
            };
            let (a, e) = (az.to_radians(), elv.to_radians());
            [r * e.cos() * a.cos(), r * e.cos() * a.sin(), r * e.sin()]
        } else {
            let mut p = [0.0; 3];
            for (c, name) in ["x", "y", "z"].iter().enumerate() {
                p[c] = parse_f64(el, name, id, path)?
                    .ok_or_else(|| Error::format(path, format!("position {id}: missing {name}")))?;
            }
            p
        };
        if out[id].is_some() {
            return Err(Error::format(path, format!("position id {id} appears twice")));
        }
        out[id] = Some(p);
    }
    Ok(Some(out.into_iter().flatten().collect()))
}

/// The `path` attribute of each `<position>` of the `kind` positions, by id (empty
/// strings where absent).
pub fn read_position_paths(doc: &Element, kind: &str) -> Vec<String> {
    let Some(ps) = doc
        .find_all("positions")
        .into_iter()
        .find(|p| kind.is_empty() || p.attr("type") == Some(kind))
    else {
        return Vec::new();
    };
    let items: Vec<&Element> = ps.children_named("position").collect();
    let mut out = vec![String::new(); items.len()];
    for (k, el) in items.iter().enumerate() {
        let id = el
            .attr("id")
            .and_then(|v| v.trim().parse::<usize>().ok())
            .filter(|&i| i < out.len())
            .unwrap_or(k);
        out[id] = el.attr("path").unwrap_or("").to_string();
    }
    out
}

/// A `<positions type=kind coordinate="cartesian">` element, one
/// `<position x y z id path/>` per point (path from `paths`, empty when `None`).
pub fn positions_element(kind: &str, points: &[[f64; 3]], paths: Option<&[String]>) -> Element {
    let mut ps = Element::new("positions")
        .with_attr("type", kind)
        .with_attr("coordinate", "cartesian");
    for (i, p) in points.iter().enumerate() {
        let path = paths.and_then(|v| v.get(i)).map(String::as_str).unwrap_or("");
        ps.children.push(
            Element::new("position")
                .with_attr("x", fmt_num(p[0]))
                .with_attr("y", fmt_num(p[1]))
                .with_attr("z", fmt_num(p[2]))
                .with_attr("id", i.to_string())
                .with_attr("path", path),
        );
    }
    ps
}

fn fmt_num(v: f64) -> String {
    // Shortest representation that reads back to the same f64; avoids "-0".
    if v == 0.0 {
        "0".into()
    } else {
        format!("{v}")
    }
}

/// The `<neighbors>` table for `n` points: `Ok(None)` when absent. Each `<neighbor
/// id="i" ids="i;j;k;"/>` may list i itself (dropped); ids out of range are errors.
pub fn read_neighbors(doc: &Element, n: usize, path: &Path) -> Result<Option<Vec<Vec<usize>>>> {
    let Some(nb) = doc.find("neighbors") else {
        return Ok(None);
    };
    let mut out: Vec<Vec<usize>> = vec![Vec::new(); n];
    for el in nb.children_named("neighbor") {
        let id_s = el.attr("id").unwrap_or("");
        let id = match id_s.trim().parse::<usize>() {
            Ok(i) if i < n => i,
            _ => {
                return Err(Error::format(
                    path,
                    format!("<neighbor id={id_s:?}>: not a direction id in 0..{n}"),
                ))
            }
        };
        for tok in el.attr("ids").unwrap_or("").split([';', ',', ' ']) {
            let tok = tok.trim();
            if tok.is_empty() {
                continue;
            }
            let j = match tok.parse::<usize>() {
                Ok(j) if j < n => j,
                _ => {
                    return Err(Error::format(
                        path,
                        format!("<neighbor id=\"{id}\">: neighbour {tok:?} is not a direction id in 0..{n}"),
                    ))
                }
            };
            if j != id && !out[id].contains(&j) {
                out[id].push(j);
            }
        }
    }
    Ok(Some(out))
}

/// The `<neighbors algorithm="NearestNeighbor">` element; each list starts with the point
/// itself, entries end with `;` (HARK's form).
pub fn neighbors_element(neighbors: &[Vec<usize>]) -> Element {
    let mut el = Element::new("neighbors").with_attr("algorithm", "NearestNeighbor");
    for (i, l) in neighbors.iter().enumerate() {
        let mut ids = format!("{i};");
        for j in l {
            ids.push_str(&format!("{j};"));
        }
        el.children.push(
            Element::new("neighbor")
                .with_attr("id", i.to_string())
                .with_attr("ids", ids),
        );
    }
    el
}

/// A `<hark_xml version="1.3">` document text with the given children.
pub fn hark_xml_document(children: Vec<Element>, xml_declaration: bool) -> String {
    let mut root = Element::new("hark_xml").with_attr("version", "1.3");
    root.children = children;
    let mut s = String::new();
    if xml_declaration {
        s.push_str("<?xml version=\"1.0\"?>\n");
    }
    s.push_str(&root.to_xml_string(0));
    s
}

/// Entry name of direction `id`'s TF under `root` (`transferFunction/`) in `folder`
/// (`localization` or `separation`): `transferFunction/localization/tf00003.mat`.
pub fn tf_entry_name(root: &str, folder: &str, id: usize) -> String {
    format!("{root}{folder}/tf{id:05}.mat")
}

/// The entries of a TF zip for `tf` (see [`write_tf_zip`]), in HARKTOOL5's order.
pub fn tf_zip_entries(tf: &TransferFunctions, comment: &str) -> Result<Vec<(String, Vec<u8>)>> {
    let nbins = tf.nfft / 2 + 1;
    if tf.first_bin != 0 || tf.num_bins != nbins {
        return Err(Error::Mismatch(format!(
            "a TF zip holds all nfft/2+1 = {nbins} bins; these TFs hold bins {}..{}",
            tf.first_bin,
            tf.first_bin + tf.num_bins
        )));
    }
    let d = tf.num_dirs();
    let m = tf.num_mics;
    if tf.data.len() != d * m * nbins {
        return Err(Error::Mismatch(format!(
            "TF data has {} values, expected {d} directions × {m} mics × {nbins} bins",
            tf.data.len()
        )));
    }
    let root = format!("{TF_ROOT}/");
    let mut out: Vec<(String, Vec<u8>)> = Vec::with_capacity(6 + 2 * d);
    out.push((root.clone(), Vec::new()));
    out.push((format!("{root}whatisthis.txt"), TF_WHATISTHIS.as_bytes().to_vec()));
    out.push((
        format!("{root}microphones.xml"),
        hark_xml_document(
            vec![positions_element("microphone", &tf.mic_positions, None)],
            false,
        )
        .into_bytes(),
    ));
    let cfg = HarkConfig::new(tf.nfft, tf.sample_rate_hz, comment);
    out.push((
        format!("{root}source.xml"),
        hark_xml_document(
            vec![
                cfg.to_element(),
                positions_element("soundsource", &tf.grid.points, None),
                neighbors_element(&tf.grid.neighbors),
            ],
            true,
        )
        .into_bytes(),
    ));
    out.push((format!("{root}localization/"), Vec::new()));
    out.push((format!("{root}separation/"), Vec::new()));
    let per = m * nbins;
    for id in 0..d {
        let loc = &tf.data[id * per..(id + 1) * per];
        out.push((
            tf_entry_name(&root, "localization", id),
            write_mat(&MatData::complex(m, nbins, loc.to_vec())),
        ));
        out.push((
            tf_entry_name(&root, "separation", id),
            write_mat(&MatData::complex(
                m,
                nbins,
                loc.iter().map(|c| c.conj()).collect(),
            )),
        ));
    }
    Ok(out)
}

/// Write `tf` as a HARK transfer-function zip at `path` (atomically). Needs all
/// nfft/2 + 1 bins. The separation TFs are the complex conjugates of the localization
/// ones (right for geometric TFs; a measured set read from a zip loses its own
/// separation TFs). The `<neighbors>` table is `tf.grid.neighbors`; microphone positions
/// `tf.mic_positions`.
pub fn write_tf_zip(tf: &TransferFunctions, path: &Path) -> Result<()> {
    // Only what the readers take back: a localizable FFT length, a sampling rate, finite
    // values.
    let bad = |m: String| Err(Error::Config(format!("{}: {m}", path.display())));
    if tf.nfft < 4 {
        return bad(format!("fft length must be at least 4, got {}", tf.nfft));
    }
    if tf.sample_rate_hz == 0 {
        return bad("the sampling rate must be a positive number of Hz, got 0".into());
    }
    if let Some(i) = tf
        .data
        .iter()
        .position(|z| !(z.re.is_finite() && z.im.is_finite()))
    {
        return bad(format!("transfer-function value {i} is not finite"));
    }
    if tf.mic_positions.iter().flatten().any(|v| !v.is_finite()) {
        return bad("a microphone position is not finite".into());
    }
    let entries = tf_zip_entries(tf, "Generated by soundloc")?;
    write_zip_entries(path, &entries)
}
