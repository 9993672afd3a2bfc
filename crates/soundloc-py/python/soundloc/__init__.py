"""soundloc: sound source localization for microphone arrays (SEVD/GEVD/GSVD-MUSIC).

    import soundloc, soundfile
    x, fs = soundfile.read("rec.wav", dtype="int16")        # (samples, channels)
    loc = soundloc.Localizer(tf="tamago_rectf.zip", noise_range=(0.0, 1.0))
    res = loc.localize(x, fs)
    res.azimuth_deg        # (results, sources), NaN where a window has fewer sources
    res.spectrum_db        # (results, directions); loc.directions()["azimuth_deg"]

Streaming: ``loc.push(block, fs)`` returns the results that block completed (``fs`` is
checked against the analysis rate; with geometry= and no fs= to Localizer the stream's
first push must name it); ``loc.flush()`` at the end (no results and a note when the
stream ended before its first window); ``loc.reset()`` starts a new stream. Many arrays on one device:
``soundloc.StreamGroup(n, **same arguments)`` and ``g.push_all([block_0, ..., block_n-1])``.

Long calls honour Ctrl-C (KeyboardInterrupt within a fraction of a second; an interrupted
localize_file writes nothing). Processes forked after soundloc was used (multiprocessing's
fork start method, ProcessPoolExecutor) work: each gets a thread pool of its own.

HARK files as numpy: read_tf / write_tf (transfer-function zips), read_noise_cm /
write_noise_cm (noise correlation matrices, zip or text pair), read_source_log /
write_source_log (source-location logs, text or XML), read_audio (WAV/FLAC; headerless PCM
with raw="s16le"|"s24le"|"s32le"|"f32le"|"f64le"|"u8", channels= and fs=).

Arguments (HARK LocalizeMUSIC name / pyroomacoustics name):
    tf: HARK transfer-function zip or HGTF file; or geometry: (M, 3) mic positions in metres
        (pyroomacoustics' ``L`` transposed; (M, 2) for a planar array, z = 0), or a geometry file (TOML, or an ODAS
        configuration ``*.cfg``, whose mapping.map picks the microphones among the device's
        raw.nChannels channels) with grid: "ring:STEP_DEG[:ELEV]", "sphere:N", "hemisphere:N" (the N directions above the horizontal plane) or
        a (D, 3) array of unit directions, grid_radius (metres, default 1) and
        speed_of_sound (m/s, default 343); fs (SAMPLING_RATE, for geometry=; without it
        the rate each localize(x, fs) or localize_file's header names, or the first
        push(x, fs) of each stream (never the previous recording's); StreamGroup needs it; with tf= the file's rate, and another one is an error). Directions are seen from the origin of
        the positions' frame, or from the microphones' centroid when that origin lies
        outside the array (room coordinates, as pyroomacoustics' ``L``).
    algorithm: "sevd" | "gevd" | "gevd-hark" | "gsvd" | "srp-phat" (MUSIC_ALGORITHM); default
        (None): without a noise source the room default (NormMUSIC: sevd with every bin
        normalised, subspace min(M/2, round(2√M)), coherence, refinement), with one the robust gevd
        (subspace max(num_sources, M/2), numerator ‖a‖·‖a_w‖, refinement); a named algorithm
        runs as HARK's.
    subspace_dim (signal subspace when it should differ from num_sources), normalize_bins
        (NormMUSIC) and refine (sub-grid peak directions): None = the default's choice (both
        on in the room default, refine in the robust one, off for a named algorithm), True or
        False whatever the algorithm; subspace_tracking (approximate
        streaming mode on the CPU: leading vectors tracked between windows; no source count),
        coherence (True/False: the channels' gains taken from the recording, so the
        microphones' gain mismatch cancels: sevd scales every window's R to a unit diagonal,
        the textbook gevd gives the steering vectors K's channel levels; None: on in the
        room default, off otherwise; with a noise source, True suits an uncalibrated array
        with geometric transfer functions), numerator (the textbook gevd's spectrum numerator:
        "raw" ‖a‖² as spec §5, where a loud noise source that K holds shows as a peak at
        its own strength; "whitened" ‖a_w‖² = aᴴK⁻¹a, which flattens it; "geometric"
        ‖a‖·‖a_w‖; None: geometric in the robust default, raw with algorithm="gevd"),
        onset_frames (onset weighting: each frame of each bin counts in the correlation by
        ((r − 1)/r)² for r > 1, else 0, r its power against its average over about that many
        frames before it — the whitened power xᴴK⁻¹x for gevd, gevd-hark and gsvd, else each
        microphone's against its own, averaged, so gains cancel — so a talker's onsets
        count and the reverberation after them does not; 0 = off as in
        HARK; None: 10 when no algorithm is named, except with noise_preceding; not for
        srp-phat).
    num_sources (NUM_SOURCE; num_src= is accepted as pyroomacoustics' name), max_peaks (MAXNUM_OUT_PEAKS), window (WINDOW, frames),
    period (PERIOD), window_type "past"|"middle"|"future" (WINDOW_TYPE), freq_range
        (LOWER/UPPER_BOUND_FREQUENCY, Hz; pyroomacoustics' freq_range), nfft (LENGTH),
        hop (ADVANCE): 512 and 160 samples, with geometry= 32 and 10 ms of the rate (the
        same at 16 kHz, 1536 and 480 at 48 kHz).
    noise: (samples, channels) noise-only array; noise_range: (t0, t1) seconds of the input;
        noise_cm: HARK noise-CM file; noise_segments ([(t0, t1), ...] seconds) /
        noise_preceding (FRAMES or (FRAMES, GAP): K from the FRAMES frames ending GAP frames
        before each window): online K updates.
    track: SourceTracker ids, with tracker_thresh_db (THRESH), tracker_pause_length
        (PAUSE_LENGTH, in tenths of a frame as HARK's: 800 keeps a silent source 80 frames),
        tracker_min_src_interval_deg (MIN_SRC_INTERVAL), tracker_min_id
        (MIN_ID) and preroll (SourceIntervalExtender's PREROLL_LENGTH, frames; delays results);
        track_active_only (each window feeds the tracker its strongest num_active peaks,
        none when 0, so silence
        starts no tracks; None: on in the room default, whose powers do not tell silence from
        talkers, off otherwise as HARK); tracker_confirm_frames (a new source gets its id
        once seen over this many frames; None: the window length when no algorithm is
        named, 0 = at once, as HARK, with one); as the CLI's --thresh, --pause-length,
        --min-src-interval, --min-id, --preroll, --active-only/--no-active-only, --confirm.
    min_deg, max_deg (MIN_DEG, MAX_DEG: the azimuth range kept, degrees); window_function
        "conj"|"hamming"|"hanning"|"rectangle" (MultiFFT WINDOW); eigenvalue_weight
        (ENABLE_EIGENVALUE_WEIGHT, True); spectrum_weight "uniform"|"a-weighting" or one
        weight per used bin (SPECTRUM_WEIGHT_TYPE, manual weights); denominator
        "squared"|"unsquared": as the CLI's --min-deg, --max-deg, --window-function,
        --eigenvalue-weight, --spectrum-weight(s), --denominator.
    device: "auto"|"cpu"|"cuda"; precision: "f32"|"f64".
    channels (TF_CHANNEL_SELECTION), input_channels (ChannelSelector); diagonal_loading: K + δ·(tr K / M)·I
        (a K that is not positive definite is otherwise an error).
    invert_channels: input channels (0-based, as the input checks' notes name them) whose
        samples are negated, for microphones wired with their polarity inverted; applied
        to the audio and to noise= (a noise_cm= file is taken as it is); the CLI's
        --invert-channels.
    channels_first: arrays are (channels, samples) instead of (samples, channels).
    resample: audio given to localize(x, fs) or localize_file at another rate than the
        analysis's (e.g. 48 kHz with a 16 kHz TF file) is converted instead of refused
        (band-limited, no delay added); push() takes blocks at the analysis rate (``loc.fs``).
        With geometry= and no fs= the analysis runs at 16 kHz and every localize(x) must
        name its audio's rate (a stream's first push(x, fs) names it once).

Errors: ValueError (bad input or configuration), TypeError (an argument of the wrong type,
e.g. a complex array as audio), OSError (files), RuntimeError (device).
"""

