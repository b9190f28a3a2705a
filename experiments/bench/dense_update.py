"""What a time-driven engine would pay before delivering a single spike: every
cell of a network updated at every step, in one compiled, vectorisable pass.

The fast engine is event-driven: a cell is advanced in closed form only when
input reaches it (the hand-over, about 18 ns a cell advanced and 39 % of the
compact network's time in stop 69's phase split). The obvious alternative is
a dense pass per step: ``v = a v + I_exc - I_inh``, both currents decayed,
threshold and reset, the cells that fired compacted into a list. This script
times that pass alone over ``--cells`` cells (the compact network's 716,532
by default) for ``--steps`` steps (an 85 ms window at 1 ms), float32 state,
best of ``--rounds`` rounds in CPU time, on whatever cores the process has
(pin it: ``taskset -c 0``).

    python -m experiments.bench.dense_update [--cells 716532] [--steps 85] [--rounds 3]

Prints one line a round: ms of CPU a window and ns a cell-step.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from numba import njit


@njit(cache=True)
def _step(v, i_exc, i_inh, a, b_exc, b_inh, threshold, fired):
    """One time step of every cell; returns how many fired (their numbers in ``fired[:n]``)."""
    n = 0
    for k in range(v.size):
        x = v[k] * a + i_exc[k] - i_inh[k]
        i_exc[k] *= b_exc
        i_inh[k] *= b_inh
        spike = x >= threshold
        v[k] = 0.0 if spike else x
        fired[n] = k  # (written always, kept only if it fired: no branch in the loop)
        n += spike
    return n


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=716_532, help="cells updated every step (the compact network's)")
    ap.add_argument("--steps", type=int, default=85, help="steps a window (85: 85 ms at 1 ms)")
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(0)
    v = (rng.random(args.cells, dtype=np.float32) * 0.5).astype(np.float32)
    i_exc = (rng.random(args.cells, dtype=np.float32) * 0.01).astype(np.float32)
    i_inh = (rng.random(args.cells, dtype=np.float32) * 0.01).astype(np.float32)
    fired = np.empty(args.cells, np.int32)
    consts = (np.float32(0.95), np.float32(0.8), np.float32(0.9), np.float32(1.0))
    _step(v, i_exc, i_inh, *consts, fired)  # (compiled, or loaded, before timing)
    print(f"load {os.getloadavg()[0]:.2f}; {args.cells:,} cells, {args.steps} steps a window")
    for r in range(args.rounds):
        t = time.process_time()
        for _ in range(args.steps * 10):
            _step(v, i_exc, i_inh, *consts, fired)
        window_s = (time.process_time() - t) / 10
        per = window_s / (args.steps * args.cells) * 1e9
        print(f"round {r + 1}: {window_s * 1000:.1f} ms of CPU a window, {per:.2f} ns a cell-step")


if __name__ == "__main__":
    main()
