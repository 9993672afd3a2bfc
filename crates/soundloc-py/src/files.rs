//! HARK and audio files as numpy: `read_audio`, `read_tf`, `read_noise_cm`, source logs,
//! and their writers.

use crate::err;
use crate::Released;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// Read a WAV or FLAC file: (samples × channels float32 array in the file's raw units,
/// e.g. int16 values for 16-bit files, sampling rate in Hz). With `raw=` ("u8", "s16le",
/// "s24le", "s32le", "f32le", "f64le"; the CLI's `--raw`), a headerless file of
/// interleaved PCM of `channels` channels at `fs` Hz.
#[pyfunction]
#[pyo3(signature = (path, raw=None, channels=None, fs=None))]
pub(crate) fn read_audio(
    py: Python<'_>,
    path: PathBuf,
    raw: Option<String>,
    channels: Option<usize>,
    fs: Option<u32>,
) -> PyResult<(Bound<'_, PyArray2<f32>>, u32)> {
    let a = match (raw, channels, fs) {
        (None, None, None) => py.released(|| soundloc::audio::read_audio(&path)),
        (Some(enc), Some(ch), Some(fs)) => {
            let enc: soundloc::audio::RawEncoding = enc.parse().map_err(err)?;
            py.released(|| soundloc::audio::read_raw_audio(&path, enc, ch, fs))
        }
        (None, ..) => {
            return Err(PyValueError::new_err(
                "channels= and fs= describe a raw file: give raw= (its encoding) too",
            ))
        }
        (Some(_), ..) => {
            return Err(PyValueError::new_err(
                "a raw file needs raw=, channels= and fs= (a headerless file does not say them)",
            ))
        }
    }
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
pub(crate) fn read_tf<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let tf = py
        .released(|| soundloc::array::TransferFunctions::load(&path))
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
pub(crate) fn read_noise_cm<'py>(
    py: Python<'py>,
    path: PathBuf,
) -> PyResult<(Bound<'py, numpy::PyArray3<numpy::Complex64>>, usize)> {
    use soundloc::formats::noise_cm::{Expected, NoiseCm};
    let k = py
        .released(|| NoiseCm::load(&path, Expected::default()))
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
pub(crate) fn read_source_log_json(
    py: Python<'_>,
    path: PathBuf,
    frame_period_s: f64,
) -> PyResult<Vec<String>> {
    let r = py
        .released(|| soundloc::formats::source_log::read(&path, frame_period_s))
        .map_err(err)?;
    Ok(r.iter().map(soundloc::output::jsonl::to_json_line).collect())
}

/// A complex numpy array of any supported precision as complex f64 values and its shape.
fn complex_array(x: &Bound<'_, PyAny>, what: &str) -> PyResult<(Vec<num_complex::Complex64>, Vec<usize>)> {
    use numpy::{PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
    if let Ok(a) = x.downcast::<PyArrayDyn<numpy::Complex64>>() {
        let r = a.readonly();
        return Ok((r.as_array().iter().copied().collect(), r.shape().to_vec()));
    }
    if let Ok(a) = x.downcast::<PyArrayDyn<numpy::Complex32>>() {
        let r = a.readonly();
        let v = r
            .as_array()
            .iter()
            .map(|z| num_complex::Complex64::new(z.re as f64, z.im as f64))
            .collect();
        return Ok((v, r.shape().to_vec()));
    }
    Err(PyTypeError::new_err(format!(
        "{what} must be a complex64 or complex128 numpy array"
    )))
}

/// Write a HARK transfer-function zip (harktool's layout, atomically): `tf` complex
/// (directions, mics, bins) localization TFs for the absolute bins `first_bin ..` (as
/// `read_tf` returns them; bins the array lacks are written as zeros: a zip holds all
/// nfft/2 + 1), `directions` (D, 3) and `mics` (M, 3) in metres, `nfft`, `fs`;
/// `neighbors` (a list per direction) or, when None, the ring's left/right or the 6
/// nearest directions. The separation TFs are the conjugates.
#[pyfunction]
#[pyo3(signature = (path, tf, directions, mics, nfft, fs, neighbors=None, first_bin=0))]
#[allow(clippy::too_many_arguments)] // mirrors the Python function
pub(crate) fn write_tf(
    py: Python<'_>,
    path: PathBuf,
    tf: &Bound<'_, PyAny>,
    directions: &Bound<'_, PyAny>,
    mics: &Bound<'_, PyAny>,
    nfft: usize,
    fs: u32,
    neighbors: Option<Vec<Vec<usize>>>,
    first_bin: usize,
) -> PyResult<()> {
    use soundloc::array::{Grid, TransferFunctions};
    let (data, shape) = complex_array(tf, "tf")?;
    let dirs = crate::points(directions, "directions")?;
    let mics = crate::positions(mics, "mics")?;
    let bins = nfft / 2 + 1;
    let given = shape.get(2).copied().unwrap_or(0);
    if shape.len() != 3 || shape[..2] != [dirs.len(), mics.len()] || given == 0 || first_bin + given > bins {
        return Err(PyValueError::new_err(format!(
            "tf has shape {shape:?}; {} directions and {} mics need ({}, {}, bins) with first_bin + bins ≤ nfft/2 + 1 = {bins}",
            dirs.len(),
            mics.len(),
            dirs.len(),
            mics.len()
        )));
    }
    // All nfft/2 + 1 bins, zeros outside the given ones.
    let (d, m) = (dirs.len(), mics.len());
    let mut full = vec![num_complex::Complex64::new(0.0, 0.0); d * m * bins];
    for (row, src) in full.chunks_mut(bins).zip(data.chunks(given)) {
        row[first_bin..first_bin + given].copy_from_slice(src);
    }
    let data = full;
    py.released(|| -> soundloc::Result<()> {
        let grid = match neighbors {
            Some(nb) => Grid::from_table(dirs, nb)?,
            None => Grid::from_points(dirs)?,
        };
        let tf = TransferFunctions {
            nfft,
            sample_rate_hz: fs,
            grid,
            num_mics: mics.len(),
            mic_positions: mics,
            first_bin: 0,
            num_bins: bins,
            data: data
                .iter()
                .map(|z| num_complex::Complex32::new(z.re as f32, z.im as f32))
                .collect(),
        };
        soundloc::formats::hark_zip::write_tf_zip(&tf, &path)
    })
    .map_err(err)
}

/// Write noise correlation matrices `k` (nfft/2 + 1, M, M) complex as HARK's zip (≥ 2.1,
/// values rounded to f32) or text pair (≤ 2.0; `path` names the pair: "K" → K_r, K_i);
/// `format` "zip" | "text", or None: zip when the path ends in .zip. Returns the paths
/// written.
#[pyfunction]
#[pyo3(signature = (path, k, format=None))]
pub(crate) fn write_noise_cm(
    py: Python<'_>,
    path: PathBuf,
    k: &Bound<'_, PyAny>,
    format: Option<&str>,
) -> PyResult<Vec<PathBuf>> {
    use soundloc::formats::noise_cm::{text_pair_paths, NoiseCm};
    let (data, shape) = complex_array(k, "k")?;
    let [f, m, m2] = shape[..] else {
        return Err(PyValueError::new_err(format!(
            "k must have shape (bins, M, M); got {shape:?}"
        )));
    };
    if m != m2 || f < 2 {
        return Err(PyValueError::new_err(format!(
            "k must have shape (nfft/2 + 1, M, M) with at least 2 bins; got {shape:?}"
        )));
    }
    let zip = match format {
        Some("zip") => true,
        Some("text") => false,
        None => path.extension().is_some_and(|e| e.eq_ignore_ascii_case("zip")),
        Some(other) => {
            return Err(PyValueError::new_err(format!(
                "format {other:?}: expected \"zip\" or \"text\""
            )))
        }
    };
    if !zip && path.extension().is_some_and(|e| e.eq_ignore_ascii_case("zip")) {
        return Err(PyValueError::new_err(format!(
            "{}: the text format writes a pair of text files, not a zip: name them without .zip or use format=\"zip\"",
            path.display()
        )));
    }
    py.released(|| -> soundloc::Result<Vec<PathBuf>> {
        let cm = NoiseCm::new(m, 2 * (f - 1), data)?;
        if zip {
            cm.write_zip(&path)?;
            Ok(vec![path.clone()])
        } else {
            let (re, im) = text_pair_paths(&path);
            cm.write_text_pair(&re, &im)?;
            Ok(vec![re, im])
        }
    })
    .map_err(err)
}

/// Write results (as JSON lines, the shape `soundloc localize` writes) as a HARK
/// source-location log, `format` "text" (≤ 2.0) or "xml" (≥ 2.1), atomically.
#[pyfunction]
pub(crate) fn write_source_log_json(
    py: Python<'_>,
    path: PathBuf,
    lines: Vec<String>,
    format: &str,
) -> PyResult<()> {
    use soundloc::formats::source_log::{write, SourceLogFormat};
    let format = match format {
        "text" => SourceLogFormat::Text,
        "xml" => SourceLogFormat::Xml,
        f => {
            return Err(PyValueError::new_err(format!(
                "format {f:?}: expected \"text\" or \"xml\""
            )))
        }
    };
    let results = lines
        .iter()
        .enumerate()
        .map(|(i, l)| {
            soundloc::output::jsonl::from_json_line(l)
                .map_err(|e| PyValueError::new_err(format!("result {i}: {e}")))
        })
        .collect::<PyResult<Vec<_>>>()?;
    py.released(|| write(&path, &results, format)).map_err(err)
}
