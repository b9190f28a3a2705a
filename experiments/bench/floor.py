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

    python -m experiments.bench.floor [--state-mb 17 125]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from numba import njit

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


def measure(state_mb: dict | None = None, events: int = EVENTS) -> dict:
    """Every floor of the module docstring (ns per event); ``state_mb``:
    network name -> the size of its cell state (MB)."""
    return {
        "in_cache_random": ns_per_event(IN_CACHE_MB, events=events),
        "contiguous": ns_per_event(IN_CACHE_MB, contiguous=True, events=events),
        "large_random": ns_per_event(LARGE_MB, events=events),
        "state_random": {name: ns_per_event(mb, events=events) for name, mb in (state_mb or {}).items()},
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
