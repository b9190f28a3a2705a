"""The exported network stepped in Loihi 2's arithmetic with numpy alone: the
reference Lava's runs are checked against, spike for spike.

STANDALONE (numpy only; copied into every Lava export as ``fg_reference.py``,
``run.py --simulator reference``). It follows :mod:`snn_fg.lava.fixed` step
by step (``arithmetic="fixed"``), or Lava's floating-point models on the
same numbers (``"float"``), with the timing Lava's processes give:
population cells are updated at our step ``n`` from what the connections
received at step ``n - 1 - delay``, then the step's spikes (the input's
too) go out through the connections. Besides the counts it says how close
the state came to the chip's limits (:class:`Limits`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

try:  # inside snn_fg
    from . import fixed
except ImportError:  # inside an export folder
    import fg_loihi as fixed


@dataclass
class Limits:
    """How the state met the chip's limits over a run: the largest |a_in| a
    step delivered (the chip's accumulator holds 16 bits: ``2**15``), the
    currents that wrapped around and the voltages that saturated (cell-steps)."""

    max_a_in: int = 0
    u_wraps: int = 0
    v_saturated: int = 0
    by_population: dict = field(default_factory=dict)


class _Csr:
    """One connection's synapses sorted by source, for gathering the synapses of the sources that spiked."""

    def __init__(self, conn, n_pre: int):
        order = np.argsort(conn.pre, kind="stable")
        self.post, self.w = conn.post[order], conn.w2m[order]
        self.ptr = np.searchsorted(conn.pre[order], np.arange(n_pre + 1))

    def select(self, spiking_idx) -> np.ndarray:
        """Positions (in this order) of the synapses of the sources ``spiking_idx``."""
        lo, hi = self.ptr[spiking_idx], self.ptr[spiking_idx + 1]
        n = hi - lo
        return np.repeat(lo - np.cumsum(n) + n, n) + np.arange(n.sum())


def simulate(meta: dict, conns: list, source_steps: list, n_steps: int, count_from: int, arithmetic: str = "fixed"):
    """Run the export described by ``meta`` (``network.json``) with its
    :class:`~snn_fg.lava.synapses.Connection` s for ``n_steps`` steps.

    ``source_steps``: the spike steps of every source cell, sources in
    ``meta``'s order (what ``fg_inputs.input_steps`` returns). Returns
    ``(counts, limits)``: population name -> spikes per cell from step
    ``count_from`` on, and the :class:`Limits` met (fixed point only).
    """
    if arithmetic not in ("fixed", "float"):
        raise ValueError(f"arithmetic must be 'fixed' or 'float', got {arithmetic!r}")
    pops = {p["name"]: p for p in meta["populations"]}
    cells = [p for p in meta["populations"] if p["neuron"] is not None]
    dtype = np.int64 if arithmetic == "fixed" else np.float64
    state = {p["name"]: (np.zeros(p["size"], dtype), np.zeros(p["size"], dtype)) for p in cells}
    last = {p["name"]: np.full(p["size"], -(10**9), np.int64) for p in cells}
    counts = {p["name"]: np.zeros(p["size"], np.int64) for p in cells}
    depth = max([c.delay_steps for c in conns] + [0]) + 2
    pending = {p["name"]: np.zeros((depth, p["size"]), dtype) for p in cells}
    csr = [_Csr(c, pops[c.source]["size"]) for c in conns]
    weights = [c_.w if arithmetic == "fixed" else fixed.float_weights(c_.w, c.weight_exp) for c, c_ in zip(conns, csr)]
    inputs = _input_schedule(meta, source_steps, n_steps)
    limits = Limits()
    for n in range(n_steps):
        spikes = dict(inputs[n])
        for p in cells:
            name, lava = p["name"], p["lava"]
            a_in = pending[name][n % depth].copy()
            pending[name][n % depth] = 0
            frozen = (n - last[name]) <= lava["refractory_steps"]
            u, v = state[name]
            if arithmetic == "fixed":
                _note(limits, name, u, v, a_in, lava)
                bias = fixed.effective_bias(lava["bias_mant"], lava["bias_exp"])
                regs = {"du": lava["du"], "dv": lava["dv"], "bias": bias, "vth": lava["vth"]}
                u, v, s = fixed.lif_fixed(u, v, a_in, frozen=frozen, **regs)
            else:
                regs = fixed.float_constants(lava["du"], lava["dv"], lava["bias_mant"], lava["bias_exp"], lava["vth"])
                u, v, s = fixed.lif_float(u, v, a_in, frozen=frozen, **regs)
            state[name] = (u, v)
            last[name][s] = n
            if n >= count_from:
                counts[name] += s
            spikes[name] = np.flatnonzero(s)
        for c, c_, w in zip(conns, csr, weights):
            if c.source not in spikes or not spikes[c.source].size:
                continue
            at = c_.select(spikes[c.source])
            a = np.bincount(c_.post[at], weights=w[at], minlength=pops[c.target]["size"])
            a = fixed.shift(a.astype(np.int64), c.weight_exp) if arithmetic == "fixed" else a
            pending[c.target][(n + 1 + c.delay_steps) % depth] += a
    return counts, limits


def _note(limits: Limits, name: str, u, v, a_in, lava):
    """Record how this step's input and state meet the limits (before the update, from the same numbers)."""
    if not a_in.size:
        return
    big = int(np.abs(a_in).max())
    raw_u = fixed.trunc_decay(u, lava["du"] + fixed.DU_OFFSET) + (a_in << fixed.ACT_SHIFT)
    wraps = int(((raw_u > fixed.STATE_MAX) | (raw_u <= -fixed.STATE_MAX)).sum())
    raw_v = fixed.trunc_decay(v, lava["dv"]) + fixed.wrap_current(raw_u)
    sat = int((np.abs(raw_v) >= fixed.STATE_MAX - 1).sum())
    limits.max_a_in = max(limits.max_a_in, big)
    limits.u_wraps += wraps
    limits.v_saturated += sat
    mine = limits.by_population.setdefault(name, {"max_a_in": 0, "u_wraps": 0, "v_saturated": 0})
    mine["max_a_in"] = max(mine["max_a_in"], big)
    mine["u_wraps"] += wraps
    mine["v_saturated"] += sat


def _input_schedule(meta: dict, source_steps: list, n_steps: int) -> list:
    """Per step, source population name -> indices of its cells that spike."""
    out = [{} for _ in range(n_steps)]
    offset = 0
    for p in meta["populations"]:
        if p["neuron"] is not None:
            continue
        cell = np.concatenate(
            [np.full(len(s), i, np.int64) for i, s in enumerate(source_steps[offset : offset + p["size"]])]
            + [np.zeros(0, np.int64)]
        )
        steps = np.concatenate([np.asarray(s, np.int64) for s in source_steps[offset : offset + p["size"]]] + [[]])
        steps = steps.astype(np.int64)
        offset += p["size"]
        for n in np.unique(steps[steps < n_steps]):
            out[n][p["name"]] = np.unique(cell[steps == n])
    return out
