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
//! `cmr.dat` → `cmi.dat`, `cm_real.txt` → `cm_imag.txt`). Otherwise give both as
//! `REAL,IMAG` (to `NoiseCm::load`, `--noise-cm`, `noisecm inspect`) or pass both paths to
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
//! [`crate::noise::estimate`] does the same for the analysis bins only. The engine
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

mod summary;
mod text;
mod zip;

use std::ops::Range;
use std::path::{Path, PathBuf};

use num_complex::Complex;

use crate::config::{LocalizeConfig, WindowFunction};
use crate::error::{Error, Result};
use crate::formats::hark_zip;
use crate::noise::NoiseMatrices;

pub use summary::{BinStats, NoiseCmSummary};
pub use text::{find_imag_path, imag_path_candidates, text_pair_paths};

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

    /// K of the microphones `channels` only (indices into this K's, in that order): the
    /// noise statistics of a subset of the array are the sub-matrices.
    pub fn select_channels(&self, channels: &[usize], path: &Path) -> Result<NoiseCm> {
        let m = self.num_mics;
        if let Some(&c) = channels.iter().find(|&&c| c >= m) {
            return Err(Error::Mismatch(format!(
                "{}: channel {c} selected, the matrices hold {m} microphones (0..{m})",
                path.display()
            )));
        }
        let n = channels.len();
        let mut data = Vec::with_capacity(self.num_bins() * n * n);
        for k in 0..self.num_bins() {
            let kk = &self.data[k * m * m..(k + 1) * m * m];
            for &i in channels {
                data.extend(channels.iter().map(|&j| kk[i * m + j]));
            }
        }
        NoiseCm::new(n, self.nfft, data)
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

    /// Before writing: only what the readers take back (finite, Hermitian matrices).
    fn check_values(&self, path: &Path) -> Result<()> {
        let mm = self.num_mics * self.num_mics;
        for (b, k) in self.data.chunks_exact(mm).enumerate() {
            check_bin(k, self.num_mics)
                .map_err(|e| Error::Config(format!("{}: K at bin {b}: {e}", path.display())))?;
        }
        Ok(())
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
    /// inside `range_s` (seconds; `None` = all), as [`crate::noise::estimate`] does
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
        let k = crate::noise::estimate(&config, sample_rate_hz, channels, range_s)?;
        let frames = k.num_frames;
        Ok((Self::from_noise_matrices(&k, nfft)?, frames))
    }

    /// The files [`load`](Self::load) reads for `path` (a zip: itself; a text pair: both),
    /// for checking that no output replaces them; `path` alone where it cannot be read.
    pub fn files_read(path: &Path) -> Vec<PathBuf> {
        match locate(path) {
            Ok(Located::Zip) | Err(_) => vec![path.to_path_buf()],
            Ok(Located::Pair(re, im)) => vec![re, im],
        }
    }

    /// Loads a zip (detected by its `PK` signature) or a text pair given its real-part file
    /// (the imaginary file is found by name, see the module docs) or both as `REAL,IMAG`
    /// (when no file has that whole name), or by the name the pair was written for
    /// (`K` for `K_r` and `K_i`, when no file `K` exists).
    pub fn load(path: &Path, expected: Expected) -> Result<Self> {
        match locate(path)? {
            Located::Zip => Self::read_zip(path, expected),
            Located::Pair(re, im) => Self::read_text_pair(&re, &im, expected),
        }
    }
}

/// What [`NoiseCm::load`] reads for a name.
enum Located {
    /// The file itself, a zip.
    Zip,
    /// A text pair: real part, imaginary part.
    Pair(PathBuf, PathBuf),
}

/// The rule of [`NoiseCm::load`]: `REAL,IMAG` or the pair written for the name when no
/// file has the name; else a zip by its signature; else a real-part file and its
/// imaginary file found by name.
fn locate(path: &Path) -> Result<Located> {
    if !path.exists() {
        if let Some((re, im)) = path.to_str().and_then(|s| s.split_once(',')) {
            return Ok(Located::Pair(re.into(), im.into()));
        }
        // The name `noisecm make -o NAME --format text` was given: NAME_r and NAME_i.
        let (re, im) = text_pair_paths(path);
        if re.is_file() && im.is_file() {
            return Ok(Located::Pair(re, im));
        }
    }
    let mut head = [0u8; 4];
    let n = std::fs::File::open(path)
        .and_then(|mut f| std::io::Read::read(&mut f, &mut head))
        .map_err(|e| Error::io(path, e))?;
    if hark_zip::looks_like_zip(&head[..n]) {
        return Ok(Located::Zip);
    }
    // A .zip name that is not a zip (empty, cut, another format) is a bad zip, not the
    // real part of a text pair.
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("zip")) {
        return Err(Error::format(
            path,
            if n == 0 {
                "empty file, not a noise correlation zip"
            } else {
                "not a zip file (no zip signature), so not a HARK noise correlation zip"
            },
        ));
    }
    if matches!(&head[..n], b"RIFF" | b"RF64" | b"fLaC") {
        return Err(Error::format(
            path,
            "a recording (WAV/FLAC), not a noise correlation matrix: give it as --noise, or build K from it with `soundloc noisecm make`",
        ));
    }
    Ok(Located::Pair(path.to_path_buf(), find_imag_path(path)?))
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

#[cfg(test)]
mod tests {
    use super::*;

    pub(super) fn hermitian(m: usize, nfft: usize, seed: u64) -> NoiseCm {
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
        let k = crate::noise::estimate(&config, fs, &ch, Some((0.0, 0.2))).unwrap();
        let cut = cm.to_noise_matrices(config.bin_range()).unwrap();
        for (a, b) in k.data.iter().zip(&cut.data) {
            assert!((a - b).norm() <= 1e-9 * a.norm().max(1.0), "{a} vs {b}");
        }
    }
}
