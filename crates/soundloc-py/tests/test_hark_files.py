"""HARK files from Python: a TF zip, a noise-CM zip and a source log written by the CLI, read
back as numpy with their known content."""

import json
import subprocess

import numpy as np
import pytest

import soundloc

from test_localizer import FS, MICS, cli, scene, write_wav


def test_tf_noise_cm_and_source_log(tmp_path):
    geo = tmp_path / "array.toml"
    geo.write_text("mics = [" + ", ".join("[%r, %r, %r]" % tuple(float(v) for v in m) for m in MICS) + "]\n")
    tf = tmp_path / "tf.zip"
    subprocess.run([str(cli()), "tf", "make", "--geometry", str(geo), "--grid", "ring:30", "-o", str(tf)],
                   check=True, capture_output=True)
    t = soundloc.read_tf(tf)
    assert t["tf"].shape == (12, 8, 257 - t["first_bin"]) and t["tf"].dtype == np.complex64
    assert t["nfft"] == 512 and t["fs"] == FS
    np.testing.assert_allclose(t["mics"], MICS, atol=1e-4)
    # Free field, HARK's convention: unit magnitude, phase −2πf·r/c with r the distance
    # from the grid point (1 m away) to each microphone.
    np.testing.assert_allclose(np.abs(t["tf"]), 1.0, atol=1e-5)
    k = 40 - t["first_bin"]
    f = 40 * FS / 512
    r = np.linalg.norm(t["directions"][3][None, :] - MICS, axis=1)
    want = np.exp(-2j * np.pi * f * r / 343.0)
    np.testing.assert_allclose(t["tf"][3, :, k], want, atol=2e-4)

    wav = tmp_path / "rec.wav"
    write_wav(wav, scene(seconds=2.0, seed=8))
    cm = tmp_path / "k.zip"
    subprocess.run([str(cli()), "noisecm", "make", str(wav), "--range", "0:1", "-o", str(cm)],
                   check=True, capture_output=True)
    K, nfft = soundloc.read_noise_cm(cm)
    assert nfft == 512 and K.shape == (257, 8, 8)
    np.testing.assert_allclose(K, np.conj(np.transpose(K, (0, 2, 1))), atol=1e-9 * np.abs(K).max())
    assert np.all(np.real(np.einsum("kii->ki", K))[1:] > 0)

    log = tmp_path / "log.txt"
    out = subprocess.run([str(cli()), "localize", str(wav), "--geometry", str(geo), "--grid", "ring:5",
                          "--device", "cpu", "-q", "--log-text", str(log)],
                         check=True, capture_output=True, text=True).stdout
    cli_results = [json.loads(line) for line in out.splitlines()]
    got = soundloc.read_source_log(log)
    assert len(got) == len(cli_results)
    # A log holds no grid index: None, not a made-up 0.
    assert all(s["grid_index"] is None for r in got for s in r["sources"])
    for a, b in zip(got, cli_results):
        assert a["frame"] == b["frame"]
        assert [round(s["azimuth_deg"]) for s in a["sources"]] == [round(s["azimuth_deg"]) for s in b["sources"]]


