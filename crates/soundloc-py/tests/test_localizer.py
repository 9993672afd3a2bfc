"""The Python binding: known directions on a synthetic scene, the same answers as the CLI,
streaming in random blocks equal to a whole-array run, and clear exceptions."""

import json
import os
import subprocess
import wave
import zipfile
from pathlib import Path

import numpy as np
import pytest

import soundloc

FS = 16000
RADIUS = 0.0365
MICS = np.array([[RADIUS * np.cos(2 * np.pi * k / 8), RADIUS * np.sin(2 * np.pi * k / 8), 0.0] for k in range(8)])
TALKERS = (30.0, -120.0)
ROOT = Path(__file__).resolve().parents[3]


def scene(seconds=2.0, seed=1, snr_db=20.0, fs=FS):
    """Two white-noise talkers as far-field plane waves on the 8-mic circle (fractional
    delays in the frequency domain), plus sensor noise; int16 (samples, channels)."""
    rng = np.random.default_rng(seed)
    n = int(seconds * fs)
    f = np.fft.rfftfreq(n, 1 / fs)
    x = np.zeros((n, 8))
    for az in TALKERS:
        s = np.fft.rfft(rng.standard_normal(n))
        u = np.array([np.cos(np.radians(az)), np.sin(np.radians(az)), 0.0])
        for m in range(8):
            tau = -MICS[m] @ u / 343.0  # arrival time relative to the centre
            x[:, m] += np.fft.irfft(s * np.exp(-2j * np.pi * f * tau), n)
    x *= 3000 / x.std()
    x += rng.standard_normal(x.shape) * 3000 * 10 ** (-snr_db / 20)
    return np.clip(np.round(x), -32768, 32767).astype(np.int16)


def test_tracker_options_equal_the_cli(tmp_path):
    """The tracker's options from Python give what the CLI's flags give (ids, preroll,
    confirmation)."""
    x = scene(seconds=2.0, seed=7)
    wav = tmp_path / "rec.wav"
    write_wav(wav, x)
    geo = write_geometry(tmp_path / "array.toml")
    out = subprocess.run(
        [str(cli()), "localize", str(wav), "--geometry", str(geo), "--grid", "ring:5", "--device", "cpu", "-q",
         "--period", "10", "--track", "--thresh", "3", "--pause-length", "300", "--min-src-interval", "15",
         "--min-id", "7", "--preroll", "20", "--confirm", "30"],
        check=True, capture_output=True, text=True,
    ).stdout
    lines = [json.loads(l) for l in out.splitlines()]
    r = localizer(period=10, track=True, tracker_thresh_db=3.0, tracker_pause_length=300.0,
                  tracker_min_src_interval_deg=15.0, tracker_min_id=7, preroll=20,
                  tracker_confirm_frames=30).localize(x, FS)
    assert len(lines) == len(r) > 0
    ids = [[s["id"] for s in l["sources"]] for l in lines]
    assert min(i for row in ids for i in row) == 7
    for i, l in enumerate(lines):
        assert l["frame"] == r.frames[i]
        assert [s["id"] for s in l["sources"]] == [int(v) for v in r.ids[i][: len(l["sources"])]]
    # Pushed in 20 ms blocks: each push's spectrum rows are those of the results it
    # returns (the preroll holds results back; their rows wait with them).
    loc = localizer(fs=FS, period=10, track=True, tracker_thresh_db=3.0, tracker_pause_length=300.0,
                    tracker_min_src_interval_deg=15.0, tracker_min_id=7, preroll=20,
                  tracker_confirm_frames=30)
    row = {f: i for i, f in enumerate(r.frames)}
    parts = [loc.push(x[i : i + 320]) for i in range(0, len(x), 320)] + [loc.flush()]
    assert sum(len(p) for p in parts) == len(r)
    for p in parts:
        if len(p):
            np.testing.assert_array_equal(p.spectrum_db, r.spectrum_db[[row[f] for f in p.frames]])
    with pytest.raises(ValueError, match="track=True"):
        localizer(preroll=10)
    with pytest.raises(ValueError, match="track=True"):
        localizer(tracker_confirm_frames=10)
    with pytest.raises(ValueError, match="MIN_ID"):
        localizer(track=True, tracker_min_id=2**31)
    with pytest.raises(TypeError, match=r"Localizer\(\) got an unexpected keyword argument 'thresh'"):
        localizer(track=True, thresh=25)


def angle(a, b):
    return abs((a - b + 180) % 360 - 180)


def localizer(**kw):
    args = dict(geometry=MICS, grid="ring:5", device="cpu")
    args.update(kw)
    return soundloc.Localizer(**args)


def test_known_directions():
    x = scene()
    loc = localizer()
    r = loc.localize(x, FS)
    assert len(r) == len(r.times) >= 3
    assert r.azimuth_deg.shape == (len(r), 2)
    assert r.spectrum_db.shape == (len(r), 72)
    for row in r.azimuth_deg:
        for t in TALKERS:
            assert min(angle(a, t) for a in row) <= 5.0, (row, t)
    d = loc.directions()
    assert d["azimuth_deg"].shape == (72,) and d["unit"].shape == (72, 3)
    # The spectrum's maxima are the reported peaks.
    best = np.argmax(r.spectrum_db, axis=1)
    assert np.all(best == r.grid_index[:, 0])


def test_srp_phat_normmusic_and_refinement():
    x = scene()
    # algorithm="sevd" named: unnamed, the room default would turn normalisation and
    # refinement on by itself.
    for kw in (
        dict(algorithm="srp-phat"),
        dict(algorithm="sevd", normalize_bins=True),
        dict(algorithm="sevd", refine=True, subspace_dim=3),
    ):
        r = localizer(**kw).localize(x, FS)
        for row in r.azimuth_deg:
            for t in TALKERS:
                assert min(angle(a, t) for a in row) <= 5.0, (kw, row, t)
    # Refined directions leave the 5° grid; grid directions stay on it.
    refined = localizer(algorithm="sevd", refine=True).localize(x, FS).azimuth_deg
    assert np.any(np.abs(refined / 5.0 - np.round(refined / 5.0)) > 1e-3)
    on_grid = localizer(algorithm="sevd").localize(x, FS).azimuth_deg
    assert np.all(np.abs(on_grid / 5.0 - np.round(on_grid / 5.0)) < 1e-9)
    with pytest.raises(ValueError, match="subspace-dim"):
        localizer(subspace_dim=8).localize(x, FS)


def test_coherence_cancels_channel_gains():
    # Channels 6 dB and 12 dB louder or quieter than the geometry says: the room default
    # (coherence normalisation on) gives the matched array's results; coherence=False does not.
    x = scene().astype(np.float64)
    g = np.array([1.0, 2.0, 0.5, 1.0, 4.0, 1.0, 0.25, 2.0])
    y = x * g
    a = localizer(precision="f64").localize(x, FS)
    b = localizer(precision="f64").localize(y, FS)
    assert np.allclose(a.azimuth_deg, b.azimuth_deg, atol=1e-6)
    assert np.allclose(a.spectrum_db, b.spectrum_db, atol=1e-7)
    for row in a.azimuth_deg:
        for t in TALKERS:
            assert min(angle(az, t) for az in row) <= 5.0, (row, t)
    off = localizer(precision="f64", coherence=False)
    assert not np.allclose(off.localize(x, FS).spectrum_db, off.localize(y, FS).spectrum_db, atol=1e-3)


