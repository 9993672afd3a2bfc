//! Transfer functions a_{d,k}: for each direction d and frequency bin k, the complex
//! response of every microphone (the steering vector of MUSIC).
//!
//! Bin k of an N-point FFT at fs Hz is the frequency f_k = k·fs/N Hz; a full set holds
//! bins 0..=N/2. Sign convention (HARK's, and [`super::freefield`]'s): the microphone
//! nearer the source has the more positive phase, a_m(k) = e^{−j2πf_k r_m/c} for a
//! free-field source at distance r_m from microphone m.
//!
//! Sources: [`TransferFunctions::load`] reads a HARK TF zip (`formats::hark_zip`) or an old
//! HGTF `*_loc.dat` (`formats::hgtf`), telling them apart by their first bytes; or compute
//! free-field TFs with [`super::freefield::free_field`].

use super::{Grid, GridKind};
use crate::formats::{hark_zip, hgtf};
use crate::{Error, Result};
use num_complex::Complex;
use std::io::Read;
use std::ops::Range;
use std::path::Path;

/// Transfer functions for a set of directions, microphones and bins.
///
/// `data` is laid out `[direction][mic][bin - first_bin]` (row-major), complex f32 as HARK
/// stores them. Bins are those of an `nfft`-point FFT at `sample_rate_hz`; a file holds all
/// `nfft/2 + 1`, a computed set may hold only the bins the analysis uses.
#[derive(Debug, Clone, PartialEq)]
pub struct TransferFunctions {
    /// FFT length the TFs are defined for.
    pub nfft: usize,
    /// Sampling rate in Hz.
    pub sample_rate_hz: u32,
    /// Directions.
    pub grid: Grid,
    /// Microphone positions in metres as given by the source (may be placeholders in
    /// vendor files: never trust them over the TF data).
    pub mic_positions: Vec<[f64; 3]>,
    /// Number of microphones.
    pub num_mics: usize,
    /// First bin held in `data`.
    pub first_bin: usize,
    /// Number of bins held in `data`.
    pub num_bins: usize,
    /// `[direction][mic][bin - first_bin]`.
    pub data: Vec<Complex<f32>>,
}

/// What `soundloc tf inspect` prints: a plain, serialisable description of a TF set.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TfSummary {
    /// Microphones.
    pub num_mics: usize,
    /// Directions.
    pub num_dirs: usize,
    /// FFT length.
    pub nfft: usize,
    /// Sampling rate, Hz.
    pub sample_rate_hz: u32,
    /// First bin held.
    pub first_bin: usize,
    /// One past the last bin held.
    pub end_bin: usize,
    /// Frequency of the first bin held, Hz.
    pub first_bin_hz: f64,
    /// Frequency of the last bin held, Hz.
    pub last_bin_hz: f64,
    /// Grid arrangement.
    pub grid_kind: GridKind,
    /// The peak search's neighbour relation, in words.
    pub neighbor_relation: String,
    /// Largest angle between a direction and one of its neighbours, degrees.
    pub max_neighbor_angle_deg: f64,
    /// Smallest azimuth, degrees.
    pub azimuth_min_deg: f64,
    /// Largest azimuth, degrees.
    pub azimuth_max_deg: f64,
    /// Smallest elevation, degrees.
    pub elevation_min_deg: f64,
    /// Largest elevation, degrees.
    pub elevation_max_deg: f64,
    /// Smallest distance of a grid point from the origin, metres.
    pub radius_min_m: f64,
    /// Largest distance of a grid point from the origin, metres.
    pub radius_max_m: f64,
    /// Microphone positions as stored (metres; possibly placeholders).
    pub mic_positions: Vec<[f64; 3]>,
    /// Directions that repeat an earlier one (within 1e-9 of its unit vector): the peak
    /// search takes each such set as one point, the first.
    pub repeated_directions: usize,
}

