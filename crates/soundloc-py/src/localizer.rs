//! `soundloc._native.Localizer`: one stream (see `soundloc.Localizer` in Python).

use crate::spec::PySpec;
use crate::turns::{Turn, Turns};
use crate::Released;
use crate::{channel_count, directions, err, results, samples, Samples};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use soundloc::audio::resample::Resampler;
use soundloc::{Block, Localizer, Output};
use std::path::PathBuf;

/// A stateful localizer (see `soundloc.Localizer` in Python for the arguments).
#[pyclass(module = "soundloc._native", name = "Localizer")]
pub(crate) struct PyLocalizer {
    /// Behind a mutex: a Python object may be used from several threads (the engine is
    /// `Send`, not `Sync`); calls from them take turns in arrival order ([`Turns`]).
    inner: Turns<Localizer>,
    channels_first: bool,
    /// Files the localizer was built from (the TF file, a noise-CM pair or recording):
    /// `localize_file` never writes over them.
    files: Vec<PathBuf>,
    /// The spec, kept while the analysis rate is open (`geometry=` without `fs=`,
    /// [`PySpec::rate_open`]): `localize(x, fs)` and `localize_file` rebuild the
    /// localizer for the audio's rate.
    open_rate: Option<PySpec>,
    /// `geometry=` with `resample=True` and no `fs=`: the analysis runs at 16 kHz and the
    /// audio's rate is unknown: `localize(x)` must name it every time (it converts), a
    /// stream once (its first `push(x, fs)`; `push` does not convert).
    resample_unnamed: bool,
}

#[pymethods]
impl PyLocalizer {
    #[new]
    fn new(py: Python<'_>, spec: &PySpec) -> PyResult<Self> {
        let mut files = Vec::new();
        if let soundloc::ArraySpec::TransferFunctions { path } = &spec.spec.array {
            files.push(path.clone());
        }
        match &spec.spec.noise {
            soundloc::NoiseSource::CorrelationFile { path } => {
                files.extend(soundloc::formats::noise_cm::NoiseCm::files_read(path))
            }
            soundloc::NoiseSource::Recording { path } => files.push(path.clone()),
            _ => {}
        }
        Ok(PyLocalizer {
            inner: Turns::new(spec.localizer(py)?, "localizer"),
            channels_first: spec.channels_first,
            files,
            open_rate: spec.rate_open().then(|| spec.clone()),
            resample_unnamed: spec.resample_rate_unnamed(),
        })
    }

