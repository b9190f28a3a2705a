"""Where the rate model's time goes: wall time per stage (measurement only).

The stage functions are wrapped with timers in this process; nothing in the
model changes. Shares are of the whole ``run_edfg`` call.
"""
from __future__ import annotations

import collections
import time

from .inputs import load

# (module, attribute, label): the parts of run_edfg that take time.
STAGES = (
    ("snn_fg.rate.edfg", "event_entries", "stages 1-4 (pyramid, DoG, orientation)"),
    ("snn_fg.rate.edfg", "oriented_responses", "  of which DoG responses (FFT)"),
    ("snn_fg.rate._sparse_kernels", "scatter", "stage 7 grouping input (scatter)"),
    ("snn_fg.rate._sparse_kernels", "winner_take_all", "stage 7 rectify + compete"),
    ("snn_fg.rate._sparse_kernels", "gather", "stage 8 feedback correlation, sparse levels (gather)"),
    ("snn_fg.rate.grouping", "SparseGrouping._correlate_dense", "stage 8 feedback correlation, dense levels (FFT)"),
    ("snn_fg.rate._sparse_kernels", "pool_add", "stage 8 cross-level pooling (bicubic at entries)"),
    ("snn_fg.rate.grouping", "SparseGrouping.readout", "stage 9 readout"),
)


def _wrap(acc, owner, attr, label):
    fn = getattr(owner, attr)

    def timed(*args, **kwargs):
        t = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            acc[label] += time.perf_counter() - t

    setattr(owner, attr, timed)


def profile(specs, repeats: int) -> dict:
    """Per-stage seconds per frame (median input order), summed over ``specs``."""
    import importlib

    from snn_fg.rate.edfg import run_edfg

    acc = collections.defaultdict(float)
    for mod, attr, label in STAGES:
        owner = importlib.import_module(mod)
        *path, name = attr.split(".")
        for p in path:
            owner = getattr(owner, p)
        _wrap(acc, owner, name, label)
    inputs = [load(s) for s in specs]
    run_edfg(inputs[0].pos, inputs[0].neg)       # warm-up (compilation, caches)
    acc.clear()
    t = time.perf_counter()
    for _ in range(repeats):
        for inp in inputs:
            run_edfg(inp.pos, inp.neg)
    total = time.perf_counter() - t
    n = repeats * len(inputs)
    stages = {label: acc[label] / n for _, _, label in STAGES}
    return {"inputs": list(specs), "total_s_per_frame": total / n, "stages_s_per_frame": stages,
            "shares": {k: v / (total / n) for k, v in stages.items()}}