import json
import warnings
from dataclasses import dataclass, field
from typing import List, Optional

import numpy as np

from ._native import Localizer as _Native, StreamGroup as _Group, spec as _spec, __version__
from ._native import read_audio, read_noise_cm, read_tf, write_tf
from ._native import write_noise_cm as _write_noise_cm
from ._native import read_source_log_json as _read_source_log_json
from ._native import write_source_log_json as _write_source_log_json
from . import archive, doa

__all__ = ["Localizer", "Results", "StreamGroup", "archive", "doa", "read_audio", "read_noise_cm",
           "read_source_log", "read_tf", "write_noise_cm", "write_source_log", "write_tf", "__version__"]


def read_source_log(path, frame_period_s=0.01):
    """A HARK source-location log (text or XML) as a list of results: dicts with frame,
    time_s (frame × frame_period_s: HARK's 160 samples at 16 kHz unless given) and sources
    (azimuth_deg, elevation_deg, x, y, z, power_db, id: None where the log has none or -1;
    grid_index None: logs do not hold it)."""
    import json

    records = [json.loads(line) for line in _read_source_log_json(str(path), frame_period_s)]
    for r in records:
        for s in r["sources"]:
            s["grid_index"] = None
            s.setdefault("id", None)
    return records


def write_noise_cm(path, k, format=None):
    """Write noise correlation matrices ``k`` (nfft/2 + 1, M, M) complex as HARK's zip
    (>= 2.1, values rounded to f32) or text pair (<= 2.0; "K" gives K_r and K_i);
    ``format`` "zip" | "text", or None: zip when the path ends in .zip. Returns the paths
    written (pathlib.Path)."""
    from pathlib import Path

    return [Path(p) for p in _write_noise_cm(str(path), k, format)]


