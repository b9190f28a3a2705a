"""Where the rate model's time goes: CPU time per stage (measurement only).

The stage functions are wrapped with timers in this process and the model
runs on one thread, so stages add up; nothing else in the model changes.
CPU time (``time.process_time``) rather than wall time, so that the shares
hold on a loaded machine. Shares are of the whole ``run_edfg`` call.
"""

from __future__ import annotations

import collections
import time

from .inputs import load

# (module, attribute, label): the parts of run_edfg that take time.
STAGES = (
    ("snn_fg.models.rate.edfg", "event_entries", "stages 1-4 (pyramid, DoG, orientation)"),
    ("snn_fg.models.rate.edfg", "oriented_responses", "  of which DoG responses, Fourier levels"),
    ("snn_fg.models.rate._sparse_kernels", "scatter", "stage 7 grouping input (scatter)"),
    ("snn_fg.models.rate._sparse_kernels", "winner_take_all", "stage 7 rectify + compete"),
    ("snn_fg.models.rate._sparse_kernels", "gather", "stage 8 feedback correlation, sparse levels (gather)"),
    (
        "snn_fg.models.rate.grouping",
        "SparseGrouping._correlate_dense",
        "stage 8 feedback correlation, dense levels (FFT)",
    ),
    ("snn_fg.models.rate._sparse_kernels", "pool_add", "stage 8 cross-level pooling (bicubic at entries)"),
    ("snn_fg.models.rate.grouping", "SparseGrouping._group_dense", "stage 7 grouping input (FFT, when most changed)"),
    ("snn_fg.models.rate.grouping", "SparseGrouping._inhibition", "stage 7 inhibition test"),
    ("snn_fg.models.rate.grouping", "SparseGrouping._plan_feedback", "stage 8 planning (sites)"),
    ("snn_fg.models.rate.grouping", "SparseGrouping.readout", "stage 9 readout"),
)


def _wrap(acc, owner, attr, label):
    fn = getattr(owner, attr)

    def timed(*args, **kwargs):
        t = time.process_time()
        try:
            return fn(*args, **kwargs)
        finally:
            acc[label] += time.process_time() - t

    setattr(owner, attr, timed)


def profile(specs, repeats: int) -> dict:
    """Per-stage seconds per frame (median input order), summed over ``specs``."""
    import importlib

    from snn_fg.models.rate import grouping
    from snn_fg.models.rate.edfg import run_edfg

    grouping._THREADS = 1

    acc = collections.defaultdict(float)
    for mod, attr, label in STAGES:
        owner = importlib.import_module(mod)
        *path, name = attr.split(".")
        for p in path:
            owner = getattr(owner, p)
        _wrap(acc, owner, name, label)
    inputs = [load(s) for s in specs]
    run_edfg(inputs[0].pos, inputs[0].neg)  # warm-up (compilation, caches)
    acc.clear()
    t = time.process_time()
    for _ in range(repeats):
        for inp in inputs:
            run_edfg(inp.pos, inp.neg)
    total = time.process_time() - t
    n = repeats * len(inputs)
    stages = {label: acc[label] / n for _, _, label in STAGES}
    return {
        "inputs": list(specs),
        "clock": "cpu (process_time), one thread",
        "total_s_per_frame": total / n,
        "stages_s_per_frame": stages,
        "shares": {k: v / (total / n) for k, v in stages.items()},
    }
