//! `soundloc._native`: the Python binding. It translates Python arguments into a
//! [`soundloc::LocalizerSpec`] and numpy arrays into sample blocks, and results back into
//! numpy arrays; every rule lives in the library. The GIL is released while localizing;
//! float32 input in C order is read in place.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use soundloc::array::Grid;
use soundloc::{LocalizationResult, Output};

mod files;
mod frames;
mod group;
mod localizer;
mod spec;
mod spec_values;
mod turns;

/// `py.released(f)`: `f` with the GIL released, its parallel work on soundloc's pool that
/// survives `fork` ([`soundloc::pool::install`]): a `multiprocessing` worker forked after
/// the parent used soundloc would otherwise wait forever on rayon's inherited global pool,
/// whose threads the child does not have. Every call into the library goes through it.
pub(crate) trait Released {
    fn released<T: Send, F: FnOnce() -> T + Send>(self, f: F) -> T;
}

impl Released for Python<'_> {
    fn released<T: Send, F: FnOnce() -> T + Send>(self, f: F) -> T {
        self.allow_threads(|| soundloc::pool::install(f))
    }
}

pub(crate) fn err(e: soundloc::Error) -> PyErr {
    match e {
        soundloc::Error::Io { .. } => PyOSError::new_err(e.to_string()),
        soundloc::Error::Device(_) => PyRuntimeError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// `v` as the value of an option named by a string (an algorithm, a window type); the
/// error lists the valid ones.
pub(crate) fn parse<T: serde::de::DeserializeOwned>(what: &str, v: &str) -> PyResult<T> {
    serde_json::from_value(serde_json::Value::String(v.to_string())).map_err(|e| {
        // serde's "unknown variant `x`, expected one of `a`, `b`" names the valid values.
        let e = e.to_string();
        let valid = e
            .split_once("expected ")
            .map(|(_, rest)| format!(" (expected {})", rest.replace('`', "\"")))
            .unwrap_or_default();
        PyValueError::new_err(format!("{what}: {v:?} is not a valid value{valid}"))
    })
}

/// Samples of a 2-D numpy array as f32 in C (row-major) order, with the array's (rows,
/// cols); float32 in C order is not copied, anything else is copied in logical order.
pub(crate) enum Samples<'py> {
    Borrowed(PyReadonlyArray2<'py, f32>),
    Owned(Vec<f32>, [usize; 2]),
}

impl Samples<'_> {
    pub(crate) fn shape(&self) -> [usize; 2] {
        match self {
            Samples::Borrowed(a) => [a.shape()[0], a.shape()[1]],
            Samples::Owned(_, s) => *s,
        }
    }
    pub(crate) fn data(&self) -> &[f32] {
        match self {
            Samples::Borrowed(a) => a.as_slice().unwrap_or(&[]),
            Samples::Owned(v, _) => v,
        }
    }
}

pub(crate) fn samples<'py>(x: &Bound<'py, PyAny>) -> PyResult<Samples<'py>> {
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
        // Only C order is read in place: `as_slice` also accepts Fortran order, whose memory
        // order is not (samples, channels).
        if r.is_c_contiguous() {
            return Ok(Samples::Borrowed(r));
        }
        let s = [r.shape()[0], r.shape()[1]];
        return Ok(Samples::Owned(r.as_array().iter().copied().collect(), s));
    }
    conv!(i16);
    conv!(i32);
    if let Ok(a) = x.downcast::<PyArray2<f64>>() {
        let a = a.readonly();
        let s = [a.shape()[0], a.shape()[1]];
        // One pass: convert, and note the first finite value that f32 cannot hold (it
        // would become an infinity and be reported as one).
        let mut v: Vec<f32> = Vec::with_capacity(s[0] * s[1]);
        let mut big = None;
        for &x in a.as_array().iter() {
            let y = x as f32;
            if big.is_none() && y.is_infinite() && x.is_finite() {
                big = Some((v.len(), x));
            }
            v.push(y);
        }
        if let Some((i, x)) = big {
            let (r, c) = (i / s[1].max(1), i % s[1].max(1));
            return Err(PyValueError::new_err(format!(
                "sample [{r}, {c}] of the array is {x:e}, beyond the range of the 32-bit floats soundloc holds samples in (±{:e}); scale the audio down",
                f32::MAX
            )));
        }
        return Ok(Samples::Owned(v, s));
    }
    let ndim = x.getattr("ndim").and_then(|n| n.extract::<usize>()).ok();
    // An array of a supported type in the other byte order (big-endian data read from a
    // file, `dtype=">i2"`): converted to the native order once, then read as above.
    if ndim == Some(2) {
        if let Ok(dt) = x.getattr("dtype") {
            let native = dt
                .getattr("isnative")
                .and_then(|v| v.extract::<bool>())
                .unwrap_or(true);
            if !native {
                let conv = x.call_method1("astype", (dt.call_method1("newbyteorder", ("=",))?,))?;
                if conv.getattr("dtype")?.getattr("isnative")?.extract::<bool>()? {
                    return samples(&conv);
                }
            }
        }
    }
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

