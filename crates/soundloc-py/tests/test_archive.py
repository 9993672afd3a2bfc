"""Archives: a dozen generated recordings localized by soundloc.archive in this process and
on a local Ray cluster, each result file equal to the CLI's for the same recording."""

import subprocess

import numpy as np
import pytest

import soundloc
from soundloc.archive import localize_files, result_path

from test_localizer import FS, MICS, cli, scene, write_wav


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    d = tmp_path_factory.mktemp("archive")
    geo = d / "array.toml"
    geo.write_text("mics = [" + ", ".join("[%r, %r, %r]" % tuple(float(v) for v in m) for m in MICS) + "]\n")
    paths = []
    for i in range(12):
        p = d / f"rec{i:02d}.wav"
        write_wav(p, scene(seconds=1.0, seed=100 + i))
        paths.append(p)
    # The CLI's result per recording.
    want = {}
    for p in paths:
        out = subprocess.run(
            [str(cli()), "localize", str(p), "--geometry", str(geo), "--grid", "ring:5", "--device", "cpu",
             "-q", "--period", "20"],
            check=True, capture_output=True, text=True,
        ).stdout
        want[str(p)] = out
    return d, paths, want


KW = dict(geometry=MICS, grid="ring:5", device="cpu", period=20)


def check(rows, want):
    assert len(rows) == len(want)
    for r in rows:
        assert r["error"] == "" and r["results"] > 0, r
        with open(r["output"]) as f:
            assert f.read() == want[r["path"]], r["path"]


def test_in_process_equals_the_cli_and_resumes(recordings, tmp_path):
    _, paths, want = recordings
    rows = localize_files(paths, tmp_path / "out", **KW)
    check(rows, want)
    again = localize_files(paths, tmp_path / "out", **KW)
    assert all(r["skipped"] for r in again)
    x, fs = soundloc.read_audio(paths[0])
    assert fs == FS and x.shape == (FS, 8) and x.dtype == np.float32


def test_ray_data_equals_the_cli(recordings, tmp_path):
    import ray

    _, paths, want = recordings
    ray.init(num_cpus=2, include_dashboard=False, ignore_reinit_error=True, log_to_driver=False)
    try:
        rows = localize_files(paths, tmp_path / "ray", ray=True, concurrency=2, **KW)
    finally:
        ray.shutdown()
    check(rows, want)
    assert [r["output"] for r in rows] == [result_path(p, tmp_path / "ray") for p in paths]
    # Bad options are the Localizer's own exception before Ray starts an actor (they
    # were a RayActorError from the dead actor), and nothing is written.
    for bad, exc in [(dict(KW, grid="ring:0"), ValueError), (dict(KW, no_such_option=1), TypeError)]:
        with pytest.raises(exc):
            localize_files(paths, tmp_path / "ray-bad", ray=True, concurrency=2, **bad)
        assert not any((tmp_path / "ray-bad").glob("*.jsonl"))


def test_errors_are_reported_per_recording(recordings, tmp_path):
    d, paths, _ = recordings
    bad = d / "broken.wav"
    bad.write_bytes(b"RIFF\x10\x00\x00\x00WAVEjunk")
    rows = localize_files([bad, paths[0]], tmp_path / "err", **KW)
    assert rows[0]["results"] == -1 and "broken.wav" in rows[0]["error"]
    assert rows[1]["error"] == "" and rows[1]["results"] > 0
    with pytest.raises(ValueError, match="would write"):
        localize_files([paths[0], d / "x" / paths[0].name], tmp_path / "dup", **KW)
    # One path, as a str or a Path, is one recording (not a list of its characters).
    for one in (str(paths[0]), paths[0]):
        (row,) = localize_files(one, tmp_path / "one", overwrite=True, **KW)
        assert row["error"] == "" and row["results"] > 0, row
