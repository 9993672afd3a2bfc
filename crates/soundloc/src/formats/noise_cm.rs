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
//!
//! ## Output names of a text pair
//! [`text_pair_paths`] turns one output name into the pair's two names: a name that already
//! marks the real part (`.real`, `.re`, or a stem ending in `real`/`Real`/`REAL`, `_re`,
//! `-re`, `_r`, `-r`, `_R`, `-R`) is the real file and the imaginary one is its first
//! [`imag_path_candidates`] renaming (`noise_r.dat` → `noise_i.dat`, `cm.real` →
//! `cm.imag`); any other name gets `_r` / `_i` appended to its stem (`K` → `K_r`, `K_i`;
//! `noise.dat` → `noise_r.dat`, `noise_i.dat`). Either way [`NoiseCm::load`] given the
//! real file finds the imaginary one.
//!
//! ## Estimation and the engine's K
//! [`NoiseCm::estimate`] averages x xᴴ over the STFT frames of a noise recording (or a time
//! range of it) for **every** bin 0 … N/2, so the result has HARK's shape;
//! [`crate::engine::estimate_noise`] does the same for the analysis bins only. The engine
//! holds K as [`NoiseMatrices`] for a range of bins: [`NoiseCm::to_noise_matrices`] cuts
//! that range out, [`NoiseCm::from_noise_matrices`] goes back to all N/2 + 1 bins, filling
//! the bins the engine does not hold with the identity (white noise of unit power: the K
//! soundloc assumes when none is given).
//!
//! ## Summary
//! [`NoiseCm::summary`] (what `soundloc noisecm inspect` prints) gives, per bin, the trace
//! and the smallest and largest eigenvalue of the Hermitian part of K_k, and its condition
//! number λ_max/λ_min (infinite when λ_min ≤ 0: such a K cannot whiten; GEVD and GSVD need
//! it positive definite).

use std::collections::BTreeMap;
use std::io::Write as _;
use std::ops::Range;
use std::path::{Path, PathBuf};

use num_complex::Complex;