def write_source_log(path, results, format=None):
    """Write results as a HARK source-location log: ``format`` "text" (HARK <= 2.0, one line
    per frame: frame, then id x y z per source) or "xml" (HARK >= 2.1), or None: xml when the
    path ends in .xml. ``results``: a :class:`Results` (sources as unit vectors from their
    azimuth and elevation) or a list of result dicts as :func:`read_source_log` returns."""
    import json

    if format is None:
        format = "xml" if str(path).lower().endswith(".xml") else "text"
    records = results.to_records() if isinstance(results, Results) else results
    # The logs hold neither grid indices nor missing ids: absent values are left out.
    def plain(r):
        sources = [{k: v for k, v in s.items() if not (k in ("grid_index", "id") and v is None)}
                   for s in r["sources"]]
        for s in sources:
            s.setdefault("grid_index", 0)
        return dict(r, sources=sources)

    _write_source_log_json(str(path), [json.dumps(plain(r)) for r in records], format)


@dataclass
class Results:
    """Results of some windows, as numpy arrays."""

    frames: np.ndarray
    times: np.ndarray
    azimuth_deg: np.ndarray
    elevation_deg: np.ndarray
    power_db: np.ndarray
    grid_index: np.ndarray
    ids: np.ndarray
    spectrum_db: Optional[np.ndarray]
    notes: List[str] = field(default_factory=list)
    # The estimated number of active sources per result (MDL; -1 where not estimated).
    num_active: Optional[np.ndarray] = None
    # Tracked sources carried through their pause (PAUSE_LENGTH) without being observed in
    # that window, at their last direction and power (as HARK's SourceTracker outputs
    # them), or copied before their first observation by preroll=; shape of ids, False
    # where not tracked or observed.
    held: Optional[np.ndarray] = None

    def __len__(self) -> int:
        return len(self.times)

    @staticmethod
    def concatenate(parts) -> "Results":
        """The results of several pushes (or flushes) as one, in order: arrays padded to
        the widest part (NaN / -1), spectrum rows joined (None when no part has any)."""
        parts = list(parts)
        width = max((p.azimuth_deg.shape[1] for p in parts if p.azimuth_deg.ndim == 2), default=0)

        def cat(name, fill, dtype):
            rows = []
            for p in parts:
                a = getattr(p, name)
                pad = np.full((len(p), width - a.shape[1]), fill, dtype=dtype)
                rows.append(np.hstack([a.astype(dtype), pad]))
            return np.concatenate(rows) if rows else np.zeros((0, width), dtype=dtype)

        spectra = [p.spectrum_db for p in parts if p.spectrum_db is not None and len(p.spectrum_db)]
        return Results(
            frames=np.concatenate([p.frames for p in parts] or [np.zeros(0, dtype=np.int64)]),
            times=np.concatenate([p.times for p in parts] or [np.zeros(0)]),
            azimuth_deg=cat("azimuth_deg", np.nan, float),
            elevation_deg=cat("elevation_deg", np.nan, float),
            power_db=cat("power_db", np.nan, float),
            grid_index=cat("grid_index", -1, np.int64),
            ids=cat("ids", -1, np.int64),
            held=cat("held", False, bool) if all(p.held is not None for p in parts) else None,
            spectrum_db=np.concatenate(spectra) if spectra else None,
            notes=[n for p in parts for n in p.notes],
            num_active=np.concatenate([p.num_active if p.num_active is not None else np.full(len(p), -1)
                                       for p in parts] or [np.zeros(0, dtype=np.int64)]).astype(np.int64),
        )

    def to_records(self) -> list:
        """One dict per result, as ``soundloc localize`` writes JSON lines: frame, time_s,
        sources (id, grid_index, azimuth_deg, elevation_deg, x, y, z as a unit vector,
        power_db, held where true), num_active where estimated."""
        out = []
        for i in range(len(self.times)):
            sources = []
            for j in range(self.azimuth_deg.shape[1]):
                az, el = self.azimuth_deg[i, j], self.elevation_deg[i, j]
                if np.isnan(az):
                    continue
                a, e = np.radians(az), np.radians(el)
                sources.append(dict(
                    id=None if self.ids[i, j] < 0 else int(self.ids[i, j]),
                    grid_index=int(self.grid_index[i, j]),
                    azimuth_deg=float(az), elevation_deg=float(el),
                    x=float(np.cos(e) * np.cos(a)), y=float(np.cos(e) * np.sin(a)), z=float(np.sin(e)),
                    power_db=float(self.power_db[i, j]),
                ))
                if self.held is not None and self.held[i, j]:
                    sources[-1]["held"] = True
            rec = dict(frame=int(self.frames[i]), time_s=float(self.times[i]), sources=sources)
            if self.num_active is not None and self.num_active[i] >= 0:
                rec["num_active"] = int(self.num_active[i])
            out.append(rec)
        return out

    def to_pandas(self):
        """One row per (result, source): frame, time_s, rank, id, azimuth_deg, elevation_deg,
        power_db, grid_index, held (True for a tracked source carried through its pause),
        num_active (the window's estimated count, None where not estimated). Unlike the
        CLI's CSV, a window without sources has no row (it is in ``frames`` and ``times``)."""
        import pandas as pd

        rows = []
        for i in range(len(self.times)):
            for j in range(self.azimuth_deg.shape[1]):
                if np.isnan(self.azimuth_deg[i, j]):
                    continue
                rows.append(
                    dict(
                        frame=int(self.frames[i]),
                        time_s=float(self.times[i]),
                        rank=j,
                        id=None if self.ids[i, j] < 0 else int(self.ids[i, j]),
                        azimuth_deg=float(self.azimuth_deg[i, j]),
                        elevation_deg=float(self.elevation_deg[i, j]),
                        power_db=float(self.power_db[i, j]),
                        grid_index=int(self.grid_index[i, j]),
                        held=bool(self.held is not None and self.held[i, j]),
                        num_active=None if self.num_active is None or self.num_active[i] < 0
                        else int(self.num_active[i]),
                    )
                )
        # The columns are there without rows too (a push that completed no window,
        # silence), so df.power_db and df[df.power_db > x] work either way.
        columns = ["frame", "time_s", "rank", "id", "azimuth_deg", "elevation_deg", "power_db",
                   "grid_index", "held", "num_active"]
        return pd.DataFrame(rows, columns=columns)


