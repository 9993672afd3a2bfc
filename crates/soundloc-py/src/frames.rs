//! `soundloc._native.FramesLocalizer`: MUSIC / SRP on given STFT frames (`soundloc.doa`).

use crate::Released;
use crate::{err, parse};
use numpy::{PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use soundloc::array::{Geometry, Grid};
use soundloc::backend::DeviceChoice;
use soundloc::{Algorithm, Precision};
use std::path::Path;
use std::sync::Mutex;

/// Windows of given STFT frames for one array and grid (pyroomacoustics' `locate_sources`
/// shape; used by `soundloc.doa`). The plan is built on the first call and reused while
/// the analysis stays the same.
#[pyclass(name = "FramesLocalizer", module = "soundloc._native")]
pub(crate) struct PyFrames {
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

    /// `x`: complex128 (M, F, S), aligned, with non-negative strides of whole elements
    /// (a C-contiguous array or a slice of one: read in place, no copy); `bins`: the used absolute bins lo..hi; `weights`: per
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
        let view = x.as_array();
        let shape = [view.shape()[0], view.shape()[1], view.shape()[2]];
        // numpy's strides in bytes: whole, non-negative elements, and an aligned start, or
        // the caller copies first (doa.py does).
        let elem = std::mem::size_of::<numpy::Complex64>() as isize;
        let st = x.strides();
        let aligned = (view.as_ptr() as usize).is_multiple_of(std::mem::align_of::<numpy::Complex64>());
        if !aligned || st.iter().any(|&v| v < 0 || v % elem != 0) {
            return Err(PyValueError::new_err(
                "x must be aligned with non-negative strides of whole elements (np.ascontiguousarray(x) first)",
            ));
        }
        let strides = [
            (st[0] / elem) as usize,
            (st[1] / elem) as usize,
            (st[2] / elem) as usize,
        ];
        let span = if shape.contains(&0) {
            0
        } else {
            1 + (0..3).map(|d| (shape[d] - 1) * strides[d]).sum::<usize>()
        };
        // SAFETY: numpy holds the array's memory for as long as `x` is borrowed (read-only
        // here); with non-negative strides every element lies in the `span` values from the
        // first, which `FramesView::new` checks again for each index it will read.
        let data: &[numpy::Complex64] = if span == 0 {
            &[]
        } else {
            unsafe { std::slice::from_raw_parts(view.as_ptr(), span) }
        };
        let frames = soundloc::frames::FramesView::new(data, shape, strides).map_err(err)?;
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
        let out = py.released(|| match self.inner.lock() {
            Ok(mut inner) => inner.process(&config, &frames).map_err(err),
            Err(_) => Err(PyRuntimeError::new_err(
                "frames localizer poisoned by an earlier panic",
            )),
        })?;
        let peaks = out.peaks.iter().map(|p| p.dir).collect();
        Ok((numpy::PyArray1::from_vec(py, out.spectrum_db), peaks))
    }
}
