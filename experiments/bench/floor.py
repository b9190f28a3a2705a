"""The machine's floor for delivering synaptic events, measured by the bench itself.

One loop, compiled with numba: stream a target index (int32) and a weight
(float64) and add the weight into a state array of float64,
``state[idx[k]] += w[k]``. It is the least work a simulator that keeps
explicit synapse lists does per synaptic event, so the fast engine's CPU
time per event is reported as a ratio to it, measured in the same run:

* ``in_cache_random`` - random targets in a :data:`IN_CACHE_MB` array (the
  compact network's state as the issue measured it): the reference floor;
* ``contiguous``      - targets one after the other in the same array;
* ``large_random``    - random targets in a :data:`LARGE_MB` array;
* ``state_random``    - random targets in an array as large as a network's
  cell state (its cells times 32 bytes), per network.

Each is the best of :data:`REPEATS` passes over :data:`EVENTS` events, in
CPU time (the machine is shared: the best pass is the least disturbed).

A spike-for-spike exact engine also visits cells: it hands each cell that
received input its summed input, the cell brought up to the present in
closed form first, and it updates the active cells step by step. The least
such visits cost is measured the same way (:func:`visit_ns`,
:func:`step_ns`): the engine's own state records (32 bytes a cell, one
cache line's half) and the arithmetic of its hand-over and active step,
with nothing else, the next cells' records asked for 48 cells ahead; and
(:func:`lazy_visit_ns`) a visit that only adds input to a parked cell's
bound and pending sums, the route of fewer full visits.
(Arrays of each field instead of records, and the same arithmetic eight
cells at a time with AVX-512 gathers and scatters, were slower on the
machine of 1 Dec 2026: 4.5 and 4.9 ns a visit in cache, against 3.1 with
records; ``experiments/bench/visit_simd.c``.)

    python -m experiments.bench.floor [--state-mb 17 125]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from numba import njit

from snn_fg.backends.fast.lif import STATE, prefetch

IN_CACHE_MB = 2.8
LARGE_MB = 256.0
EVENTS = 20_000_000
REPEATS = 5
SEED = 7


@njit(cache=True)
def scatter_add(idx, w, state):
    """``state[idx[k]] += w[k]`` for every event ``k``."""
    for k in range(idx.size):
        state[idx[k]] += w[k]


def ns_per_event(state_mb: float, contiguous: bool = False, events: int = EVENTS, repeats: int = REPEATS) -> float:
    """CPU nanoseconds per event of :func:`scatter_add` into a ``state_mb`` MB array."""
    rng = np.random.default_rng(SEED)
    n = max(1, int(state_mb * 1e6 / 8))
    state = np.zeros(n)
    idx = (np.arange(events) % n) if contiguous else rng.integers(0, n, events)
    idx = idx.astype(np.int32)
    w = rng.random(events)
    scatter_add(idx[:10], w[:10], state)  # (compiled, or loaded from numba's cache)
    best = np.inf
    for _ in range(repeats):
        t = time.process_time()
        scatter_add(idx, w, state)
        best = min(best, time.process_time() - t)
    return 1e9 * best / events


@njit(cache=True)
def visit(idx, w, k, state, tab, v_rest, peak, gap, new):
    """The least a hand-over does for each cell ``idx[j]``: bring it ``k[j]``
    steps forward in closed form (the ``k``-th run of 8 values of ``tab``), add
    ``w[j]`` to its excitatory current, bound whether it might now fire, store
    it, and list it if it might (without a branch). Returns how many it listed."""
    n_new = 0
    for j in range(idx.size):
        if j + 48 < idx.size:
            prefetch(state, idx[j + 48])
        g = idx[j]
        c = state[g]
        at = k[j] * 8
        v = v_rest + ((tab[at] * (c.v - v_rest) + c.e * tab[at + 3]) - c.i * tab[at + 4])
        e = c.e * tab[at + 1] + w[j]
        i = c.i * tab[at + 2]
        c.v, c.e, c.i = v, e, i
        u, x = v - v_rest, max(e - i, 0.0)
        new[n_new] = g
        n_new += (max(u, x) > gap) & (max(u, 0.0) + peak * x > gap)
    return n_new


@njit(cache=True)
def step(idx, state, a, v_rest, v_th, v_reset, fired):
    """The least an active cell's step does for each cell ``idx[j]`` (sorted, as
    the engine keeps its active cells): one step of the closed form (``a``), the
    threshold and the reset; the cells that fired listed. Returns how many fired."""
    n_fired = 0
    for j in range(idx.size):
        g = idx[j]
        c = state[g]
        v = v_rest + ((a[0] * (c.v - v_rest) + c.e * a[3]) - c.i * a[4])
        c.e, c.i = c.e * a[1], c.i * a[2]
        spike = v > v_th
        c.v = v_reset if spike else v
        fired[n_fired] = g
        n_fired += spike
    return n_fired


#: the record of a cell that takes its input without being brought up to the present (the route of
#: fewer visits, issue 59): a bound on its potential, its input pending (summed with per-step factors
#: for its two decays), its last full update and its spike step; 32 bytes, as the engine's STATE
LAZY_STATE = np.dtype([("bound", "f8"), ("pe", "f8"), ("pm", "f8"), ("last", "i4"), ("spike", "i4")], align=True)


@njit(cache=True)
def lazy_visit(idx, w, ge, gm, state, peak, gap, new):
    """The least a visit costs that only adds input to a parked cell: the bound raised by the most
    the input can raise the potential (``peak * w``), the input added to the pending sums with the
    step's factors ``ge``, ``gm``, and the cell listed when the bound reaches ``gap`` (to be
    brought up to the present then). Returns how many it listed."""
    n_new = 0
    # (the loop's head written out as in visit: a helper that takes the arrays made a visit 20.9 ns, not 3.2,
    # numba counting references to them on each call; 1 Dec 02:46)
    for j in range(idx.size):
        if j + 48 < idx.size:
            prefetch(state, idx[j + 48])
        g = idx[j]
        c = state[g]
        b = c.bound + peak * w[j]
        c.bound, c.pe, c.pm = b, c.pe + w[j] * ge, c.pm + w[j] * gm
        new[n_new] = g
        n_new += b > gap
    return n_new


def lazy_visit_ns(state_mb: float = IN_CACHE_MB, visits: int = EVENTS, repeats: int = 3) -> float:
    """CPU nanoseconds a cell of :func:`lazy_visit`, to random cells of a ``state_mb`` MB state."""
    rng = np.random.default_rng(SEED)
    n = max(1, int(state_mb * 1e6 / LAZY_STATE.itemsize))
    state = np.zeros(n, LAZY_STATE)
    idx, w = rng.integers(0, n, visits).astype(np.uint64), 1e-9 * rng.random(visits)
    new = np.zeros(visits, np.int64)
    return 1e9 * _best(lambda: lazy_visit(idx, w, 1.01, 1.02, state, 0.2, 0.01, new), repeats) / visits


def example_tables(steps: int = 64) -> np.ndarray:
    """Advance tables shaped as the engine's (8 values a step: the decays of
    ``v``, ``I_exc``, ``I_inh``, then ``v``'s response to each current), of a
    cell with 20, 5 and 6.7 ms time constants at 1 ms steps."""
    k = np.arange(steps + 1)
    dm, de, di = 0.95, 0.8, 0.85
    t = np.zeros((steps + 1, 8))
    t[:, 0], t[:, 1], t[:, 2] = dm**k, de**k, di**k
    t[:, 3], t[:, 4] = 0.1 * (de**k - dm**k), 0.1 * (di**k - dm**k)
    return t.ravel()


def _best(call, repeats: int) -> float:
    call()  # (compiled, or loaded from numba's cache; the state warmed)
    best = np.inf
    for _ in range(repeats):
        t = time.process_time()
        call()
        best = min(best, time.process_time() - t)
    return best


def visit_ns(state_mb: float = IN_CACHE_MB, visits: int = EVENTS, repeats: int = 3) -> float:
    """CPU nanoseconds a cell of :func:`visit`, to random cells of a ``state_mb`` MB state."""
    rng = np.random.default_rng(SEED)
    n = max(1, int(state_mb * 1e6 / STATE.itemsize))
    state = np.zeros(n, STATE)
    state["v"] = -0.07
    idx = rng.integers(0, n, visits).astype(np.uint64)
    w, k = 1e-3 * rng.random(visits), rng.integers(1, 20, visits).astype(np.uint64)
    new, tab = np.zeros(visits, np.int64), example_tables()
    return 1e9 * _best(lambda: visit(idx, w, k, state, tab, -0.07, 0.2, 0.01, new), repeats) / visits


def step_ns(state_mb: float = IN_CACHE_MB, repeats: int = 5) -> float:
    """CPU nanoseconds a cell of :func:`step`, over every cell of a ``state_mb`` MB state in order."""
    n = max(1, int(state_mb * 1e6 / STATE.itemsize))
    state = np.zeros(n, STATE)
    state["v"] = -0.07
    idx, fired, a = np.arange(n, dtype=np.uint64), np.zeros(n, np.int64), example_tables()[8:16].copy()
    return 1e9 * _best(lambda: step(idx, state, a, -0.07, -0.05, -0.07, fired), repeats) / n


def measure(state_mb: dict | None = None, events: int = EVENTS) -> dict:
    """Every floor of the module docstring (ns per event); ``state_mb``:
    network name -> the size of its cell state (MB)."""
    return {
        "in_cache_random": ns_per_event(IN_CACHE_MB, events=events),
        "contiguous": ns_per_event(IN_CACHE_MB, contiguous=True, events=events),
        "large_random": ns_per_event(LARGE_MB, events=events),
        "state_random": {name: ns_per_event(mb, events=events) for name, mb in (state_mb or {}).items()},
        "visit_in_cache": visit_ns(IN_CACHE_MB, visits=events),
        "active_step_in_cache": step_ns(IN_CACHE_MB),
        "in_cache_mb": IN_CACHE_MB,
        "large_mb": LARGE_MB,
        "state_mb": dict(state_mb or {}),
        "events": events,
    }


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(prog="python -m experiments.bench.floor", description=__doc__.splitlines()[0])
    ap.add_argument("--state-mb", type=float, nargs="*", default=[], help="sizes of further random-target arrays (MB)")
    args = ap.parse_args(argv)
    print(json.dumps(measure({f"{mb:g} MB": mb for mb in args.state_mb}), indent=1))


if __name__ == "__main__":
    main()