use crate::config::{LocalizeConfig, WindowFunction};
use crate::error::{Error, Result};
use crate::formats::hark_mat::{read_mat, write_mat, MatData};
use crate::formats::{hark_zip, xml};
use crate::noise::NoiseMatrices;
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
        Ok(NoiseCm { num_mics, nfft, data })
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
        NoiseCm { num_mics, nfft, data }
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
            check_bin(self.get(k), self.num_mics).map_err(|m| Error::format(p, format!("bin {k}: {m}")))?;
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
                    format!("{num_bins} matrices, but nfft {n} needs nfft/2+1 = {}", n / 2 + 1),
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
            check_bin(&data[start..], m).map_err(|msg| Error::format(&ep, format!("bin {bin}: {msg}")))?;
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

    /// K for the absolute bins `bins` as the engine's [`NoiseMatrices`] (`num_frames` 0:
    /// unknown). Errors when `bins` is empty or reaches past bin N/2.
    pub fn to_noise_matrices(&self, bins: Range<usize>) -> Result<NoiseMatrices> {
        if bins.is_empty() || bins.end > self.num_bins() {
            return Err(Error::Mismatch(format!(
                "noise correlation: bins {}..{} requested, the matrices hold bins 0..{} (nfft {})",
                bins.start,
                bins.end,
                self.num_bins(),
                self.nfft
            )));
        }
        let mm = self.num_mics * self.num_mics;
        Ok(NoiseMatrices {
            num_mics: self.num_mics,
            first_bin: bins.start,
            num_bins: bins.len(),
            num_frames: 0,
            data: self.data[bins.start * mm..bins.end * mm].to_vec(),
        })
    }

    /// All N/2 + 1 bins of an `nfft`-point FFT from the engine's K: the bins `k` holds are
    /// copied, every other bin is the identity (see the module docs). Errors when `k`
    /// holds bins beyond N/2 or its data does not match its shape.
    pub fn from_noise_matrices(k: &NoiseMatrices, nfft: usize) -> Result<Self> {
        let mm = k.num_mics * k.num_mics;
        let end = k.first_bin + k.num_bins;
        if k.num_mics == 0 || k.data.len() != k.num_bins * mm {
            return Err(Error::Mismatch(format!(
                "noise correlation: {} values for {} bins of {} × {} matrices",
                k.data.len(),
                k.num_bins,
                k.num_mics,
                k.num_mics
            )));
        }
        if nfft < 2 || end > nfft / 2 + 1 {
            return Err(Error::Mismatch(format!(
                "noise correlation: bins {}..{end} do not fit an nfft of {nfft} (bins 0..{})",
                k.first_bin,
                nfft / 2 + 1
            )));
        }
        let mut cm = NoiseCm::identity(k.num_mics, nfft);
        cm.data[k.first_bin * mm..end * mm].copy_from_slice(&k.data);
        Ok(cm)
    }

    /// Estimates K for every bin 0 … N/2 from planar samples: x xᴴ averaged over the
    /// complete `nfft`-sample frames (every `hop` samples, `window` applied, unscaled FFT)
    /// inside `range_s` (seconds; `None` = all), as [`crate::engine::estimate_noise`] does
    /// for the analysis bins. Returns K and the number of frames averaged.
    pub fn estimate(
        channels: &[Vec<f32>],
        sample_rate_hz: u32,
        nfft: usize,
        hop: usize,
        window: WindowFunction,
        range_s: Option<(f64, f64)>,
    ) -> Result<(Self, usize)> {
        if channels.is_empty() {
            return Err(Error::Mismatch("noise estimate: no channels".into()));
        }
        let config = LocalizeConfig {
            nfft,
            hop,
            sample_rate_hz,
            window_function: window,
            lower_freq_hz: 0.0,
            // ⌊fs·N/fs⌋ = N, capped at N/2 + 1 by bin_range: every bin.
            upper_freq_hz: sample_rate_hz as f64,
            ..LocalizeConfig::default()
        };
        let k = crate::engine::estimate_noise(&config, sample_rate_hz, channels, range_s)?;
        let frames = k.num_frames;
        Ok((Self::from_noise_matrices(&k, nfft)?, frames))
    }

    /// Per-bin trace, eigenvalue range and condition number (see the module docs).
    pub fn summary(&self) -> NoiseCmSummary {
        let m = self.num_mics;
        let bins: Vec<BinStats> = (0..self.num_bins()).map(|k| bin_stats(self.get(k), m)).collect();
        let finite_cond: Vec<f64> = bins
            .iter()
            .map(|b| b.condition)
            .filter(|c| c.is_finite())
            .collect();
        let traces: Vec<f64> = bins.iter().map(|b| b.trace).collect();
        NoiseCmSummary {
            num_mics: m,
            nfft: self.nfft,
            num_bins: self.num_bins(),
            not_positive_definite: bins.iter().filter(|b| !b.condition.is_finite()).count(),
            trace_min: traces.iter().copied().fold(f64::INFINITY, f64::min),
            trace_median: median(&traces),
            trace_max: traces.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            condition_median: median(&finite_cond),
            worst_bin: bins
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.condition.total_cmp(&b.1.condition))
                .map_or(0, |(k, _)| k),
            bins,
        }
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

/// One bin's numbers in a [`NoiseCmSummary`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct BinStats {
    /// Trace of K_k (real part): the total noise power over the microphones.
    pub trace: f64,
    /// Smallest eigenvalue of the Hermitian part of K_k.
    pub min_eigenvalue: f64,
    /// Largest eigenvalue of the Hermitian part of K_k.
    pub max_eigenvalue: f64,
    /// λ_max / λ_min; infinite when λ_min ≤ 0 (not positive definite).
    #[serde(serialize_with = "finite_or_null")]
    pub condition: f64,
}

/// What `soundloc noisecm inspect` prints: shape and per-bin conditioning of a [`NoiseCm`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct NoiseCmSummary {
    /// Microphones (channels) M.
    pub num_mics: usize,
    /// FFT length N.
    pub nfft: usize,
    /// Bins, N/2 + 1.
    pub num_bins: usize,
    /// Bins whose K is not positive definite.
    pub not_positive_definite: usize,
    /// Smallest trace over the bins.
    pub trace_min: f64,
    /// Median trace.
    pub trace_median: f64,
    /// Largest trace.
    pub trace_max: f64,
    /// Median condition number over the positive definite bins (NaN when there are none).
    #[serde(serialize_with = "finite_or_null")]
    pub condition_median: f64,
    /// The bin with the largest condition number.
    pub worst_bin: usize,
    /// Per bin, index = bin.
    pub bins: Vec<BinStats>,
}