    /// Localize a whole recording: (samples, channels) (or (channels, samples) with
    /// channels_first=True) at `fs` Hz. The stream is reset first.
    #[pyo3(signature = (x, fs=None, channels_first=None))]
    fn localize<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        fs: Option<&Bound<'py, PyAny>>,
        channels_first: Option<bool>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let fs = fs.map(crate::spec_values::rate).transpose()?;
        let channels_first = channels_first.unwrap_or(self.channels_first);
        let s = samples(x)?;
        // One lock throughout: another thread's call cannot come between the reset and
        // the recording.
        let mut guard = self.lock(py)?;
        match fs {
            Some(f) => self.adopt_rate(py, &mut guard, f)?,
            None => self.rate_known("localize(x)", "localize(x, fs)", None)?,
        }
        let loc = &mut *guard;
        let mut out = match converter(loc, &s, fs, channels_first)? {
            None => {
                loc.reset().map_err(err)?;
                run(py, loc, &s, channels_first, true)?
            }
            Some(r) => run_converted(py, loc, &s, channels_first, r)?,
        };
        results(py, &mut out, loc.grid().len(), loc.config())
    }

    /// Localize a WAV/FLAC file and write its results to `output` as the CLI does
    /// (`format` "jsonl" or "csv"; the file is written whole or not at all). Returns the
    /// number of results. The GIL is released throughout.
    #[pyo3(signature = (input, output, format="jsonl"))]
    fn localize_file(
        &self,
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
        if output.as_os_str() == "-" {
            // The CLI's `-o -` is its stdout; a library writing past sys.stdout would be
            // lost in a notebook and mixed with print()'s buffer elsewhere.
            return Err(PyValueError::new_err(
                "output \"-\": localize_file writes a file (the CLI's -o - is its standard output); \
                 for the results in Python use localize(soundloc.read_audio(path)[0], fs)",
            ));
        }
        let files = self.files.clone();
        let mut inner = self.lock(py)?;
        if self.open_rate.is_some() {
            // The recording's rate, from its header, is the rate to analyse at.
            let fs = py
                .released(|| soundloc::audio::open_source(&input).map(|s| s.format().sample_rate_hz))
                .map_err(err)?;
            self.adopt_rate(py, &mut inner, fs)?;
        }
        let loc = &mut *inner;
        let named = |e: soundloc::Error| soundloc::Error::Config(format!("{}: {e}", input.display()));
        let audio = py
            .released(|| -> soundloc::Result<soundloc::audio::Audio> {
                let ins: Vec<(&std::path::Path, &str)> = std::iter::once((input.as_path(), "input"))
                    .chain(files.iter().map(|p| (p.as_path(), "a file of this localizer")))
                    .collect();
                soundloc::output::atomic::check_outputs(&[(&output, "output")], &ins)?;
                let mut audio = soundloc::audio::read_audio(&input)?;
                if let Some(r) = loc
                    .input_converter(audio.sample_rate_hz, audio.num_channels())
                    .map_err(named)?
                {
                    audio = soundloc::audio::resample::resample_audio(&audio, r.rate_out()).map_err(named)?;
                }
                loc.reset()?;
                Ok(audio)
            })
            .map_err(err)?;
        // In pieces, Ctrl-C honoured between them; interrupted, nothing is written.
        let mut out = Output::default();
        push_in_pieces(py, loc, Block::Planar(&audio.channels), &mut out)?;
        py.released(|| -> soundloc::Result<usize> {
            loc.flush(&mut out)?;
            if csv {
                soundloc::output::csv::write_csv_file(&output, &out.results)?;
            } else {
                soundloc::output::jsonl::write_jsonl_file(&output, &out.results)?;
            }
            Ok(out.results.len())
        })
        .map_err(err)
    }

    /// Push a block of any length at `fs` Hz; returns the results its samples completed.
    /// `fs` is checked against the analysis rate; with an open rate
    /// ([`PySpec::rate_open`]) the first push of a stream must name it and the stream
    /// runs at that rate.
    #[pyo3(signature = (x, fs=None, channels_first=None))]
    fn push<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        fs: Option<&Bound<'py, PyAny>>,
        channels_first: Option<bool>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let fs = fs.map(crate::spec_values::rate).transpose()?;
        let s = samples(x)?;
        let mut guard = self.lock(py)?;
        self.stream_rate(py, &mut guard, fs)?;
        let loc = &mut *guard;
        let mut out = run(py, loc, &s, channels_first.unwrap_or(self.channels_first), false)?;
        results(py, &mut out, loc.grid().len(), loc.config())
    }

    /// End of input: results still held (a noise range, the tracker's delay). A stream
    /// that ended before its first window gives no results and says so in a note (a
    /// live capture stopped early is not an error; `localize` of too short a recording
    /// is).
    fn flush<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let mut out = Output::default();
        let mut inner = self.lock(py)?;
        let loc = &mut *inner;
        match py.released(|| loc.flush(&mut out)) {
            Err(soundloc::Error::NoWindow(m)) => out.notes.push(format!("no results: {m}")),
            r => r.map_err(err)?,
        }
        results(py, &mut out, inner.grid().len(), inner.config())
    }

    /// Start a new stream (same plan and device).
    fn reset(&self, py: Python<'_>) -> PyResult<()> {
        self.lock(py)?.reset().map_err(err)
    }

    /// Frames between a result's frame and the last frame of its window.
    #[getter]
    fn latency_frames(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(self.lock(py)?.latency_frames())
    }

    /// Samples per channel still needed before the next result.
    #[getter]
    fn samples_needed_next(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(self.lock(py)?.samples_needed_next())
    }

    /// The device description.
    #[getter]
    fn device(&self, py: Python<'_>) -> PyResult<String> {
        Ok(self.lock(py)?.device_name())
    }

    /// The algorithm that runs.
    #[getter]
    fn algorithm(&self, py: Python<'_>) -> PyResult<&'static str> {
        Ok(self.lock(py)?.config().algorithm.name())
    }

    /// Analysis sampling rate, Hz.
    #[getter]
    fn fs(&self, py: Python<'_>) -> PyResult<u32> {
        Ok(self.lock(py)?.config().sample_rate_hz)
    }

    /// The analysis that runs, every default resolved, as JSON (`soundloc.Localizer.config`).
    #[getter]
    fn config_json(&self, py: Python<'_>) -> PyResult<String> {
        serde_json::to_string(self.lock(py)?.config()).map_err(|e| PyValueError::new_err(e.to_string()))
    }

    /// Microphones used.
    #[getter]
    fn num_mics(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(self.lock(py)?.num_mics())
    }

    /// Notes from building (the algorithm chosen…).
    #[getter]
    fn notes(&self, py: Python<'_>) -> PyResult<Vec<String>> {
        Ok(self.lock(py)?.notes().to_vec())
    }

    /// The grid: (D, 3) unit direction vectors, azimuth and elevation in degrees.
    fn directions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        directions(py, self.lock(py)?.grid())
    }
}

