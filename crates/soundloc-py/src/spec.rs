//! Python keyword arguments → a [`LocalizerSpec`], plus what only Python can give (a grid or
//! a noise recording as arrays). `Localizer` and `StreamGroup` are both built from one
//! [`PySpec`], so they take the same arguments (documented on `soundloc.Localizer`).

use crate::spec_values::{pair, preceding, rate, spectrum_weight_of};
use crate::Released;
use crate::{err, parse, points, samples};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use soundloc::array::freefield::free_field;
use soundloc::array::grid::GridSpec;
use soundloc::array::{Geometry, Grid, TransferFunctions};
use soundloc::backend::DeviceChoice;
use soundloc::config::WindowType;
use soundloc::noise::NoiseMatrices;
use soundloc::{
    Algorithm, ArraySpec, Localizer, LocalizerGroup, LocalizerSpec, NoiseSource, NoiseUpdate, Precision,
    TrackingSpec,
};
use std::path::{Path, PathBuf};

/// A localizer's description: the library's spec and the arrays Python passed.
#[pyclass(module = "soundloc._native", name = "Spec", frozen)]
#[derive(Clone)]
pub(crate) struct PySpec {
    pub spec: LocalizerSpec,
    /// `grid=` as a (D, 3) array of directions.
    grid_points: Option<Vec<[f64; 3]>>,
    /// `noise=` as samples and their (rows, cols).
    noise_audio: Option<(Vec<f32>, [usize; 2])>,
    pub channels_first: bool,
    grid_radius: f64,
    speed_of_sound: f64,
    /// `fs=` as given (with `tf=` it must be the file's rate).
    fs_given: Option<u32>,
    /// `nfft=`, `hop=` as given (None: [`frame_sizes`] at the analysis rate).
    frames_given: (Option<usize>, Option<usize>),
    /// A note when `geometry=` was a 3 × 3 array (rows or columns?).
    square_note: Option<String>,
}

/// `nfft=`, `hop=` where given, else the array's (the CLI's rule,
/// [`soundloc::ArraySpec::default_frame_sizes`]: HARK's durations at `fs` for free-field
/// TFs, a TF zip's own FFT length).
fn frame_sizes(given: (Option<usize>, Option<usize>), fs: u32, array: &ArraySpec) -> (usize, usize) {
    match given {
        (Some(n), Some(h)) => (n, h),
        (n, h) => {
            let (nfft, hop) = array.default_frame_sizes(fs);
            (n.unwrap_or(nfft), h.unwrap_or(hop))
        }
    }
}

#[pymethods]
impl PySpec {
    /// The library's spec as JSON (`soundloc::LocalizerSpec`, serde), as given.
    fn to_json(&self) -> PyResult<String> {
        serde_json::to_string_pretty(&self.spec).map_err(|e| PyValueError::new_err(e.to_string()))
    }
}

/// The spec from `soundloc.Localizer`'s keyword arguments.
#[pyfunction]
#[pyo3(signature = (*, tf=None, geometry=None, grid=None, algorithm=None, num_sources=2, max_peaks=-1,
    window=50, period=50, window_type="future", freq_range=None, nfft=None, hop=None, fs=None,
    noise=None, noise_range=None, noise_cm=None, noise_segments=None, noise_preceding=None,
    track=false, tracker_thresh_db=0.0, tracker_pause_length=None, tracker_min_src_interval_deg=None,
    tracker_min_id=None, tracker_confirm_frames=None, preroll=0, track_active_only=None, device="auto", precision="f32", channels=None,
    input_channels=None, invert_channels=None, spectrum=true, grid_radius=None, speed_of_sound=None, channels_first=false,
    subspace_dim=None, normalize_bins=None, refine=None, subspace_tracking=false, resample=false,
    diagonal_loading=0.0, coherence=None, numerator=None, onset_frames=None, min_deg=-180.0,
    max_deg=180.0, window_function="conj", eigenvalue_weight=true, spectrum_weight=None,
    denominator="squared"))]
