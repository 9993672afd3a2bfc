//! `soundloc._native`: the Python binding. It translates Python arguments into a
//! [`soundloc::LocalizerSpec`] and numpy arrays into sample blocks, and results back into
//! numpy arrays; every rule lives in the library. The GIL is released while localizing;
//! float32 input in C order is read in place.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use soundloc::array::freefield::free_field;
use soundloc::array::grid::GridSpec;
use soundloc::array::{Geometry, Grid};
use soundloc::backend::DeviceChoice;
use soundloc::config::WindowType;
use soundloc::{
    Algorithm, ArraySpec, Block, LocalizationResult, Localizer, LocalizerSpec, NoiseSource, NoiseUpdate,
    Output, Precision, TrackingSpec,
};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

fn err(e: soundloc::Error) -> PyErr {
    match e {
        soundloc::Error::Io { .. } => PyOSError::new_err(e.to_string()),
        soundloc::Error::Device(_) => PyRuntimeError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

fn parse<T: serde::de::DeserializeOwned>(what: &str, v: &str) -> PyResult<T> {
    serde_json::from_value(serde_json::Value::String(v.to_string()))
        .map_err(|_| PyValueError::new_err(format!("{what}: {v:?} is not a valid value")))
}

/// Samples of a 2-D numpy array as f32, with the array's (rows, cols); float32 in C order
/// is not copied.
enum Samples<'py> {
    Borrowed(PyReadonlyArray2<'py, f32>),
    Owned(Vec<f32>, [usize; 2]),
}

impl Samples<'_> {
    fn shape(&self) -> [usize; 2] {
        match self {
            Samples::Borrowed(a) => [a.shape()[0], a.shape()[1]],
            Samples::Owned(_, s) => *s,
        }
    }
    fn data(&self) -> &[f32] {
        match self {
            Samples::Borrowed(a) => a.as_slice().unwrap_or(&[]),
            Samples::Owned(v, _) => v,
        }
    }
}

fn samples<'py>(x: &Bound<'py, PyAny>) -> PyResult<Samples<'py>> {
    macro_rules! conv {
        ($t:ty) => {
            if let Ok(a) = x.downcast::<PyArray2<$t>>() {
                let a = a.readonly();
                let s = [a.shape()[0], a.shape()[1]];
                let v: Vec<f32> = a.as_array().iter().map(|&v| v as f32).collect();
                return Ok(Samples::Owned(v, s));
            }
        };
    }
    if let Ok(a) = x.downcast::<PyArray2<f32>>() {
        let r = a.readonly();
        if r.as_slice().is_ok() {
            return Ok(Samples::Borrowed(r));
        }
        let s = [r.shape()[0], r.shape()[1]];
        return Ok(Samples::Owned(r.as_array().iter().copied().collect(), s));
    }
    conv!(i16);
    conv!(i32);
    conv!(f64);
    let ndim = x.getattr("ndim").and_then(|n| n.extract::<usize>()).ok();
    match ndim {
        Some(2) => Err(PyTypeError::new_err(format!(
            "audio must be int16, int32, float32 or float64; got dtype {}",
            x.getattr("dtype").map(|d| d.to_string()).unwrap_or_else(|_| "?".into())
        ))),
        Some(n) => Err(PyValueError::new_err(format!(
            "audio must be a 2-D array (samples, channels) or, with channels_first=True, (channels, samples); got {n} dimensions"
        ))),
        None => Err(PyTypeError::new_err("audio must be a numpy array")),
    }
}

