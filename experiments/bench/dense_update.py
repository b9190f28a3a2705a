"""What a time-driven engine would pay before delivering a single spike: every
cell of a network updated at every step, in one compiled, vectorisable pass.

The fast engine is event-driven: a cell is advanced in closed form only when
input reaches it (the hand-over, about 18 ns a cell advanced and 39 % of the
compact network's time in stop 69's phase split). The obvious alternative is
a dense pass per step with Brian2's update for every cell:
``v += (1 - d_m)(v_rest - v) + p_e I_exc - p_i I_inh`` unless refractory, both
currents decayed, threshold, reset and the refractory period; then the cells
that fired listed. This script times that over ``--cells`` cells (the compact
network's 716,532 by default) for ``--steps`` steps (an 85 ms window at 1 ms),
``--rounds`` rounds in CPU time, on whatever cores the process has
(pin it: ``taskset -c 0``), in float64 (the engine's and Brian2's state) and
float32.

The update loop holds no branch and no loop-carried value, so the compiler
makes it vector code; whether a cell fired is written as a byte, and the
cells that fired are listed in a second pass that skips eight silent cells at
a time. (Until 30 Nov the loop listed them as it went, ``fired[n] = k; n +=
spike``: that running count kept it scalar, at 1.12-1.22 ns a cell-step.)

    python -m experiments.bench.dense_update [--cells 716532] [--steps 85] [--rounds 3]

Prints one line a round and precision: ms of CPU a window and ns a cell-step.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from numba import njit


@njit(cache=True)
def _update(n, v, i_exc, i_inh, last_spike, k, fired):
    """Brian2's step for every cell at step ``n`` (``k``: the neuron type's constants
    ``1 - d_m, p_e, p_i, d_e, d_i, v_rest, v_th, v_reset, ref_steps``, in the state's
    precision), whether each fired into ``fired`` (0 or 1)."""
    leak, p_e, p_i, d_e, d_i, v_rest, v_th, v_reset, ref = k
    for c in range(v.size):
        x, e, i = v[c], i_exc[c], i_inh[c]
        ready = n - last_spike[c] >= ref
        x = x + ((e * p_e + leak * (v_rest - x)) - i * p_i) if ready else x
        spike = ready & (x > v_th)
        v[c] = v_reset if spike else x
        i_exc[c] = e * d_e
        i_inh[c] = i * d_i
        last_spike[c] = n if spike else last_spike[c]
        fired[c] = spike


@njit(cache=True)
def _listed(fired, out):
    """The cells with ``fired`` set, into ``out``; returns how many (eight at a time
    where none fired)."""
    words = fired[: fired.size - fired.size % 8].view(np.uint64)
    m = 0
    for w in range(words.size):
        if words[w] != 0:
            for c in range(8 * w, 8 * w + 8):
                out[m] = c
                m += fired[c]
    for c in range(8 * words.size, fired.size):
        out[m] = c
        m += fired[c]
    return m


def window(state, k, steps: int) -> int:
    """One window's steps over every cell; returns the spikes."""
    v, i_exc, i_inh, last_spike, fired, out = state
    total = 0
    for n in range(steps):
        _update(n, v, i_exc, i_inh, last_spike, k, fired)
        total += _listed(fired, out)
    return total


def make_state(cells: int, dtype, seed: int = 0):
    """Cells under threshold with some input, a few of which fire (about 2,000 of the
    compact network's 716,532 in a window: the refractory period and reset are taken)."""
    rng = np.random.default_rng(seed)
    v = (rng.random(cells) * 0.011).astype(dtype)
    i_exc = (rng.random(cells) * 0.002).astype(dtype)
    i_inh = (rng.random(cells) * 0.001).astype(dtype)
    last_spike = np.full(cells, -1000, np.int32)
    return v, i_exc, i_inh, last_spike, np.zeros(cells, np.uint8), np.empty(cells, np.int64)


def constants(dtype):
    """A neuron type's constants at 1 ms (tau_m 10 ms, both currents 5 ms, threshold 10 mV)."""
    c = [1 - np.exp(-0.1), 0.1, 0.1, np.exp(-0.2), np.exp(-0.2), 0.0, 0.01, 0.0]
    return (*(dtype(x) for x in c), 4)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=716_532, help="cells updated every step (the compact network's)")
    ap.add_argument("--steps", type=int, default=85, help="steps a window (85: 85 ms at 1 ms)")
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args(argv)
    print(f"load {os.getloadavg()[0]:.2f}; {args.cells:,} cells, {args.steps} steps a window")
    for dtype in (np.float64, np.float32):
        k = constants(dtype)
        window(make_state(64, dtype), k, 1)  # (compiled, or loaded, before timing)
        for r in range(args.rounds):
            state = make_state(args.cells, dtype, seed=r)
            t = time.process_time()
            spikes = window(state, k, args.steps)
            window_s = time.process_time() - t
            per = window_s / (args.steps * args.cells) * 1e9
            print(
                f"{np.dtype(dtype).name} round {r + 1}: {window_s * 1000:.1f} ms of CPU a window, "
                f"{per:.2f} ns a cell-step ({spikes:,} spikes)"
            )


if __name__ == "__main__":
    main()
