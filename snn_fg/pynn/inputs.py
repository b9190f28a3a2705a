"""An export's input spike file (``snn-fg events INPUT --write-spikes``), read by its ``run.py``.

STANDALONE (numpy and the standard library only): copied into every PyNN
and Lava export as ``fg_inputs.py``. A file that is missing or not one for
the export ends the program with one line naming the file and the problem.
"""

from __future__ import annotations

import os
import sys
import zipfile

import numpy as np

#: what an input spike file holds (``snn-fg events INPUT --write-spikes`` writes one)
INPUT_KEYS = ("indices", "steps", "dt_ms", "period_steps", "shape")


def read_input(path, frame_shape, n_sources, dt_ms=None):
    """The arrays of an input spike file, or exit with one line naming the
    file and what is wrong with it (missing, not an .npz, a key missing, a
    frame other than the network's, a time step other than the network's
    ``dt_ms`` where given, a source the network does not have)."""
    if not os.path.isfile(path):
        sys.exit(
            f"run.py: error: {path}: no such file (snn-fg events INPUT --write-spikes {path} --export . writes one)"
        )
    try:
        with np.load(path) as d:
            missing = [k for k in INPUT_KEYS if k not in d.files]
            if missing:
                sys.exit(
                    f"run.py: error: {path}: not an input spike file: no {', '.join(missing)} (it needs "
                    f"{', '.join(INPUT_KEYS)}; snn-fg events INPUT --write-spikes writes one)"
                )
            d = {k: d[k] for k in INPUT_KEYS}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError):
        sys.exit(
            f"run.py: error: {path}: not an .npz file (expected the input spike file that "
            f"snn-fg events INPUT --write-spikes writes)"
        )
    shape = tuple(int(v) for v in d["shape"])
    if frame_shape is not None and shape != tuple(frame_shape):
        sys.exit(
            f"run.py: error: {path}: spikes of a {shape[1]} x {shape[0]} frame; this network's frame is "
            f"{frame_shape[1]} x {frame_shape[0]} (width x height): write them with --export . from this folder"
        )
    if dt_ms is not None and abs(float(d["dt_ms"]) - float(dt_ms)) > 1e-9:
        sys.exit(f"run.py: error: {path}: dt_ms={float(d['dt_ms'])} differs from the network's {float(dt_ms)}")
    idx = d["indices"]
    if idx.size and (idx.min() < 0 or idx.max() >= n_sources):
        bad = int(np.flatnonzero((idx < 0) | (idx >= n_sources))[0])
        sys.exit(
            f"run.py: error: {path}: spike {bad} comes from source {int(idx[bad])}; the network has {n_sources} sources"
        )
    return d


def input_spikes(path, n_steps, n_sources, frame_shape=None, dt_ms=None):
    """``(indices, steps, dt_ms)``: every spike of the file's sources before ``n_steps`` (periodic
    patterns repeated up to it), ordered by source, then step; checked by :func:`read_input`."""
    d = read_input(path, frame_shape, n_sources, dt_ms)
    idx, steps, period = d["indices"].astype(np.int64), d["steps"].astype(np.int64), int(d["period_steps"])
    if period > 0:
        reps = -(-n_steps // period)
        idx = np.tile(idx, reps)
        steps = (steps[None, :] + period * np.arange(reps)[:, None]).ravel()
    keep = steps < n_steps
    idx, steps = idx[keep], steps[keep]
    order = np.lexsort((steps, idx))
    return idx[order], steps[order], float(d["dt_ms"])


def input_steps(path, n_steps, n_sources, frame_shape=None, dt_ms=None):
    """Spike steps of every source (periodic patterns repeated up to n_steps)."""
    idx, steps, dt_ms = input_spikes(path, n_steps, n_sources, frame_shape, dt_ms)
    bounds = np.searchsorted(idx, np.arange(n_sources + 1))
    return [steps[a:b] for a, b in zip(bounds[:-1], bounds[1:])], dt_ms
