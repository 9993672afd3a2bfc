"""Archives of recordings: one result file per recording, on Ray Data or in this process.

    from soundloc.archive import localize_files
    rows = localize_files(paths, "results/", tf="tf.zip", noise_range=(0.0, 1.0))   # here
    rows = localize_files(paths, "results/", ray=True, concurrency=4, tf="tf.zip")  # Ray Data

Each worker builds one ``soundloc.Localizer`` (the plan, and on a GPU the compiled
kernels, once) and localizes its recordings one after another with
``Localizer.localize_file``, which writes exactly what ``soundloc localize -o`` writes
(JSONL or CSV, whole or not at all). With Ray, workers are stateful actors
(``map_batches`` with a class); ``num_gpus=1`` gives each actor one GPU, which it uses
with ``device="auto"``. Recordings whose result file exists are skipped unless
``overwrite=True`` (a rerun resumes). The CLI's ``soundloc batch`` does the same for
SLURM arrays and GNU parallel (``--manifest``, ``--shard K/N``).
"""

import os
from pathlib import Path

import numpy as np

__all__ = ["localize_files", "result_path"]


def result_path(recording, out_dir, fmt="jsonl"):
    """Where the results of ``recording`` go: ``out_dir/<stem>.<fmt>``."""
    return str(Path(out_dir) / (Path(recording).stem + "." + fmt))


class _Worker:
    """One Localizer per worker (Ray actor or this process)."""

    def __init__(self, out_dir, fmt, localizer_kwargs):
        from . import Localizer

        self.out_dir, self.fmt = str(out_dir), fmt
        self.loc = Localizer(**localizer_kwargs)

    def one(self, path):
        out = result_path(path, self.out_dir, self.fmt)
        try:
            return out, int(self.loc.localize_file(str(path), out, self.fmt)), ""
        except (ValueError, OSError, RuntimeError) as e:
            return out, -1, str(e)

    def __call__(self, batch):
        rows = [self.one(p) for p in batch["path"]]
        return {
            "path": np.asarray(batch["path"]),
            "output": np.array([r[0] for r in rows]),
            "results": np.array([r[1] for r in rows], dtype=np.int64),
            "error": np.array([r[2] for r in rows]),
        }


def localize_files(paths, out_dir, *, fmt="jsonl", overwrite=False, ray=False, concurrency=None,
                   num_gpus=None, **localizer_kwargs):
    """Localize every recording in ``paths`` into ``out_dir`` (created if missing).

    Returns one dict per recording, in input order: ``path``, ``output``, ``results``
    (number of results; -1 on error), ``error`` ("" when it worked), ``skipped``.
    ``localizer_kwargs`` are ``soundloc.Localizer``'s (``tf=``/``geometry=``, ``noise_range=``,
    …). With ``ray=True`` (Ray must be installed and initialised, or it starts a local
    instance) ``concurrency`` actors run at once (default: 2), each with ``num_gpus`` GPUs.
    """
    if fmt not in ("jsonl", "csv"):
        raise ValueError(f"fmt {fmt!r}: expected 'jsonl' or 'csv'")
    # One path (a str or os.PathLike) is a list of one, not of its characters.
    paths = [os.fspath(paths)] if isinstance(paths, (str, bytes, os.PathLike)) else [os.fspath(p) for p in paths]
    paths = [os.fsdecode(p) for p in paths]
    outs = [result_path(p, out_dir, fmt) for p in paths]
    seen, dup = set(), set()
    for o in outs:
        (dup if o in seen else seen).add(o)
    if dup:
        raise ValueError(f"several recordings would write {sorted(dup)[0]}: rename them or use separate folders")
    os.makedirs(out_dir, exist_ok=True)
    todo = [p for p, o in zip(paths, outs) if overwrite or not os.path.exists(o)]
    done = {}
    if todo and ray:
        import ray as _ray

        # Bad options fail here, with their own exception, not as a dead Ray actor. On the
        # CPU: the driver may have no GPU where the actors do.
        from . import Localizer

        Localizer(**dict(localizer_kwargs, device="cpu"))

        ds = _ray.data.from_items([{"path": p} for p in todo])
        ds = ds.map_batches(
            _Worker,
            fn_constructor_kwargs=dict(out_dir=str(out_dir), fmt=fmt, localizer_kwargs=localizer_kwargs),
            batch_size=1,
            concurrency=concurrency or 2,
            num_gpus=num_gpus or 0,
        )
        for row in ds.take_all():
            done[str(row["path"])] = (str(row["output"]), int(row["results"]), str(row["error"]))
    elif todo:
        w = _Worker(out_dir, fmt, localizer_kwargs)
        for p in todo:
            done[p] = w.one(p)
    rows = []
    for p, o in zip(paths, outs):
        if p in done:
            out, n, err = done[p]
            rows.append(dict(path=p, output=out, results=n, error=err, skipped=False))
        else:
            rows.append(dict(path=p, output=o, results=None, error="", skipped=True))
    return rows