fn points(x: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<[f64; 3]>> {
    let v: Vec<Vec<f64>> = x
        .call_method0("tolist")
        .and_then(|l| l.extract())
        .or_else(|_| x.extract())
        .map_err(|_| PyValueError::new_err(format!("{what}: expected an (N, 3) array of positions")))?;
    v.into_iter()
        .map(|p| {
            <[f64; 3]>::try_from(p.as_slice())
                .map_err(|_| PyValueError::new_err(format!("{what}: every row must hold x, y, z")))
        })
        .collect()
}

/// A stateful localizer (see `soundloc.Localizer` in Python for the arguments).
#[pyclass(module = "soundloc._native", name = "Localizer")]
struct PyLocalizer {
    /// Behind a mutex: a Python object may be used from several threads (the engine is
    /// `Send`, not `Sync`).
    inner: Mutex<Localizer>,
    channels_first: bool,
}

#[pymethods]
impl PyLocalizer {
    #[new]
    #[pyo3(signature = (*, tf=None, geometry=None, grid=None, algorithm=None, num_sources=2, max_peaks=-1,
        window=50, period=50, window_type="future", freq_range=(500.0, 2800.0), nfft=512, hop=160, fs=16000,
        noise=None, noise_range=None, noise_cm=None, noise_segments=None, noise_preceding=None,
        track=false, tracker_thresh_db=0.0, device="auto", precision="f32", channels=None,
        input_channels=None, spectrum=true, grid_radius=1.0, speed_of_sound=343.0, channels_first=false,
        subspace_dim=None, normalize_bins=false, refine=false))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        tf: Option<PathBuf>,
        geometry: Option<&Bound<'_, PyAny>>,
        grid: Option<&Bound<'_, PyAny>>,
        algorithm: Option<&str>,
        num_sources: usize,
        max_peaks: i64,
        window: usize,
        period: usize,
        window_type: &str,
        freq_range: (f64, f64),
        nfft: usize,
        hop: usize,
        fs: u32,
        noise: Option<&Bound<'_, PyAny>>,
        noise_range: Option<(f64, f64)>,
        noise_cm: Option<PathBuf>,
        noise_segments: Option<Vec<(f64, f64)>>,
        noise_preceding: Option<(usize, usize)>,
        track: bool,
        tracker_thresh_db: f64,
        device: &str,
        precision: &str,
        channels: Option<Vec<usize>>,
        input_channels: Option<Vec<usize>>,
        spectrum: bool,
        grid_radius: f64,
        speed_of_sound: f64,
        channels_first: bool,
        subspace_dim: Option<usize>,
        normalize_bins: bool,
        refine: bool,
    ) -> PyResult<Self> {
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
        let mics = geometry.map(|g| points(g, "geometry")).transpose()?;
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
        let a = &mut spec.analysis;
        a.num_sources = num_sources;
        a.subspace_dim = subspace_dim;
        a.normalize_bins = normalize_bins;
        // The robust default (a noise source, no algorithm) turns refinement on itself.
        a.refine = refine;
        a.max_peaks = max_peaks;
        a.window = window;
        a.period = period;
        a.window_type = parse::<WindowType>("window_type", window_type)?;
        (a.lower_freq_hz, a.upper_freq_hz) = freq_range;
        a.nfft = nfft;
        a.hop = hop;
        a.sample_rate_hz = fs;
        spec.channels = channels.unwrap_or_default();
        spec.input_channels = input_channels.unwrap_or_default();
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
            (None, Some((frames, gap))) => NoiseUpdate::Preceding { frames, gap },
            (None, None) => NoiseUpdate::Fixed,
        };
        spec.tracking = track.then(|| TrackingSpec {
            tracker: soundloc::tracking::TrackerConfig {
                thresh_db: tracker_thresh_db,
                ..Default::default()
            },
            preroll: 0,
        });
        spec.device = parse::<DeviceChoice>("device", device)?;
        spec.precision = parse::<Precision>("precision", precision)?;
        spec.spectrum = spectrum;
        // A noise recording as an array: K from it, through the same channel map.
        let noise_audio: Option<(Vec<f32>, [usize; 2])> = noise
            .map(samples)
            .transpose()?
            .map(|n| (n.data().to_vec(), n.shape()));
        let noise_given = noise_audio.is_some();
        if noise_given && spec.noise == NoiseSource::None {
            // Make the spec say a noise source is given (the default algorithm depends on it).
            spec.noise = NoiseSource::Recording {
                path: PathBuf::from("(array)"),
            };
        }
        let inner = py
            .allow_threads(|| -> soundloc::Result<Localizer> {
                if grid_points.is_none() && !noise_given {
                    return Localizer::new(&spec);
                }
                let (alg, _) = spec.resolved_algorithm();
                let config = soundloc::LocalizeConfig {
                    algorithm: alg,
                    ..spec.analysis.clone()
                };
                let tf = match (&grid_points, &spec.array) {
                    (Some(p), ArraySpec::FreeField { mics, .. }) => {
                        let g = Grid::from_points(p.iter().map(|v| v.map(|c| c * grid_radius)).collect())?;
                        free_field(
                            &Geometry::new(mics.clone(), Path::new("geometry"))?,
                            &g,
                            config.nfft,
                            config.sample_rate_hz,
                            0..config.nfft / 2 + 1,
                            speed_of_sound,
                        )?
                    }
                    (Some(_), _) => {
                        return Err(soundloc::Error::Config(
                            "grid= as an array needs geometry=".into(),
                        ))
                    }
                    _ => spec.load_array(&config)?,
                };
                let k = match &noise_audio {
                    Some((data, shape)) => {
                        Some(noise_matrices(&spec, &config, &tf, data, *shape, channels_first)?)
                    }
                    None => None,
                };
                Localizer::with_transfer_functions(&spec, tf, k)
            })
            .map_err(err)?;
        Ok(PyLocalizer {
            inner: Mutex::new(inner),
            channels_first,
        })
    }

    /// Localize a whole recording: (samples, channels) (or (channels, samples) with
    /// channels_first=True) at `fs` Hz. The stream is reset first.
    #[pyo3(signature = (x, fs=None, channels_first=None))]
    fn localize<'py>(
        &mut self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        fs: Option<u32>,
        channels_first: Option<bool>,
    ) -> PyResult<Bound<'py, PyDict>> {
        self.check_rate(fs)?;
        self.lock()?.reset().map_err(err)?;
        let mut out = self.run(py, x, channels_first.unwrap_or(self.channels_first), true)?;
        results(py, &mut out, self.lock()?.grid().len())
    }

    /// Localize a WAV/FLAC file and write its results to `output` as the CLI does
    /// (`format` "jsonl" or "csv"; the file is written whole or not at all). Returns the
    /// number of results. The GIL is released throughout.
    #[pyo3(signature = (input, output, format="jsonl"))]
    fn localize_file(
        &mut self,
        py: Python<'_>,
        input: PathBuf,
        output: PathBuf,
        format: &str,
    ) -> PyResult<usize> {
        let csv = match format {
            "jsonl" => false,
            "csv" => true,
            f => {
                return Err(PyValueError::new_err(format!(
                    "format {f:?}: expected \"jsonl\" or \"csv\""
                )))
            }
        };
        let mut inner = self.lock()?;
        let loc = &mut *inner;
        py.allow_threads(|| -> soundloc::Result<usize> {
            let audio = soundloc::audio::read_audio(&input)?;
            loc.check_input(audio.sample_rate_hz, audio.num_channels())
                .map_err(|e| soundloc::Error::Config(format!("{}: {e}", input.display())))?;
            loc.reset()?;
            let run = loc.localize(&audio.channels)?;
            if csv {
                soundloc::output::csv::write_csv_file(&output, &run.results)?;
            } else {
                soundloc::output::jsonl::write_jsonl_file(&output, &run.results)?;
            }
            Ok(run.results.len())
        })
        .map_err(err)
    }

    /// Push a block of any length; returns the results its samples completed.
    #[pyo3(signature = (x, channels_first=None))]
    fn push<'py>(
        &mut self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        channels_first: Option<bool>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let mut out = self.run(py, x, channels_first.unwrap_or(self.channels_first), false)?;
        results(py, &mut out, self.lock()?.grid().len())
    }

    /// End of input: results still held (a noise range, the tracker's delay).
    fn flush<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let mut out = Output::default();
        let mut inner = self.lock()?;
        let loc = &mut *inner;
        py.allow_threads(|| loc.flush(&mut out)).map_err(err)?;
        results(py, &mut out, inner.grid().len())
    }

    /// Start a new stream (same plan and device).
    fn reset(&mut self) -> PyResult<()> {
        self.lock()?.reset().map_err(err)
    }

    /// Frames between a result's frame and the last frame of its window.
    #[getter]
    fn latency_frames(&self) -> PyResult<usize> {
        Ok(self.lock()?.latency_frames())
    }

    /// Samples per channel still needed before the next result.
    #[getter]
    fn samples_needed_next(&self) -> PyResult<usize> {
        Ok(self.lock()?.samples_needed_next())
    }

    /// The device description.
    #[getter]
    fn device(&self) -> PyResult<String> {
        Ok(self.lock()?.device_name())
    }

    /// The algorithm that runs.
    #[getter]
    fn algorithm(&self) -> PyResult<&'static str> {
        Ok(self.lock()?.config().algorithm.name())
    }

    /// Analysis sampling rate, Hz.
    #[getter]
    fn fs(&self) -> PyResult<u32> {
        Ok(self.lock()?.config().sample_rate_hz)
    }

    /// Microphones used.
    #[getter]
    fn num_mics(&self) -> PyResult<usize> {
        Ok(self.lock()?.num_mics())
    }

    /// Notes from building (the algorithm chosen…).
    #[getter]
    fn notes(&self) -> PyResult<Vec<String>> {
        Ok(self.lock()?.notes().to_vec())
    }

    /// The grid: (D, 3) unit direction vectors, azimuth and elevation in degrees.
    fn directions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let inner = self.lock()?;
        let g = inner.grid();
        let d = PyDict::new(py);
        let unit: Vec<f64> = (0..g.len()).flat_map(|i| g.unit(i)).collect();
        let unit =
            Array2::from_shape_vec((g.len(), 3), unit).map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
        d.set_item("unit", unit.into_pyarray(py))?;
        d.set_item(
            "azimuth_deg",
            (0..g.len())
                .map(|i| g.azimuth_deg(i))
                .collect::<Vec<_>>()
                .into_pyarray(py),
        )?;
        d.set_item(
            "elevation_deg",
            (0..g.len())
                .map(|i| g.elevation_deg(i))
                .collect::<Vec<_>>()
                .into_pyarray(py),
        )?;
        Ok(d)
    }
}