impl std::fmt::Display for NoiseCmSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "microphones      {}", self.num_mics)?;
        writeln!(f, "nfft             {}", self.nfft)?;
        writeln!(
            f,
            "bins             {} (0..={})",
            self.num_bins,
            self.num_bins - 1
        )?;
        writeln!(
            f,
            "trace            {:.4e} … {:.4e} (median {:.4e})",
            self.trace_min, self.trace_max, self.trace_median
        )?;
        writeln!(
            f,
            "condition        median {:.4e}, worst {:.4e} at bin {}",
            self.condition_median,
            self.bins.get(self.worst_bin).map_or(f64::NAN, |b| b.condition),
            self.worst_bin
        )?;
        writeln!(f, "not pos. def.    {} bin(s)", self.not_positive_definite)
    }
}

fn finite_or_null<S: serde::Serializer>(v: &f64, s: S) -> std::result::Result<S::Ok, S::Error> {
    if v.is_finite() {
        s.serialize_f64(*v)
    } else {
        s.serialize_none()
    }
}

fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

/// Trace and eigenvalues of the Hermitian part of one bin's K.
fn bin_stats(k: &[Complex<f64>], m: usize) -> BinStats {
    let h = faer::Mat::<faer::c64>::from_fn(m, m, |i, j| (k[i * m + j] + k[j * m + i].conj()) * 0.5);
    let trace = (0..m).map(|i| k[i * m + i].re).sum();
    let (lo, hi) = match h.self_adjoint_eigenvalues(faer::Side::Lower) {
        // Sorted in nondecreasing order.
        Ok(ev) if !ev.is_empty() => (ev[0], ev[ev.len() - 1]),
        _ => (f64::NAN, f64::NAN),
    };
    let condition = if lo > 0.0 { hi / lo } else { f64::INFINITY };
    BinStats {
        trace,
        min_eigenvalue: lo,
        max_eigenvalue: hi,
        condition,
    }
}