def test_subspace_tracking_stays_next_to_the_exact_path():
    x = scene()
    exact = localizer(period=1, window_type="past").localize(x, FS)
    approx = localizer(period=1, window_type="past", subspace_tracking=True).localize(x, FS)
    assert np.mean(exact.grid_index[:, 0] == approx.grid_index[:, 0]) >= 0.98
    rms = np.sqrt(np.mean((exact.spectrum_db - approx.spectrum_db) ** 2))
    assert 0 < rms < 0.01  # tracked (not the exact path), and close to it
    with pytest.raises(ValueError, match="MUSIC algorithm"):
        localizer(algorithm="srp-phat", subspace_tracking=True).localize(x, FS)


def test_dtypes_layouts_and_random_blocks_give_the_same_results():
    x = scene(seconds=1.5, seed=2)
    loc = localizer(window_type="past", period=7)
    whole = loc.localize(x, FS)
    for variant in (x.astype(np.float32), x.astype(np.float64), x.astype(np.int32)):
        v = loc.localize(variant, FS)
        np.testing.assert_array_equal(v.azimuth_deg, whole.azimuth_deg)
        np.testing.assert_array_equal(v.spectrum_db, whole.spectrum_db)
    cf = loc.localize(np.ascontiguousarray(x.T), FS, channels_first=True)
    np.testing.assert_array_equal(cf.spectrum_db, whole.spectrum_db)
    loc.reset()
    rng = np.random.default_rng(3)
    parts, pos = [], 0
    while pos < len(x):
        n = int(rng.integers(1, 4000))
        # A new stream's first push names the rate (geometry= without fs=).
        parts.append(loc.push(x[pos : pos + n], FS if pos == 0 else None))
        pos += n
    parts.append(loc.flush())
    times = np.concatenate([p.times for p in parts])
    az = np.concatenate([p.azimuth_deg for p in parts if len(p)])
    spec = np.concatenate([p.spectrum_db for p in parts if len(p)])
    np.testing.assert_array_equal(times, whole.times)
    np.testing.assert_array_equal(az, whole.azimuth_deg)
    np.testing.assert_array_equal(spec, whole.spectrum_db)
    assert loc.latency_frames == 0
    # Every push's arrays are as wide as the peaks reported, also an empty push's, and
    # Results.concatenate joins them (padding where tracking or max_peaks=0 widen some).
    assert {p.azimuth_deg.shape[1] for p in parts} == {2}
    assert any(len(p) == 0 for p in parts)
    joined = soundloc.Results.concatenate(parts)
    np.testing.assert_array_equal(joined.frames, whole.frames)
    np.testing.assert_array_equal(joined.azimuth_deg, whole.azimuth_deg)
    np.testing.assert_array_equal(joined.spectrum_db, whole.spectrum_db)
    wide = localizer(window_type="past", period=7, max_peaks=0, track=True)
    whole = wide.localize(x, FS)
    wide.reset()
    parts = [wide.push(x[i : i + 1000], FS) for i in range(0, len(x), 1000)] + [wide.flush()]
    assert len({p.azimuth_deg.shape[1] for p in parts}) > 1
    assert soundloc.Results.concatenate(parts).to_records() == whole.to_records()


def test_noise_array_selects_gevd_and_tracking_gives_ids():
    x = scene(seconds=2.0, seed=4)
    noise = (np.random.default_rng(5).standard_normal((16000, 8)) * 30).astype(np.float32)
    loc = localizer(noise=noise, track=True)
    assert loc.algorithm == "gevd"
    assert any("textbook GEVD" in n for n in loc.notes)
    r = loc.localize(x, FS)
    # New tracks are confirmed over a window (W = 50 frames) first, then both talkers
    # are tracked in every result.
    assert np.all(r.ids[r.frames < 50] < 0)
    assert np.all(r.ids[r.frames >= 50, :2] >= 0)
    r = localizer(noise=noise, track=True, tracker_confirm_frames=0).localize(x, FS)
    assert np.all(r.ids[:, :2] >= 0)
    loc = localizer(noise_range=(0.0, 0.5), algorithm="gsvd")
    assert loc.algorithm == "gsvd"
    assert len(loc.localize(x, FS)) > 0
    # The robust default's numerator is geometric; numerator= chooses another for the
    # textbook gevd (the CLI's --numerator: the same spectra) and is refused by the others.
    default = localizer(noise=noise)
    assert json.loads(default.spec_json()).get("numerator") is None
    assert any("‖a‖·‖a_w‖" in n for n in default.notes)
    spectra = {n: localizer(noise=noise, numerator=n).localize(x, FS).spectrum_db
               for n in ("raw", "whitened", "geometric")}
    np.testing.assert_array_equal(spectra["geometric"], default.localize(x, FS).spectrum_db)
    assert not np.allclose(spectra["raw"], spectra["geometric"])
    with pytest.raises(ValueError, match="numerator is defined for the textbook gevd"):
        localizer(noise=noise, numerator="whitened", algorithm="gsvd")
    with pytest.raises(ValueError, match="numerator"):
        localizer(noise=noise, numerator="sqrt")
    # noise_preceding as the CLI's FRAMES[:GAP]: a count, or a pair as a tuple or list.
    runs = [localizer(noise_preceding=p, window_type="past").localize(x, FS).azimuth_deg
            for p in (30, (30, 0), [30, 0])]
    for r in runs[1:]:
        np.testing.assert_array_equal(r, runs[0])
    for bad in (0, (30, 1, 2), "30", True):
        with pytest.raises((ValueError, TypeError), match="noise_preceding"):
            localizer(noise_preceding=bad)


def write_wav(path, x):
    with wave.open(str(path), "wb") as w:
        w.setnchannels(x.shape[1])
        w.setsampwidth(2)
        w.setframerate(FS)
        w.writeframes(x.astype("<i2").tobytes())


def write_geometry(path):
    """MICS as a geometry file for the CLI."""
    path.write_text("mics = [" + ", ".join("[%r, %r, %r]" % tuple(float(v) for v in m) for m in MICS) + "]\n")
    return path


def cli():
    b = Path(os.environ.get("SOUNDLOC_BIN", ROOT / "target" / "release" / "soundloc"))
    if not b.exists():
        pytest.skip(f"SKIPPED python_equals_cli: {b} not built")
    return b