impl PyLocalizer {
    fn lock(&self) -> PyResult<MutexGuard<'_, Localizer>> {
        self.inner
            .lock()
            .map_err(|_| PyRuntimeError::new_err("the localizer failed in another thread"))
    }

    fn check_rate(&self, fs: Option<u32>) -> PyResult<()> {
        let want = self.lock()?.config().sample_rate_hz;
        match fs {
            Some(f) if f != want => Err(PyValueError::new_err(format!(
                "the audio is sampled at {f} Hz, but the transfer functions are for {want} Hz"
            ))),
            _ => Ok(()),
        }
    }

    fn run(
        &mut self,
        py: Python<'_>,
        x: &Bound<'_, PyAny>,
        channels_first: bool,
        flush: bool,
    ) -> PyResult<Output> {
        let s = samples(x)?;
        let [rows, cols] = s.shape();
        let n_ch = if channels_first { rows } else { cols };
        let mut guard = self.lock()?;
        let fs = guard.config().sample_rate_hz;
        if let Err(e) = guard.check_input(fs, n_ch) {
            let other = if channels_first { cols } else { rows };
            let hint = if guard.check_input(fs, other).is_ok() {
                if channels_first {
                    " (the array looks like (samples, channels): drop channels_first=True)"
                } else {
                    " (the array looks like (channels, samples): pass channels_first=True)"
                }
            } else {
                ""
            };
            return Err(PyValueError::new_err(format!(
                "audio of shape ({rows}, {cols}): {e}{hint}"
            )));
        }
        let mut out = Output::default();
        let data = s.data();
        let inner = &mut *guard;
        py.allow_threads(|| -> soundloc::Result<()> {
            let block = if channels_first {
                Block::ChannelsFirst { data, channels: n_ch }
            } else {
                Block::Interleaved { data, channels: n_ch }
            };
            inner.push(block, &mut out)?;
            if flush {
                inner.flush(&mut out)?;
            }
            Ok(())
        })
        .map_err(err)?;
        Ok(out)
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
    let map = soundloc::ChannelMap {
        input_channels: spec.input_channels.clone(),
        tf_channels: spec.channels.clone(),
        full_mics: tf.num_mics,
        mics: if spec.channels.is_empty() {
            tf.num_mics
        } else {
            spec.channels.len()
        },
    };
    let idx = map
        .resolve(nch)
        .map_err(|e| soundloc::Error::Mismatch(format!("noise of shape ({rows}, {cols}): {e}")))?;
    let planar: Vec<Vec<f32>> = idx
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
    let config = soundloc::LocalizeConfig {
        sample_rate_hz: tf.sample_rate_hz,
        ..config.clone()
    };
    soundloc::noise::estimate(&config, config.sample_rate_hz, &planar, None)
}