/// Positions or directions, one per row: (N, 3).
pub(crate) fn points(x: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<[f64; 3]>> {
    rows_of_3(x, what, false)
}

/// Microphone positions, one per row: (M, 3), or (M, 2) for a planar array (z = 0).
pub(crate) fn positions(x: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<[f64; 3]>> {
    rows_of_3(x, what, true)
}

fn rows_of_3(x: &Bound<'_, PyAny>, what: &str, planar: bool) -> PyResult<Vec<[f64; 3]>> {
    let v: Vec<Vec<f64>> = x
        .call_method0("tolist")
        .and_then(|l| l.extract())
        .or_else(|_| x.extract())
        .map_err(|_| PyValueError::new_err(format!("{what}: expected an (N, 3) array of positions")))?;
    // pyroomacoustics' L is (2 or 3, M): one microphone per column.
    let by_columns = matches!(v.len(), 2 | 3) && v.iter().all(|r| r.len() == v[0].len() && r.len() != 3);
    if by_columns {
        let hint = match (planar, v[0].len()) {
            // (2, 2), (3, 2): planar positions by rows, too.
            (true, 2) => {
                " or (M, 2): L.T; planar positions given by rows, P: np.column_stack([P, np.zeros(len(P))])"
            }
            (true, _) => " or (M, 2): L.T",
            _ => ": L.T",
        };
        return Err(PyValueError::new_err(format!(
            "{what}: a ({}, {}) array holds one {} per column (pyroomacoustics' L); give one per row, (M, 3){hint}",
            v.len(),
            v[0].len(),
            if planar { "microphone" } else { "point" },
        )));
    }
    // Planar positions, one per row: (M, 2) with M > 3 (a 2 × 2 or 3 × 2 array could be
    // either layout and is named above): z = 0.
    if v.len() > 3 && v.iter().all(|r| r.len() == 2) {
        if planar {
            return Ok(v.into_iter().map(|r| [r[0], r[1], 0.0]).collect());
        }
        return Err(PyValueError::new_err(format!(
            "{what}: a ({}, 2) array holds 2 values per row; give (N, 3) unit vectors (x, y, z)",
            v.len()
        )));
    }
    v.into_iter()
        .enumerate()
        .map(|(i, p)| {
            <[f64; 3]>::try_from(p.as_slice()).map_err(|_| {
                PyValueError::new_err(format!(
                    "{what}: every row must hold x, y, z (row {i} has {} values)",
                    p.len()
                ))
            })
        })
        .collect()
}

/// Results as numpy arrays (NaN / -1 where a window has fewer sources), at least as
/// wide as the peaks `config` reports (every push of a default localizer gives arrays of
/// one width, also an empty one; the tracker's carried sources and `max_peaks=0` can
/// widen them: `Results.concatenate` pads).
pub(crate) fn results<'py>(
    py: Python<'py>,
    out: &mut Output,
    num_dirs: usize,
    config: &soundloc::LocalizeConfig,
) -> PyResult<Bound<'py, PyDict>> {
    let r: &[LocalizationResult] = &out.results;
    let width = match config.peaks_out() {
        usize::MAX => 0,
        n => n.min(num_dirs),
    };
    let s = r.iter().map(|x| x.sources.len()).max().unwrap_or(0).max(width);
    let n = r.len();
    let mut az = vec![f64::NAN; n * s];
    let mut el = vec![f64::NAN; n * s];
    let mut pw = vec![f64::NAN; n * s];
    let mut gi = vec![-1i64; n * s];
    let mut ids = vec![-1i64; n * s];
    let mut held = vec![false; n * s];
    for (i, x) in r.iter().enumerate() {
        for (j, src) in x.sources.iter().enumerate() {
            az[i * s + j] = src.azimuth_deg;
            el[i * s + j] = src.elevation_deg;
            pw[i * s + j] = src.power_db;
            gi[i * s + j] = src.grid_index as i64;
            ids[i * s + j] = src.id.unwrap_or(-1);
            held[i * s + j] = src.held;
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
    d.set_item(
        "held",
        Array2::from_shape_vec((n, s), held)
            .map_err(bad)?
            .into_pyarray(py),
    )?;
    d.set_item(
        "num_active",
        r.iter()
            .map(|x| x.num_active.map_or(-1, |n| n as i64))
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
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

/// The channel count of a (rows, cols) block — cols, or rows with `channels_first` —
/// after `check` accepts it; the error names the shape and, when the other, shorter
/// axis would fit, says so.
pub(crate) fn channel_count(
    [rows, cols]: [usize; 2],
    channels_first: bool,
    check: impl Fn(usize) -> soundloc::Result<()>,
) -> PyResult<usize> {
    let n_ch = if channels_first { rows } else { cols };
    if let Err(e) = check(n_ch) {
        let other = if channels_first { cols } else { rows };
        // The other axis is offered only where it is the shorter one: an array of
        // channels is much shorter than it is long, and a block of a few samples or an
        // option's index out of range otherwise "fits" the long axis.
        let hint = if other < n_ch && check(other).is_ok() {
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
    Ok(n_ch)
}

/// The grid as numpy: (D, 3) unit direction vectors, azimuth and elevation in degrees.
pub(crate) fn directions<'py>(py: Python<'py>, g: &Grid) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let unit: Vec<f64> = (0..g.len()).flat_map(|i| g.unit(i)).collect();
    let unit =
        Array2::from_shape_vec((g.len(), 3), unit).map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    d.set_item("unit", unit.into_pyarray(py))?;
    let az: Vec<f64> = (0..g.len()).map(|i| g.azimuth_deg(i)).collect();
    let el: Vec<f64> = (0..g.len()).map(|i| g.elevation_deg(i)).collect();
    d.set_item("azimuth_deg", az.into_pyarray(py))?;
    d.set_item("elevation_deg", el.into_pyarray(py))?;
    Ok(d)
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(spec::spec, m)?)?;
    m.add_function(wrap_pyfunction!(files::read_tf, m)?)?;
    m.add_function(wrap_pyfunction!(files::write_tf, m)?)?;
    m.add_function(wrap_pyfunction!(files::read_noise_cm, m)?)?;
    m.add_function(wrap_pyfunction!(files::write_noise_cm, m)?)?;
    m.add_function(wrap_pyfunction!(files::read_source_log_json, m)?)?;
    m.add_function(wrap_pyfunction!(files::write_source_log_json, m)?)?;
    m.add_function(wrap_pyfunction!(files::read_audio, m)?)?;
    m.add_class::<spec::PySpec>()?;
    m.add_class::<localizer::PyLocalizer>()?;
    m.add_class::<group::PyGroup>()?;
    m.add_class::<frames::PyFrames>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
