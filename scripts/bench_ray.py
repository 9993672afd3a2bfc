#!/usr/bin/env python3
"""soundloc.archive on a local Ray cluster: wall time for N recordings with 1 and 2 actors
(and in-process), each result file checked equal to the in-process one.

    python scripts/bench_ray.py [N] [SECONDS]
"""
import os
import shutil
import sys
import tempfile
import time
import wave

import numpy as np
import ray

from soundloc.archive import localize_files

FS = 16000
N = int(sys.argv[1]) if len(sys.argv) > 1 else 24
SEC = float(sys.argv[2]) if len(sys.argv) > 2 else 10.0
R = 0.0365
MICS = np.array([[R * np.cos(2 * np.pi * k / 8), R * np.sin(2 * np.pi * k / 8), 0.0] for k in range(8)])

d = tempfile.mkdtemp()
rng = np.random.default_rng(0)
paths = []
for i in range(N):
    x = (rng.standard_normal((int(SEC * FS), 8)) * 1000).astype("<i2")
    p = os.path.join(d, f"r{i:03d}.wav")
    with wave.open(p, "wb") as w:
        w.setnchannels(8)
        w.setsampwidth(2)
        w.setframerate(FS)
        w.writeframes(x.tobytes())
    paths.append(p)
kw = dict(geometry=MICS, grid="sphere:2522", device="cpu", period=10)
t = time.perf_counter()
localize_files(paths, os.path.join(d, "local"), **kw)
print(f"in-process: {time.perf_counter() - t:.1f} s for {N} x {SEC:.0f} s recordings (8 mics, 2522 dirs, PERIOD 10)")
ray.init(num_cpus=os.cpu_count(), include_dashboard=False, log_to_driver=False)
for c in (1, 2):
    out = os.path.join(d, f"ray{c}")
    t = time.perf_counter()
    rows = localize_files(paths, out, ray=True, concurrency=c, **kw)
    dt = time.perf_counter() - t
    same = all(open(r["output"]).read() == open(os.path.join(d, "local", os.path.basename(r["output"]))).read() for r in rows)
    print(f"ray, {c} actor(s): {dt:.1f} s, results equal to in-process: {same}")
ray.shutdown()
shutil.rmtree(d)