# Arguments that are counts or indices (unsigned in the library).
_COUNTS = {"num_sources", "window", "period", "nfft", "hop", "channels", "input_channels",
           "invert_channels",
           "subspace_dim", "preroll", "noise_preceding", "tracker_confirm_frames", "onset_frames"}


# Arguments that are flags: True/False, also as numpy bools or the integers 0 and 1.
_FLAGS = {"track", "track_active_only", "spectrum", "channels_first", "normalize_bins", "refine",
          "subspace_tracking", "resample", "coherence", "eigenvalue_weight"}


def _flag(name, v):
    """A flag's value as bool (None stays None); anything but a bool, a numpy bool, 0 or 1
    is a TypeError naming the argument."""
    if v is None or isinstance(v, bool):
        return v
    if isinstance(v, np.bool_):
        return bool(v)
    if isinstance(v, (int, np.integer)) and v in (0, 1):
        return bool(v)
    raise TypeError(f"{name}= must be True or False, got {v!r}")


def _array(x):
    """x as a numpy array where it is another array-like (a CPU tensor, a memoryview, an
    array of another library: anything with ``__array__`` or the buffer protocol), or as
    it is (a numpy array, or something the binding will name as wrong)."""
    if isinstance(x, np.ndarray) or x is None or isinstance(x, (str, bytes, int, float)):
        return x
    if hasattr(x, "__array__") or isinstance(x, memoryview):
        return np.asarray(x)
    return x