/// Results as numpy arrays (NaN / -1 where a window has fewer sources).
fn results<'py>(py: Python<'py>, out: &mut Output, num_dirs: usize) -> PyResult<Bound<'py, PyDict>> {
    let r: &[LocalizationResult] = &out.results;
    let s = r.iter().map(|x| x.sources.len()).max().unwrap_or(0);
    let n = r.len();
    let mut az = vec![f64::NAN; n * s];
    let mut el = vec![f64::NAN; n * s];
    let mut pw = vec![f64::NAN; n * s];
    let mut gi = vec![-1i64; n * s];
    let mut ids = vec![-1i64; n * s];
    for (i, x) in r.iter().enumerate() {
        for (j, src) in x.sources.iter().enumerate() {
            az[i * s + j] = src.azimuth_deg;
            el[i * s + j] = src.elevation_deg;
            pw[i * s + j] = src.power_db;
            gi[i * s + j] = src.grid_index as i64;
            ids[i * s + j] = src.id.unwrap_or(-1);
        }
    }
    let shape = |v: Vec<f64>| Array2::from_shape_vec((n, s), v);
    let shape_i = |v: Vec<i64>| Array2::from_shape_vec((n, s), v);
    let bad = |e: numpy::ndarray::ShapeError| PyRuntimeError::new_err(e.to_string());
    let d = PyDict::new(py);
    d.set_item(
        "frames",
        r.iter()
            .map(|x| x.frame as i64)
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        "times",
        r.iter().map(|x| x.time_s).collect::<Vec<_>>().into_pyarray(py),
    )?;
    d.set_item("azimuth_deg", shape(az).map_err(bad)?.into_pyarray(py))?;
    d.set_item("elevation_deg", shape(el).map_err(bad)?.into_pyarray(py))?;
    d.set_item("power_db", shape(pw).map_err(bad)?.into_pyarray(py))?;
    d.set_item("grid_index", shape_i(gi).map_err(bad)?.into_pyarray(py))?;
    d.set_item("ids", shape_i(ids).map_err(bad)?.into_pyarray(py))?;
    match out.spectrum.take() {
        Some(t) => {
            let rows = t.frames.len();
            let a = Array2::from_shape_vec((rows, num_dirs), t.db).map_err(bad)?;
            d.set_item("spectrum_db", a.into_pyarray(py))?;
        }
        None => d.set_item("spectrum_db", py.None())?,
    }
    d.set_item("notes", std::mem::take(&mut out.notes))?;
    Ok(d)
}