def test_write_tf_noise_cm_and_source_log(tmp_path):
    """Files written from Python read back equal, and the CLI localizes with them."""
    d = np.array([[np.cos(a), np.sin(a), 0.0] for a in np.radians(np.arange(0, 360, 10))])
    f = np.arange(257) * FS / 512
    r = np.linalg.norm(d[:, None, :] - MICS[None, :, :], axis=2)  # (D, M) distances, 1 m grid
    tf = np.exp(-2j * np.pi * f[None, None, :] * r[:, :, None] / 343.0)
    path = tmp_path / "py_tf.zip"
    soundloc.write_tf(path, tf, d, MICS, 512, FS)
    back = soundloc.read_tf(path)
    lo = back["first_bin"]
    np.testing.assert_allclose(back["tf"], tf[:, :, lo:lo + back["tf"].shape[2]], atol=1e-6)
    np.testing.assert_allclose(back["directions"], d, atol=1e-12)
    # The CLI localizes the two talkers with the TF written here.
    wav = tmp_path / "rec.wav"
    write_wav(wav, scene(seconds=1.5, seed=4))
    out = subprocess.run([str(cli()), "localize", str(wav), "--tf", str(path), "--format", "jsonl"],
                         check=True, capture_output=True, text=True).stdout
    rows = [json.loads(line) for line in out.splitlines()]
    assert rows and all(
        min(abs((s["azimuth_deg"] - t + 180) % 360 - 180) for s in row["sources"]) <= 10.0
        for row in rows for t in (30.0, -120.0))
    with pytest.raises(ValueError, match="shape"):
        soundloc.write_tf(tmp_path / "bad.zip", tf[:, :, :100], d, MICS, 512, FS, first_bin=200)
    # What read_tf returns (bins first_bin..) writes back with first_bin=.
    part = soundloc.read_tf(path)
    soundloc.write_tf(tmp_path / "again.zip", part["tf"], part["directions"], part["mics"], 512, FS,
                      first_bin=part["first_bin"])
    again = soundloc.read_tf(tmp_path / "again.zip")
    lo2 = again["first_bin"]
    np.testing.assert_allclose(again["tf"][:, :, lo - lo2:], part["tf"], atol=1e-6)

    # Noise CMs: zip (f32 values) and text pair (full precision), read back.
    rng = np.random.default_rng(3)
    a = rng.standard_normal((257, 8, 8)) + 1j * rng.standard_normal((257, 8, 8))
    k = a @ np.conj(np.transpose(a, (0, 2, 1))) + 8 * np.eye(8)
    (z,) = soundloc.write_noise_cm(tmp_path / "k.zip", k)
    kz, nfft = soundloc.read_noise_cm(z)
    assert nfft == 512
    np.testing.assert_allclose(kz, k, rtol=1e-6, atol=1e-5)
    re, im = soundloc.write_noise_cm(tmp_path / "k", k)
    assert (re.name, im.name) == ("k_r", "k_i")
    kt, _ = soundloc.read_noise_cm(re)
    np.testing.assert_allclose(kt, k, rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="not a zip"):
        soundloc.write_noise_cm(tmp_path / "k2.zip", k, format="text")
    with pytest.raises(ValueError, match="shape"):
        soundloc.write_noise_cm(tmp_path / "k3.zip", k[:, :, :4])
    # What the readers would refuse is not written.
    kn = k.copy()
    kn[3, 1, 2] = np.nan
    with pytest.raises(ValueError, match=r"K at bin 3: K\(1, 2\) = NaN.* is not finite"):
        soundloc.write_noise_cm(tmp_path / "nan.zip", kn)
    kh = k.copy()
    kh[5, 0, 1] += 1.0  # no longer Hermitian
    with pytest.raises(ValueError, match="K at bin 5: not Hermitian"):
        soundloc.write_noise_cm(tmp_path / "kh.zip", kh)
    with pytest.raises(ValueError, match="beyond single precision"):
        soundloc.write_noise_cm(tmp_path / "big.zip", k * 1e38)
    assert not any((tmp_path / f).exists() for f in ("kh.zip", "big.zip"))
    with pytest.raises(ValueError, match="sampling rate"):
        soundloc.write_tf(tmp_path / "fs0.zip", tf, d, MICS, 512, 0)
    assert not (tmp_path / "nan.zip").exists() and not (tmp_path / "fs0.zip").exists()

    # Source logs from a Results object: the directions and ids come back.
    res = soundloc.Localizer(geometry=MICS, grid="ring:5", device="cpu", track=True).localize(
        scene(seconds=1.5, seed=4), FS)
    for fmt, name in (("text", "log.txt"), (None, "log.xml")):
        soundloc.write_source_log(tmp_path / name, res, format=fmt)
        log = soundloc.read_source_log(tmp_path / name)
        assert [r["frame"] for r in log] == list(res.frames)
        for i, r in enumerate(log):
            got = sorted((s["id"], round(s["azimuth_deg"], 6)) for s in r["sources"])
            want = sorted((int(res.ids[i, j]), round(float(res.azimuth_deg[i, j]), 6))
                          for j in range(res.azimuth_deg.shape[1]) if not np.isnan(res.azimuth_deg[i, j]))
            assert got == want, (fmt, i)
    # And a list of dicts as read_source_log returns round-trips too.
    soundloc.write_source_log(tmp_path / "again.txt", log)
    assert (tmp_path / "again.txt").read_text() == (tmp_path / "log.txt").read_text()


def test_read_audio_reads_raw_pcm_as_its_wav(tmp_path):
    """A headerless file (np.tofile's, or a recorder's) reads with raw=, channels=, fs= as the
    WAV holding the same samples; f32 as given; a size that is not whole frames, a missing
    argument and an unknown encoding are ValueErrors naming the problem."""
    x = scene(seconds=0.5)
    write_wav(tmp_path / "a.wav", x)
    x.astype("<i2").tofile(tmp_path / "a.s16")
    w, fs_w = soundloc.read_audio(tmp_path / "a.wav")
    r, fs_r = soundloc.read_audio(tmp_path / "a.s16", raw="s16le", channels=8, fs=FS)
    assert fs_r == fs_w == FS and r.shape == (len(x), 8)
    np.testing.assert_array_equal(r, w)
    f = (x / 32768.0).astype("<f4")
    f.tofile(tmp_path / "a.f32")
    g, _ = soundloc.read_audio(str(tmp_path / "a.f32"), raw="f32le", channels=8, fs=FS)
    np.testing.assert_array_equal(g, f)
    with pytest.raises(ValueError, match=r"not a whole number of sample frames"):
        soundloc.read_audio(tmp_path / "a.s16", raw="s16le", channels=7, fs=FS)
    with pytest.raises(ValueError, match=r"raw=, channels= and fs="):
        soundloc.read_audio(tmp_path / "a.s16", raw="s16le", channels=8)
    with pytest.raises(ValueError, match=r"give raw="):
        soundloc.read_audio(tmp_path / "a.wav", channels=8)
    with pytest.raises(ValueError, match=r"expected u8, s16le"):
        soundloc.read_audio(tmp_path / "a.s16", raw="s16be", channels=8, fs=FS)
    with pytest.raises(OSError):
        soundloc.read_audio(tmp_path / "none.raw", raw="s16le", channels=8, fs=FS)
