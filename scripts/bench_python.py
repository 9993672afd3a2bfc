#!/usr/bin/env python3
"""Python overhead per call against the Rust API (issue 12's benchmark).

    target/pyvenv/bin/python scripts/bench_python.py [SECONDS] [REPEATS]

The same stream — 8-mic ring, 72 directions, GEVD, PERIOD 1 (a result every 10 ms), f32,
CPU, Gaussian noise — is pushed in 10 ms blocks through `soundloc.Localizer.push` and through
the Rust API (`soundloc bench --stream --array ring8`, which times `Localizer::push` in
Rust); the difference per push is what the binding adds (argument checks, the block view,
the GIL release, the result dict and its numpy arrays). Also: a push that completes no
window (1 sample), and the same with the spectrum returned. Run both halves on an idle
machine; the minimum over REPEATS is reported."""

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import soundloc

ROOT = Path(__file__).resolve().parents[1]
BIN = os.environ.get("SOUNDLOC_BIN", str(ROOT / "target" / "release" / "soundloc"))
FS = 16000
R = 0.0365
MICS = np.array([[R * np.cos(2 * np.pi * k / 8), R * np.sin(2 * np.pi * k / 8), 0.0] for k in range(8)])


def python_push(seconds, spectrum):
    loc = soundloc.Localizer(geometry=MICS, grid="ring:5", algorithm="gevd", period=1, window=50,
                             device="cpu", spectrum=spectrum)
    rng = np.random.default_rng(1)
    x = (1000 * rng.standard_normal((int(seconds * FS), 8))).astype(np.float32)
    warm = x[:FS]
    for i in range(0, len(warm), 160):
        loc.push(warm[i:i + 160])
    n = 0
    t0 = time.perf_counter()
    for i in range(0, len(x), 160):
        n += len(loc.push(x[i:i + 160]))
    dt = time.perf_counter() - t0
    pushes = len(x) // 160
    # Pushes that complete no window (a fresh stream needs W·hop samples before its first
    # result): the binding's fixed cost.
    loc.reset()
    one = x[:1]
    n1 = min(2000, loc.samples_needed_next - 1)
    t1 = time.perf_counter()
    for _ in range(n1):
        loc.push(one)
    empty = (time.perf_counter() - t1) / n1
    return dt / pushes, empty, n / pushes


def rust_push(seconds):
    out = subprocess.run([BIN, "bench", "--stream", "--array", "ring8", "--algorithm", "gevd", "--device", "cpu",
                          "--period", "1", "--seconds", str(seconds), "--json"],
                         check=True, capture_output=True, text=True).stdout
    rep = json.loads(out.strip().splitlines()[-1])
    rep = rep[0] if isinstance(rep, list) else rep
    return rep["rtf"] * 0.010  # seconds of compute per 10 ms push


def main():
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 10.0
    repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    py = min(python_push(seconds, False)[0] for _ in range(repeats))
    py_spec, empty, per = min(python_push(seconds, True) for _ in range(repeats))
    rs = min(rust_push(seconds) for _ in range(repeats))
    print("ring8 GEVD PERIOD 1, 10 ms pushes, %.0f s, %d cores, min of %d" % (seconds, os.cpu_count(), repeats))
    print("  Rust Localizer::push          %8.1f us/push" % (rs * 1e6))
    print("  Python Localizer.push         %8.1f us/push (+%.1f us, %.1f %%)" % (py * 1e6, (py - rs) * 1e6,
                                                                             100 * (py - rs) / rs))
    print("  Python push, spectrum on      %8.1f us/push (+%.1f us; the Rust figure returns no spectrum rows)" % (py_spec * 1e6, (py_spec - rs) * 1e6))
    print("  Python push completing none   %8.1f us/push (1 sample; %.2f results per 10 ms push above)"
          % (empty * 1e6, per))


if __name__ == "__main__":
    main()
