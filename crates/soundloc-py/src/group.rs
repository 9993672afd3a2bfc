//! `soundloc._native.StreamGroup`: several arrays' streams sharing one plan and one device
//! (the library's [`LocalizerGroup`]); see `soundloc.StreamGroup` in Python.

use crate::spec::PySpec;
use crate::turns::{Turn, Turns};
use crate::Released;
use crate::{channel_count, directions, err, results, samples, Samples};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use soundloc::{Block, LocalizerGroup, Output};

struct State {
    group: LocalizerGroup,
    /// Per stream: results produced (by any run) and not yet returned to Python.
    outs: Vec<Output>,
}

/// Streams of several arrays of one kind, localized together. Calls from several
/// threads take turns in arrival order ([`Turns`]).
#[pyclass(module = "soundloc._native", name = "StreamGroup")]
pub(crate) struct PyGroup {
    state: Turns<State>,
    channels_first: bool,
}

fn block<'a>(s: &'a Samples<'_>, channels_first: bool, channels: usize) -> Block<'a> {
    if channels_first {
        Block::ChannelsFirst {
            data: s.data(),
            channels,
        }
    } else {
        Block::Interleaved {
            data: s.data(),
            channels,
        }
    }
}

#[pymethods]
impl PyGroup {
    #[new]
    fn new(py: Python<'_>, spec: &PySpec, streams: usize) -> PyResult<Self> {
        let group = spec.group(py, streams)?;
        Ok(PyGroup {
            state: Turns::new(
                State {
                    outs: vec![Output::default(); group.len()],
                    group,
                },
                "stream group",
            ),
            channels_first: spec.channels_first,
        })
    }

    /// Add a stream like the others; returns its index.
    fn add_stream(&self, py: Python<'_>) -> PyResult<usize> {
        let mut st = self.lock(py)?;
        let i = st.group.add_stream().map_err(err)?;
        st.outs.push(Output::default());
        Ok(i)
    }

    fn __len__(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(self.lock(py)?.group.len())
    }

    /// Queue a block into stream `i`; its windows run at the next `run`, `push_all` or
    /// `flush`.
    #[pyo3(signature = (i, x, channels_first=None))]
    fn push(
        &self,
        py: Python<'_>,
        i: usize,
        x: &Bound<'_, PyAny>,
        channels_first: Option<bool>,
    ) -> PyResult<()> {
        let cf = channels_first.unwrap_or(self.channels_first);
        let s = samples(x)?;
        let mut guard = self.lock(py)?;
        let st = &mut *guard;
        let fs = st.group.config().sample_rate_hz;
        let n = channel_count(s.shape(), cf, |c| st.group.check_input(fs, c))?;
        let out = st.outs.get_mut(i).ok_or_else(|| {
            PyValueError::new_err(format!("no stream {i} in a group of {}", st.group.len()))
        })?;
        let g = &mut st.group;
        let b = block(&s, cf, n);
        py.released(|| g.push(i, b, out)).map_err(err)
    }