/// Windows of given STFT frames for one array and grid (pyroomacoustics' `locate_sources`
/// shape; used by `soundloc.doa`). The plan is built on the first call and reused while
/// the analysis stays the same.
#[pyclass(name = "FramesLocalizer", module = "soundloc._native")]
struct PyFrames {
    inner: Mutex<soundloc::frames::FramesLocalizer>,
    fs: u32,
    nfft: usize,
    algorithm: Algorithm,
    normalize_bins: bool,
    eigenvalue_weight: bool,
}

#[pymethods]
impl PyFrames {
    /// `mics`: (M, 3) metres; `grid`: (D, 3) points (directions scaled to the source
    /// distance; far field = far away).
    #[new]
    #[pyo3(signature = (mics, grid, fs, nfft, c, algorithm, normalize_bins, eigenvalue_weight, precision, device))]
    #[allow(clippy::too_many_arguments)] // mirrors the Python constructor
    fn new(
        mics: PyReadonlyArray2<'_, f64>,
        grid: PyReadonlyArray2<'_, f64>,
        fs: u32,
        nfft: usize,
        c: f64,
        algorithm: &str,
        normalize_bins: bool,
        eigenvalue_weight: bool,
        precision: &str,
        device: &str,
    ) -> PyResult<Self> {
        let algorithm: Algorithm = parse("algorithm", algorithm)?;
        let precision: Precision = parse("precision", precision)?;
        let device: DeviceChoice = device.parse().map_err(err)?;
        let rows = |a: &PyReadonlyArray2<'_, f64>, what: &str| -> PyResult<Vec<[f64; 3]>> {
            if a.shape()[1] != 3 {
                return Err(PyValueError::new_err(format!("{what} must have shape (n, 3)")));
            }
            Ok(a.as_array()
                .rows()
                .into_iter()
                .map(|r| [r[0], r[1], r[2]])
                .collect())
        };
        let g = Grid::from_points(rows(&grid, "grid")?).map_err(err)?;
        let geometry = Geometry::new(rows(&mics, "mics")?, Path::new("mics")).map_err(err)?;
        Ok(PyFrames {
            inner: Mutex::new(soundloc::frames::FramesLocalizer::new(
                geometry, g, c, device, precision,
            )),
            fs,
            nfft,
            algorithm,
            normalize_bins,
            eigenvalue_weight,
        })
    }

    /// `x`: complex128 (M, F, S); `bins`: the used absolute bins lo..hi; `weights`: per
    /// used bin (empty = uniform). Returns the dB spectrum (D,) and the peak indices,
    /// strongest first.
    fn process<'py>(
        &self,
        py: Python<'py>,
        x: numpy::PyReadonlyArray3<'py, numpy::Complex64>,
        bins: (usize, usize),
        weights: Vec<f64>,
        num_src: usize,
    ) -> PyResult<(Bound<'py, numpy::PyArray1<f32>>, Vec<usize>)> {
        use soundloc::config::SpectrumWeight;
        let shape = [x.shape()[0], x.shape()[1], x.shape()[2]];
        let xs = x
            .as_slice()
            .map_err(|_| PyValueError::new_err("x must be C-contiguous"))?;
        let hz = |k: usize| k as f64 * self.fs as f64 / self.nfft as f64;
        let config = soundloc::LocalizeConfig {
            algorithm: self.algorithm,
            nfft: self.nfft,
            sample_rate_hz: self.fs,
            num_sources: num_src,
            max_peaks: num_src as i64,
            // Bin k is used when ⌊f·N/fs⌋ = k: the middle of the bin gives exactly k.
            lower_freq_hz: hz(bins.0) + 0.5 * hz(1),
            upper_freq_hz: hz(bins.1) + 0.5 * hz(1),
            eigenvalue_weight: self.eigenvalue_weight,
            normalize_bins: self.normalize_bins,
            spectrum_weight: if weights.is_empty() {
                SpectrumWeight::Uniform
            } else {
                SpectrumWeight::Manual(weights)
            },
            ..Default::default()
        };
        let out = py.allow_threads(|| match self.inner.lock() {
            Ok(mut inner) => inner.process(&config, xs, shape).map_err(err),
            Err(_) => Err(PyRuntimeError::new_err(
                "frames localizer poisoned by an earlier panic",
            )),
        })?;
        let peaks = out.peaks.iter().map(|p| p.dir).collect();
        Ok((numpy::PyArray1::from_vec(py, out.spectrum_db), peaks))
    }
}