impl std::fmt::Display for TfSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "microphones      {}", self.num_mics)?;
        writeln!(f, "directions       {} ({})", self.num_dirs, self.grid_kind)?;
        writeln!(f, "nfft             {}", self.nfft)?;
        writeln!(f, "sample rate      {} Hz", self.sample_rate_hz)?;
        writeln!(
            f,
            "bins             {}..{} ({:.1}–{:.1} Hz)",
            self.first_bin, self.end_bin, self.first_bin_hz, self.last_bin_hz
        )?;
        writeln!(
            f,
            "azimuth          {:.1}° … {:.1}°",
            self.azimuth_min_deg, self.azimuth_max_deg
        )?;
        writeln!(
            f,
            "elevation        {:.1}° … {:.1}°",
            self.elevation_min_deg, self.elevation_max_deg
        )?;
        writeln!(
            f,
            "distance         {:.3} … {:.3} m",
            self.radius_min_m, self.radius_max_m
        )?;
        writeln!(
            f,
            "neighbours       {} (max {:.1}° apart)",
            self.neighbor_relation, self.max_neighbor_angle_deg
        )?;
        if self.repeated_directions > 0 {
            writeln!(
                f,
                "repeated         {} direction(s) given again (one point each for the peaks, the first)",
                self.repeated_directions
            )?;
        }
        Ok(())
    }
}

impl TransferFunctions {
    /// Number of directions.
    pub fn num_dirs(&self) -> usize {
        self.grid.len()
    }
    /// Range of bins held.
    pub fn bins(&self) -> std::ops::Range<usize> {
        self.first_bin..self.first_bin + self.num_bins
    }
    /// `a_{dir,bin}[mic]`. `bin` is an absolute FFT bin index; panics if not held.
    #[inline]
    pub fn get(&self, dir: usize, mic: usize, bin: usize) -> Complex<f32> {
        debug_assert!(self.bins().contains(&bin));
        self.data[(dir * self.num_mics + mic) * self.num_bins + (bin - self.first_bin)]
    }
    /// Frequency of absolute bin `bin` in Hz: bin·fs/nfft.
    pub fn bin_hz(&self, bin: usize) -> f64 {
        bin as f64 * self.sample_rate_hz as f64 / self.nfft as f64
    }

    /// Read a HARK transfer-function zip or an old HGTF file, told apart by the first
    /// bytes (`PK\x03\x04` / `HARK....HGTF`), then [`TransferFunctions::validate`]. Every
    /// error names the file.
    pub fn load(path: &Path) -> Result<Self> {
        Self::load_bins(path, None)
    }

    /// [`TransferFunctions::load_bins`] through the prepared-TF cache ([`super::tf_cache`]):
    /// a zip whose used bins were prepared before is read from the cache.
    pub fn load_cached(
        path: &Path,
        want: Option<(usize, u32, Range<usize>)>,
        cache: &super::tf_cache::TfCache,
    ) -> Result<(Self, super::tf_cache::CacheOutcome)> {
        let mut head = [0u8; 4];
        let is_zip = std::fs::File::open(path)
            .and_then(|mut f| f.read_exact(&mut head))
            .is_ok()
            && hark_zip::looks_like_zip(&head);
        if !is_zip {
            return Ok((
                Self::load_bins(path, want)?,
                super::tf_cache::CacheOutcome::Bypassed,
            ));
        }
        super::tf_cache::load_cached(path, &want, cache, || Self::load_bins(path, want.clone()))
    }

    /// [`TransferFunctions::load`] keeping only `bins` — when the file is for `nfft` points
    /// at `sample_rate_hz` and holds them; otherwise all bins, so that the caller's own
    /// checks report the mismatch. A TF zip then inflates only what it needs and keeps
    /// only those bins in memory (an HGTF file is read whole and cut).
    pub fn load_bins(path: &Path, want: Option<(usize, u32, Range<usize>)>) -> Result<Self> {
        let mut head = [0u8; 12];
        let n = {
            let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
            let mut n = 0;
            while n < head.len() {
                match f.read(&mut head[n..]) {
                    Ok(0) => break,
                    Ok(k) => n += k,
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(e) => return Err(Error::io(path, e)),
                }
            }
            n
        };
        let head = &head[..n];
        let matches = |nfft: usize, fs: u32| {
            want.clone()
                .filter(|(n, r, b)| *n == nfft && *r == fs && !b.is_empty() && b.end <= nfft / 2 + 1)
                .map(|w| w.2)
        };
        let tf = if hark_zip::looks_like_zip(head) {
            hark_zip::read_tf_zip_bins(path, |c| matches(c.nfft, c.sampling_rate_hz))?
        } else if hgtf::looks_like_hgtf(head) {
            let tf = hgtf::read_hgtf_file(path)?;
            match matches(tf.nfft, tf.sample_rate_hz)
                .filter(|b| b.start >= tf.first_bin && b.end <= tf.first_bin + tf.num_bins)
            {
                Some(b) => tf.restrict_bins(b)?,
                None => tf,
            }
        } else {
            return Err(Error::format(
                path,
                format!(
                    "not a HARK transfer-function zip or HGTF file (starts with \"{}\")",
                    head[..head.len().min(8)].escape_ascii()
                ),
            ));
        };
        tf.validate().map_err(|e| Error::format(path, e.to_string()))?;
        Ok(tf)
    }

