#!/usr/bin/env python3
"""soundloc.doa against pyroomacoustics.doa on identical STFT windows: ms of compute per
second of audio (the fastest of three passes over all windows, for each library) and how
often the peaks agree; then each library's usual single call on the whole recording's STFT
(the fastest of three). Needs pyroomacoustics and the soundloc wheel.

    python scripts/bench_doa.py            # 8-mic ring (72 dirs) and 60-mic sphere (2522 dirs)
"""
import time

import numpy as np
import pyroomacoustics as pra

import soundloc.doa

FS, NFFT, HOP, WIN = 16000, 512, 160, 50  # HARK-like framing: 50 frames per window
PASSES = 3


def frames(L, seconds, seed):
    rng = np.random.default_rng(seed)
    dim = L.shape[0]
    room = pra.AnechoicRoom(dim, fs=FS, sigma2_awgn=1e-2)
    for az in (40.0, -110.0):
        a = np.radians(az)
        p = 3.0 * np.array([np.cos(a), np.sin(a)] + ([0.3] if dim == 3 else []))
        room.add_source(p, signal=rng.standard_normal(int(FS * seconds)))
    room.add_microphone_array(pra.MicrophoneArray(L, fs=FS))
    if hasattr(pra, "random") and hasattr(pra.random, "seed"):
        pra.random.seed(seed)  # the sensor noise of simulate(): the same scene every run
    np.random.seed(seed)
    room.simulate()
    return np.array([pra.transform.stft.analysis(s, NFFT, HOP).T for s in room.mic_array.signals])


def fib(n):
    i = np.arange(n) + 0.5
    return np.mod(np.pi * (1 + 5 ** 0.5) * i, 2 * np.pi), np.arccos(1 - 2 * i / n)


def run(label, L, kw, seconds=2.0):
    X = frames(L, seconds, 1)
    nwin = X.shape[2] // WIN
    print(f"\n{label}: M={L.shape[1]}, {nwin} windows of {WIN} frames ({seconds} s), bins 500-4000 Hz")
    for name in ["MUSIC", "NormMUSIC", "SRP"]:
        res = {}
        for lib in (pra.doa, soundloc.doa):
            d = lib.algorithms[name](L, FS, NFFT, num_src=2, **kw)
            d.locate_sources(X[:, :, :WIN], freq_range=[500.0, 4000.0])  # warm-up: plans, caches
            best = float("inf")
            for _ in range(PASSES):  # the fastest pass over all windows, for both libraries
                peaks = []
                t = time.perf_counter()
                for w in range(nwin):
                    d.locate_sources(X[:, :, w * WIN:(w + 1) * WIN], freq_range=[500.0, 4000.0])
                    peaks.append(set(np.round(d.src_idx).tolist()))
                best = min(best, time.perf_counter() - t)
            res[lib.__name__] = (best * 1e3 / seconds, peaks)
        (tp, pp), (ts, ps) = res["pyroomacoustics.doa"], res["soundloc.doa"]
        same = sum(a == b for a, b in zip(pp, ps))
        print(f"  {name:9s} pyroomacoustics {tp:9.1f} ms/s   soundloc {ts:7.1f} ms/s   {tp / ts:6.1f}x   same peaks {same}/{len(pp)}")
    # pyroomacoustics' usual call: the whole recording's STFT as one window.
    for name in ["MUSIC", "NormMUSIC", "SRP"]:
        res = {}
        for lib in (pra.doa, soundloc.doa):
            d = lib.algorithms[name](L, FS, NFFT, num_src=2, **kw)
            d.locate_sources(X, freq_range=[500.0, 4000.0])
            best = float("inf")
            for _ in range(PASSES):
                t = time.perf_counter()
                d.locate_sources(X, freq_range=[500.0, 4000.0])
                best = min(best, time.perf_counter() - t)
            res[lib.__name__] = (best * 1e3, set(np.round(d.src_idx).tolist()))
        (tp, pp), (ts, ps) = res["pyroomacoustics.doa"], res["soundloc.doa"]
        print(f"  {name:9s} whole recording, one call: pyroomacoustics {tp:8.1f} ms   soundloc {ts:7.2f} ms   "
              f"{tp / ts:6.1f}x   same peaks {int(pp == ps)}/1")


run("8-mic ring (r 3.65 cm), 72 directions", pra.circular_2D_array([0, 0], 8, 0.0, 0.0365),
    dict(azimuth=np.radians(np.arange(0, 360, 5.0))), seconds=10.0)
pts = np.array([[np.sin(c) * np.cos(a), np.sin(c) * np.sin(a), np.cos(c)] for a, c in zip(*fib(60))]).T * 0.1
run("60-mic sphere (r 10 cm), 2522 directions", pts, dict(dim=3, n_grid=2522), seconds=2.0)
