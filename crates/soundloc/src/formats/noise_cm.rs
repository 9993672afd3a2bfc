//! Noise correlation matrices K_k as HARK's `CMSave` writes and `CMLoad` reads them.
//!
//! [`NoiseCm`] holds one M × M complex matrix per frequency bin k = 0 … N/2 (N = `nfft`,
//! N/2 + 1 bins), row-major: `data[k·M² + i·M + j]` = K_k(i, j). Values are in the units of
//! the correlation they were estimated from (HARK: raw PCM values squared).
//!
//! ## HARK ≤ 2.0: text pair (CMLoad `FILENAMER` / `FILENAMEI`)
//! Two text files, the real part and the imaginary part. Each has one line per bin (N/2 + 1
//! lines), each line the M² numbers of K_k row-major (column i·M + j holds K(i, j)),
//! space separated, `%e` style. soundloc writes Rust's shortest round-trip exponent form
//! (`1.25e-3`), which every `%e`/`strtod` reader accepts, so a written pair reads back
//! exactly. Each file is replaced atomically; the pair as a whole is not.
//!
//! [`NoiseCm::load`] given the real-part file finds the imaginary one by the first of these
//! renamings that names an existing file (see [`imag_path_candidates`]):
//! `X.real` → `X.imag`, `X.re` → `X.im`; for the name without extension,
//! `…real` → `…imag`, `…Real` → `…Imag`, `…REAL` → `…IMAG`, `…_re` → `…_im`,
//! `…-re` → `…-im`, `…r` → `…i`, `…R` → `…I` (so `noise_r.dat` → `noise_i.dat`,
//! `cmr.dat` → `cmi.dat`, `cm_real.txt` → `cm_imag.txt`). Otherwise pass both paths to
//! [`NoiseCm::read_text_pair`].
//!
//! ## HARK ≥ 2.1: zip (*unverified layout*)
//! The transfer-function zip container, with (folder `correlationMatrix/` when writing):
//! - `correlationMatrix/whatisthis.txt`: `correlation matrix`;
//! - `correlationMatrix/source.xml`: `<config><nfft>N</nfft></config>` and one
//!   `<position x="0" y="0" z="0" id="k"/>` per bin (id = bin);
//! - `correlationMatrix/microphones.xml`: M placeholder microphone positions;
//! - `correlationMatrix/localization/cm%05d.mat`: bin k's K_k as an M × M `complex` matrix
//!   (f32, so writing a zip rounds to single precision).
//!
//! The reader is tolerant: the folder is whichever holds `whatisthis.txt` (any name, or the
//! zip root); matrices are every `….mat` under it whose name ends in the bin number
//! (`cm00003.mat`, `tf00003.mat`), preferring a `localization/` sub-folder when several
//! folders hold them; `nfft` comes from a `<nfft>` element when present, else from the bin
//! count (N = 2·(bins − 1)).
//!
//! ## Validation (every reader)
//! Bin count = N/2 + 1 (and = `expected.nfft`/2 + 1 when given), M² values per bin (M =
//! `expected.num_mics` when given), every value finite, and each K_k Hermitian:
//! |K(i,j) − conj K(j,i)| ≤ [`HERMITIAN_RTOL`] · max |K_k| (which also bounds the imaginary
//! part of the diagonal). Errors name the file and the line (text) or entry (zip).

use std::collections::BTreeMap;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use num_complex::Complex;

use crate::error::{Error, Result};
use crate::formats::hark_mat::{read_mat, write_mat, MatData};
use crate::formats::{hark_zip, xml};
use crate::output::atomic::write_atomically;

/// Root folder written in a correlation-matrix zip.
pub const CM_ROOT: &str = "correlationMatrix";

/// Relative tolerance of the Hermitian check (text files carry 6–7 significant digits).
pub const HERMITIAN_RTOL: f64 = 1e-4;

