"""How a weight-shared projection becomes synapses: the one definition.

STANDALONE like :mod:`snn_fg.pynn.network`: numpy only, copied verbatim
into every PyNN and Lava export (as ``fg_tables.py``), where ``run.py`` unrolls each
projection's kernel taps or interpolation matrices into explicit synapse
lists at build time. Inside snn_fg the same functions make the synapses of
the Brian2 and NEST backends (:mod:`snn_fg.lowering.connect`), of a board's
export (:mod:`snn_fg.export.board`) and the fast engine's stencils
(:mod:`snn_fg.backends.fast.tables`): a change to padding, stride or
folding is made here, once. Populations are described by plain dicts
(``grid``, ``stride``, ``level_shape``, ``channels``).

The rule of a Conv (:func:`land`): tap ``(c_out, c_in, dr, dc)`` makes
target channel ``c_out`` at level pixel ``P`` read source channel ``c_in``
at ``P + (dr, dc)``; with wrap-around padding that position is taken modulo
the level shape, otherwise a position outside the level has no synapse, and
neither has one off the source's lattice (not a multiple of its stride).
Taps that land on the same pair of cells (a kernel larger than a wrapped
level) add up (:func:`fold`).
"""

from __future__ import annotations

import json
import os
import sys

import numpy as np

#: elements per vectorised block when following kernel taps
CHUNK = 1 << 22


def kernel_taps(kernel: np.ndarray, prune: float, mode: str):
    """The kept taps of a kernel ``(C_out, C_in, kh, kw)``: arrays ``(c_out,
    c_in, dr, dc, value)`` and the kept fraction of ``sum |K|``. Taps under
    ``prune`` times the largest |value| are left out (with ``prune`` 0, the
    zeros); ``mode`` ``conv`` flips the kernel (``corr``: as it is)."""
    ab = np.abs(kernel)
    keep = ab >= prune * ab.max() if prune > 0 else ab > 0
    co, ci, r, c = np.nonzero(keep)
    dr, dc = r - kernel.shape[2] // 2, c - kernel.shape[3] // 2
    if mode == "conv":
        dr, dc = -dr, -dc
    return co, ci, dr, dc, kernel[co, ci, r, c], float(ab[keep].sum() / ab.sum())


def land(r, c, dr, dc, level_shape, stride: int, wrap: bool):
    """Level pixel ``(r + dr, c + dc)`` as a lattice point of a grid with
    ``stride`` on a level of ``level_shape``: ``(ok, i, j)``, ``ok`` False
    where there is no synapse (outside the level without ``wrap``, or off the
    lattice). Broadcasts over its arguments."""
    lr, lc = level_shape
    r, c = r + dr, c + dc
    if wrap:
        r, c = r % lr, c % lc
        ok = np.ones(np.shape(r), bool)
    else:
        ok = (r >= 0) & (r < lr) & (c >= 0) & (c < lc)
    if stride != 1:
        ok &= (r % stride == 0) & (c % stride == 0)
    return ok, r // stride, c // stride


