"""HARK files from Python: a TF zip, a noise-CM zip and a source log written by the CLI, read
back as numpy with their known content."""

import json
import subprocess

import numpy as np

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
    for a, b in zip(got, cli_results):
        assert a["frame"] == b["frame"]
        assert [round(s["azimuth_deg"]) for s in a["sources"]] == [round(s["azimuth_deg"]) for s in b["sources"]]