    /// Run every waiting window of every stream (one launch per batch); returns one result
    /// set per stream.
    fn run<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let mut guard = self.lock(py)?;
        let st = &mut *guard;
        let (g, outs) = (&mut st.group, &mut st.outs);
        py.released(|| g.run(outs)).map_err(err)?;
        take_all(py, st)
    }

    /// One block per stream (a list, in stream order), then one run: the tick of a
    /// server that receives all its arrays' audio in step. Returns one result set per
    /// stream.
    #[pyo3(signature = (blocks, channels_first=None))]
    fn push_all<'py>(
        &self,
        py: Python<'py>,
        blocks: Vec<Bound<'py, PyAny>>,
        channels_first: Option<bool>,
    ) -> PyResult<Bound<'py, PyList>> {
        let cf = channels_first.unwrap_or(self.channels_first);
        let mut guard = self.lock(py)?;
        let st = &mut *guard;
        if blocks.len() != st.group.len() {
            return Err(PyValueError::new_err(format!(
                "{} blocks for {} streams",
                blocks.len(),
                st.group.len()
            )));
        }
        let fs = st.group.config().sample_rate_hz;
        let mut data = Vec::with_capacity(blocks.len());
        for (i, x) in blocks.iter().enumerate() {
            let s = samples(x)?;
            let n = channel_count(s.shape(), cf, |c| st.group.check_input(fs, c))
                .map_err(|e| PyValueError::new_err(format!("stream {i}: {e}")))?;
            data.push((s, n));
        }
        let views: Vec<Block<'_>> = data.iter().map(|(s, n)| block(s, cf, *n)).collect();
        let (g, outs) = (&mut st.group, &mut st.outs);
        py.released(|| g.push_all(&views, outs)).map_err(err)?;
        drop(views);
        take_all(py, st)
    }

    /// End stream `i`'s input: returns its last results (other streams' windows that ran
    /// meanwhile are returned by the next `run` / `push_all`).
    fn flush<'py>(&self, py: Python<'py>, i: usize) -> PyResult<Bound<'py, PyDict>> {
        let mut guard = self.lock(py)?;
        let st = &mut *guard;
        let (g, outs) = (&mut st.group, &mut st.outs);
        // As Localizer.flush: a stream that ended before its first window gives no
        // results and a note (it is ended either way; reset(i) starts it again).
        let short = match py.released(|| g.flush(i, outs)) {
            Err(soundloc::Error::NoWindow(m)) => Some(format!("no results: {m}")),
            r => r.map(|_| None).map_err(err)?,
        };
        let n = st.group.grid().len();
        let mut out = std::mem::take(&mut st.outs[i]);
        out.notes.extend(short);
        results(py, &mut out, n, st.group.config())
    }

    /// Start stream `i` again (same plan and device); its unreturned results are dropped.
    fn reset(&self, py: Python<'_>, i: usize) -> PyResult<()> {
        let mut st = self.lock(py)?;
        st.group.reset(i).map_err(err)?;
        st.outs[i] = Output::default();
        Ok(())
    }

    /// Frames between a result's frame and the last frame of its window.
    #[getter]
    fn latency_frames(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(self.lock(py)?.group.latency_frames())
    }

    /// Samples per channel stream `i` still needs before its next result.
    fn samples_needed_next(&self, py: Python<'_>, i: usize) -> PyResult<usize> {
        self.lock(py)?.group.samples_needed_next(i).map_err(err)
    }

    /// The device description.
    #[getter]
    fn device(&self, py: Python<'_>) -> PyResult<String> {
        Ok(self.lock(py)?.group.device_name())
    }

    /// The algorithm that runs.
    #[getter]
    fn algorithm(&self, py: Python<'_>) -> PyResult<&'static str> {
        Ok(self.lock(py)?.group.config().algorithm.name())
    }

    /// The analysis that runs, every default resolved, as JSON (`soundloc.StreamGroup.config`).
    #[getter]
    fn config_json(&self, py: Python<'_>) -> PyResult<String> {
        serde_json::to_string(self.lock(py)?.group.config())
            .map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))
    }

    /// Analysis sampling rate, Hz.
    #[getter]
    fn fs(&self, py: Python<'_>) -> PyResult<u32> {
        Ok(self.lock(py)?.group.config().sample_rate_hz)
    }

    /// Microphones per array.
    #[getter]
    fn num_mics(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(self.lock(py)?.group.num_mics())
    }

    /// Notes from building.
    #[getter]
    fn notes(&self, py: Python<'_>) -> PyResult<Vec<String>> {
        Ok(self.lock(py)?.group.notes().to_vec())
    }

    /// The grid: (D, 3) unit direction vectors, azimuth and elevation in degrees.
    fn directions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        directions(py, self.lock(py)?.group.grid())
    }
}

impl PyGroup {
    fn lock(&self, py: Python<'_>) -> PyResult<Turn<'_, State>> {
        self.state.lock(py)
    }
}

/// Every stream's unreturned results, as one result dict per stream.
fn take_all<'py>(py: Python<'py>, st: &mut State) -> PyResult<Bound<'py, PyList>> {
    let n = st.group.grid().len();
    let list = PyList::empty(py);
    for o in st.outs.iter_mut() {
        let mut out = std::mem::take(o);
        list.append(results(py, &mut out, n, st.group.config())?)?;
    }
    Ok(list)
}