def test_python_equals_the_cli(tmp_path):
    x = scene(seconds=2.0, seed=6)
    wav = tmp_path / "rec.wav"
    write_wav(wav, x)
    geo = write_geometry(tmp_path / "array.toml")
    out = subprocess.run(
        [str(cli()), "localize", str(wav), "--geometry", str(geo), "--grid", "ring:5", "--device", "cpu", "-q",
         "--period", "20"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    lines = [json.loads(l) for l in out.splitlines()]
    r = localizer(period=20).localize(x, FS)
    assert len(lines) == len(r)
    for i, l in enumerate(lines):
        assert l["frame"] == r.frames[i]
        assert [s["azimuth_deg"] for s in l["sources"]] == list(r.azimuth_deg[i])
        assert [s["power_db"] for s in l["sources"]] == list(r.power_db[i])
        assert l["num_active"] == r.num_active[i]
    assert [rec["num_active"] for rec in r.to_records()] == [l["num_active"] for l in lines]


def test_bad_input_raises_the_right_exception(tmp_path):
    loc = localizer()
    x = scene(seconds=1.0)
    with pytest.raises(TypeError):
        loc.localize(x.astype(np.complex64), FS)
    with pytest.raises(ValueError, match="2-D"):
        loc.localize(x[:, 0], FS)
    with pytest.raises(ValueError, match="channels_first=True"):
        loc.localize(np.ascontiguousarray(x.T), FS)
    with pytest.raises(ValueError, match="4 channels"):
        loc.localize(x[:, :4], FS)
    with pytest.raises(ValueError, match="48000 Hz"):
        localizer(fs=FS).localize(x, 48000)
    with pytest.raises(TypeError, match="fs must be a number of Hz, got '16000' of type str"):
        loc.localize(x, "16000")
    with pytest.raises(ValueError, match="fs must be a positive whole number"):
        loc.localize(x, 16000.5)
    bad = x.astype(np.float32)
    bad[100, 3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        loc.localize(bad, FS)
    huge = x.astype(np.float64)
    huge[7, 2] = 1e300  # finite, but not a float32
    with pytest.raises(ValueError, match=r"sample \[7, 2\] of the array is 1e300, beyond the range of the 32-bit floats"):
        loc.localize(huge, FS)
    with pytest.raises(ValueError, match="needs at least"):
        loc.localize(x[:1000], FS)
    with pytest.raises(OSError, match="missing.zip"):
        soundloc.Localizer(tf=str(tmp_path / "missing.zip"))
    with pytest.raises(ValueError, match="algorithm"):
        localizer(algorithm="nope")
    with pytest.raises(ValueError, match="num-sources"):
        localizer(num_sources=8)
    with pytest.raises(ValueError, match="no array"):
        soundloc.Localizer()
    with pytest.raises(ValueError, match="noise: the array holds no samples"):
        localizer(noise=np.zeros((0, 8), np.float32))
    # Negative counts and indices are bad values (not OverflowError).
    with pytest.raises(ValueError, match="num_sources: must be a non-negative integer"):
        localizer(num_sources=-1)
    with pytest.raises(ValueError, match="^channels: must be a non-negative integer"):
        localizer(channels=[0, -1], max_peaks=-1)
    with pytest.raises(ValueError, match="^nfft: must be a non-negative integer"):
        localizer(nfft=2 ** 64)
    with pytest.raises(ValueError, match="streams must be at least 1"):
        soundloc.StreamGroup(0, geometry=MICS, grid="ring:5", fs=FS, device="cpu")


def test_fortran_order_and_strided_arrays_read_in_logical_order():
    """(samples, channels) arrays that are not C-ordered (a transposed view, Fortran order,
    a strided slice) give exactly what their C-ordered copy gives — audio and noise alike."""
    x = scene(seconds=1.5, seed=31).astype(np.float32)
    noise = scene(seconds=0.5, seed=32, snr_db=-30.0).astype(np.float32)
    want = localizer(noise=noise).localize(x, FS)
    for xv, nv in ((np.asfortranarray(x), np.asfortranarray(noise)),
                   (np.ascontiguousarray(x.T).T, np.ascontiguousarray(noise.T).T),
                   (np.repeat(x, 2, axis=1)[:, ::2], np.repeat(noise, 2, axis=1)[:, ::2])):
        assert not xv.flags["C_CONTIGUOUS"]
        got = localizer(noise=nv).localize(xv, FS)
        np.testing.assert_array_equal(got.azimuth_deg, want.azimuth_deg)
        np.testing.assert_array_equal(got.spectrum_db, want.spectrum_db)
    # channels_first with a C-ordered (channels, samples) array and its F-ordered twin.
    a = localizer().localize(np.ascontiguousarray(x.T), FS, channels_first=True)
    b = localizer().localize(np.asfortranarray(x.T), FS, channels_first=True)
    np.testing.assert_array_equal(a.spectrum_db, b.spectrum_db)


def test_resample_converts_another_rate(tmp_path):
    """resample=True: 48 kHz audio (an array or a file) reaches a 16 kHz analysis converted;
    without it the rate mismatch is a ValueError naming both rates."""
    x48 = scene(fs=48000)
    with pytest.raises(ValueError, match="48000 Hz.*16000 Hz"):
        localizer(fs=FS).localize(x48, 48000)
    loc = localizer(resample=True)
    # Without fs= anywhere the audio's rate is unknown: refused, not taken as 16 kHz.
    free = soundloc.Localizer(geometry=MICS, grid="ring:5", resample=True, period=10)
    with pytest.raises(ValueError, match="sampling rate is not known.*resample=True"):
        free.localize(x48)
    with pytest.raises(ValueError, match="sampling rate is not known.*first push"):
        free.push(x48[:4800])
    fr = free.localize(x48, 48000)
    with pytest.raises(ValueError, match="sampling rate is not known"):
        free.localize(x48)
    free.reset()
    free.push(scene()[:1600], FS)
    free.push(scene()[1600:3200])
    assert len(fr) >= 3
    r = loc.localize(x48, 48000)
    r16 = localizer().localize(scene(), FS)
    assert len(r) == len(r16) >= 3
    for row in r.azimuth_deg:
        for t in TALKERS:
            assert min(angle(a, t) for a in row) <= 5.0, (row, t)
    # Channels-first arrays too, with the same answers.
    rc = loc.localize(np.ascontiguousarray(x48.T), 48000, channels_first=True)
    np.testing.assert_array_equal(rc.azimuth_deg, r.azimuth_deg)
    # A 48 kHz file through localize_file.
    wav = tmp_path / "x48.wav"
    with wave.open(str(wav), "wb") as w:
        w.setnchannels(8)
        w.setsampwidth(2)
        w.setframerate(48000)
        w.writeframes(x48.tobytes())
    out = tmp_path / "x48.jsonl"
    assert loc.localize_file(wav, out) == len(r)
    rows = [json.loads(l) for l in out.read_text().splitlines()]
    got = [[s["azimuth_deg"] for s in row["sources"]] for row in rows]
    np.testing.assert_allclose(np.sort(got, axis=1), np.sort(r.azimuth_deg, axis=1))
    with pytest.raises(ValueError, match="48000 Hz"):
        localizer(fs=FS).localize_file(wav, tmp_path / "no.jsonl")
    assert not (tmp_path / "no.jsonl").exists()
    # "-" is the CLI's stdout, not a file named "-" (one was written until 2026-12-08).
    import os
    here = os.getcwd()
    os.chdir(tmp_path)
    try:
        with pytest.raises(ValueError, match=r"localize_file writes a file \(the CLI's -o - is its standard output\)"):
            loc.localize_file(wav, "-")
        assert not (tmp_path / "-").exists()
    finally:
        os.chdir(here)
    # Results never replace the recording they come from.
    before = wav.read_bytes()
    with pytest.raises(ValueError, match="would overwrite the input"):
        loc.localize_file(wav, wav)
    assert wav.read_bytes() == before


def test_geometry_without_fs_takes_the_audios_rate(tmp_path):
    """geometry= without fs=: the free-field transfer functions are made for the rate that
    localize(x, fs) or localize_file's header names (48 kHz audio analysed at 48 kHz, the
    talkers found, times in seconds of that audio), exactly as with fs=48000 given; a note
    says so. (Until 2026-12-01 it analysed at 16 kHz: the talkers 5-15 degrees off, times
    3x too late, or a rate error for audio it could have taken as it is.)"""
    x48 = scene(fs=48000)
    loc = localizer()
    assert any("no fs= given" in n for n in loc.notes)
    r = loc.localize(x48, 48000)
    assert loc.fs == 48000
    want = localizer(fs=48000).localize(x48, 48000)
    np.testing.assert_array_equal(r.azimuth_deg, want.azimuth_deg)
    np.testing.assert_array_equal(r.times, want.times)
    # HARK's frame durations at 48 kHz (1536 and 480 samples): a result every 0.5 s.
    assert len(r) >= 3 and r.times[1] - r.times[0] == pytest.approx(0.5)
    assert any("the frames are 1536 samples with a hop of 480" in n for n in loc.notes)
    np.testing.assert_array_equal(localizer(nfft=1536, hop=480, fs=48000).localize(x48, 48000).azimuth_deg,
                                  r.azimuth_deg)
    for row in r.azimuth_deg:
        for t in TALKERS:
            assert min(angle(a, t) for a in row) <= 5.0, (row, t)
    # A 16 kHz recording afterwards: back to 16 kHz.
    r16 = loc.localize(scene(), FS)
    np.testing.assert_array_equal(r16.azimuth_deg, localizer().localize(scene(), FS).azimuth_deg)
    wav = tmp_path / "x48.wav"
    with wave.open(str(wav), "wb") as w:
        w.setnchannels(8)
        w.setsampwidth(2)
        w.setframerate(48000)
        w.writeframes(x48.tobytes())
    out = tmp_path / "x48.jsonl"
    assert localizer().localize_file(wav, out) == len(r)
    rows = [json.loads(l) for l in out.read_text().splitlines()]
    np.testing.assert_allclose([[s["azimuth_deg"] for s in row["sources"]] for row in rows], r.azimuth_deg)
    # A rate given, or a TF file's, stays the rate: no note.
    assert not any("no fs= given" in n for n in localizer(fs=FS).notes)


def test_push_needs_the_rate_where_it_is_open():
    """geometry= without fs=: push() and localize(x) refuse audio whose rate no call has
    named (until 2026-12-02 push() analysed it as 16 kHz audio: 48 kHz talkers found
    5-15 degrees off, no error); a stream's first push(x, fs) names it, and the results
    equal those with fs= given. A rate other than the stream's is refused, naming both."""
    x48 = scene(fs=48000)
    loc = localizer()
    with pytest.raises(ValueError, match="sampling rate is not known"):
        loc.push(x48[:4800])
    with pytest.raises(ValueError, match="sampling rate is not known"):
        loc.localize(x48)
    step = 4800
    got = [loc.push(x48[:step], fs=48000)] + [loc.push(x48[i : i + step]) for i in range(step, len(x48), step)]
    got = soundloc.Results.concatenate(got + [loc.flush()])
    assert loc.fs == 48000
    want = localizer(fs=48000).localize(x48, 48000)
    assert len(got) == len(want) >= 3
    np.testing.assert_array_equal(got.azimuth_deg, want.azimuth_deg)
    np.testing.assert_array_equal(got.times, want.times)
    for row in got.azimuth_deg:
        for t in TALKERS:
            assert min(angle(a, t) for a in row) <= 5.0, (row, t)
    # Within a stream the rate stays; a new stream's first push may name another.
    loc.reset()
    loc.push(x48[:step], fs=48000)
    with pytest.raises(ValueError, match="this stream runs at 48000 Hz"):
        loc.push(scene()[:1600], fs=FS)
    loc.reset()
    x = scene()
    r16 = soundloc.Results.concatenate([loc.push(x, fs=FS), loc.flush()])
    assert loc.fs == FS
    np.testing.assert_array_equal(r16.azimuth_deg, localizer(fs=FS).localize(x, FS).azimuth_deg)
    # Each recording, and each new stream, names its rate: the previous one's is not
    # assumed (until 2026-12-03 a second localize(x) after localize(x48, 48000) analysed
    # 16 kHz audio as 48 kHz: a talker at 60 degrees came out at 80, no error).
    loc.localize(x48, 48000)
    with pytest.raises(ValueError, match="sampling rate is not known.*each recording names its own"):
        loc.localize(x)
    loc.reset()
    with pytest.raises(ValueError, match="sampling rate is not known.*first push names it"):
        loc.push(x[:1600])
    # A fixed rate (fs= given): a block named at another rate is refused.
    with pytest.raises(ValueError, match=r"push\(fs=48000\): the localizer analyses 16000 Hz"):
        localizer(fs=FS).push(x48, fs=48000)
    # A group has no recording to take a rate from.
    with pytest.raises(ValueError, match="StreamGroup.*needs fs="):
        soundloc.StreamGroup(2, geometry=MICS, grid="ring:5", device="cpu")


def test_flush_of_a_stream_shorter_than_one_window():
    """A stream that ends before its first window (a live capture stopped at once) flushes
    to no results and a note; it raised the engine's too-short error until 2026-12-02.
    localize() of so short a recording stays an error."""
    x = scene()
    loc = localizer(fs=FS)
    assert len(loc.push(x[:1000])) == 0
    r = loc.flush()
    assert len(r) == 0 and r.azimuth_deg.shape[0] == 0
    # A (0, D) spectrum, not None: the parts of a stream join with np.concatenate too.
    d = len(loc.directions()["azimuth_deg"])
    assert r.spectrum_db.shape == (0, d) and r.spectrum_db.dtype == np.float32
    assert localizer(fs=FS, spectrum=False).push(x[:1000]).spectrum_db is None
    assert any(n.startswith("no results: the audio has 1000 samples") for n in r.notes), r.notes
    with pytest.raises(ValueError, match=r"push after the end of the stream \(flush, or localize"):
        loc.push(x[:100])
    loc.reset()
    np.testing.assert_array_equal(soundloc.Results.concatenate([loc.push(x), loc.flush()]).azimuth_deg,
                                  localizer(fs=FS).localize(x, FS).azimuth_deg)
    with pytest.raises(ValueError, match="the audio has 1000 samples"):
        localizer(fs=FS).localize(x[:1000], FS)
    # Only the stream's lack of a window is a note: a noise range the stream never
    # reached stays an error.
    late = localizer(fs=FS, noise_range=(5.0, 6.0))
    late.push(x)
    with pytest.raises(ValueError, match="noise range 5:6 s starts after the end"):
        late.flush()


def test_num_sources_bounds_a_subspace_only():
    """SRP-PHAT has no subspace: num_sources (the peaks reported) may reach M; the MUSIC
    family refuses it, naming the bound."""
    x = scene()
    r = localizer(fs=FS, algorithm="srp-phat", num_sources=8).localize(x, FS)
    two = localizer(fs=FS, algorithm="srp-phat").localize(x, FS)
    assert r.azimuth_deg.shape[1] == 8
    np.testing.assert_array_equal(r.azimuth_deg[:, :2], two.azimuth_deg)
    with pytest.raises(ValueError, match="between 1 and M-1 = 7 for 8 microphones with sevd"):
        localizer(fs=FS, algorithm="sevd", num_sources=8)


def test_big_endian_and_shape_hints():
    """Big-endian arrays (read from files as ">i2") are converted, not refused as the
    wrong dtype; the channels_first hint is given only where the other axis is the
    shorter one (not for an input_channels index out of range)."""
    x = scene()
    loc = localizer(fs=FS)
    want = loc.localize(x, FS)
    for dt in (">i2", ">f4", ">f8", ">i4"):
        np.testing.assert_array_equal(loc.localize(x.astype(dt), FS).azimuth_deg, want.azimuth_deg)
    with pytest.raises(ValueError, match=r"pass channels_first=True"):
        loc.localize(np.ascontiguousarray(x.T), FS)
    sel = localizer(fs=FS, input_channels=list(range(1, 9)))
    with pytest.raises(ValueError) as e:
        sel.localize(x, FS)
    assert "channels_first" not in str(e.value), str(e.value)


def test_geometry_by_columns_and_a_hop_past_the_frame_are_named():
    """pyroomacoustics' L (one microphone per column) is refused with the transpose to
    pass, (M, 2) is a planar array, a 3 × 3 array (rows or columns alike) is read by rows with a note, and a hop
    longer than the frame gets a note (samples between frames go unanalysed)."""
    with pytest.raises(ValueError, match=r"\(3, 8\) array holds one microphone per column .*L\.T"):
        soundloc.Localizer(geometry=MICS.T, grid="ring:5", device="cpu")
    with pytest.raises(ValueError, match=r"\(2, 8\) array .*\(M, 3\) or \(M, 2\): L\.T$"):
        soundloc.Localizer(geometry=MICS.T[:2], grid="ring:5", device="cpu")
    # (3, 2): three planar microphones by rows, or two by columns: the message names both.
    with pytest.raises(ValueError, match=r"\(3, 2\) array .*L\.T; planar positions given by rows.*column_stack"):
        soundloc.Localizer(geometry=MICS[:3, :2], grid="ring:5", device="cpu", num_sources=1)
    # A grid of (D, 2) is not directions (azimuth/elevation pairs would be misread).
    with pytest.raises(ValueError, match=r"grid: a \(72, 2\) array holds 2 values per row"):
        soundloc.Localizer(geometry=MICS, grid=np.zeros((72, 2)), device="cpu")
    # (M, 2): a planar array, z = 0 (the ring's z is 0: the same results).
    x = scene(seconds=1.0)
    np.testing.assert_array_equal(
        soundloc.Localizer(geometry=MICS[:, :2], grid="ring:5", device="cpu").localize(x, FS).azimuth_deg,
        localizer().localize(x, FS).azimuth_deg)
    three = soundloc.Localizer(geometry=MICS[[0, 3, 5]], grid="ring:5", device="cpu", num_sources=1)
    assert any("3 × 3 array" in n for n in three.notes)
    assert not any("3 × 3" in n for n in localizer().notes)
    assert any("the hop (1024 samples) is longer than the frame (512)" in n
               for n in localizer(nfft=512, hop=1024).notes)
    assert not any("longer than the frame" in n for n in localizer().notes)


def test_room_default_tracks_start_only_where_sources_are_active():
    """track=True in the room default: a second of sensor noise before the talkers feeds
    the tracker nothing (num_active 0 there), so no track starts in it; with
    track_active_only=False and tracker_confirm_frames=0 (HARK's tracker, every window)
    tracks start in the silence."""
    rng = np.random.default_rng(5)
    quiet = np.round(rng.standard_normal((FS, 8)) * 30).astype(np.int16)
    x = np.concatenate([quiet, scene(seconds=2.0, seed=9)])
    kw = dict(track=True, period=10, window_type="past")
    gated = localizer(**kw).localize(x, FS)
    silent = gated.times < 0.99
    assert silent.sum() >= 5
    assert np.all(gated.num_active[silent] == 0)
    assert np.all(np.isnan(gated.azimuth_deg[silent]))
    talk = gated.times >= 1.6
    for t in TALKERS:
        assert np.mean([min(angle(a, t) for a in row if a == a) <= 5.0 for row in gated.azimuth_deg[talk]]) >= 0.8
    hark = localizer(track_active_only=False, tracker_confirm_frames=0, **kw).localize(x, FS)
    assert np.mean(~np.isnan(hark.azimuth_deg[silent][:, 0])) >= 0.5
    # After the talkers stop, their tracks are carried through the pause (0.8 s), marked
    # held; while they talk, the tracked sources are observed.
    after = localizer(**kw).localize(np.concatenate([x, quiet]), FS)
    tracked = after.ids >= 0
    talking = (after.times >= 1.6) & (after.times < 2.5)
    assert after.held[talking][tracked[talking]].mean() < 0.2
    # PAST windows wholly after the talk (t − 0.49 s ≥ 3 s), within the pause.
    pause = (after.times >= 3.55) & (after.times < 3.95)
    assert pause.sum() >= 3 and after.held[pause][tracked[pause]].all() and tracked[pause].any()
    recs = after.to_records()
    assert all(s.get("held", False) == bool(after.held[i, j])
               for i, r in enumerate(recs) for j, s in enumerate(r["sources"]))
    df = after.to_pandas()
    shown = ~np.isnan(after.azimuth_deg)
    assert len(df) == shown.sum() and df.held.sum() == (after.held & shown).sum() > 0
    assert list(df.held) == list(after.held[shown])
    assert list(df.grid_index) == list(after.grid_index[shown])
    with pytest.raises(ValueError, match="track=True"):
        localizer(track_active_only=True)


def test_arguments_as_pyroomacoustics_users_write_them():
    """Lists and arrays for ranges, a float sample rate, diagonal loading of K, and a
    rejected block that leaves the stream as it was."""
    x = scene(seconds=2.0, seed=3)
    ref = localizer(freq_range=(500.0, 2800.0), noise_range=(0.0, 0.5)).localize(x, FS)
    got = localizer(freq_range=[500, 2800], noise_range=np.array([0.0, 0.5])).localize(x, float(FS))
    np.testing.assert_array_equal(got.azimuth_deg, ref.azimuth_deg)
    with pytest.raises(ValueError, match="freq_range must be two numbers"):
        localizer(freq_range=[500])
    with pytest.raises(ValueError, match="positive whole number"):
        localizer().localize(x, 16000.5)
    with pytest.raises(ValueError, match="positive whole number"):
        localizer().localize(x, True)
    seg = localizer(noise_range=[0.0, 0.5], noise_segments=[[1.0, 1.5]]).localize(x, FS)
    assert len(seg) == len(ref)
    # K from too few noise frames is not positive definite; diagonal loading makes it usable.
    noise = (np.random.default_rng(5).standard_normal((1500, 8)) * 30).astype(np.int16)
    with pytest.raises(ValueError, match="diagonal loading"):
        localizer(noise=noise).localize(x, FS)
    r = localizer(noise=noise, diagonal_loading=0.1).localize(x, FS)
    for row in r.azimuth_deg:
        for t in TALKERS:
            assert min(angle(a, t) for a in row) <= 5.0, (row, t)
    # One NaN in a pushed block: the block is refused whole, the stream goes on unchanged.
    loc, whole = localizer(fs=FS, period=10), localizer(fs=FS, period=10)
    want = whole.push(x)
    bad = x[12000:16000].astype(np.float32)
    bad[3900, 5] = np.nan
    first = loc.push(x[:12000])
    assert len(first) > 0
    with pytest.raises(ValueError, match="NaN"):
        loc.push(bad)
    rest = loc.push(x[12000:])
    np.testing.assert_array_equal(np.concatenate([first.frames, rest.frames]), want.frames)
    np.testing.assert_array_equal(np.concatenate([first.azimuth_deg, rest.azimuth_deg]), want.azimuth_deg)


def test_geometry_files_toml_and_odas_configuration(tmp_path):
    """geometry= takes a file name too: TOML gives the same results as the array; an ODAS
    configuration's mapping.map picks the microphones among the device's channels."""
    x = scene()
    want = localizer().localize(x, FS)
    got = localizer(geometry=str(write_geometry(tmp_path / "ring8.toml"))).localize(x, FS)
    assert np.array_equal(got.azimuth_deg, want.azimuth_deg)
    # A 10-channel device: microphone i on device channel 10 - i (1-based), two channels of something else.
    mics = ",\n".join("{ mu = ( %r, %r, %r ); }" % tuple(float(v) for v in m) for m in MICS)
    cfg = tmp_path / "ring8.cfg"
    cfg.write_text(
        "raw: { fS = 16000; nChannels = 10; }\nmapping: { map: (10, 9, 8, 7, 6, 5, 4, 3); }\n"
        "general: { mics = (\n" + mics + "\n); };\n"
    )
    device = np.zeros((x.shape[0], 10), dtype=np.int16)
    device[:, :2] = np.random.default_rng(5).integers(-9000, 9000, (x.shape[0], 2))
    for i in range(8):
        device[:, 9 - i] = x[:, i]
    got = localizer(geometry=cfg).localize(device, FS)
    assert np.array_equal(got.azimuth_deg, want.azimuth_deg)
    with pytest.raises(ValueError, match="maps 8 of a 10-channel device"):
        localizer(geometry=cfg).localize(device[:, :9], FS)
    cfg.write_text(cfg.read_text().replace("(10,", "(11,"))
    with pytest.raises(ValueError, match=r"ring8.cfg: mapping.map\[0\] is 11"):
        localizer(geometry=cfg)


def test_calls_from_several_threads_take_turns():
    """One Localizer used from several threads: calls wait for each other (they raised
    PyO3's "Already borrowed" before), each localize() is whole, getters never fail."""
    import threading
    from concurrent.futures import ThreadPoolExecutor

    x = scene()
    want = localizer().localize(x, FS)
    loc = localizer()
    stop = threading.Event()
    seen = []

    def read_getters():
        while not stop.is_set():
            seen.append((loc.latency_frames, loc.samples_needed_next, loc.num_mics))

    reader = threading.Thread(target=read_getters)
    reader.start()
    try:
        with ThreadPoolExecutor(4) as ex:
            got = list(ex.map(lambda _: loc.localize(x, FS), range(8)))
    finally:
        stop.set()
        reader.join()
    assert len(seen) > 0 and all(s[2] == 8 for s in seen)
    for g in got:
        assert np.array_equal(g.azimuth_deg, want.azimuth_deg)
        assert np.array_equal(g.spectrum_db, want.spectrum_db)


def test_a_thread_in_a_tight_loop_does_not_starve_another():
    """Turns go in arrival order: while one thread pushes block after block, another's
    calls still get their turn (it could wait for ever when the lock went to whoever held
    the GIL as it freed)."""
    import threading
    import time

    x = scene(seconds=1.0)
    loc = localizer(fs=FS, period=1)
    done = threading.Event()
    calls = []

    def other():
        for _ in range(20):
            calls.append(loc.fs)
        done.set()

    t = threading.Thread(target=other)
    end = time.monotonic() + 30
    t.start()
    while not done.is_set() and time.monotonic() < end:
        loc.push(x[:160])
    t.join(timeout=30)
    assert done.is_set() and calls == [FS] * 20


def test_switches_off_in_the_default_and_options_a_tf_file_does_not_take(tmp_path):
    """refine=False and normalize_bins=False are honoured in the room default (they were
    overridden by it); grid=, grid_radius=, speed_of_sound= and another fs= with tf= are
    errors, not ignored; positions in room coordinates are seen from the array."""
    x = scene()
    on = localizer().localize(x, FS)
    off_loc = localizer(refine=False, normalize_bins=False)
    assert json.loads(off_loc.spec_json())["refine"] is False
    off = off_loc.localize(x, FS)
    assert np.all(np.abs(off.azimuth_deg / 5.0 - np.round(off.azimuth_deg / 5.0)) < 1e-9)
    assert np.any(np.abs(on.azimuth_deg / 5.0 - np.round(on.azimuth_deg / 5.0)) > 1e-3)
    # Without per-bin normalisation the powers leave NormMUSIC's scale (≤ 10·log10(bins + 1)).
    assert off.power_db.max() > on.power_db.max() + 3
    assert "without per-bin normalisation" in " ".join(off_loc.notes)
    for row in off.azimuth_deg:
        for t in TALKERS:
            assert min(angle(a, t) for a in row) <= 5.0, (row, t)
    # A TF file made from the same array.
    tf = tmp_path / "ring.zip"
    geo = write_geometry(tmp_path / "array.toml")
    subprocess.run([str(cli()), "tf", "make", "--geometry", str(geo), "--grid", "ring:5", "-o", str(tf)],
                   check=True, capture_output=True)
    ok = soundloc.Localizer(tf=tf, fs=FS, device="cpu").localize(x)
    np.testing.assert_array_equal(ok.azimuth_deg, soundloc.Localizer(tf=tf, device="cpu").localize(x).azimuth_deg)
    with pytest.raises(ValueError, match="fs=48000: the transfer functions in .*ring.zip are for 16000 Hz"):
        soundloc.Localizer(tf=tf, fs=48000, device="cpu")
    # The zip's rate is read from its small entries before any matrix is inflated: with
    # every matrix broken, a wrong fs= is still named as such (and the right one reaches
    # the load, which names the broken entry).
    broken = tmp_path / "broken.zip"
    with zipfile.ZipFile(tf) as src, zipfile.ZipFile(broken, "w") as dst:
        for e in src.infolist():
            dst.writestr(e, b"not a matrix" if e.filename.endswith(".mat") else src.read(e))
    with pytest.raises(ValueError, match="fs=48000: the transfer functions in .*broken.zip are for 16000 Hz"):
        soundloc.Localizer(tf=broken, fs=48000, device="cpu")
    with pytest.raises((OSError, ValueError), match=r"broken\.zip.*\.mat|\.mat.*broken\.zip"):
        soundloc.Localizer(tf=broken, fs=FS, device="cpu")
    for kw in (dict(grid="ring:10"), dict(grid_radius=2.0), dict(speed_of_sound=340.0)):
        with pytest.raises(ValueError, match="applies to geometry="):
            soundloc.Localizer(tf=tf, device="cpu", **kw)
    # pyroomacoustics' L in room coordinates: the array's own directions, with a grid
    # given by name or as unit vectors.
    room = MICS + np.array([3.0, 2.5, 1.2])
    units = soundloc.Localizer(geometry=MICS, grid="ring:5", device="cpu").directions()["unit"]
    for grid in ("ring:5", units):
        loc = localizer(geometry=room, grid=grid)
        r = loc.localize(x, FS)
        np.testing.assert_allclose(r.azimuth_deg, on.azimuth_deg, atol=0.01)
    for grid in ("ring:5", units):
        assert any("seen from the centroid" in n for n in localizer(geometry=room, grid=grid).notes)
    # A robot's frame (the origin 0.36 m from the array, within half the 1 m grid) is kept.
    near = localizer(geometry=MICS + np.array([0.3, -0.2, 0.0]))
    assert any("directions are seen from the origin" in n for n in near.notes)


def test_input_checks_name_a_flipped_and_a_dead_channel():
    """The engine's input checks reach Python's notes: none on a clean scene, one naming
    the polarity-inverted channel, one naming a dead channel (input channel numbers)."""
    x = scene(seconds=3.0)
    checks = lambda r: [n for n in r.notes if "input channel" in n]
    assert checks(localizer().localize(x, FS)) == []
    flipped = x.copy()
    flipped[:, 5] = -flipped[:, 5].astype(np.int32).clip(-32767, 32767)
    n = checks(localizer().localize(flipped, FS))
    assert len(n) == 1 and "input channel 5 (0-based) looks polarity-inverted" in n[0], n
    assert "invert_channels=[5]" in n[0], n
    # The option the note names negates it again: the clean scene's results, no note.
    clean = x.copy()
    clean[:, 5] = x[:, 5].astype(np.int32).clip(-32767, 32767)
    want = localizer().localize(clean, FS)
    got = localizer(invert_channels=[5]).localize(flipped, FS)
    assert checks(got) == []
    np.testing.assert_array_equal(got.azimuth_deg, want.azimuth_deg)
    np.testing.assert_array_equal(got.power_db, want.power_db)
    with pytest.raises(ValueError, match="input channel 9 is to be inverted"):
        localizer(invert_channels=[9]).localize(flipped, FS)
    dead = x.copy()
    dead[:, 2] = 0
    n = checks(localizer().localize(dead, FS))
    assert len(n) == 1 and "input channel 2 (0-based) is constant" in n[0], n


def test_positions_in_millimetres_get_a_units_warning():
    """A warning (Python's warnings too, since 2026-12-08: a note in .notes alone went
    unseen), and the note stays in .notes."""
    with pytest.warns(UserWarning, match=r"span 73\.0 m: positions are in metres"):
        notes = soundloc.Localizer(geometry=MICS * 1000, grid="ring:5", device="cpu").notes
    assert any("span 73.0 m: positions are in metres" in n and "divide them by 1000" in n for n in notes), notes
    with pytest.warns(UserWarning, match="grid radius 0.01 m is inside the array"):
        soundloc.StreamGroup(1, geometry=MICS, grid="ring:5", fs=FS, device="cpu", grid_radius=0.01)
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert not any("positions are in metres" in n for n in localizer().notes)


def test_copy_is_refused_cleanly():
    """A Localizer holds a native stream: copy.copy would share it between two objects
    (one stream's frames and results split between them); copy, deepcopy and pickle are a
    TypeError that says what to do, for a StreamGroup too."""
    import copy
    import pickle
    for obj in (localizer(), soundloc.StreamGroup(2, geometry=MICS, grid="ring:5", fs=FS, device="cpu")):
        for f in (copy.copy, copy.deepcopy):
            with pytest.raises(TypeError, match="cannot be copied.*same arguments"):
                f(obj)
        with pytest.raises(TypeError):
            pickle.dumps(obj)


def test_config_shows_what_the_defaults_resolved_to():
    """spec_json() is the spec as given; config() the analysis that runs: the robust
    default (a noise source, no algorithm) is GEVD with half the array as its subspace,
    the geometric numerator, onset weighting and refinement; the room default is
    normalised SEVD; a named algorithm is HARK's, as it is."""
    noise = (np.random.default_rng(5).standard_normal((16000, 8)) * 30).astype(np.float32)
    robust = localizer(noise=noise)
    assert json.loads(robust.spec_json()).get("algorithm") is None
    c = robust.config()
    assert (c["algorithm"], c["subspace_dim"], c["numerator"], c["refine"]) == (
        "gevd", len(MICS) // 2, "geometric", True)
    assert c["onset_frames"] > 0 and c["sample_rate_hz"] == FS
    room = localizer().config()
    assert (room["algorithm"], room["normalize_bins"], room["refine"]) == ("sevd", True, True)
    hark = localizer(noise=noise, algorithm="gsvd").config()
    assert (hark["algorithm"], hark["subspace_dim"], hark["refine"]) == ("gsvd", None, False)
    assert "numerator" not in hark and "onset_frames" not in hark
    g = soundloc.StreamGroup(2, geometry=MICS, grid="ring:5", fs=FS, device="cpu")
    assert g.config() == room


def test_pyroomacoustics_argument_names_are_accepted():
    """num_src= and c= (pyroomacoustics' DOA names) mean num_sources= and speed_of_sound=:
    the same spec; naming both is an error."""
    a = soundloc.Localizer(geometry=MICS, grid="ring:5", device="cpu", num_src=1, c=340.0)
    b = soundloc.Localizer(geometry=MICS, grid="ring:5", device="cpu", num_sources=1, speed_of_sound=340.0)
    assert a.spec_json() == b.spec_json()
    assert a.spec_json() != soundloc.Localizer(geometry=MICS, grid="ring:5", device="cpu").spec_json()
    with pytest.raises(TypeError, match="num_src= and num_sources= name the same argument"):
        soundloc.Localizer(geometry=MICS, grid="ring:5", num_src=1, num_sources=2)


def _localize_in_worker(seed):
    """A forked worker's job: its own localizer on the scene (module level: Pool pickles
    it by name)."""
    return localizer(period=10).localize(scene(seed=seed), FS).azimuth_deg


@pytest.mark.skipif(not hasattr(os, "fork"), reason="fork is POSIX-only")
def test_forked_workers_localize_after_the_parent_did():
    """multiprocessing's fork start method (the default on Linux until Python 3.14; also
    ProcessPoolExecutor's, and data-loader workers'): workers forked after the parent used
    soundloc get the same results as the parent. Until 2026-12-03 every such worker waited
    forever on rayon's global pool, which a fork copies without its threads."""
    import multiprocessing

    want = [localizer(period=10).localize(scene(seed=s), FS).azimuth_deg for s in (1, 2)]
    pool = multiprocessing.get_context("fork").Pool(2)
    try:
        got = pool.map_async(_localize_in_worker, [1, 2]).get(timeout=120)
    finally:
        pool.terminate()
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)


def test_ctrl_c_stops_a_long_call_and_writes_nothing(tmp_path):
    """Ctrl-C (SIGINT) during a long localize / localize_file raises KeyboardInterrupt
    within a fraction of the call instead of after all of it (until 2026-12-03 it came at
    the end: 20.7 s into a 22.5 s call), localize_file then writes no file, and the
    localizer works afterwards."""
    import signal
    import threading
    import time

    x = np.tile(scene(seconds=2.0), (6, 1))  # 12 s
    loc = localizer(fs=FS, grid="sphere:2000", period=1)
    t = time.perf_counter()
    want = loc.localize(x, FS)
    whole = time.perf_counter() - t
    assert whole > 1.0, f"the call must be long enough to interrupt ({whole:.2f} s)"

    def interrupted(call):
        timer = threading.Timer(0.15 * whole, lambda: os.kill(os.getpid(), signal.SIGINT))
        timer.start()
        t = time.perf_counter()
        with pytest.raises(KeyboardInterrupt):
            call()
        timer.join()
        return time.perf_counter() - t

    took = interrupted(lambda: loc.localize(x, FS))
    assert took < 0.6 * whole, f"interrupted after {took:.2f} s of a {whole:.2f} s call"
    wav = tmp_path / "long.wav"
    write_wav(wav, x)
    out = tmp_path / "long.jsonl"
    took = interrupted(lambda: loc.localize_file(wav, out))
    assert took < 0.6 * whole, f"interrupted after {took:.2f} s"
    assert not out.exists() and list(tmp_path.iterdir()) == [wav]
    again = loc.localize(x, FS)
    np.testing.assert_array_equal(again.azimuth_deg, want.azimuth_deg)


def test_array_likes_flags_and_empty_frames():
    """What numpy pipelines pass: array-likes with __array__ (a CPU tensor's stand-in) and
    memoryviews are taken as numpy arrays, flags as 0/1 and numpy bools; a name not among
    an option's values lists them; a result set without rows still has its DataFrame
    columns (a push that completed no window)."""

    class Tensor:  # what torch.Tensor offers numpy
        def __init__(self, a):
            self.a = a

        def __array__(self, dtype=None, copy=None):
            return self.a if dtype is None else self.a.astype(dtype)

    x = scene()
    want = localizer(fs=FS).localize(x, FS)
    loc = localizer(fs=FS)
    got = loc.localize(Tensor(x), FS)
    np.testing.assert_array_equal(got.azimuth_deg, want.azimuth_deg)
    got = loc.localize(memoryview(np.ascontiguousarray(x.T)), FS, channels_first=1)
    np.testing.assert_array_equal(got.azimuth_deg, want.azimuth_deg)
    got = localizer(fs=FS, geometry=Tensor(MICS), channels_first=np.bool_(True)).localize(x.T.copy(), FS)
    np.testing.assert_array_equal(got.azimuth_deg, want.azimuth_deg)
    with pytest.raises(TypeError, match="channels_first= must be True or False, got 2"):
        loc.localize(x, FS, channels_first=2)
    with pytest.raises(ValueError, match='"music" is not a valid value.*expected one of.*"sevd"'):
        localizer(fs=FS, algorithm="music")
    pd = pytest.importorskip("pandas")
    empty = localizer(fs=FS).push(x[:100])
    df = empty.to_pandas()
    assert len(df) == 0 and "power_db" in df.columns and "azimuth_deg" in df.columns
    assert len(df[df.power_db > 10]) == 0
    assert isinstance(df, pd.DataFrame)


def test_harks_other_parameters_equal_the_cli(tmp_path):
    """MIN_DEG / MAX_DEG, the MultiFFT window, ENABLE_EIGENVALUE_WEIGHT, the spectrum
    weights and the denominator as keywords: the CLI's results with the same flags, and
    MIN_DEG/MAX_DEG keep only the talker inside them."""
    x = scene(seconds=2.0, seed=6)
    wav = tmp_path / "rec.wav"
    write_wav(wav, x)
    geo = write_geometry(tmp_path / "array.toml")
    bins = 0
    for kw, flags in [
        (dict(min_deg=-90.0, max_deg=90.0), ["--min-deg", "-90", "--max-deg", "90"]),
        (dict(window_function="hamming", eigenvalue_weight=False, denominator="unsquared"),
         ["--window-function", "hamming", "--eigenvalue-weight", "false", "--denominator", "unsquared"]),
        (dict(spectrum_weight="a-weighting"), ["--spectrum-weight", "a-weighting"]),
        (dict(spectrum_weight=[1.0 + 0.1 * k for k in range(73)]),
         ["--spectrum-weights", ",".join(repr(1.0 + 0.1 * k) for k in range(73))]),
    ]:
        out = subprocess.run(
            [str(cli()), "localize", str(wav), "--geometry", str(geo), "--grid", "ring:5", "--device", "cpu",
             "-q", "--period", "20", "--algorithm", "sevd"] + flags,
            check=True, capture_output=True, text=True,
        ).stdout
        lines = [json.loads(l) for l in out.splitlines()]
        r = localizer(period=20, algorithm="sevd", **kw).localize(x, FS)
        assert len(lines) == len(r), kw
        for i, l in enumerate(lines):
            # (Python pads a window's missing peaks with NaN.)
            n = len(l["sources"])
            assert [s["azimuth_deg"] for s in l["sources"]] == list(r.azimuth_deg[i][:n]), kw
            assert [s["power_db"] for s in l["sources"]] == list(r.power_db[i][:n]), kw
            assert np.all(np.isnan(r.azimuth_deg[i][n:])), kw
        if "min_deg" in kw:
            az = np.concatenate([np.asarray(a) for a in r.azimuth_deg])
            az = az[~np.isnan(az)]
            assert az.size and np.all(np.abs(az) <= 90.0), az
            assert any(angle(a, 30.0) <= 5 for a in az)
    with pytest.raises(ValueError, match="window_function"):
        localizer(window_function="blackman")
    with pytest.raises(ValueError, match="one per used bin"):
        localizer(spectrum_weight="manual")
    with pytest.raises(TypeError):
        localizer(eigenvalue_weight="no")