# Arguments that are arrays: other array-likes are taken through numpy.
_ARRAYS = {"noise", "geometry"}


# pyroomacoustics' names for the same arguments (its DOA constructors' num_src and c).
_ALIASES = {"num_src": "num_sources", "c": "speed_of_sound"}


def _spec_of(kwargs):
    for alias, name in _ALIASES.items():
        if alias in kwargs:
            if name in kwargs:
                raise TypeError(f"{alias}= and {name}= name the same argument: give one")
            kwargs = {(name if k == alias else k): v for k, v in kwargs.items()}
    kwargs = {k: (_flag(k, v) if k in _FLAGS else _array(v) if k in _ARRAYS else v)
              for k, v in kwargs.items()}
    # A negative count or index is a bad value, not a numeric overflow.
    try:
        return _spec(**kwargs)
    except TypeError as e:
        # The binding's keyword function is an implementation detail: name the class.
        raise TypeError(str(e).replace("spec()", "Localizer()")) from None
    except OverflowError as e:
        def out_of_range(v):
            if isinstance(v, (list, tuple)):
                return any(out_of_range(x) for x in v)
            return isinstance(v, int) and not isinstance(v, bool) and not 0 <= v < 2 ** 63
        bad = [k for k, v in kwargs.items() if k in _COUNTS and out_of_range(v)]
        what = ", ".join(bad) or "a count or index"
        raise ValueError(f"{what}: must be a non-negative integer in range ({e})") from None


# copy.copy would share one stream's state between two objects.
_NO_COPY = ("a {0} cannot be copied: it holds one stream's state (and a device's plan); "
            "make another with the same arguments, soundloc.{0}(**kwargs), for a new stream")


def _warn(notes):
    """The set-up's warnings (positions that look like millimetres, a grid radius inside
    the array, an implausible speed of sound, ...) through Python's warnings; every note
    stays in ``.notes``."""
    for n in notes:
        if n.startswith("warning: "):
            warnings.warn(n[len("warning: "):], UserWarning, stacklevel=3)


class Localizer:
    """A stateful localizer; see the module docstring for the arguments."""

    def __init__(self, **kwargs):
        spec = _spec_of(kwargs)
        self._spec_json = spec.to_json()
        self._n = _Native(spec)
        _warn(self._n.notes)

    def localize(self, x, fs=None, channels_first=None) -> Results:
        """Localize a whole recording (the stream is reset first)."""
        return Results(**self._n.localize(_array(x), fs=fs, channels_first=_flag("channels_first", channels_first)))

    def localize_file(self, input, output, format="jsonl") -> int:
        """Localize a WAV/FLAC file and write its results as ``soundloc localize -o`` does
        (``format`` "jsonl" or "csv", whole or not at all); returns the number of results."""
        return self._n.localize_file(str(input), str(output), format)

    def push(self, block, fs=None, channels_first=None) -> Results:
        """Push a block of any length (at ``fs`` Hz: checked, and named on a stream's
        first push where the rate is open); returns the results it completed."""
        return Results(**self._n.push(_array(block), fs=fs, channels_first=_flag("channels_first", channels_first)))

    def flush(self) -> Results:
        """End of input: the results still held."""
        return Results(**self._n.flush())

    def reset(self) -> None:
        """Start a new stream."""
        self._n.reset()

    def directions(self) -> dict:
        """The grid: unit vectors (D, 3), azimuth_deg (D,), elevation_deg (D,)."""
        return self._n.directions()

    def spec_json(self) -> str:
        """The library's spec (Rust's ``soundloc::LocalizerSpec``, serde JSON) as given:
        options left out stay out, so the defaults that depend on the array and the noise
        source are chosen again wherever it is read. What they resolved to: :meth:`config`."""
        return self._spec_json

    def config(self) -> dict:
        """The analysis that runs, every default resolved: the algorithm (the robust
        default's GEVD, the room default's SEVD), subspace_dim, normalize_bins, refine,
        numerator, onset_frames, the frame sizes and the used band. Where the rate is open
        (``geometry=`` without ``fs=``) the rate and frame sizes are the stream's once its
        first block has named its rate."""
        return json.loads(self._n.config_json)

    def __copy__(self):
        raise TypeError(_NO_COPY.format("Localizer"))

    def __deepcopy__(self, memo):
        raise TypeError(_NO_COPY.format("Localizer"))

    def __getattr__(self, name):
        # latency_frames, samples_needed_next, device, algorithm, fs, num_mics, notes.
        # Only called for names not found; _n itself missing (an object made without
        # __init__, e.g. by pickle) is an AttributeError, not a recursion.
        if name == "_n" or (name.startswith("__") and name.endswith("__")):
            raise AttributeError(name)
        return getattr(self._n, name)


