"""The whole network's synapses from its weight-shared tables.

STANDALONE like :mod:`snn_fg.pynn.network`: numpy only, copied verbatim
into every PyNN export (as ``fg_tables.py``), where ``run.py`` unrolls each
projection's kernel taps or interpolation matrices into explicit synapse
lists at build time; :mod:`snn_fg.export.board` uses the same code in
snn_fg. Populations are described by plain dicts (``grid``, ``stride``,
``level_shape``, ``channels``).
"""

from __future__ import annotations

import json
import os
import sys

import numpy as np


def conv_pairs(taps: np.ndarray, values: np.ndarray, src: dict, tgt: dict, wrap: bool):
    """Synapses ``(pre, post, K)`` (flat cell indices, kernel values) of a
    weight-shared projection between two whole populations of one level.

    ``taps`` rows are ``(c_out, c_in, dr, dc)``: target channel ``c_out`` at
    level pixel ``p`` reads source channel ``c_in`` at ``p + (dr, dc)``
    (taken modulo the level shape with ``wrap``, else dropped outside it, and
    dropped off the source's stride lattice). Taps that fold onto the same
    source (a kernel larger than a wrapped level) add up.
    """
    lr, lc = tgt["level_shape"]
    t_gr, t_gc = tgt["grid"]
    s_gr, s_gc = src["grid"]
    ss, ts = src["stride"], tgt["stride"]
    ii, jj = np.meshgrid(np.arange(t_gr), np.arange(t_gc), indexing="ij")
    r0, c0 = (ii * ts).ravel(), (jj * ts).ravel()
    cell = np.arange(r0.size)
    pre_l, post_l, k_l = [], [], []
    for (co, ci, dr, dc), k in zip(taps, values):
        r, c = r0 + dr, c0 + dc
        if wrap:
            r, c = r % lr, c % lc
            ok = np.ones(r.shape, bool)
        else:
            ok = (r >= 0) & (r < lr) & (c >= 0) & (c < lc)
        if ss != 1:
            ok &= (r % ss == 0) & (c % ss == 0)
        pre_l.append((ci * s_gr + r[ok] // ss) * s_gc + c[ok] // ss)
        post_l.append(co * t_gr * t_gc + cell[ok])
        k_l.append(np.full(int(ok.sum()), k))
    pre, post, k = _cat(pre_l, post_l, k_l)
    if wrap and pre.size:
        n_pre = src["channels"] * s_gr * s_gc
        key = post * n_pre + pre
        uniq, inv = np.unique(key, return_inverse=True)
        ks = np.bincount(inv, weights=k, minlength=uniq.size)
        keep = ks != 0
        pre, post, k = uniq[keep] % n_pre, uniq[keep] // n_pre, ks[keep]
    return pre, post, k


def resize_pairs(rows: tuple, cols: tuple, channels: int, src: dict, tgt: dict, k_min: float):
    """Synapses ``(pre, post, K)`` of an interpolation between two whole
    populations: target ``(c, i, j)`` reads source ``(c, i', j')`` with
    ``K = A_r[i, i'] * A_c[j, j']``; ``rows``/``cols`` are each 1-D matrix's
    non-zeros per row as (index, value) arrays padded with index -1; products
    under ``k_min`` in magnitude are left out."""
    (ri, rv), (cj, cv) = rows, cols
    s_gr, s_gc = src["grid"]
    t_gr, t_gc = tgt["grid"]
    pre_l, post_l, k_l = [], [], []
    for a in range(ri.shape[1]):
        for b in range(cj.shape[1]):
            val = rv[:, a, None] * cv[None, :, b]
            ok = (ri[:, a, None] >= 0) & (cj[None, :, b] >= 0) & (val != 0) & (np.abs(val) >= k_min)
            ti, tj = np.nonzero(ok)
            src_flat = ri[ti, a] * s_gc + cj[tj, b]
            tgt_flat = ti * t_gc + tj
            for c in range(channels):
                pre_l.append(c * s_gr * s_gc + src_flat)
                post_l.append(c * t_gr * t_gc + tgt_flat)
                k_l.append(val[ti, tj])
    return _cat(pre_l, post_l, k_l)


def _cat(pre_l, post_l, k_l):
    if not pre_l:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    return (
        np.concatenate(pre_l).astype(np.int64),
        np.concatenate(post_l).astype(np.int64),
        np.concatenate(k_l).astype(np.float64),
    )


def load_tables(meta, tables):
    """Projection name -> what the unrollers above take (``tables``: an export's ``tables.npz``,
    ``meta``: its ``network.json``)."""
    out = {}
    for pr in meta["projections"]:
        key = pr["table"]
        if pr["type"] == "conv":
            out[pr["name"]] = (tables[f"{key}_taps"], tables[f"{key}_values"])
        else:
            out[pr["name"]] = tuple((tables[f"{key}_{a}_idx"], tables[f"{key}_{a}_val"]) for a in ("rows", "cols"))
    return out


def load_export():
    """``(network.json, tables.npz)`` of the export folder run.py runs in, or exit with one line."""
    for name in ("network.json", "tables.npz"):
        if not os.path.isfile(name):
            sys.exit(
                f"run.py: error: no {name} here: run run.py in the folder of its export (cd DIR && python run.py ...)"
            )
    with open("network.json") as fh:
        return json.load(fh), np.load("tables.npz")