#[allow(clippy::too_many_arguments)] // mirrors the Python keywords
pub(crate) fn spec(
    tf: Option<PathBuf>,
    geometry: Option<&Bound<'_, PyAny>>,
    grid: Option<&Bound<'_, PyAny>>,
    algorithm: Option<&str>,
    num_sources: usize,
    max_peaks: i64,
    window: usize,
    period: usize,
    window_type: &str,
    freq_range: Option<&Bound<'_, PyAny>>,
    nfft: Option<usize>,
    hop: Option<usize>,
    fs: Option<&Bound<'_, PyAny>>,
    noise: Option<&Bound<'_, PyAny>>,
    noise_range: Option<&Bound<'_, PyAny>>,
    noise_cm: Option<PathBuf>,
    noise_segments: Option<Vec<Bound<'_, PyAny>>>,
    noise_preceding: Option<&Bound<'_, PyAny>>,
    track: bool,
    tracker_thresh_db: f64,
    tracker_pause_length: Option<f64>,
    tracker_min_src_interval_deg: Option<f64>,
    tracker_min_id: Option<i64>,
    tracker_confirm_frames: Option<usize>,
    preroll: usize,
    track_active_only: Option<bool>,
    device: &str,
    precision: &str,
    channels: Option<Vec<usize>>,
    input_channels: Option<Vec<usize>>,
    invert_channels: Option<Vec<usize>>,
    spectrum: bool,
    grid_radius: Option<f64>,
    speed_of_sound: Option<f64>,
    channels_first: bool,
    subspace_dim: Option<usize>,
    normalize_bins: Option<bool>,
    refine: Option<bool>,
    subspace_tracking: bool,
    resample: bool,
    diagonal_loading: f64,
    coherence: Option<bool>,
    numerator: Option<&str>,
    onset_frames: Option<usize>,
    min_deg: f64,
    max_deg: f64,
    window_function: &str,
    eigenvalue_weight: bool,
    spectrum_weight: Option<&Bound<'_, PyAny>>,
    denominator: &str,
) -> PyResult<PySpec> {
    // Defaults: HARK's band (500–2800 Hz) and 16 kHz.
    let freq_range = freq_range.map_or(Ok((500.0, 2800.0)), |r| pair(r, "freq_range"))?;
    let noise_range = noise_range.map(|r| pair(r, "noise_range")).transpose()?;
    let fs_given = fs.map(rate).transpose()?;
    let fs = fs_given.unwrap_or(16000);
    if tf.is_some() && geometry.is_none() {
        // A TF file brings its directions, distance, speed of sound and rate.
        let given = [
            (grid.is_some(), "grid="),
            (grid_radius.is_some(), "grid_radius="),
            (speed_of_sound.is_some(), "speed_of_sound="),
        ];
        if let Some((_, what)) = given.iter().find(|(g, _)| *g) {
            return Err(PyValueError::new_err(format!(
                "{what} applies to geometry=: a transfer-function file's directions are its own"
            )));
        }
    }
    let grid_radius = grid_radius.unwrap_or(1.0);
    let speed_of_sound = speed_of_sound.unwrap_or(soundloc::array::freefield::DEFAULT_SPEED_OF_SOUND_M_S);
    let noise_segments = noise_segments
        .map(|v| {
            v.iter()
                .map(|r| pair(r, "noise_segments"))
                .collect::<PyResult<Vec<_>>>()
        })
        .transpose()?;
    let grid_spec: Option<GridSpec> = match grid {
        Some(g) => match g.extract::<String>() {
            Ok(s) => Some(s.parse().map_err(err)?),
            Err(_) => None,
        },
        None => Some("ring:5".parse().map_err(err)?),
    };
    let grid_points = match (grid, &grid_spec) {
        (Some(g), None) => Some(points(g, "grid")?),
        _ => None,
    };
    // A file name (TOML or an ODAS configuration, with its device map) or positions.
    let mut raw_mapping = None;
    let mics = match geometry {
        None => None,
        Some(g) => match g.extract::<PathBuf>() {
            Ok(path) => {
                let (geometry, mapping) = Geometry::load_with_mapping(&path).map_err(err)?;
                raw_mapping = mapping;
                Some(geometry.mics)
            }
            Err(_) => Some(crate::positions(g, "geometry")?),
        },
    };
    // Three microphones as a 3 × 3 array: rows or columns alike (pyroomacoustics' L).
    let square_note = mics.as_ref().is_some_and(|m| m.len() == 3).then(|| {
        "geometry= is a 3 × 3 array: read as one microphone per row (x, y, z); pyroomacoustics' L \
         holds one per column: pass L.T if it is that"
            .to_string()
    });
    let array = match (&tf, &mics) {
        (Some(p), None) => ArraySpec::TransferFunctions { path: p.clone() },
        (None, Some(m)) => ArraySpec::FreeField {
            mics: m.clone(),
            grid: grid_spec.unwrap_or(GridSpec::Ring {
                step_deg: 5.0,
                elevation_deg: 0.0,
            }),
            radius_m: grid_radius,
            speed_of_sound_m_s: speed_of_sound,
        },
        (Some(_), Some(_)) => return Err(PyValueError::new_err("give tf= or geometry=, not both")),
        (None, None) => {
            return Err(PyValueError::new_err(
                "no array: give tf= (a HARK transfer-function file) or geometry= (an (M, 3) array of positions in metres)",
            ))
        }
    };
    let mut spec = LocalizerSpec::with_array(array);
    spec.algorithm = algorithm
        .map(|a| parse::<Algorithm>("algorithm", a))
        .transpose()?;
    // None: the default's choice (on in the room default).
    spec.coherence = coherence;
    // None: the default's choice (both on in the room default, refinement in the robust
    // one); a value wins whatever the algorithm.
    spec.normalize_bins = normalize_bins;
    spec.refine = refine;
    // None: the default's choice (geometric in the robust default).
    spec.numerator = numerator
        .map(|n| parse::<soundloc::config::Numerator>("numerator", n))
        .transpose()?;
    // None: the default's choice (on when no algorithm is named).
    spec.onset_frames = onset_frames;
    let a = &mut spec.analysis;
    a.num_sources = num_sources;
    a.subspace_dim = subspace_dim;
    a.subspace_tracking = subspace_tracking;
    a.max_peaks = max_peaks;
    a.window = window;
    a.period = period;
    a.window_type = parse::<WindowType>("window_type", window_type)?;
    (a.lower_freq_hz, a.upper_freq_hz) = freq_range;
    a.sample_rate_hz = fs;
    let frames_given = (nfft, hop);
    (a.nfft, a.hop) = frame_sizes(frames_given, fs, &spec.array);
    a.diagonal_loading = diagonal_loading;
    // HARK's MIN_DEG / MAX_DEG, MultiFFT WINDOW, ENABLE_EIGENVALUE_WEIGHT,
    // SPECTRUM_WEIGHT_TYPE (or one weight per used bin) and the denominator.
    (a.min_deg, a.max_deg) = (min_deg, max_deg);
    a.window_function = parse("window_function", window_function)?;
    a.eigenvalue_weight = eigenvalue_weight;
    a.spectrum_weight = spectrum_weight_of(spectrum_weight)?;
    a.denominator = parse("denominator", denominator)?;
    spec.channels = channels.unwrap_or_default();
    spec.input_channels = input_channels.unwrap_or_default();
    spec.invert_channels = invert_channels.unwrap_or_default();
    spec.raw_mapping = raw_mapping;
    let given = [noise.is_some(), noise_range.is_some(), noise_cm.is_some()];
    if given.iter().filter(|&&g| g).count() > 1 {
        return Err(PyValueError::new_err(
            "give at most one of noise=, noise_range=, noise_cm=",
        ));
    }
    spec.noise = match (noise_range, noise_cm) {
        (Some((start_s, end_s)), _) => NoiseSource::Range { start_s, end_s },
        (_, Some(path)) => NoiseSource::CorrelationFile { path },
        _ => NoiseSource::None,
    };
    spec.noise_update = match (noise_segments, noise_preceding) {
        (Some(_), Some(_)) => {
            return Err(PyValueError::new_err(
                "give noise_segments= or noise_preceding=, not both",
            ))
        }
        (Some(s), None) => NoiseUpdate::Segments(s),
        (None, Some(p)) => {
            let (frames, gap) = preceding(p)?;
            NoiseUpdate::Preceding { frames, gap }
        }
        (None, None) => NoiseUpdate::Fixed,
    };
    let given = tracker_pause_length.is_some()
        || tracker_min_src_interval_deg.is_some()
        || tracker_min_id.is_some()
        || tracker_confirm_frames.is_some()
        || preroll > 0
        || track_active_only.is_some()
        || tracker_thresh_db != 0.0;
    if given && !track {
        return Err(PyValueError::new_err(
            "tracker_*, preroll and track_active_only set the tracker: give track=True too",
        ));
    }
    let d = soundloc::tracking::TrackerConfig::default();
    let tracker = soundloc::tracking::TrackerConfig {
        thresh_db: tracker_thresh_db,
        pause_length: tracker_pause_length.unwrap_or(d.pause_length),
        min_src_interval_deg: tracker_min_src_interval_deg.unwrap_or(d.min_src_interval_deg),
        min_id: tracker_min_id.unwrap_or(d.min_id),
        confirm_frames: tracker_confirm_frames,
    };
    tracker.validate().map_err(err)?;
    spec.tracking = track.then_some(TrackingSpec {
        tracker,
        preroll,
        active_only: track_active_only,
    });
    spec.device = parse::<DeviceChoice>("device", device)?;
    spec.precision = parse::<Precision>("precision", precision)?;
    spec.spectrum = spectrum;
    spec.resample = resample;
    // A noise recording as an array: K from it, through the same channel map.
    let noise_audio: Option<(Vec<f32>, [usize; 2])> = noise
        .map(samples)
        .transpose()?
        .map(|n| (n.data().to_vec(), n.shape()));
    if noise_audio.as_ref().is_some_and(|(d, _)| d.is_empty()) {
        return Err(PyValueError::new_err(
            "noise: the array holds no samples (a noise recording of at least one analysis frame is needed)",
        ));
    }
    let noise_given = noise_audio.is_some();
    if noise_given && spec.noise == NoiseSource::None {
        // Make the spec say a noise source is given (the default algorithm depends on it).
        spec.noise = NoiseSource::Recording {
            path: PathBuf::from("(array)"),
        };
    }
    Ok(PySpec {
        spec,
        grid_points,
        noise_audio,
        channels_first,
        grid_radius,
        speed_of_sound,
        fs_given,
        frames_given,
        square_note,
    })
}