class StreamGroup:
    """Streams of several arrays of one kind, localized together: one plan, one device,
    the windows of all streams in one batch (one GPU launch serves every array).

        g = soundloc.StreamGroup(4, tf="tf.zip", noise_cm="k.zip")
        for blocks in capture():               # one (samples, channels) block per array
            for i, r in enumerate(g.push_all(blocks)):
                ...                            # r: Results of array i

    Takes :class:`Localizer`'s arguments; the noise matrix is shared, so it must be given
    up front (``noise=`` array, ``noise_cm=``), not as ``noise_range=`` or online updates.
    Each stream's results equal those of its own :class:`Localizer`.
    """

    def __init__(self, streams, **kwargs):
        if int(streams) < 1:
            raise ValueError(f"streams must be at least 1, got {streams}")
        self._n = _Group(_spec_of(kwargs), int(streams))
        _warn(self._n.notes)

    def __len__(self):
        return len(self._n)

    def add_stream(self) -> int:
        """Add a stream like the others; returns its index."""
        return self._n.add_stream()

    def push(self, i, block, channels_first=None) -> None:
        """Queue a block into stream ``i``; its windows run at the next run/push_all/flush."""
        self._n.push(self._index(i), _array(block), channels_first=_flag("channels_first", channels_first))

    def run(self) -> List[Results]:
        """Run every waiting window; one :class:`Results` per stream."""
        return [Results(**r) for r in self._n.run()]

    def push_all(self, blocks, channels_first=None) -> List[Results]:
        """One block per stream (in stream order), then one run; one :class:`Results` per stream."""
        return [Results(**r) for r in self._n.push_all([_array(b) for b in blocks], channels_first=_flag("channels_first", channels_first))]

    def flush(self, i) -> Results:
        """End stream ``i``'s input: its last results."""
        return Results(**self._n.flush(self._index(i)))

    def reset(self, i) -> None:
        """Start stream ``i`` again."""
        self._n.reset(self._index(i))

    def _index(self, i):
        if int(i) != i or not 0 <= int(i) < len(self):
            raise ValueError(f"no stream {i} in a group of {len(self)}")
        return int(i)

    def directions(self) -> dict:
        """The grid: unit vectors (D, 3), azimuth_deg (D,), elevation_deg (D,)."""
        return self._n.directions()

    def config(self) -> dict:
        """The analysis that runs, every default resolved (as :meth:`Localizer.config`)."""
        return json.loads(self._n.config_json)

    def __copy__(self):
        raise TypeError(_NO_COPY.format("StreamGroup"))

    def __deepcopy__(self, memo):
        raise TypeError(_NO_COPY.format("StreamGroup"))

    def __getattr__(self, name):
        # latency_frames, samples_needed_next(i), device, algorithm, fs, num_mics, notes.
        # Only called for names not found; _n itself missing (an object made without
        # __init__, e.g. by pickle) is an AttributeError, not a recursion.
        if name == "_n" or (name.startswith("__") and name.endswith("__")):
            raise AttributeError(name)
        return getattr(self._n, name)
