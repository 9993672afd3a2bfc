"""StreamGroup: several arrays' streams sharing one plan and device. Each stream's results
equal its own Localizer's, whatever the blocks; a per-stream noise range is refused."""

import numpy as np
import pytest

import soundloc

from test_localizer import FS, MICS, TALKERS, angle, scene


def kwargs(noise):
    return dict(geometry=MICS, grid="ring:5", fs=FS, device="cpu", noise=noise, track=True, period=10)


def test_each_stream_equals_its_own_localizer():
    xs = [scene(seconds=1.5, seed=20 + i, snr_db=10.0) for i in range(3)]
    noise = scene(seconds=0.5, seed=99, snr_db=-40.0)  # mostly sensor noise
    g = soundloc.StreamGroup(3, **kwargs(noise))
    assert len(g) == 3 and g.algorithm == "gevd"
    got = [[] for _ in xs]
    rng = np.random.default_rng(5)
    pos = 0
    while pos < len(xs[0]):
        n = int(rng.integers(1, 4000))
        for i, r in enumerate(g.push_all([x[pos:pos + n] for x in xs])):
            got[i].append(r)
        pos += n
    for i in range(3):
        got[i].append(g.flush(i))
    for i, x in enumerate(xs):
        want = soundloc.Localizer(**kwargs(noise)).localize(x, FS)
        frames = np.concatenate([r.frames for r in got[i]])
        az = np.concatenate([r.azimuth_deg for r in got[i] if len(r)])
        spec = np.concatenate([r.spectrum_db for r in got[i] if len(r)])
        assert len(want) >= 10
        np.testing.assert_array_equal(frames, want.frames)
        np.testing.assert_array_equal(az, want.azimuth_deg)
        np.testing.assert_array_equal(spec, want.spectrum_db)
        # Tracks are confirmed over a window (50 frames) before they are output.
        assert np.all(np.isnan(want.azimuth_deg[want.frames < 50]))
        for row in want.azimuth_deg[want.frames >= 50]:
            for t in TALKERS:
                assert min(angle(a, t) for a in row) <= 5.0
    # push + run queue per stream; the streams differ.
    g.reset(0)
    g.push(0, xs[1])
    first = g.run()
    assert len(first) == 3 and len(first[0]) > 0 and len(first[1]) == len(first[2]) == 0


def test_flush_of_a_stream_shorter_than_one_window():
    """As Localizer.flush: a stream that ends before its first window (one array of many
    disconnected at once) gives no results and a note, not an exception; the other streams
    go on, and reset(i) starts it again. It raised until 2026-12-08."""
    x = scene(seconds=1.0, seed=7)
    g = soundloc.StreamGroup(2, geometry=MICS, grid="ring:5", fs=FS, device="cpu")
    g.push(0, x[:100])
    r = g.flush(0)
    assert len(r) == 0 and r.azimuth_deg.shape[0] == 0
    assert any(n.startswith("no results: the audio has 100 samples") for n in r.notes), r.notes
    with pytest.raises(ValueError, match="push after the end of the stream"):
        g.push(0, x[:100])
    g.push(1, x)
    got = soundloc.Results.concatenate([g.run()[1], g.flush(1)])
    want = soundloc.Localizer(geometry=MICS, grid="ring:5", fs=FS, device="cpu").localize(x, FS)
    np.testing.assert_array_equal(got.azimuth_deg, want.azimuth_deg)
    g.reset(0)
    g.push(0, x)
    again = soundloc.Results.concatenate([g.run()[0], g.flush(0)])
    np.testing.assert_array_equal(again.azimuth_deg, want.azimuth_deg)


def test_group_refuses_what_it_cannot_share():
    with pytest.raises(ValueError, match="one fixed noise matrix"):
        soundloc.StreamGroup(2, geometry=MICS, grid="ring:5", fs=FS, device="cpu", noise_range=(0.0, 0.5))
    g = soundloc.StreamGroup(2, geometry=MICS, grid="ring:5", fs=FS, device="cpu")
    with pytest.raises(ValueError, match="2 blocks|blocks for 2 streams"):
        g.push_all([scene(seconds=0.1)])
    with pytest.raises(ValueError, match="no stream 5"):
        g.push(5, scene(seconds=0.1))
    for bad in (-1, 1.5):
        with pytest.raises(ValueError, match=f"no stream {bad}"):
            g.push(bad, scene(seconds=0.1))
        with pytest.raises(ValueError, match=f"no stream {bad}"):
            g.flush(bad)
    with pytest.raises(ValueError, match="channels"):
        g.push_all([scene(seconds=0.1), scene(seconds=0.1)[:, :4]])


def test_two_threads_on_one_group_never_deadlock():
    """While one thread computes (GIL released), another thread's calls on the same group
    return or raise at once — they never wait on the group with the GIL held."""
    import threading

    g = soundloc.StreamGroup(2, geometry=MICS, grid="ring:5", fs=FS, device="cpu", period=1)
    xs = [scene(seconds=1.0, seed=40 + i) for i in range(2)]
    errors = []

    def work():
        try:
            for _ in range(3):
                g.push_all(xs)
        except Exception as e:  # noqa: BLE001 - reported below
            errors.append(e)

    t = threading.Thread(target=work)
    t.start()
    answered = 0
    while t.is_alive():
        try:
            len(g)
            g.latency_frames
        except RuntimeError:
            pass  # "already borrowed": the other thread is computing
        answered += 1
    t.join(timeout=60)
    assert not t.is_alive() and not errors and answered > 0