/// What a caller expects of a loaded matrix set; `None` accepts what the file holds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Expected {
    /// Microphone count M.
    pub num_mics: Option<usize>,
    /// FFT length N (N/2 + 1 bins).
    pub nfft: Option<usize>,
}

/// Noise correlation matrices, one M × M complex matrix per bin. See the [module docs](self).
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseCm {
    /// Microphone count M.
    pub num_mics: usize,
    /// FFT length N; there are N/2 + 1 bins.
    pub nfft: usize,
    /// `[bin][i][j]`, row-major: `data[k·M² + i·M + j]` = K_k(i, j).
    pub data: Vec<Complex<f64>>,
}

impl NoiseCm {
    /// Wraps `data`, checking its length is (nfft/2 + 1)·M².
    pub fn new(num_mics: usize, nfft: usize, data: Vec<Complex<f64>>) -> Result<Self> {
        let want = (nfft / 2 + 1) * num_mics * num_mics;
        if num_mics == 0 || nfft == 0 || data.len() != want {
            return Err(Error::Mismatch(format!(
                "noise correlation: {} values for {num_mics} mics and nfft {nfft} (expected {want})",
                data.len()
            )));
        }
        Ok(NoiseCm {
            num_mics,
            nfft,
            data,
        })
    }

    /// Identity matrices (white, uncorrelated noise of unit power).
    pub fn identity(num_mics: usize, nfft: usize) -> Self {
        let m = num_mics;
        let mut data = vec![Complex::new(0.0, 0.0); (nfft / 2 + 1) * m * m];
        for (idx, z) in data.iter_mut().enumerate() {
            let e = idx % (m * m);
            if e / m == e % m {
                *z = Complex::new(1.0, 0.0);
            }
        }
        NoiseCm {
            num_mics,
            nfft,
            data,
        }
    }

    /// Number of bins, N/2 + 1.
    pub fn num_bins(&self) -> usize {
        self.nfft / 2 + 1
    }

    /// K_k for bin `bin`, M² values row-major. Panics when `bin ≥ num_bins()` (like slice
    /// indexing); see [`try_get`](Self::try_get).
    pub fn get(&self, bin: usize) -> &[Complex<f64>] {
        let mm = self.num_mics * self.num_mics;
        &self.data[bin * mm..(bin + 1) * mm]
    }

    /// K_k for bin `bin`, or `None` when out of range.
    pub fn try_get(&self, bin: usize) -> Option<&[Complex<f64>]> {
        let mm = self.num_mics * self.num_mics;
        self.data.get(bin * mm..(bin + 1) * mm)
    }

    /// Checks sizes, finiteness and Hermitian symmetry (see the module docs); errors name
    /// `path_for_errors` and the bin.
    pub fn validate(&self, path_for_errors: &Path) -> Result<()> {
        let p = path_for_errors;
        let mm = self.num_mics * self.num_mics;
        if self.num_mics == 0 || self.data.len() != self.num_bins() * mm {
            return Err(Error::format(
                p,
                format!(
                    "{} values for {} mics and nfft {} (expected {})",
                    self.data.len(),
                    self.num_mics,
                    self.nfft,
                    self.num_bins() * mm
                ),
            ));
        }
        for k in 0..self.num_bins() {
            check_bin(self.get(k), self.num_mics)
                .map_err(|m| Error::format(p, format!("bin {k}: {m}")))?;
        }
        Ok(())
    }

