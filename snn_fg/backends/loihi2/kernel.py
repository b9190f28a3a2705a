"""The step loop of the Loihi 2 backend, compiled by numba.

It is :func:`snn_fg.lava.reference.simulate` (``arithmetic="fixed"``) in
plain loops, step for step in the same order, with the integer rules of
:mod:`snn_fg.lava.fixed`:

1. every cell of every LIF population takes what the connections put in
   its slot of this step (``pending[n % depth]``, the sum ``a_in``), and
   is updated as :func:`~snn_fg.lava.fixed.lif_fixed` updates it: the
   current decays (truncated toward zero), gains ``a_in << 6`` and wraps
   around at 24 bits; unless the cell is refractory (it spiked at most
   ``refractory_steps`` steps ago) the voltage decays, gains the current
   and the bias and saturates at 24 bits; it spikes where it exceeds
   ``vth << 6`` and is set to 0 there. Cells left out of the run
   (``present`` 0) only have their slot cleared;
2. the step's spikes, the input's and the cells', go out through every
   connection: the sum of the weights ``W`` of each target's synapses from
   the sources that spiked, shifted by the connection's weight exponent
   (:func:`~snn_fg.lava.fixed.shift`), lands in the target's slot of step
   ``n + 1 + delay``. Where the shift of the sum is the sum of the shifts
   (an exponent of 0 or more, or every ``W`` a multiple of ``2**-e``) the
   weights come shifted already (:data:`C_LINEAR`); otherwise the sums are
   gathered per target first and shifted then, as Lava does.

Integers throughout, so the order of the additions cannot change a sum.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ...lava import fixed

#: columns of the per-population table ``pops``
P_FIRST, P_SIZE, P_LIF, P_KU, P_KV, P_BIAS, P_VTH, P_REFR = range(8)
#: columns of the per-connection table ``conns``
C_SRC, C_DELAY, C_EXP, C_LINEAR, C_PTR = range(5)
#: the run's counters (``counters``): the largest |a_in| a cell took, currents
#: wrapped and voltages saturated (cell-steps, as :class:`snn_fg.lava.reference.Limits`
#: counts them), synaptic events
K_MAX_A_IN, K_U_WRAPS, K_V_SATURATED, K_EVENTS = range(4)
N_COUNTERS = 4

UNITY, SHIFT = fixed.DECAY_UNITY, fixed.DECAY_SHIFT
ACT, TOP = fixed.ACT_SHIFT, fixed.STATE_MAX


@njit(cache=True, inline="always")
def _decay(x, k):
    """``x * k / 4096`` rounded toward zero (:func:`~snn_fg.lava.fixed.trunc_decay`, ``k = 4096 - d``)."""
    y = x * k
    return y >> SHIFT if y >= 0 else -((-y) >> SHIFT)


@njit(cache=True, inline="always")
def _shift(a, e):
    """:func:`~snn_fg.lava.fixed.shift`: ``a << e``, or ``a >> -e`` (floor)."""
    return a << e if e > 0 else a >> -e


@njit(cache=True)
def run_steps(n0, n1, pops, conns, ptr, post, w, present, u, v, last, total, pending, in_ptr, in_ids, in_first,
              buf, cnt, acc, mark, touched, log, step_start, scalars, counters):  # fmt: skip
    """Advance from step ``n0`` to ``n1`` (exclusive); returns the step
    reached, less than ``n1`` when the spike log may not hold another step.

    ``in_ptr``/``in_ids``: the input's spikes (cell numbers) of the steps
    from ``in_first``, step ``n``'s at ``in_ptr[n - in_first]``; ``buf``,
    ``cnt``: the step's spikes per population; ``acc``, ``mark``,
    ``touched``: the per-target sums of a connection that shifts its sums;
    ``log``: every cell spike's number, those of step ``n`` from
    ``step_start[n]``, ``scalars[0]`` of them (``scalars[1]`` 0: no log)."""
    depth = pending.shape[0]
    n_pops = pops.shape[0]
    lif_cells = 0
    for q in range(n_pops):
        if pops[q, P_LIF]:
            lif_cells += pops[q, P_SIZE]
    for n in range(n0, n1):
        if scalars[1] and log.size - scalars[0] < lif_cells:
            return n
        step_start[n] = scalars[0]
        slot = n % depth
        # the input's spikes of this step, by population
        for q in range(n_pops):
            cnt[q] = 0
        for k in range(in_ptr[n - in_first], in_ptr[n - in_first + 1]):
            g = in_ids[k]
            for q in range(n_pops):
                if pops[q, P_FIRST] <= g < pops[q, P_FIRST] + pops[q, P_SIZE]:
                    buf[pops[q, P_FIRST] + cnt[q]] = g
                    cnt[q] += 1
                    break
        # 1. the cells
        for q in range(n_pops):
            if not pops[q, P_LIF]:
                continue
            first, ku, kv = pops[q, P_FIRST], pops[q, P_KU], pops[q, P_KV]
            bias, vth, refr = pops[q, P_BIAS], pops[q, P_VTH], pops[q, P_REFR]
            for i in range(first, first + pops[q, P_SIZE]):
                a = pending[slot, i]
                pending[slot, i] = 0
                if not present[i]:
                    continue
                if abs(a) > counters[K_MAX_A_IN]:
                    counters[K_MAX_A_IN] = abs(a)
                uu = _decay(u[i], ku) + a * (1 << ACT)
                if uu > TOP or uu <= -TOP:
                    counters[K_U_WRAPS] += 1
                if uu > TOP:
                    uu -= 2 * TOP
                elif uu <= -TOP:
                    uu += 2 * TOP
                u[i] = uu
                vv = _decay(v[i], kv) + uu
                if vv >= TOP - 1 or vv <= 1 - TOP:
                    counters[K_V_SATURATED] += 1
                vv += bias
                if vv > TOP - 1:
                    vv = TOP - 1
                elif vv < 1 - TOP:
                    vv = 1 - TOP
                if n - last[i] > refr:
                    v[i] = vv
                if v[i] > vth:
                    v[i] = 0
                    last[i] = n
                    total[i] += 1
                    buf[first + cnt[q]] = i
                    cnt[q] += 1
                    if scalars[1]:
                        log[scalars[0]] = i
                        scalars[0] += 1
        # 2. the spikes through the connections
        for c in range(conns.shape[0]):
            q, e = conns[c, C_SRC], conns[c, C_EXP]
            if cnt[q] == 0:
                continue
            to = (n + 1 + conns[c, C_DELAY]) % depth
            first, base = pops[q, P_FIRST], conns[c, C_PTR]
            if conns[c, C_LINEAR]:
                for k in range(first, first + cnt[q]):
                    s = buf[k] - first
                    a, b = ptr[base + s], ptr[base + s + 1]
                    counters[K_EVENTS] += b - a
                    for j in range(a, b):
                        pending[to, post[j]] += w[j]
                continue
            n_touched = 0
            for k in range(first, first + cnt[q]):
                s = buf[k] - first
                a, b = ptr[base + s], ptr[base + s + 1]
                counters[K_EVENTS] += b - a
                for j in range(a, b):
                    t = post[j]
                    if not mark[t]:
                        mark[t] = 1
                        touched[n_touched] = t
                        n_touched += 1
                    acc[t] += w[j]
            for k in range(n_touched):
                t = touched[k]
                pending[to, t] += _shift(acc[t], e)
                acc[t] = 0
                mark[t] = 0
    return n1