/// What [`PySpec::arrays`] builds: the TFs, K, and a note on how the positions were read.
type Arrays = (TransferFunctions, Option<NoiseMatrices>, Option<String>);

impl PySpec {
    /// Transfer functions and K built here when Python gave a grid or noise as arrays
    /// (the spec cannot name them); None when the spec alone says everything.
    fn arrays(&self) -> soundloc::Result<Option<Arrays>> {
        let (spec, grid_points, noise_audio) = (&self.spec, &self.grid_points, &self.noise_audio);
        let (grid_radius, speed_of_sound, channels_first) =
            (self.grid_radius, self.speed_of_sound, self.channels_first);
        if grid_points.is_none() && noise_audio.is_none() {
            return Ok(None);
        }
        let (alg, _) = spec.resolved_algorithm();
        let config = soundloc::LocalizeConfig {
            algorithm: alg,
            ..spec.analysis.clone()
        };
        let (tf, note) = match (grid_points, &spec.array) {
            (Some(p), ArraySpec::FreeField { mics, .. }) => {
                let g = Grid::from_points(p.iter().map(|v| v.map(|c| c * grid_radius)).collect())?;
                let (geometry, note) =
                    Geometry::new(mics.clone(), Path::new("geometry"))?.direction_frame(grid_radius);
                let tf = free_field(
                    &geometry,
                    &g,
                    config.nfft,
                    config.sample_rate_hz,
                    0..config.nfft / 2 + 1,
                    speed_of_sound,
                )?;
                (tf, note)
            }
            (Some(_), _) => {
                return Err(soundloc::Error::Config(
                    "grid= as an array needs geometry=".into(),
                ))
            }
            _ => spec.load_array_noted(&config)?,
        };
        let k = match noise_audio {
            Some((data, shape)) => Some(noise_matrices(spec, &config, &tf, data, *shape, channels_first)?),
            None => None,
        };
        Ok(Some((tf, k, note)))
    }