/// The two files of a text pair written for the output name `output`: (real, imaginary).
/// See the module docs for the rule.
pub fn text_pair_paths(output: &Path) -> (PathBuf, PathBuf) {
    let name = output
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let (stem, ext) = match name.rfind('.') {
        Some(i) if i > 0 => (&name[..i], &name[i..]),
        _ => (name.as_str(), ""),
    };
    let marks_real = name.ends_with(".real")
        || name.ends_with(".re")
        || ["real", "Real", "REAL", "_re", "-re", "_r", "-r", "_R", "-R"]
            .iter()
            .any(|m| stem.ends_with(m));
    if marks_real {
        if let Some(imag) = imag_path_candidates(output).into_iter().next() {
            return (output.to_path_buf(), imag);
        }
    }
    (
        output.with_file_name(format!("{stem}_r{ext}")),
        output.with_file_name(format!("{stem}_i{ext}")),
    )
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
                Error::format(path, format!("line {n}, column {}: not a number: {tok:?}", c + 1))
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
                format!("{} line(s): need nfft/2+1 ≥ 2 lines, one per bin", rows.len()),
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

#[cfg(test)]
mod tests {
    use super::*;

    fn hermitian(m: usize, nfft: usize, seed: u64) -> NoiseCm {
        // K_k = A Aᴴ + I with a deterministic A: Hermitian, positive definite.
        let mut s = seed;
        let mut rnd = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 33) as f64 / (1u64 << 31) as f64) - 0.5
        };
        let nb = nfft / 2 + 1;
        let mut data = Vec::with_capacity(nb * m * m);
        for _ in 0..nb {
            let a: Vec<Complex<f64>> = (0..m * m).map(|_| Complex::new(rnd(), rnd())).collect();
            for i in 0..m {
                for j in 0..m {
                    let mut v: Complex<f64> = (0..m).map(|l| a[i * m + l] * a[j * m + l].conj()).sum();
                    if i == j {
                        v.re += 1.0;
                        v.im = 0.0;
                    }
                    data.push(v);
                }
            }
        }
        NoiseCm::new(m, nfft, data).unwrap()
    }

    #[test]
    fn noise_matrices_round_trip_with_identity_outside() {
        let cm = hermitian(3, 16, 7);
        let k = cm.to_noise_matrices(2..6).unwrap();
        assert_eq!((k.num_mics, k.first_bin, k.num_bins), (3, 2, 4));
        assert_eq!(k.bin(4).unwrap(), cm.get(4));
        let back = NoiseCm::from_noise_matrices(&k, 16).unwrap();
        assert_eq!(back.num_bins(), 9);
        for b in 0..9 {
            if (2..6).contains(&b) {
                assert_eq!(back.get(b), cm.get(b));
            } else {
                assert_eq!(back.get(b), NoiseCm::identity(3, 16).get(b));
            }
        }
        assert!(cm.to_noise_matrices(5..10).is_err());
        assert!(cm.to_noise_matrices(3..3).is_err());
        assert!(NoiseCm::from_noise_matrices(&k, 8).is_err());
    }

    #[test]
    fn estimate_covers_every_bin_and_matches_the_engine() {
        let fs = 16000;
        let ch: Vec<Vec<f32>> = (0..2)
            .map(|c| (0..4000).map(|i| ((i * (c + 3)) % 17) as f32 - 8.0).collect())
            .collect();
        let (cm, frames) =
            NoiseCm::estimate(&ch, fs, 64, 32, WindowFunction::Hanning, Some((0.0, 0.2))).unwrap();
        assert_eq!((cm.num_mics, cm.nfft, cm.num_bins()), (2, 64, 33));
        assert_eq!(frames, (3200 - 64) / 32 + 1);
        cm.validate(Path::new("k")).unwrap();
        let config = LocalizeConfig {
            nfft: 64,
            hop: 32,
            sample_rate_hz: fs,
            window_function: WindowFunction::Hanning,
            lower_freq_hz: 1000.0,
            upper_freq_hz: 4000.0,
            ..LocalizeConfig::default()
        };
        let k = crate::engine::estimate_noise(&config, fs, &ch, Some((0.0, 0.2))).unwrap();
        let cut = cm.to_noise_matrices(config.bin_range()).unwrap();
        for (a, b) in k.data.iter().zip(&cut.data) {
            assert!((a - b).norm() <= 1e-9 * a.norm().max(1.0), "{a} vs {b}");
        }
    }

    #[test]
    fn summary_reports_conditioning() {
        let mut cm = NoiseCm::identity(2, 8);
        // Bin 1: diag(4, 1) → condition 4; bin 2: rank one → not positive definite.
        cm.data[4] = Complex::new(4.0, 0.0);
        for v in &mut cm.data[8..12] {
            *v = Complex::new(1.0, 0.0);
        }
        let s = cm.summary();
        assert_eq!((s.num_mics, s.nfft, s.num_bins), (2, 8, 5));
        assert!((s.bins[1].condition - 4.0).abs() < 1e-12);
        assert!((s.bins[1].trace - 5.0).abs() < 1e-12);
        assert!(!s.bins[2].condition.is_finite());
        assert_eq!((s.not_positive_definite, s.worst_bin), (1, 2));
        assert!((s.condition_median - 1.0).abs() < 1e-12);
        let text = s.to_string();
        assert!(text.contains("not pos. def.    1 bin"), "{text}");
        let json = serde_json::to_string(&s).unwrap();
        assert!(json.contains("\"condition\":null"), "{json}");
    }

    #[test]
    fn text_pair_names_are_found_again() {
        let cases = [
            ("K", "K_r", "K_i"),
            ("noise.dat", "noise_r.dat", "noise_i.dat"),
            ("noise_r.dat", "noise_r.dat", "noise_i.dat"),
            ("cm.real", "cm.real", "cm.imag"),
            ("cm_real.txt", "cm_real.txt", "cm_imag.txt"),
            ("cluster", "cluster_r", "cluster_i"),
        ];
        let dir = std::env::temp_dir().join(format!("soundloc-cmnames-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let cm = hermitian(2, 8, 3);
        for (out, re, im) in cases {
            let (r, i) = text_pair_paths(&dir.join(out));
            assert_eq!((r.clone(), i.clone()), (dir.join(re), dir.join(im)), "{out}");
            cm.write_text_pair(&r, &i).unwrap();
            assert_eq!(find_imag_path(&r).unwrap(), i, "{out}");
            let back = NoiseCm::load(&r, Expected::default()).unwrap();
            assert_eq!(back, cm);
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
