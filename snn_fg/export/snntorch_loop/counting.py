"""A graph of the snnTorch profile run by snnTorch through nirtorch, each population's spikes counted.

STANDALONE (numpy and the standard library; torch and snnTorch imported when a graph is run):
copied into a NIR export folder as ``fg_snntorch.py``, which its ``run.py`` runs without
snn_fg; inside snn_fg :func:`snn_fg.export.snntorch_run.run_snntorch` runs it. The graph's
one ``Input`` node takes a frame of shape (2, H, W) each step: ON pixels, then OFF pixels, a
spike a 1. The window clock's source (``2 * H * W``, after every pixel's) has no node in the
graph (:mod:`snn_fg.export.nir_snntorch` leaves the clock out): its spikes are left out.
snnTorch's modules are named after the populations (``.`` as ``_``); each cell module's
output at a step is its spikes, counted from ``count_from_step`` on.
"""

from __future__ import annotations

import contextlib
import io

import numpy as np


def step_bounds(indices, steps, n_steps: int):
    """``(indices, bounds)``: the pixel spikes ``indices`` (at ``steps``) ordered by step, and
    where each step's spikes start in them (``bounds[k]:bounds[k + 1]`` are step ``k``'s)."""
    order = np.argsort(steps, kind="stable")
    idx, st = np.asarray(indices)[order], np.asarray(steps)[order]
    return idx, np.searchsorted(st, np.arange(n_steps + 1))


def first_counted_step(count_from_ms: float, step_ms: float) -> int:
    """The first step whose start lies at or after ``count_from_ms`` (the counting window's first)."""
    return int(np.ceil((count_from_ms - 1e-9) / step_ms))


def count_spikes(graph, populations, indices, steps, shape, *, n_steps: int, count_from_step: int) -> dict:
    """Run the NIR ``graph`` (read with ``nir.read``) in snnTorch for ``n_steps`` steps on the
    pixel spikes ``indices`` (ON pixel ``y * W + x``, OFF pixel ``H * W + y * W + x``) at
    ``steps``, for a frame of ``shape`` (H, W); count each of ``populations`` (``(name, size)``
    of its cells) from step ``count_from_step`` on: name -> counts per cell (flat order)."""
    import torch
    from snntorch.import_nir import import_from_nir

    with contextlib.redirect_stdout(io.StringIO()):  # snnTorch prints its weight-scaling notes
        module = import_from_nir(graph)
    mods = dict(module.named_modules())
    counts, live = {}, [False]

    def hook(name):
        def count(_mod, _inp, out):
            if live[0]:
                counts[name] += (out[0] if isinstance(out, tuple) else out).reshape(-1).numpy().astype(np.int64)

        return count

    for name, size in populations:
        counts[name] = np.zeros(size, np.int64)
        mods[name.replace(".", "_")].register_forward_hook(hook(name))
    h, w = shape
    pixels = np.asarray(indices) < 2 * h * w  # (the window clock's spikes, if any: no node takes them)
    idx, bounds = step_bounds(np.asarray(indices)[pixels], np.asarray(steps)[pixels], n_steps)
    frame = np.zeros(2 * h * w, np.float32)
    state = None
    with torch.no_grad():
        for k in range(n_steps):
            frame[:] = 0
            frame[idx[bounds[k] : bounds[k + 1]]] = 1.0
            live[0] = k >= count_from_step
            _, state = module(torch.from_numpy(frame.reshape(1, 2, h, w)), state)
    return counts