    /// Whether the analysis rate is open: free-field TFs (`geometry=`) with no `fs=` and
    /// no `resample=True`, so the audio's rate, where a call names it, is the rate to
    /// analyse at (16 kHz until then).
    pub fn rate_open(&self) -> bool {
        self.fs_given.is_none()
            && !self.spec.resample
            && matches!(self.spec.array, ArraySpec::FreeField { .. })
    }

    /// Free-field TFs with `resample=True` and no `fs=`: the analysis runs at its default
    /// rate, and the audio's own rate is unknown until a call names it.
    pub fn resample_rate_unnamed(&self) -> bool {
        self.fs_given.is_none()
            && self.spec.resample
            && matches!(self.spec.array, ArraySpec::FreeField { .. })
    }

    /// This spec for audio at `fs` Hz (free-field TFs made for that rate), where the rate
    /// is open ([`Self::rate_open`]).
    pub fn at_rate(&self, fs: u32) -> Option<PySpec> {
        self.rate_open().then(|| {
            let mut s = self.clone();
            s.spec.analysis.sample_rate_hz = fs;
            (s.spec.analysis.nfft, s.spec.analysis.hop) = frame_sizes(self.frames_given, fs, &s.spec.array);
            s
        })
    }

    /// Notes on what Python passed: an open rate ([`Self::rate_open`]), a 3 × 3 geometry.
    fn notes(&self) -> Vec<String> {
        self.rate_note()
            .into_iter()
            .chain(self.square_note.clone())
            .collect()
    }

