"""Live sound source localization from a microphone array with the `sounddevice` package.

    pip install sounddevice          # needs PortAudio (Debian: apt-get install libportaudio2)
    python live_sounddevice.py --tf tf.zip                       # HARK transfer functions
    python live_sounddevice.py --geometry mics.npy --grid ring:5 # (M, 3) positions, metres
    python live_sounddevice.py --tf tf.zip --noise-seconds 2     # first 2 s: noise only → GEVD
    python live_sounddevice.py --list-devices

Audio is captured in 10 ms blocks by PortAudio's callback thread and handed to the main
thread through a queue; every block goes to ``Localizer.push``, which returns the results
that block completed (one line per result: time, then azimuth/elevation/power per source).
With ``--noise-seconds`` the first seconds are taken as noise only (say, the drone's rotors
before anyone talks): K is estimated from them and the textbook GEVD runs from then on.
Ctrl-C stops; the last results are flushed.
"""

import argparse
import queue
import sys

import numpy as np

import soundloc


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--tf", help="HARK transfer-function zip or HGTF file")
    p.add_argument("--geometry", help="(M, 3) microphone positions in metres, .npy or text")
    p.add_argument("--grid", default="ring:5", help="direction grid with --geometry (ring:STEP, sphere:N)")
    p.add_argument("--fs", type=int, default=16000, help="sampling rate with --geometry, Hz")
    p.add_argument("--device", default=None, help="input device (name or index; see --list-devices)")
    p.add_argument("--list-devices", action="store_true", help="list audio devices and exit")
    p.add_argument("--seconds", type=float, default=None, help="stop after this long (default: Ctrl-C)")
    p.add_argument("--noise-seconds", type=float, default=0.0, help="noise-only lead-in for GEVD")
    p.add_argument("--num-sources", type=int, default=2)
    p.add_argument("--track", action="store_true", help="tracking with ids")
    p.add_argument("--compute", default="auto", help="soundloc device: auto, cpu, cuda")
    return p.parse_args(argv)


def localizer_kwargs(args):
    kw = dict(num_sources=args.num_sources, track=args.track, device=args.compute, spectrum=False)
    if args.tf:
        kw["tf"] = args.tf
    elif args.geometry:
        mics = np.load(args.geometry) if args.geometry.endswith(".npy") else np.loadtxt(args.geometry)
        kw.update(geometry=mics, grid=args.grid, fs=args.fs)
    else:
        raise SystemExit("give --tf or --geometry")
    return kw


def format_result(res, i):
    parts = ["%8.3f s" % res.times[i]]
    for j in range(res.azimuth_deg.shape[1]):
        if np.isnan(res.azimuth_deg[i, j]):
            continue
        tag = "" if res.ids[i, j] < 0 else "#%d " % res.ids[i, j]
        parts.append("%saz %7.1f el %5.1f %5.1f dB" % (tag, res.azimuth_deg[i, j], res.elevation_deg[i, j],
                                                        res.power_db[i, j]))
    return "  ".join(parts)


def run(args, sd=None, out=sys.stdout):
    """Capture and localize; returns every result as one list per push (for tests)."""
    if sd is None:
        import sounddevice as sd
    if args.list_devices:
        print(sd.query_devices(), file=out)
        return []
    kw = localizer_kwargs(args)
    probe = soundloc.Localizer(**kw)  # the array's rate and channel count
    fs, channels = probe.fs, probe.num_mics
    blocks = queue.Queue(maxsize=1000)  # 10 s of 10 ms blocks: beyond that we are too slow

    def callback(indata, frames, time, status):
        if status:
            print("capture:", status, file=sys.stderr)
        try:
            blocks.put_nowait(indata.copy())
        except queue.Full:
            print("capture: localization is falling behind; a block was dropped", file=sys.stderr)

    got = []
    loc = None if args.noise_seconds > 0 else probe
    noise, noise_len, total = [], 0, 0
    limit = None if args.seconds is None else int(args.seconds * fs)
    with sd.InputStream(samplerate=fs, channels=channels, dtype="float32", blocksize=fs // 100,
                        device=args.device, callback=callback):
        print("listening: %d channels at %d Hz (Ctrl-C stops)" % (channels, fs), file=sys.stderr)
        try:
            while limit is None or total < limit:
                x = blocks.get(timeout=5.0)
                if limit is not None:
                    x = x[: limit - total]
                total += len(x)
                if loc is None:  # still collecting the noise-only lead-in
                    take = min(len(x), int(round(args.noise_seconds * fs)) - noise_len)
                    noise.append(x[:take])
                    noise_len += take
                    x = x[take:]
                    if noise_len < int(round(args.noise_seconds * fs)):
                        continue
                    loc = soundloc.Localizer(noise=np.concatenate(noise), **kw)
                    print("noise matrix from %.2f s; algorithm %s; times count from its end"
                          % (noise_len / fs, loc.algorithm), file=sys.stderr)
                    if len(x) == 0:
                        continue
                r = loc.push(x)
                got.append(r)
                for i in range(len(r)):
                    print(format_result(r, i), file=out, flush=True)
        except KeyboardInterrupt:
            pass
        except queue.Empty:
            print("capture: no audio for 5 s", file=sys.stderr)
    if loc is not None:
        r = loc.flush()
        got.append(r)
        for i in range(len(r)):
            print(format_result(r, i), file=out, flush=True)
    return got


if __name__ == "__main__":
    run(parse_args())