    /// Check internal consistency: at least one direction and microphone, data size =
    /// directions × mics × bins, bins within 0..=nfft/2, a positive sample rate, mic
    /// positions either absent or one per microphone, one neighbour list per direction
    /// with indices in range, and all values finite.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Mismatch(format!("transfer functions: {m}")));
        if self.num_dirs() == 0 || self.num_mics == 0 || self.num_bins == 0 {
            return bad(format!(
                "empty: {} directions, {} microphones, {} bins",
                self.num_dirs(),
                self.num_mics,
                self.num_bins
            ));
        }
        if self.nfft < 2 || self.sample_rate_hz == 0 {
            return bad(format!(
                "nfft {} / sample rate {} Hz not usable",
                self.nfft, self.sample_rate_hz
            ));
        }
        if self.first_bin + self.num_bins > self.nfft / 2 + 1 {
            return bad(format!(
                "bins {}..{} exceed nfft/2+1 = {}",
                self.first_bin,
                self.first_bin + self.num_bins,
                self.nfft / 2 + 1
            ));
        }
        let want = self.num_dirs() * self.num_mics * self.num_bins;
        if self.data.len() != want {
            return bad(format!(
                "{} values, expected {} directions × {} mics × {} bins = {want}",
                self.data.len(),
                self.num_dirs(),
                self.num_mics,
                self.num_bins
            ));
        }
        if !self.mic_positions.is_empty() && self.mic_positions.len() != self.num_mics {
            return bad(format!(
                "{} microphone positions for {} microphones",
                self.mic_positions.len(),
                self.num_mics
            ));
        }
        if self.grid.neighbors.len() != self.num_dirs() {
            return bad(format!(
                "{} neighbour lists for {} directions",
                self.grid.neighbors.len(),
                self.num_dirs()
            ));
        }
        let n = self.num_dirs();
        if let Some((i, j)) = self
            .grid
            .neighbors
            .iter()
            .enumerate()
            .find_map(|(i, l)| l.iter().find(|&&j| j >= n || j == i).map(|&j| (i, j)))
        {
            return bad(format!("direction {i} lists invalid neighbour {j}"));
        }
        if let Some(k) = self
            .data
            .iter()
            .position(|c| !(c.re.is_finite() && c.im.is_finite()))
        {
            let per_dir = self.num_mics * self.num_bins;
            return bad(format!(
                "non-finite value {} at direction {}, mic {}, bin {}",
                self.data[k],
                k / per_dir,
                (k % per_dir) / self.num_bins,
                self.first_bin + k % self.num_bins
            ));
        }
        Ok(())
    }

    /// Keep only the microphones `channels` (HARK's TF_CHANNEL_SELECTION), in that order:
    /// microphone i of the result is microphone `channels[i]` of `self`. Errors on an
    /// empty list, an index ≥ num_mics, or a repeated index.
    pub fn select_channels(&self, channels: &[usize]) -> Result<Self> {
        if channels.is_empty() {
            return Err(Error::Config("TF_CHANNEL_SELECTION: no channels selected".into()));
        }
        if let Some((c, _, _)) = crate::input::repeated(channels) {
            return Err(Error::Config(format!(
                "TF_CHANNEL_SELECTION: channel {c} is selected twice"
            )));
        }
        for &c in channels {
            if c >= self.num_mics {
                return Err(Error::Config(format!(
                    "TF_CHANNEL_SELECTION: channel {c} is out of range: the transfer functions have {} microphones (0..={})",
                    self.num_mics,
                    self.num_mics - 1
                )));
            }
        }
        let nb = self.num_bins;
        let mut data = Vec::with_capacity(self.num_dirs() * channels.len() * nb);
        for d in 0..self.num_dirs() {
            for &c in channels {
                let o = (d * self.num_mics + c) * nb;
                data.extend_from_slice(&self.data[o..o + nb]);
            }
        }
        let mic_positions = if self.mic_positions.len() == self.num_mics {
            channels.iter().map(|&c| self.mic_positions[c]).collect()
        } else {
            Vec::new()
        };
        Ok(TransferFunctions {
            nfft: self.nfft,
            sample_rate_hz: self.sample_rate_hz,
            grid: self.grid.clone(),
            mic_positions,
            num_mics: channels.len(),
            first_bin: self.first_bin,
            num_bins: nb,
            data,
        })
    }

    /// Keep only the absolute bins `bins` (must be non-empty and within [`Self::bins`]).
    pub fn restrict_bins(&self, bins: Range<usize>) -> Result<Self> {
        let held = self.bins();
        if bins.start >= bins.end || bins.start < held.start || bins.end > held.end {
            return Err(Error::Mismatch(format!(
                "bins {}..{} requested, but the transfer functions hold bins {}..{} (nfft {}, {} Hz)",
                bins.start, bins.end, held.start, held.end, self.nfft, self.sample_rate_hz
            )));
        }
        let nb = bins.end - bins.start;
        let off = bins.start - self.first_bin;
        let mut data = Vec::with_capacity(self.num_dirs() * self.num_mics * nb);
        for dm in 0..self.num_dirs() * self.num_mics {
            let o = dm * self.num_bins + off;
            data.extend_from_slice(&self.data[o..o + nb]);
        }
        Ok(TransferFunctions {
            nfft: self.nfft,
            sample_rate_hz: self.sample_rate_hz,
            grid: self.grid.clone(),
            mic_positions: self.mic_positions.clone(),
            num_mics: self.num_mics,
            first_bin: bins.start,
            num_bins: nb,
            data,
        })
    }

    /// A summary for `soundloc tf inspect`.
    pub fn summary(&self) -> TfSummary {
        TfSummary::new(
            &self.grid,
            self.nfft,
            self.sample_rate_hz,
            self.num_mics,
            self.bins(),
            &self.mic_positions,
        )
    }
}