    fn check_expected(&self, expected: Expected, path: &Path) -> Result<()> {
        if let Some(m) = expected.num_mics {
            if m != self.num_mics {
                return Err(Error::format(
                    path,
                    format!(
                        "holds {} × {} matrices, expected {m} microphones",
                        self.num_mics, self.num_mics
                    ),
                ));
            }
        }
        if let Some(n) = expected.nfft {
            if n / 2 + 1 != self.num_bins() {
                return Err(Error::format(
                    path,
                    format!(
                        "holds {} bins, expected {} (nfft {n} → nfft/2+1)",
                        self.num_bins(),
                        n / 2 + 1
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Reads a HARK ≤ 2.0 text pair (real-part file, imaginary-part file).
    pub fn read_text_pair(real: &Path, imag: &Path, expected: Expected) -> Result<Self> {
        let re = read_text_matrix(real, expected)?;
        let im = read_text_matrix(imag, expected)?;
        if re.rows.len() != im.rows.len() || re.cols != im.cols {
            return Err(Error::format(
                imag,
                format!(
                    "{} lines of {} numbers, but the real part {} has {} lines of {}",
                    im.rows.len(),
                    im.cols,
                    real.display(),
                    re.rows.len(),
                    re.cols
                ),
            ));
        }
        let m = re.num_mics;
        let data: Vec<Complex<f64>> = re
            .rows
            .iter()
            .zip(&im.rows)
            .flat_map(|(r, i)| r.iter().zip(i).map(|(&a, &b)| Complex::new(a, b)))
            .collect();
        let nfft = expected.nfft.unwrap_or(2 * (re.rows.len() - 1));
        let cm = NoiseCm {
            num_mics: m,
            nfft,
            data,
        };
        for k in 0..cm.num_bins() {
            check_bin(cm.get(k), m).map_err(|msg| {
                Error::format(
                    real,
                    format!("line {} (bin {k}, with {}): {msg}", k + 1, imag.display()),
                )
            })?;
        }
        Ok(cm)
    }

    /// Writes the HARK ≤ 2.0 text pair (each file atomically).
    pub fn write_text_pair(&self, real: &Path, imag: &Path) -> Result<()> {
        self.validate_shape(real)?;
        let part = |f: fn(&Complex<f64>) -> f64| {
            let mut s = String::new();
            for k in 0..self.num_bins() {
                for (c, z) in self.get(k).iter().enumerate() {
                    if c > 0 {
                        s.push(' ');
                    }
                    s.push_str(&format!("{:e}", f(z)));
                }
                s.push('\n');
            }
            s
        };
        let re = part(|z| z.re);
        write_atomically(real, |w| w.write_all(re.as_bytes()))?;
        let im = part(|z| z.im);
        write_atomically(imag, |w| w.write_all(im.as_bytes()))
    }

    fn validate_shape(&self, path: &Path) -> Result<()> {
        let want = self.num_bins() * self.num_mics * self.num_mics;
        if self.num_mics == 0 || self.data.len() != want {
            return Err(Error::Mismatch(format!(
                "{}: cannot write {} values as {} bins of {} × {} matrices",
                path.display(),
                self.data.len(),
                self.num_bins(),
                self.num_mics,
                self.num_mics
            )));
        }
        Ok(())
    }

    /// Reads a HARK ≥ 2.1 correlation-matrix zip (see the module docs).
    pub fn read_zip(path: &Path, expected: Expected) -> Result<Self> {
        let entries = hark_zip::read_zip_entries(path)?;
        let (root, what) = hark_zip::container_root(&entries, path)?;
        if what != hark_zip::CM_WHATISTHIS {
            return Err(Error::format(
                hark_zip::entry_path(path, &format!("{root}whatisthis.txt")),
                format!(
                    "says {what:?}, expected {:?} (a transfer-function zip is not a noise matrix)",
                    hark_zip::CM_WHATISTHIS
                ),
            ));
        }
        // Matrices: `<root>…/<letters><digits>.mat`, grouped by folder.
        let mut folders: BTreeMap<&str, BTreeMap<usize, &String>> = BTreeMap::new();
        for name in entries.keys() {
            let Some(rel) = name.strip_prefix(root.as_str()) else {
                continue;
            };
            let Some(stem) = rel.strip_suffix(".mat") else {
                continue;
            };
            let (dir, file) = match stem.rfind('/') {
                Some(i) => (&rel[..i], &stem[i + 1..]),
                None => ("", stem),
            };
            let digits = file.trim_start_matches(|c: char| !c.is_ascii_digit());
            if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
                continue;
            }
            if let Ok(bin) = digits.parse::<usize>() {
                folders.entry(dir).or_default().insert(bin, name);
            }
        }
        let chosen = folders
            .iter()
            .find(|(d, _)| d.rsplit('/').next() == Some("localization"))
            .or_else(|| folders.iter().next())
            .map(|(_, m)| m)
            .ok_or_else(|| Error::format(path, format!("no <bin>.mat matrices under {root:?}")))?;
        let num_bins = chosen.len();
        for (i, (&bin, name)) in chosen.iter().enumerate() {
            if bin != i {
                return Err(Error::format(
                    path,
                    format!("bin {i} is missing (next matrix: {name}); bins must be numbered 0..{num_bins}"),
                ));
            }
        }
        // nfft: from any <nfft> in an XML file of the container, else from the bin count.
        let mut nfft = None;
        for (name, bytes) in entries.range(root.clone()..) {
            if !name.starts_with(root.as_str()) {
                break;
            }
            if name.ends_with(".xml") {
                let ep = hark_zip::entry_path(path, name);
                let doc = xml::parse_file_text(&String::from_utf8_lossy(bytes), &ep)?;
                if let Some(e) = doc.find("nfft") {
                    let t = e.text_trimmed();
                    nfft = Some(t.parse::<usize>().map_err(|_| {
                        Error::format(&ep, format!("<nfft> is not a positive integer: {t:?}"))
                    })?);
                    break;
                }
            }
        }
        let nfft = match nfft {
            Some(n) if n / 2 + 1 != num_bins => {
                return Err(Error::format(
                    path,
                    format!(
                        "{num_bins} matrices, but nfft {n} needs nfft/2+1 = {}",
                        n / 2 + 1
                    ),
                ))
            }
            Some(n) => n,
            None if num_bins < 2 => {
                return Err(Error::format(
                    path,
                    format!("{num_bins} matrix: need nfft/2+1 ≥ 2"),
                ))
            }
            None => 2 * (num_bins - 1),
        };
        let mut m = 0;
        let mut data = Vec::new();
        for (&bin, name) in chosen {
            let ep = hark_zip::entry_path(path, name);
            let mat = read_mat(&entries[*name], &ep)?;
            let (rows, cols) = (mat.rows, mat.cols);
            if rows != cols || rows == 0 {
                return Err(Error::format(
                    &ep,
                    format!("{rows} × {cols} matrix, expected M × M"),
                ));
            }
            if bin == 0 {
                m = rows;
            } else if rows != m {
                return Err(Error::format(
                    &ep,
                    format!("{rows} × {rows} matrix, but bin 0 is {m} × {m}"),
                ));
            }
            if let Some(em) = expected.num_mics {
                if em != m {
                    return Err(Error::format(
                        &ep,
                        format!("{m} × {m} matrix, expected {em} microphones"),
                    ));
                }
            }
            let vals = mat.into_complex(&ep)?;
            if vals.len() != m * m {
                return Err(Error::format(
                    &ep,
                    format!("{} values, expected {}", vals.len(), m * m),
                ));
            }
            let start = data.len();
            data.extend(
                vals.iter()
                    .map(|z| Complex::new(f64::from(z.re), f64::from(z.im))),
            );
            check_bin(&data[start..], m)
                .map_err(|msg| Error::format(&ep, format!("bin {bin}: {msg}")))?;
        }
        let cm = NoiseCm {
            num_mics: m,
            nfft,
            data,
        };
        cm.check_expected(expected, path)?;
        Ok(cm)
    }

    /// The zip's entries (see the module docs), in writing order.
    pub fn zip_entries(&self) -> Result<Vec<(String, Vec<u8>)>> {
        self.validate_shape(Path::new(CM_ROOT))?;
        let root = format!("{CM_ROOT}/");
        let m = self.num_mics;
        let mut e: Vec<(String, Vec<u8>)> = vec![
            (root.clone(), Vec::new()),
            (
                format!("{root}whatisthis.txt"),
                hark_zip::CM_WHATISTHIS.as_bytes().to_vec(),
            ),
        ];
        let mics = hark_zip::positions_element("microphone", &vec![[0.0; 3]; m], None);
        e.push((
            format!("{root}microphones.xml"),
            hark_zip::hark_xml_document(vec![mics], false).into_bytes(),
        ));
        let config = xml::Element::new("config")
            .with_child(xml::Element::new("nfft").with_text(self.nfft.to_string()));
        let bins = hark_zip::positions_element("frequency", &vec![[0.0; 3]; self.num_bins()], None);
        e.push((
            format!("{root}source.xml"),
            hark_zip::hark_xml_document(vec![config, bins], false).into_bytes(),
        ));
        e.push((format!("{root}localization/"), Vec::new()));
        for k in 0..self.num_bins() {
            let vals = self
                .get(k)
                .iter()
                .map(|z| Complex::new(z.re as f32, z.im as f32))
                .collect();
            e.push((
                format!("{root}localization/cm{k:05}.mat"),
                write_mat(&MatData::complex(m, m, vals)),
            ));
        }
        Ok(e)
    }

    /// Writes the HARK ≥ 2.1 zip (atomically; values rounded to f32).
    pub fn write_zip(&self, path: &Path) -> Result<()> {
        hark_zip::write_zip_entries(path, &self.zip_entries()?)
    }

    /// Loads a zip (detected by its `PK` signature) or a text pair given its real-part file
    /// (the imaginary file is found by name, see the module docs).
    pub fn load(path: &Path, expected: Expected) -> Result<Self> {
        let mut head = [0u8; 4];
        let n = std::fs::File::open(path)
            .and_then(|mut f| std::io::Read::read(&mut f, &mut head))
            .map_err(|e| Error::io(path, e))?;
        if hark_zip::looks_like_zip(&head[..n]) {
            return Self::read_zip(path, expected);
        }
        let imag = find_imag_path(path)?;
        Self::read_text_pair(path, &imag, expected)
    }
}

/// Checks one bin: finite values, Hermitian within [`HERMITIAN_RTOL`].
fn check_bin(k: &[Complex<f64>], m: usize) -> std::result::Result<(), String> {
    let mut scale = 0.0f64;
    for (idx, z) in k.iter().enumerate() {
        if !(z.re.is_finite() && z.im.is_finite()) {
            return Err(format!(
                "K({}, {}) = {} is not finite",
                idx / m,
                idx % m,
                fmt_c(*z)
            ));
        }
        scale = scale.max(z.norm());
    }
    let tol = HERMITIAN_RTOL * scale;
    for i in 0..m {
        for j in i..m {
            let (a, b) = (k[i * m + j], k[j * m + i].conj());
            if (a - b).norm() > tol {
                return Err(format!(
                    "not Hermitian: K({i}, {j}) = {} but conj K({j}, {i}) = {} (tolerance {tol:.3e})",
                    fmt_c(a),
                    fmt_c(b)
                ));
            }
        }
    }
    Ok(())
}

fn fmt_c(z: Complex<f64>) -> String {
    format!("{}{:+}i", z.re, z.im)
}

struct TextMatrix {
    rows: Vec<Vec<f64>>,
    cols: usize,
    num_mics: usize,
}

/// Reads one text file of the pair: N/2 + 1 lines of M² finite numbers.
fn read_text_matrix(path: &Path, expected: Expected) -> Result<TextMatrix> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut rows = Vec::new();
    let mut cols = None;
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let mut row = Vec::new();
        for (c, tok) in line.split_whitespace().enumerate() {
            let v: f64 = tok.parse().map_err(|_| {
                Error::format(
                    path,
                    format!("line {n}, column {}: not a number: {tok:?}", c + 1),
                )
            })?;
            if !v.is_finite() {
                return Err(Error::format(
                    path,
                    format!("line {n}, column {}: not finite: {tok:?}", c + 1),
                ));
            }
            row.push(v);
        }
        match cols {
            None => {
                let m = isqrt(row.len());
                if m * m != row.len() {
                    return Err(Error::format(
                        path,
                        format!(
                            "line {n}: {} numbers is not M² for any microphone count M",
                            row.len()
                        ),
                    ));
                }
                if let Some(em) = expected.num_mics {
                    if em != m {
                        return Err(Error::format(
                            path,
                            format!(
                                "line {n}: {} numbers = {m}² but {em} microphones expected ({} numbers)",
                                row.len(),
                                em * em
                            ),
                        ));
                    }
                }
                cols = Some(row.len());
            }
            Some(c) if c != row.len() => {
                return Err(Error::format(
                    path,
                    format!("line {n}: {} numbers, expected {c} like line 1", row.len()),
                ));
            }
            Some(_) => {}
        }
        rows.push(row);
    }
    let Some(cols) = cols else {
        return Err(Error::format(path, "empty file: no matrix lines"));
    };
    match expected.nfft {
        Some(nfft) if rows.len() != nfft / 2 + 1 => {
            return Err(Error::format(
                path,
                format!(
                    "{} lines, expected {} (one per bin: nfft {nfft} → nfft/2+1)",
                    rows.len(),
                    nfft / 2 + 1
                ),
            ))
        }
        None if rows.len() < 2 => {
            return Err(Error::format(
                path,
                format!(
                    "{} line(s): need nfft/2+1 ≥ 2 lines, one per bin",
                    rows.len()
                ),
            ))
        }
        _ => {}
    }
    Ok(TextMatrix {
        rows,
        cols,
        num_mics: isqrt(cols),
    })
}

fn isqrt(n: usize) -> usize {
    let mut r = (n as f64).sqrt() as usize;
    while r * r > n {
        r -= 1;
    }
    while (r + 1) * (r + 1) <= n {
        r += 1;
    }
    r
}

/// Candidate imaginary-part paths for a real-part path, in the order tried (see the module
/// docs for the renaming rules).
pub fn imag_path_candidates(real: &Path) -> Vec<PathBuf> {
    let Some(name) = real.file_name().and_then(|n| n.to_str()) else {
        return Vec::new();
    };
    let mut names: Vec<String> = Vec::new();
    for (from, to) in [(".real", ".imag"), (".re", ".im")] {
        if let Some(base) = name.strip_suffix(from) {
            names.push(format!("{base}{to}"));
        }
    }
    let (stem, ext) = match name.rfind('.') {
        Some(i) if i > 0 => (&name[..i], &name[i..]),
        _ => (name, ""),
    };
    for (from, to) in [
        ("real", "imag"),
        ("Real", "Imag"),
        ("REAL", "IMAG"),
        ("_re", "_im"),
        ("-re", "-im"),
        ("r", "i"),
        ("R", "I"),
    ] {
        if let Some(base) = stem.strip_suffix(from) {
            names.push(format!("{base}{to}{ext}"));
        }
    }
    let mut seen = std::collections::HashSet::new();
    names
        .into_iter()
        .filter(|n| n != name && seen.insert(n.clone()))
        .map(|n| real.with_file_name(n))
        .collect()
}

/// The imaginary-part file of a text pair: the first existing [`imag_path_candidates`].
pub fn find_imag_path(real: &Path) -> Result<PathBuf> {
    let cands = imag_path_candidates(real);
    if let Some(p) = cands.iter().find(|p| p.is_file()) {
        return Ok(p.clone());
    }
    let tried: Vec<String> = cands.iter().map(|p| p.display().to_string()).collect();
    Err(Error::format(
        real,
        if tried.is_empty() {
            "cannot derive the imaginary-part file name (expected names like X_r.dat/X_i.dat, X.real/X.imag); give both files".to_string()
        } else {
            format!(
                "imaginary-part file not found (tried {}); give both files",
                tried.join(", ")
            )
        },
    ))
}