impl PyLocalizer {
    fn lock(&self, py: Python<'_>) -> PyResult<Turn<'_, Localizer>> {
        self.inner.lock(py)
    }

    /// The rate a pushed block is at (`fs`, where `push` names it) against the stream's:
    /// with an open rate ([`PySpec::rate_open`]) a stream's first push may name another
    /// rate and the localizer is rebuilt for it; otherwise (and after the first push)
    /// another rate is refused, naming both. Without `fs` the rate last named stays, and
    /// none named is an error ([`Self::rate_known`]): a 48 kHz block analysed as 16 kHz
    /// audio would give wrong directions without one.
    fn stream_rate(&self, py: Python<'_>, loc: &mut Localizer, fs: Option<u32>) -> PyResult<()> {
        let first = loc.samples_received() == 0;
        let open = self.open_rate.is_some();
        let have = loc.config().sample_rate_hz;
        match fs {
            None => self.rate_known("push(x)", "push(x, fs)", Some(!first)),
            Some(f) if open && first => self.adopt_rate(py, loc, f),
            Some(f) if f != have => Err(PyValueError::new_err(if open {
                format!(
                    "push(fs={f}): this stream runs at {have} Hz, its first block's rate; call reset() \
                     to start a stream at another rate"
                )
            } else {
                format!(
                    "push(fs={f}): the localizer analyses {have} Hz audio; push audio at that rate \
                     (localize(x, fs) converts whole recordings with resample=True)"
                )
            })),
            Some(_) => Ok(()),
        }
    }

    /// With an open rate ([`PySpec::rate_open`]), the localizer rebuilt for audio at
    /// `fs` Hz when it analyses another rate (the stream starts anew, as `localize` and
    /// `localize_file` start it anyway).
    fn adopt_rate(&self, py: Python<'_>, loc: &mut Localizer, fs: u32) -> PyResult<()> {
        if let Some(spec) = self.open_rate.as_ref().and_then(|s| s.at_rate(fs)) {
            if loc.config().sample_rate_hz != fs {
                *loc = spec.localizer(py)?;
            }
        }
        Ok(())
    }

    /// A call (`what`) without the audio's rate: refused while the rate is open
    /// ([`PySpec::rate_open`]) or with `resample=True` and no `fs=`
    /// ([`PyLocalizer::resample_unnamed`]), except for a push that continues a stream
    /// (`stream`: `Some(true)`; its first push named the rate). `localize(x)` starts a new
    /// recording, so it names its rate every time (`stream`: `None`): the previous
    /// recording's would be a guess. Free-field transfer functions are made for the rate,
    /// so a guess gives wrong directions silently. `with` is the call that names it.
    fn rate_known(&self, what: &str, with: &str, stream: Option<bool>) -> PyResult<()> {
        if (self.open_rate.is_none() && !self.resample_unnamed) || stream == Some(true) {
            return Ok(());
        }
        if self.resample_unnamed {
            let how = if stream.is_some() {
                "a stream's first push names it (16000 Hz, the rate the analysis runs at: push does not convert)"
            } else {
                "it is converted to the 16000 Hz the analysis runs at"
            };
            return Err(PyValueError::new_err(format!(
                "{what}: the audio's sampling rate is not known (resample=True, geometry= without fs=): \
                 call {with}; {how}. fs= to Localizer() sets the analysis rate. A guess would give wrong \
                 directions for audio at another rate"
            )));
        }
        let each = if stream.is_some() {
            "a stream's first push names it"
        } else {
            "each recording names its own: the previous one's is not assumed"
        };
        Err(PyValueError::new_err(format!(
            "{what}: the audio's sampling rate is not known (geometry= without fs=): pass fs= to \
             Localizer(), or call {with}; {each} (free-field transfer functions are made for that \
             rate; a guess would give wrong directions for audio at another)"
        )))
    }
}

/// How audio at `fs` Hz reaches `loc`: as it is (`None`), through a converter
/// (`resample=True` and another rate), or an error naming both rates.
fn converter(
    loc: &Localizer,
    s: &Samples<'_>,
    fs: Option<u32>,
    channels_first: bool,
) -> PyResult<Option<Resampler>> {
    let want = loc.config().sample_rate_hz;
    match fs {
        Some(f) if f != want => {
            let n_ch = channel_count(s.shape(), channels_first, |c| loc.check_input(want, c))?;
            loc.input_converter(f, n_ch).map_err(err)
        }
        _ => Ok(None),
    }
}

/// A whole recording through `r`: reset, convert, push, flush.
fn run_converted(
    py: Python<'_>,
    loc: &mut Localizer,
    s: &Samples<'_>,
    channels_first: bool,
    mut r: Resampler,
) -> PyResult<Output> {
    let [rows, cols] = s.shape();
    let n_ch = if channels_first { rows } else { cols };
    let block = block_of(s.data(), n_ch, channels_first);
    let mut out = Output::default();
    let conv = py
        .released(|| -> soundloc::Result<Vec<f32>> {
            let mut inter = Vec::new();
            block.append_interleaved(&mut inter)?;
            let mut conv = Vec::new();
            r.process(&inter, &mut conv)?;
            r.finish(&mut conv)?;
            loc.reset()?;
            Ok(conv)
        })
        .map_err(err)?;
    push_in_pieces(py, loc, block_of(&conv, n_ch, false), &mut out)?;
    py.released(|| loc.flush(&mut out)).map_err(err)?;
    Ok(out)
}

/// Push `s` (and flush after it when `flush`), with the GIL released.
fn run(
    py: Python<'_>,
    loc: &mut Localizer,
    s: &Samples<'_>,
    channels_first: bool,
    flush: bool,
) -> PyResult<Output> {
    let fs = loc.config().sample_rate_hz;
    let n_ch = channel_count(s.shape(), channels_first, |c| loc.check_input(fs, c))?;
    let mut out = Output::default();
    push_in_pieces(py, loc, block_of(s.data(), n_ch, channels_first), &mut out)?;
    if flush {
        py.released(|| loc.flush(&mut out)).map_err(err)?;
    }
    Ok(out)
}

/// Wall time a piece of [`push_in_pieces`] may take before the next is not made larger.
const PIECE_SECONDS: f64 = 0.25;

/// `loc.push(block)`, in pieces with the GIL released, Ctrl-C honoured between them: a
/// `KeyboardInterrupt` (or another signal handler's exception) stops a long call within
/// about [`PIECE_SECONDS`] instead of after the whole block. Pieces start at one second
/// of audio and double while one takes less than that (a device's batches stay large);
/// the results equal one push's. The block is checked whole first, so a bad sample
/// anywhere in it leaves the stream as it was. Interrupted, the stream holds the pieces
/// pushed so far and their results are dropped with the call.
fn push_in_pieces(py: Python<'_>, loc: &mut Localizer, block: Block<'_>, out: &mut Output) -> PyResult<()> {
    loc.check_block(&block).map_err(err)?;
    let total = block.samples().map_err(err)?;
    let mut piece = (loc.config().sample_rate_hz as usize).max(1);
    let mut scratch = Vec::new();
    let mut start = 0usize;
    loop {
        let end = total.min(start.saturating_add(piece));
        let t = std::time::Instant::now();
        py.released(|| loc.push(block.range(start..end, &mut scratch), out))
            .map_err(err)?;
        start = end;
        if start >= total {
            return Ok(());
        }
        py.check_signals()?;
        if t.elapsed().as_secs_f64() < PIECE_SECONDS {
            piece = piece.saturating_mul(2);
        }
    }
}

/// A view of (samples, channels) or, channels first, (channels, samples) data.
fn block_of(data: &[f32], channels: usize, channels_first: bool) -> Block<'_> {
    if channels_first {
        Block::ChannelsFirst { data, channels }
    } else {
        Block::Interleaved { data, channels }
    }
}