impl TfSummary {
    /// The summary of a TF set with these parts (`bins`: the bins held).
    pub fn new(
        grid: &Grid,
        nfft: usize,
        sample_rate_hz: u32,
        num_mics: usize,
        bins: Range<usize>,
        mic_positions: &[[f64; 3]],
    ) -> TfSummary {
        let ((az0, az1), (el0, el1)) = grid.angle_ranges_deg().unwrap_or(((0.0, 0.0), (0.0, 0.0)));
        let radii: Vec<f64> = (0..grid.len()).map(|i| grid.radius_m(i)).collect();
        let r0 = radii.iter().copied().fold(f64::INFINITY, f64::min);
        let r1 = radii.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let hz = |b: usize| b as f64 * sample_rate_hz as f64 / nfft.max(1) as f64;
        TfSummary {
            num_mics,
            num_dirs: grid.len(),
            nfft,
            sample_rate_hz,
            first_bin: bins.start,
            end_bin: bins.end,
            first_bin_hz: hz(bins.start),
            last_bin_hz: hz(bins.end.saturating_sub(1)),
            grid_kind: grid.kind,
            neighbor_relation: grid.neighbor_relation(),
            max_neighbor_angle_deg: grid.max_neighbor_angle_deg(),
            azimuth_min_deg: az0,
            azimuth_max_deg: az1,
            elevation_min_deg: el0,
            elevation_max_deg: el1,
            radius_min_m: if r0.is_finite() { r0 } else { 0.0 },
            radius_max_m: if r1.is_finite() { r1 } else { 0.0 },
            mic_positions: mic_positions.to_vec(),
            repeated_directions: crate::peaks::coincident_first(grid)
                .iter()
                .enumerate()
                .filter(|&(i, &f)| f != i)
                .count(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> TransferFunctions {
        let grid = Grid::ring(90.0, 0.0, 1.0);
        let (m, nb) = (3, 5);
        let data = (0..4 * m * nb)
            .map(|i| Complex::new(i as f32, -(i as f32)))
            .collect();
        TransferFunctions {
            nfft: 8,
            sample_rate_hz: 16000,
            grid,
            mic_positions: vec![[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.2, 0.0, 0.0]],
            num_mics: m,
            first_bin: 0,
            num_bins: nb,
            data,
        }
    }

    #[test]
    fn select_and_restrict() {
        let tf = small();
        tf.validate().unwrap();
        let s = tf.select_channels(&[2, 0]).unwrap();
        assert_eq!(s.num_mics, 2);
        for d in 0..4 {
            for k in 0..5 {
                assert_eq!(s.get(d, 0, k), tf.get(d, 2, k));
                assert_eq!(s.get(d, 1, k), tf.get(d, 0, k));
            }
        }
        assert_eq!(s.mic_positions, vec![[0.2, 0.0, 0.0], [0.0, 0.0, 0.0]]);
        s.validate().unwrap();
        let e = tf.select_channels(&[0, 3]).unwrap_err().to_string();
        assert!(
            e.contains("channel 3 is out of range") && e.contains("3 microphones"),
            "{e}"
        );
        assert!(tf
            .select_channels(&[1, 1])
            .unwrap_err()
            .to_string()
            .contains("twice"));
        assert!(tf.select_channels(&[]).is_err());

        let r = tf.restrict_bins(1..4).unwrap();
        assert_eq!(r.bins(), 1..4);
        assert_eq!(r.get(3, 2, 3), tf.get(3, 2, 3));
        assert_eq!(r.get(1, 1, 1), tf.get(1, 1, 1));
        let rr = r.restrict_bins(2..3).unwrap();
        assert_eq!(rr.get(2, 0, 2), tf.get(2, 0, 2));
        assert!(r
            .restrict_bins(0..2)
            .unwrap_err()
            .to_string()
            .contains("hold bins 1..4"));
        assert!(r.restrict_bins(2..2).is_err());
    }

    #[test]
    fn validate_catches() {
        let mut tf = small();
        tf.data[17] = Complex::new(f32::NAN, 0.0);
        let e = tf.validate().unwrap_err().to_string();
        assert!(
            e.contains("non-finite") && e.contains("direction 1, mic 0, bin 2"),
            "{e}"
        );
        let mut tf = small();
        tf.data.pop();
        assert!(tf.validate().is_err());
        let mut tf = small();
        tf.num_bins = 6;
        tf.data.extend(std::iter::repeat_n(Complex::new(0.0, 0.0), 12));
        assert!(tf.validate().unwrap_err().to_string().contains("exceed"));
    }

    #[test]
    fn summary_fields() {
        let s = small().summary();
        assert_eq!(
            (s.num_mics, s.num_dirs, s.nfft, s.first_bin, s.end_bin),
            (3, 4, 8, 0, 5)
        );
        assert_eq!(s.grid_kind, GridKind::Ring);
        assert_eq!(s.last_bin_hz, 8000.0);
        assert!((s.azimuth_max_deg - 180.0).abs() < 1e-9 && (s.azimuth_min_deg + 90.0).abs() < 1e-9);
        let text = s.to_string();
        assert!(text.contains("left/right"), "{text}");
        let json = serde_json::to_string(&s).unwrap();
        assert!(json.contains("\"grid_kind\":\"ring\""), "{json}");
        assert_eq!(s.repeated_directions, 0);
        assert!(!text.contains("repeated"), "{text}");
        // A direction given twice (here the last is the first again) is said.
        let mut tf = small();
        tf.grid.points[3] = tf.grid.points[0];
        let s = tf.summary();
        assert_eq!(s.repeated_directions, 1);
        assert!(
            s.to_string()
                .contains("repeated         1 direction(s) given again"),
            "{s}"
        );
    }

    #[test]
    fn load_rejects_unknown() {
        let p = std::env::temp_dir().join(format!("soundloc-notatf-{}.bin", std::process::id()));
        std::fs::write(&p, b"RIFF1234WAVEfmt ").unwrap();
        let e = TransferFunctions::load(&p).unwrap_err().to_string();
        let _ = std::fs::remove_file(&p);
        assert!(e.contains("not a HARK transfer-function zip or HGTF file"), "{e}");
        assert!(e.contains("soundloc-notatf"), "{e}");
    }
}