/// Read a WAV or FLAC file: (samples × channels float32 array in the file's raw units,
/// e.g. int16 values for 16-bit files, sampling rate in Hz).
#[pyfunction]
fn read_audio(py: Python<'_>, path: PathBuf) -> PyResult<(Bound<'_, PyArray2<f32>>, u32)> {
    let a = py
        .allow_threads(|| soundloc::audio::read_audio(&path))
        .map_err(err)?;
    let (n, c) = (a.channels.first().map_or(0, |v| v.len()), a.channels.len());
    let mut x = Array2::<f32>::zeros((n, c));
    for (j, ch) in a.channels.iter().enumerate() {
        for (i, v) in ch.iter().enumerate() {
            x[(i, j)] = *v;
        }
    }
    Ok((x.into_pyarray(py), a.sample_rate_hz))
}

/// A HARK transfer-function file (zip or HGTF) as numpy: `tf` complex64 (directions,
/// mics, bins) for the absolute bins `first_bin ..`, `directions` (D, 3) as stored,
/// `mics` (M, 3) metres, `nfft`, `fs`.
#[pyfunction]
fn read_tf<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let tf = py
        .allow_threads(|| soundloc::array::TransferFunctions::load(&path))
        .map_err(err)?;
    let (d, m, b) = (tf.grid.len(), tf.num_mics, tf.num_bins);
    let data: Vec<numpy::Complex32> = tf
        .data
        .iter()
        .map(|z| numpy::Complex32::new(z.re, z.im))
        .collect();
    let arr = numpy::ndarray::Array3::from_shape_vec((d, m, b), data)
        .map_err(|e| PyValueError::new_err(format!("{}: {e}", path.display())))?;
    let rows = |v: &[[f64; 3]]| Array2::from_shape_fn((v.len(), 3), |(i, j)| v[i][j]);
    let out = PyDict::new(py);
    out.set_item("tf", arr.into_pyarray(py))?;
    out.set_item("first_bin", tf.first_bin)?;
    out.set_item("nfft", tf.nfft)?;
    out.set_item("fs", tf.sample_rate_hz)?;
    out.set_item("directions", rows(&tf.grid.points).into_pyarray(py))?;
    out.set_item("mics", rows(&tf.mic_positions).into_pyarray(py))?;
    Ok(out)
}

