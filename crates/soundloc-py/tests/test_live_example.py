"""The sounddevice live example (examples/live_sounddevice.py), driven by a stand-in for
PortAudio that plays a synthetic scene through the same callback interface: its results
equal a whole-array run on the same audio. With a real capture device and the
sounddevice package the example also runs for a second against it."""

import importlib.util
import io
import threading
from pathlib import Path

import numpy as np
import pytest

import soundloc

from test_localizer import FS, MICS, TALKERS, angle, scene

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "live_sounddevice.py"


def load_example():
    spec = importlib.util.spec_from_file_location("live_sounddevice", EXAMPLE)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


class FakeSoundDevice:
    """sounddevice.InputStream's callback contract over a recording: float32 blocks of
    `blocksize` frames from a PortAudio-like thread."""

    def __init__(self, audio):
        self.audio = audio.astype(np.float32)
        self.opened = []

    def query_devices(self):
        return "0 fake array, 8 in, 0 out"

    def InputStream(self, samplerate, channels, dtype, blocksize, device, callback):
        assert dtype == "float32" and channels == self.audio.shape[1]
        self.opened.append((samplerate, channels, blocksize, device))
        audio = self.audio

        class Stream:
            def __enter__(s):
                def play():
                    for i in range(0, len(audio), blocksize):
                        callback(audio[i:i + blocksize], blocksize, None, None)
                s.t = threading.Thread(target=play)
                s.t.start()
                return s

            def __exit__(s, *a):
                s.t.join()

        return Stream()


def test_live_example_equals_a_whole_run(tmp_path):
    ex = load_example()
    x = scene(seconds=2.0, seed=12, snr_db=10.0)
    np.save(tmp_path / "mics.npy", MICS)
    args = ex.parse_args(["--geometry", str(tmp_path / "mics.npy"), "--seconds", "2", "--compute", "cpu"])
    sd = FakeSoundDevice(x)
    out = io.StringIO()
    got = ex.run(args, sd=sd, out=out)
    assert sd.opened == [(FS, 8, FS // 100, None)]
    az = np.concatenate([r.azimuth_deg for r in got if len(r)])
    want = soundloc.Localizer(geometry=MICS, grid="ring:5", device="cpu", spectrum=False).localize(
        x.astype(np.float32), FS)
    np.testing.assert_array_equal(az, want.azimuth_deg)
    assert len(out.getvalue().splitlines()) == len(want) >= 3
    for row in az:
        for t in TALKERS:
            assert min(angle(a, t) for a in row) <= 5.0

    # A noise-only lead-in: K from the first 0.505 s (not a whole number of 10 ms blocks:
    # the block across the boundary is split), GEVD on the rest.
    args = ex.parse_args(["--geometry", str(tmp_path / "mics.npy"), "--seconds", "2", "--compute", "cpu",
                          "--noise-seconds", "0.505"])
    got = ex.run(args, sd=FakeSoundDevice(x), out=io.StringIO())
    lead = int(round(0.505 * FS))
    xf = x.astype(np.float32)
    want = soundloc.Localizer(geometry=MICS, grid="ring:5", device="cpu", spectrum=False,
                              noise=xf[:lead]).localize(xf[lead:], FS)
    np.testing.assert_array_equal(np.concatenate([r.frames for r in got if len(r)]), want.frames)
    np.testing.assert_array_equal(np.concatenate([r.azimuth_deg for r in got if len(r)]), want.azimuth_deg)


def test_live_example_on_a_real_device(tmp_path):
    try:
        import sounddevice as sd
    except (ImportError, OSError) as e:
        pytest.skip("SKIPPED test_live_example_on_a_real_device: sounddevice/PortAudio not available (%s)" % e)
    inputs = [d for d in sd.query_devices() if d["max_input_channels"] >= 8]
    if not inputs:
        pytest.skip("SKIPPED test_live_example_on_a_real_device: no capture device with 8 channels")
    ex = load_example()
    np.save(tmp_path / "mics.npy", MICS)
    args = ex.parse_args(["--geometry", str(tmp_path / "mics.npy"), "--seconds", "1", "--device",
                          inputs[0]["name"]])
    got = ex.run(args, out=io.StringIO())
    assert sum(len(r) for r in got) >= 1
