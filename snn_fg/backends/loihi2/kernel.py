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
   ``vth << 6`` and is set to 0 there;
2. the step's spikes, the input's and the cells', go out through every
   connection: the sum of the weights ``W`` of each target's synapses from
   the sources that spiked, shifted by the connection's weight exponent
   (:func:`~snn_fg.lava.fixed.shift`), lands in the target's slot of step
   ``n + 1 + delay``. Where the shift of the sum is the sum of the shifts
   (an exponent of 0 or more, or every ``W`` a multiple of ``2**-e``) the
   weights come shifted already (:data:`C_LINEAR`); otherwise the sums are
   gathered per target first and shifted then, as Lava does.

Integers throughout, so the order of the additions cannot change a sum.

**Cells that cannot spike without input are not touched** (:mod:`.rest`):
after its update such a cell is *parked* (``flag`` :data:`F_PARKED`, out
of the list of active cells ``act``) or, with input on its way, parked
until that input arrives (``F_WAKE`` plus the step's low 8 bits, and in
that step's wake list); a synapse that reaches a parked cell schedules it
for the step its input arrives. A cell woken has the steps it missed
applied first (:func:`~.rest.catch_up`). The run computes what updating
every cell at every step computes; the cells left out of the run
(:data:`F_ABSENT`) are never active.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from .rest import (
    ACT,
    P_BIAS,
    P_FIRST,
    P_KU,
    P_KV,
    P_LIF,
    P_REFR,
    P_SIZE,
    P_VTH,
    S_LAST,
    S_U,
    S_UPD,
    S_V,
    TOP,
    catch_up,
    clip,
    decay,
    may_rest,
    shift,
)

#: columns of the per-connection table ``conns``
C_SRC, C_DELAY, C_EXP, C_LINEAR, C_PTR = range(5)
#: a cell's ``flag``: parked, active, absent (left out of the run, or a spike
#: source), parked until step ``n`` (``F_WAKE + (n & 255)``; delays are below 64 steps)
F_PARKED, F_ACTIVE, F_ABSENT, F_WAKE = 0, 1, 2, 256
#: the run's counters (``counters``): the largest |a_in| a cell took, currents
#: wrapped and voltages saturated (cell-steps, as :class:`snn_fg.lava.reference.Limits`
#: counts them), synaptic events, cell updates, parked cells woken
K_MAX_A_IN, K_U_WRAPS, K_V_SATURATED, K_EVENTS, K_UPDATES, K_WAKES = range(6)
N_COUNTERS = 6

#: the network's arrays (:class:`~snn_fg.backends.loihi2.tables.Loihi2Tables`)
Net = namedtuple("Net", "pops conns ptr post w pop_of")
#: a run's arrays (:func:`run_steps`)
Cells = namedtuple(
    "Cells",
    "flag act merged wake wake_n state total pending in_ptr in_ids buf cnt acc mark touched log step_start "
    "scalars counters",
)


@njit(cache=True, nogil=True)
def run_steps(n0, n1, in_first, net, cells):
    """Advance from step ``n0`` to ``n1`` (exclusive); returns the step
    reached, less than ``n1`` when the spike log may not hold another step.
    ``net``: a :data:`Net`, ``cells``: :data:`Cells`, whose arrays are:

    ``act``: the active cells in order (``scalars[2]`` of them; ``merged``
    room to merge the cells woken into the list); ``wake[n % depth]``: the
    ``wake_n[n % depth]`` cells to wake at step ``n`` (those whose ``flag``
    still says so); ``pending[n % depth, i]``: cell ``i``'s input at step
    ``n``; ``in_ptr``/``in_ids``: the input's spikes (cell numbers) of the
    steps from ``in_first``, step ``n``'s at ``in_ptr[n - in_first]``;
    ``buf``, ``cnt``: the step's spikes per population; ``acc``, ``mark``,
    ``touched``: the per-target sums of a connection that shifts its sums;
    ``log``: every cell spike's number, those of step ``n`` from
    ``step_start[n]``, ``scalars[0]`` of them (``scalars[1]`` 0: no log)."""
    pops, conns, ptr, post, w, pop_of = net
    flag, act, merged, wake, wake_n, state, total, pending, in_ptr, in_ids = cells[:10]
    buf, cnt, acc, mark, touched, log, step_start, scalars, counters = cells[10:]
    depth, room = pending.shape[0], wake.shape[1]
    n_pops = pops.shape[0]
    lif_cells = 0
    for q in range(n_pops):
        if pops[q, P_LIF]:
            lif_cells += pops[q, P_SIZE]
    n_act = scalars[2]
    for n in range(n0, n1):
        if scalars[1] and log.size - scalars[0] < lif_cells:
            scalars[2] = n_act
            return n
        step_start[n] = scalars[0]
        slot = n % depth
        # the parked cells whose input arrives now join the active ones, in order
        kept = n_act
        for k in range(wake_n[slot]):
            i = wake[slot, k]
            if flag[i] == F_WAKE + (n & 255):
                catch_up(i, n - 1, pops[pop_of[i]], state)
                flag[i] = F_ACTIVE
                act[n_act] = i
                n_act += 1
        wake_n[slot] = 0
        if n_act > kept:
            counters[K_WAKES] += n_act - kept
            _merge(act, kept, n_act, merged)
        # the input's spikes of this step, by population
        for q in range(n_pops):
            cnt[q] = 0
        for k in range(in_ptr[n - in_first], in_ptr[n - in_first + 1]):
            g = in_ids[k]
            q = pop_of[g]
            buf[pops[q, P_FIRST] + cnt[q]] = g
            cnt[q] += 1
        # 1. the cells
        counters[K_UPDATES] += n_act
        kept = 0
        for k in range(n_act):
            i = act[k]
            q = pop_of[i]
            row = pops[q]
            a = pending[slot, i]
            pending[slot, i] = 0
            if abs(a) > counters[K_MAX_A_IN]:
                counters[K_MAX_A_IN] = abs(a)
            uu = decay(int(state[i, S_U]), row[P_KU]) + a * (1 << ACT)
            if uu > TOP or uu <= -TOP:
                counters[K_U_WRAPS] += 1
            if uu > TOP:
                uu -= 2 * TOP
            elif uu <= -TOP:
                uu += 2 * TOP
            state[i, S_U] = uu
            vv = decay(int(state[i, S_V]), row[P_KV]) + uu
            if vv >= TOP - 1 or vv <= 1 - TOP:
                counters[K_V_SATURATED] += 1
            if n - state[i, S_LAST] > row[P_REFR]:
                state[i, S_V] = clip(vv + row[P_BIAS])
            if state[i, S_V] > row[P_VTH]:
                state[i, S_V] = 0
                state[i, S_LAST] = n
                total[i] += 1
                buf[row[P_FIRST] + cnt[q]] = i
                cnt[q] += 1
                if scalars[1]:
                    log[scalars[0]] = i
                    scalars[0] += 1
            elif may_rest(uu, int(state[i, S_V]), row):
                m = n + 1  # the first step with input on its way
                while m < n + depth and pending[m % depth, i] == 0:
                    m += 1
                if m == n + depth:
                    flag[i] = F_PARKED
                elif wake_n[m % depth] < room:
                    flag[i] = F_WAKE + (m & 255)
                    wake[m % depth, wake_n[m % depth]] = i
                    wake_n[m % depth] += 1
                if flag[i] != F_ACTIVE:
                    state[i, S_UPD] = n
                    continue
            act[kept] = i
            kept += 1
        n_act = kept
        # 2. the spikes through the connections
        for c in range(conns.shape[0]):
            q = conns[c, C_SRC]
            if cnt[q] == 0:
                continue
            arrive = n + 1 + conns[c, C_DELAY]
            to = arrive % depth
            first, base, linear = pops[q, P_FIRST], conns[c, C_PTR], conns[c, C_LINEAR]
            n_touched = 0
            for k in range(first, first + cnt[q]):
                s = buf[k] - first
                a, b = ptr[base + s], ptr[base + s + 1]
                counters[K_EVENTS] += b - a
                for j in range(a, b):
                    t = post[j]
                    f = flag[t]
                    if f != F_ACTIVE:
                        if f == F_ABSENT:
                            continue
                        if f == F_PARKED or ((f - F_WAKE - n) & 255) > arrive - n:  # (woken sooner)
                            if wake_n[to] < room:
                                flag[t] = F_WAKE + (arrive & 255)
                                wake[to, wake_n[to]] = t
                                wake_n[to] += 1
                            else:  # (no room left: active from now on)
                                catch_up(t, n, pops[pop_of[t]], state)
                                flag[t] = F_ACTIVE
                                act[n_act] = t
                                n_act += 1
                    if linear:
                        pending[to, t] += w[j]
                    elif not mark[t]:
                        mark[t] = 1
                        touched[n_touched] = t
                        n_touched += 1
                        acc[t] = w[j]
                    else:
                        acc[t] += w[j]
            for k in range(n_touched):
                t = touched[k]
                pending[to, t] += shift(acc[t], conns[c, C_EXP])
                acc[t] = 0
                mark[t] = 0
        if n_act > kept:
            _merge(act, kept, n_act, merged)
    scalars[2] = n_act
    return n1


@njit(cache=True)
def _merge(act, kept, n_act, merged):
    """``act[:kept]`` (in order) and ``act[kept:n_act]`` merged in order into ``act[:n_act]``."""
    act[kept:n_act] = np.sort(act[kept:n_act])
    i, j, m = 0, kept, 0
    while i < kept and j < n_act:
        if act[i] < act[j]:
            merged[m] = act[i]
            i += 1
        else:
            merged[m] = act[j]
            j += 1
        m += 1
    merged[m : m + kept - i] = act[i:kept]
    m += kept - i
    merged[m : m + n_act - j] = act[j:n_act]
    act[:n_act] = merged[:n_act]


@njit(cache=True)
def catch_up_all(n, pops, pop_of, flag, state):
    """Bring every parked cell's state to the end of step ``n`` (to read it)."""
    for i in range(flag.size):
        if flag[i] != F_ACTIVE and flag[i] != F_ABSENT:
            catch_up(i, n, pops[pop_of[i]], state)
            state[i, S_UPD] = n