/// A HARK noise correlation file (zip, or a text pair given as its real-part file or
/// "REAL,IMAG") as complex128 (nfft/2 + 1, M, M), and nfft.
#[pyfunction]
fn read_noise_cm<'py>(
    py: Python<'py>,
    path: PathBuf,
) -> PyResult<(Bound<'py, numpy::PyArray3<numpy::Complex64>>, usize)> {
    use soundloc::formats::noise_cm::{Expected, NoiseCm};
    let k = py
        .allow_threads(|| NoiseCm::load(&path, Expected::default()))
        .map_err(err)?;
    let (f, m) = (k.nfft / 2 + 1, k.num_mics);
    let data: Vec<numpy::Complex64> = k.data.iter().map(|z| numpy::Complex64::new(z.re, z.im)).collect();
    let arr = numpy::ndarray::Array3::from_shape_vec((f, m, m), data)
        .map_err(|e| PyValueError::new_err(format!("{}: {e}", path.display())))?;
    Ok((arr.into_pyarray(py), k.nfft))
}

/// A HARK source-location log (text or XML) as JSON lines (parsed in Python).
#[pyfunction]
#[pyo3(signature = (path, frame_period_s=0.01))]
fn read_source_log_json(py: Python<'_>, path: PathBuf, frame_period_s: f64) -> PyResult<Vec<String>> {
    let r = py
        .allow_threads(|| soundloc::formats::source_log::read(&path, frame_period_s))
        .map_err(err)?;
    Ok(r.iter().map(soundloc::output::jsonl::to_json_line).collect())
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_tf, m)?)?;
    m.add_function(wrap_pyfunction!(read_noise_cm, m)?)?;
    m.add_function(wrap_pyfunction!(read_source_log_json, m)?)?;
    m.add_function(wrap_pyfunction!(read_audio, m)?)?;
    m.add_class::<PyLocalizer>()?;
    m.add_class::<PyFrames>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