    /// The note of an open rate ([`Self::rate_open`]).
    fn rate_note(&self) -> Option<String> {
        self.rate_open().then(|| {
            format!(
                "no fs= given: the free-field transfer functions are made for {} Hz audio; \
                 localize(x, fs) and localize_file take the audio's rate instead, and a stream's first \
                 push(x, fs=...) names it",
                self.spec.analysis.sample_rate_hz
            )
        })
    }

    /// A localizer (the GIL released while files load and the plan is built).
    pub fn localizer(&self, py: Python<'_>) -> PyResult<Localizer> {
        let mut loc = self.localizer_noted(py)?;
        for n in self.notes().into_iter().rev() {
            loc.prepend_note(n);
        }
        Ok(loc)
    }

    fn localizer_noted(&self, py: Python<'_>) -> PyResult<Localizer> {
        self.check_fs_early()?;
        let loc = py
            .released(|| match self.arrays()? {
                None => Localizer::new(&self.spec),
                Some((tf, k, note)) => {
                    let mut loc = Localizer::with_transfer_functions(&self.spec, tf, k)?;
                    if let Some(n) = note {
                        loc.prepend_note(n);
                    }
                    Ok(loc)
                }
            })
            .map_err(err)?;
        self.check_fs(loc.config().sample_rate_hz)?;
        Ok(loc)
    }

