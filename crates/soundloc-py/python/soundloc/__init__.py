"""soundloc: sound source localization for microphone arrays (SEVD/GEVD/GSVD-MUSIC).

    import soundloc, soundfile
    x, fs = soundfile.read("rec.wav", dtype="int16")        # (samples, channels)
    loc = soundloc.Localizer(tf="tamago_rectf.zip", noise_range=(0.0, 1.0))
    res = loc.localize(x, fs)
    res.azimuth_deg        # (results, sources), NaN where a window has fewer sources
    res.spectrum_db        # (results, directions); loc.directions()["azimuth_deg"]

Streaming: ``loc.push(block)`` returns the results that block completed; ``loc.flush()``
at the end; ``loc.reset()`` starts a new stream.

Arguments (HARK LocalizeMUSIC name / pyroomacoustics name):
    tf: HARK transfer-function zip or HGTF file; or geometry: (M, 3) mic positions in metres
        (pyroomacoustics' ``L`` transposed) with grid: "ring:STEP_DEG[:ELEV]", "sphere:N" or
        a (D, 3) array of unit directions; fs (SAMPLING_RATE, for geometry=).
    algorithm: "sevd" | "gevd" | "gevd-hark" | "gsvd" | "srp-phat" (MUSIC_ALGORITHM); default
        sevd, or the robust gevd (subspace num_sources+2, refinement) when a noise source is given.
    subspace_dim (signal subspace when it should differ from num_sources), normalize_bins
        (NormMUSIC), refine (sub-grid peak directions).
    num_sources (NUM_SOURCE / num_src), max_peaks (MAXNUM_OUT_PEAKS), window (WINDOW, frames),
    period (PERIOD), window_type "past"|"middle"|"future" (WINDOW_TYPE), freq_range
        (LOWER/UPPER_BOUND_FREQUENCY, Hz; pyroomacoustics' freq_range), nfft (LENGTH),
        hop (ADVANCE).
    noise: (samples, channels) noise-only array; noise_range: (t0, t1) seconds of the input;
        noise_cm: HARK noise-CM file; noise_segments / noise_preceding: online K updates.
    track: SourceTracker ids; device: "auto"|"cpu"|"cuda"; precision: "f32"|"f64".
    channels (TF_CHANNEL_SELECTION), input_channels (ChannelSelector).
    channels_first: arrays are (channels, samples) instead of (samples, channels).

Errors: ValueError (bad input or configuration), OSError (files), RuntimeError (device).
"""

from dataclasses import dataclass, field
from typing import List, Optional

import numpy as np

from ._native import Localizer as _Native, __version__, read_audio, read_noise_cm, read_tf
from ._native import read_source_log_json as _read_source_log_json
from . import archive, doa

__all__ = ["Localizer", "Results", "archive", "doa", "read_audio", "read_noise_cm", "read_source_log",
           "read_tf", "__version__"]


def read_source_log(path, frame_period_s=0.01):
    """A HARK source-location log (text or XML) as a list of results: dicts with frame,
    time_s and sources (azimuth_deg, elevation_deg, x, y, z, power_db, id)."""
    import json

    return [json.loads(line) for line in _read_source_log_json(str(path), frame_period_s)]


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

    def __len__(self) -> int:
        return len(self.times)

    def to_pandas(self):
        """One row per (result, source): frame, time_s, rank, id, azimuth_deg, elevation_deg, power_db."""
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
                    )
                )
        return pd.DataFrame(rows)


class Localizer:
    """A stateful localizer; see the module docstring for the arguments."""

    def __init__(self, **kwargs):
        self._n = _Native(**kwargs)

    def localize(self, x, fs=None, channels_first=None) -> Results:
        """Localize a whole recording (the stream is reset first)."""
        return Results(**self._n.localize(x, fs=fs, channels_first=channels_first))

    def localize_file(self, input, output, format="jsonl") -> int:
        """Localize a WAV/FLAC file and write its results as ``soundloc localize -o`` does
        (``format`` "jsonl" or "csv", whole or not at all); returns the number of results."""
        return self._n.localize_file(str(input), str(output), format)

    def push(self, block, channels_first=None) -> Results:
        """Push a block of any length; returns the results it completed."""
        return Results(**self._n.push(block, channels_first=channels_first))

    def flush(self) -> Results:
        """End of input: the results still held."""
        return Results(**self._n.flush())

    def reset(self) -> None:
        """Start a new stream."""
        self._n.reset()

    def directions(self) -> dict:
        """The grid: unit vectors (D, 3), azimuth_deg (D,), elevation_deg (D,)."""
        return self._n.directions()

    def __getattr__(self, name):
        # latency_frames, samples_needed_next, device, algorithm, fs, num_mics, notes
        return getattr(self._n, name)
