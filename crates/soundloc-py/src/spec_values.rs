//! Python values of options that are not plain numbers or names: pairs of numbers, a
//! rate, `noise_preceding`'s frames and gap, spectrum weights.

use crate::parse;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use soundloc::config::SpectrumWeight;

/// Two numbers from a tuple, list or array (pyroomacoustics users write `[500, 4000]`).
pub(crate) fn pair(v: &Bound<'_, PyAny>, what: &str) -> PyResult<(f64, f64)> {
    match v.extract::<Vec<f64>>() {
        Ok(p) if p.len() == 2 => Ok((p[0], p[1])),
        _ => Err(PyValueError::new_err(format!(
            "{what} must be two numbers (start, end), got {}",
            v.repr().map(|r| r.to_string()).unwrap_or_default()
        ))),
    }
}

/// `noise_preceding`: FRAMES, or (FRAMES, GAP) as a tuple or list (the CLI's
/// FRAMES[:GAP]; GAP 0 when left out).
pub(crate) fn preceding(v: &Bound<'_, PyAny>) -> PyResult<(usize, usize)> {
    let bad = || {
        PyValueError::new_err(format!(
            "noise_preceding must be FRAMES or (FRAMES, GAP), whole numbers with FRAMES ≥ 1, got {}",
            v.repr().map(|r| r.to_string()).unwrap_or_default()
        ))
    };
    if v.is_instance_of::<pyo3::types::PyBool>() {
        return Err(bad());
    }
    let (frames, gap) = match (v.extract::<usize>(), v.extract::<Vec<usize>>()) {
        (Ok(f), _) => (f, 0),
        (_, Ok(p)) if p.len() == 2 => (p[0], p[1]),
        (_, Ok(p)) if p.len() == 1 => (p[0], 0),
        _ => return Err(bad()),
    };
    if frames == 0 {
        return Err(bad());
    }
    Ok((frames, gap))
}

/// A sample rate in Hz: a positive whole number (16000 or 16000.0).
pub(crate) fn rate(v: &Bound<'_, PyAny>) -> PyResult<u32> {
    let bad = || {
        PyValueError::new_err(format!(
            "fs must be a positive whole number of Hz, got {}",
            v.repr().map(|r| r.to_string()).unwrap_or_default()
        ))
    };
    if v.is_instance_of::<pyo3::types::PyBool>() {
        return Err(bad());
    }
    // Not a number at all (a string, say): the wrong type, as Python's own calls say.
    let f: f64 = v.extract().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(format!(
            "fs must be a number of Hz, got {} of type {}",
            v.repr().map(|r| r.to_string()).unwrap_or_default(),
            v.get_type().name().map(|n| n.to_string()).unwrap_or_default()
        ))
    })?;
    if f.fract() == 0.0 && f >= 1.0 && f <= u32::MAX as f64 {
        Ok(f as u32)
    } else {
        Err(bad())
    }
}

/// `spectrum_weight`: None (uniform), a name ("uniform", "a-weighting") or one weight per
/// used bin (HARK's manual weights).
pub(crate) fn spectrum_weight_of(w: Option<&Bound<'_, PyAny>>) -> PyResult<SpectrumWeight> {
    let Some(w) = w else {
        return Ok(SpectrumWeight::Uniform);
    };
    match w.extract::<String>() {
        Ok(name) if name != "manual" => parse("spectrum_weight", &name),
        Ok(_) => Err(PyValueError::new_err(
            "spectrum_weight: give the weights themselves (one per used bin), not \"manual\"",
        )),
        Err(_) => w.extract::<Vec<f64>>().map(SpectrumWeight::Manual).map_err(|_| {
            PyValueError::new_err(
                "spectrum_weight: \"uniform\", \"a-weighting\" or a sequence of weights, one per used bin",
            )
        }),
    }
}