    /// A group of `streams` streams sharing the plan.
    pub fn group(&self, py: Python<'_>, streams: usize) -> PyResult<LocalizerGroup> {
        if self.rate_open() {
            return Err(PyValueError::new_err(
                "StreamGroup(geometry=...) needs fs=, the streams' sampling rate in Hz: free-field \
                 transfer functions are made for it, and a group has no recording to take it from",
            ));
        }
        self.check_fs_early()?;
        let g = py
            .released(|| match self.arrays()? {
                None => LocalizerGroup::new(&self.spec, streams),
                Some((tf, k, note)) => {
                    let mut g = LocalizerGroup::with_transfer_functions(&self.spec, tf, k, streams)?;
                    if let Some(n) = note {
                        g.prepend_note(n);
                    }
                    Ok(g)
                }
            })
            .map_err(err)?;
        self.check_fs(g.config().sample_rate_hz)?;
        let mut g = g;
        for n in self.notes().into_iter().rev() {
            g.prepend_note(n);
        }
        Ok(g)
    }

    /// [`PySpec::check_fs`] before anything is loaded, for a TF zip: its rate is in its
    /// small entries, so a wrong `fs=` is refused without inflating the matrices. (Other
    /// files, and a zip whose entries cannot be read, are checked after the load, whose
    /// own errors then name the problem.)
    fn check_fs_early(&self) -> PyResult<()> {
        match (&self.spec.array, self.fs_given) {
            (ArraySpec::TransferFunctions { path }, Some(_))
                if soundloc::formats::hark_zip::file_looks_like_zip(path) =>
            {
                match soundloc::formats::tf_zip_read::read_tf_zip_config(path) {
                    Ok(c) => self.check_fs(c.sampling_rate_hz),
                    Err(_) => Ok(()),
                }
            }
            _ => Ok(()),
        }
    }

    /// `fs=` with `tf=`: the analysis runs at the file's rate, so another rate is refused
    /// here rather than audio at it being taken for the file's.
    fn check_fs(&self, analysis_hz: u32) -> PyResult<()> {
        match (&self.spec.array, self.fs_given) {
            (ArraySpec::TransferFunctions { path }, Some(f)) if f != analysis_hz => {
                Err(PyValueError::new_err(format!(
                    "fs={f}: the transfer functions in {} are for {analysis_hz} Hz, the rate the analysis \
                     runs at; leave fs out, and for audio at another rate pass its rate to localize(x, fs) \
                     with resample=True",
                    path.display()
                )))
            }
            _ => Ok(()),
        }
    }
}

/// K from a noise array through the spec's channel map.
fn noise_matrices(
    spec: &LocalizerSpec,
    config: &soundloc::LocalizeConfig,
    tf: &soundloc::array::TransferFunctions,
    data: &[f32],
    [rows, cols]: [usize; 2],
    channels_first: bool,
) -> soundloc::Result<soundloc::noise::NoiseMatrices> {
    let (nch, len) = if channels_first {
        (rows, cols)
    } else {
        (cols, rows)
    };
    let map = spec.channel_map(tf.num_mics)?;
    let idx = map
        .resolve(nch)
        .map_err(|e| soundloc::Error::Mismatch(format!("noise of shape ({rows}, {cols}): {e}")))?;
    let mut planar: Vec<Vec<f32>> = idx
        .iter()
        .map(|&c| {
            (0..len)
                .map(|i| {
                    if channels_first {
                        data[c * len + i]
                    } else {
                        data[i * nch + c]
                    }
                })
                .collect()
        })
        .collect();
    map.invert(&idx, &mut planar);
    let config = soundloc::LocalizeConfig {
        sample_rate_hz: tf.sample_rate_hz,
        ..config.clone()
    };
    soundloc::noise::estimate(&config, config.sample_rate_hz, &planar, None)
}