def walk_taps(r, c, ch_to, dr, dc, other: dict, other_map, wrap: bool):
    """Follow taps from cells at level pixels ``(r, c)`` (of one channel) to
    the cells of population ``other``: tap ``k`` leads to
    channel ``ch_to[k]`` at ``(r + dr[k], c + dc[k])`` (:func:`land`);
    ``other_map`` gives the number of each of ``other``'s grid cells, -1
    where there is none. Returns ``(other's numbers, cell indices, tap
    indices)`` of every synapse, tap by tap in blocks of :data:`CHUNK`."""
    g_r, g_c = other["grid"]
    to_l, from_l, tap_l = [], [], []
    step = max(1, CHUNK // max(np.size(r), 1))
    for a0 in range(0, len(ch_to), step):
        ta = np.arange(a0, min(a0 + step, len(ch_to)))
        ok, i, j = land(r[None, :], c[None, :], dr[ta, None], dc[ta, None], other["level_shape"], other["stride"], wrap)
        flat = (ch_to[ta, None] * g_r + i) * g_c + j
        idx = np.where(ok, other_map[np.where(ok, flat, 0)], -1)
        ti, si = np.nonzero(idx >= 0)
        to_l.append(idx[ti, si])
        from_l.append(si)
        tap_l.append(ta[ti])
    if not to_l:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
    return (np.concatenate(to_l).astype(np.int64), np.concatenate(from_l), np.concatenate(tap_l))


def fold(pre, post, k, n_pre: int):
    """Synapses with the same ``(pre, post)`` merged, their values summed (those summing to 0 dropped)."""
    key = post * n_pre + pre
    uniq, inv = np.unique(key, return_inverse=True)
    ks = np.bincount(inv.ravel(), weights=k, minlength=uniq.size)
    keep = ks != 0
    return uniq[keep] % n_pre, uniq[keep] // n_pre, ks[keep]


def conv_pairs(taps: np.ndarray, values: np.ndarray, src: dict, tgt: dict, wrap: bool):
    """Synapses ``(pre, post, K)`` (flat cell indices, kernel values) of a
    weight-shared projection between two whole populations of one level;
    ``taps`` rows are ``(c_out, c_in, dr, dc)`` (module docstring)."""
    t_gr, t_gc = tgt["grid"]
    s_gr, s_gc = src["grid"]
    ts = tgt["stride"]
    ii, jj = np.meshgrid(np.arange(t_gr), np.arange(t_gc), indexing="ij")
    r0, c0 = (ii * ts).ravel(), (jj * ts).ravel()
    cell = np.arange(r0.size)
    pre_l, post_l, k_l = [], [], []
    for (co, ci, dr, dc), k in zip(taps, values, strict=True):
        ok, i, j = land(r0, c0, dr, dc, src["level_shape"], src["stride"], wrap)
        pre_l.append((ci * s_gr + i[ok]) * s_gc + j[ok])
        post_l.append(co * t_gr * t_gc + cell[ok])
        k_l.append(np.full(int(ok.sum()), k))
    pre, post, k = _cat(pre_l, post_l, k_l)
    if wrap and pre.size:
        pre, post, k = fold(pre, post, k, src["channels"] * s_gr * s_gc)
    return pre, post, k


def conv_stencil(taps: np.ndarray, values: np.ndarray, tgt: dict, wrap: bool):
    """The taps as seen from a spike: a source at level pixel ``p`` of input
    channel ``c_in`` reaches the target's lattice point ``p // stride - q``
    (``stride``: the target's) through the taps of its class ``(c_in,
    p mod stride)``; returns ``(c_out, class, qr, qc, value, folded)`` with
    class ``(c_in * stride + p_r mod stride) * stride + p_c mod stride``.

    The offsets are where :func:`land` puts each tap for a source of each
    class far from the level's edges; with ``wrap`` and a kernel wider than
    the level (``folded``), for a source at the level's corner, the offsets
    taken modulo the grid and the taps landing together added up
    (:func:`fold`)."""
    s = tgt["stride"]
    gr, gc = tgt["grid"]
    co, ci, dr, dc = (np.asarray(taps[:, k], np.int64) for k in range(4))
    reach = int(np.abs(taps[:, 2:]).max()) // s if len(taps) else 0
    folded = wrap and 2 * reach + 1 > min(gr, gc)
    far = s * (reach + 2)  # (a lattice point far from every edge of an unbounded level)
    level = (np.iinfo(np.int32).max,) * 2 if not folded else tuple(tgt["level_shape"])
    base = 0 if folded else far
    out = [[] for _ in range(5)]
    for a in range(s):
        for b in range(s):
            # a source at level pixel (base + a, base + b) reaches a target T where T + d lands on it
            ok, i, j = land(base + a, base + b, -dr, -dc, level, s, folded)
            qr, qc = (base + a) // s - i[ok], (base + b) // s - j[ok]
            if folded:
                qr, qc = qr % gr, qc % gc
            for lst, v in zip(out, (co[ok], (ci[ok] * s + a) * s + b, qr, qc, values[ok]), strict=True):
                lst.append(v)
    co, cls, qr, qc, k = (np.concatenate(v) if v else np.zeros(0) for v in out)
    if folded and co.size:  # (taps on one cell add up: the key is (c_out, class, qr, qc))
        n = np.array([co.max() + 1, cls.max() + 1, gr, gc], np.int64)
        key = ((co * n[1] + cls) * n[2] + qr) * n[3] + qc
        key, _, k = fold(key, np.zeros_like(key), k, int(np.prod(n)))
        qc, key = key % n[3], key // n[3]
        qr, key = key % n[2], key // n[2]
        cls, co = key % n[1], key // n[1]
    return co.astype(np.int64), cls.astype(np.int64), qr.astype(np.int64), qc.astype(np.int64), k, folded


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
    """``(network.json, tables.npz)`` of the export folder run.py runs in, or exit with one line
    (also when ``network.json``, which a user may edit, is not valid JSON or breaks a rule of
    :func:`export_problem`)."""
    for name in ("network.json", "tables.npz"):
        if not os.path.isfile(name):
            sys.exit(
                f"run.py: error: no {name} here: run run.py in the folder of its export (cd DIR && python run.py ...)"
            )
    with open("network.json") as fh:
        try:
            meta = json.load(fh)
        except ValueError as exc:
            sys.exit(f"run.py: error: network.json: not valid JSON: {exc}")
    problem = export_problem(meta)
    if problem:
        sys.exit(f"run.py: error: network.json: {problem}; nothing was run")
    return meta, np.load("tables.npz")


def _number(value, lo=None, lo_open=False) -> bool:
    """Whether ``value`` is a finite number (not a bool) at least ``lo`` (above it: ``lo_open``)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        return False
    return lo is None or (value > lo if lo_open else value >= lo)


#: the neuron constants of an export's population, and the rule each keeps (snn-fg's own, snn_fg.network.nodes.Neuron)
NEURON_RULES = {
    "tau_m_ms": (0, True),
    "tau_exc_ms": (0, True),
    "tau_inh_ms": (0, True),
    "t_ref_ms": (0, False),
    "v_rest_mv": (None, False),
    "v_reset_mv": (None, False),
    "v_th_mv": (None, False),
}


def export_problem(meta) -> str:
    """What makes an export's ``network.json`` (``meta``, as read) unfit to run, in words, or ``""``:
    a missing key (a key misspelt in an edit), or a value that breaks the rule snn-fg's own
    description keeps (a time constant above 0, the threshold above rest and reset, a projection's
    gain and delay at least 0, its sign +1 or -1, its populations in the file; a Lava export's
    threshold above 0)."""
    if not isinstance(meta, dict):
        return "expected a JSON object"
    for key in ("dt_ms", "populations", "projections"):
        if key not in meta:
            return f"has no {key!r} (a key misspelt?)"
    if not _number(meta["dt_ms"], 0, True):
        return f"dt_ms={meta['dt_ms']!r} must be a number above 0"
    names = set()
    for p in meta["populations"]:
        name = p.get("name") if isinstance(p, dict) else None
        if not isinstance(name, str) or not name:
            return f"a population without a name: {str(p)[:60]}"
        names.add(name)
        for key in ("size", "neuron"):
            if key not in p:
                return f"population {name!r} has no {key!r} (a key misspelt?)"
        neuron = p["neuron"]
        if neuron is not None:
            for key, (lo, lo_open) in NEURON_RULES.items():
                if key not in neuron:
                    return f"population {name!r}: its neuron has no {key!r} (a key misspelt?)"
                if not _number(neuron[key], lo, lo_open):
                    rule = "a number" if lo is None else f"a number {'above' if lo_open else 'at least'} {lo}"
                    return f"population {name!r}: {key}={neuron[key]!r} must be {rule}"
            if neuron["v_th_mv"] <= max(neuron["v_rest_mv"], neuron["v_reset_mv"]):
                return f"population {name!r}: v_th_mv={neuron['v_th_mv']!r} must lie above v_rest_mv and v_reset_mv"
        lava = p.get("lava")
        if isinstance(lava, dict) and "vth" in lava and not _number(lava["vth"], 0, True):
            return f"population {name!r}: lava vth={lava['vth']!r} must be a number above 0"
    for pr in meta["projections"]:
        name = pr.get("name") if isinstance(pr, dict) else None
        if not isinstance(name, str) or not name:
            return f"a projection without a name: {str(pr)[:60]}"
        for key in ("source", "target", "sign", "gain_mv", "delay_ms", "table", "type"):
            if key not in pr:
                return f"projection {name!r} has no {key!r} (a key misspelt?)"
        for key in ("source", "target"):
            if pr[key] not in names:
                return f"projection {name!r}: its {key} {pr[key]!r} is no population of the file"
        if pr["sign"] not in (1, -1) or isinstance(pr["sign"], bool):
            return f"projection {name!r}: sign={pr['sign']!r} must be 1 or -1"
        for key in ("gain_mv", "delay_ms"):
            if not _number(pr[key], 0):
                return f"projection {name!r}: {key}={pr[key]!r} must be a number at least 0"
        if pr["type"] not in ("conv", "resize"):
            return f"projection {name!r}: type={pr['type']!r} must be 'conv' or 'resize'"
    return ""
