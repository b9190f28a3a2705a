"""Loihi 2's integer update of one cell, compiled, and when a cell may be
left alone: the rules :mod:`.kernel` steps the network with.

A cell that cannot spike without input is *parked*: not updated until
input reaches it. Parking changes nothing the run computes, provided the
cell's future without input is known to hold no spike, no current wrapping
around and no voltage counted as saturated (:func:`may_rest`), and the
steps it missed are applied when it wakes (:func:`catch_up`: the same
integer update with no input).

**The bound.** With no input a cell's current decays toward 0, ``|u_m| <=
b^m |u|`` (``b = ku / 4096``; truncation toward 0 only shrinks it), and
each step that it is not refractory its voltage becomes ``trunc(a v) +
u_m + bias`` (``a = kv / 4096``), within 1 of ``a v + u_m + bias``. So
every later voltage lies at or below ``max(v, (bias + 1) / (1 - a)) +
u+ S`` and at or above ``min(v, (bias - 1) / (1 - a)) - u- S``, where
``S = max over m of sum_{k <= m} a^(m - k) b^k`` is the most a unit of
current, decaying, can add to the voltage (:func:`pile_factor`; refractory
steps only drop terms). A cell rests when the upper bound is at most its
threshold and both stay, with the current, clear of the 24-bit rails.
Without leak (``dv`` 0) only a voltage at a fixed point with no current
rests.
"""

from __future__ import annotations

import math

from numba import njit

from ...lava import fixed

#: columns of the per-population table ``pops``: its first cell, size,
#: whether it has LIF cells, its registers as the update uses them
#: (``4096 - du - 1``, ``4096 - dv``, effective bias, ``vth << 6``,
#: refractory steps) and :func:`pile_factor` in units of ``2**-PILE_BITS``
P_FIRST, P_SIZE, P_LIF, P_KU, P_KV, P_BIAS, P_VTH, P_REFR, P_PILE = range(9)
N_POP_COLUMNS = 9
PILE_BITS = 20
#: columns of the per-cell ``state`` (int32): current, voltage, step of the
#: last spike, and of a parked cell the step its state is of
S_U, S_V, S_LAST, S_UPD = range(4)
N_STATE_COLUMNS = 4

UNITY, SHIFT = fixed.DECAY_UNITY, fixed.DECAY_SHIFT
ACT, TOP = fixed.ACT_SHIFT, fixed.STATE_MAX


@njit(cache=True, inline="always")
def decay(x, k):
    """``x * k / 4096`` rounded toward zero (:func:`~snn_fg.lava.fixed.trunc_decay`, ``k = 4096 - d``)."""
    y = x * k
    return y >> SHIFT if y >= 0 else -((-y) >> SHIFT)


@njit(cache=True, inline="always")
def shift(a, e):
    """:func:`~snn_fg.lava.fixed.shift`: ``a << e``, or ``a >> -e`` (floor)."""
    return a << e if e > 0 else a >> -e


@njit(cache=True, inline="always")
def clip(x):
    """A voltage saturated at 24 bits."""
    return TOP - 1 if x > TOP - 1 else (1 - TOP if x < 1 - TOP else x)


@njit(cache=True, inline="always")
def may_rest(x, y, row):
    """Whether a cell of population ``row`` (of ``pops``) with current
    ``x`` and voltage ``y`` can be left alone until input comes (module docstring)."""
    kv, bias = row[P_KV], row[P_BIAS]
    dv = UNITY - kv
    if dv <= 0:
        d = decay(y, kv)
        return x == 0 and clip(d + bias) == y and TOP - 1 > d > 1 - TOP
    pile = ((abs(x) * row[P_PILE]) >> PILE_BITS) + 2  # (rounded up, with room)
    hi = max(y, -((-(bias + 1) * UNITY) // dv)) + (pile if x > 0 else 0) + 1
    lo = min(y, ((bias - 1) * UNITY) // dv) - (pile if x < 0 else 0) - 1
    return hi <= row[P_VTH] and max(hi, -lo) + abs(x) < TOP - 1


@njit(cache=True, inline="always")
def catch_up(i, n, row, state):
    """Apply to parked cell ``i`` (of population ``row``) the steps after
    ``state[i, S_UPD]`` up to ``n``, each the update with no input, until
    its current is 0 and its voltage a fixed point (nothing else can change then)."""
    ku, kv, bias, refr = row[P_KU], row[P_KV], row[P_BIAS], row[P_REFR]
    x, y, last = int(state[i, S_U]), int(state[i, S_V]), int(state[i, S_LAST])
    s = int(state[i, S_UPD]) + 1
    while s <= n and x != 0:
        x = decay(x, ku)
        if s - last > refr:
            y = clip(decay(y, kv) + x + bias)
        s += 1
    s = max(s, last + refr + 1)  # (with no current a refractory cell's voltage stays)
    while s <= n:
        z = clip(decay(y, kv) + bias)
        if z == y:
            break
        y = z
        s += 1
    state[i, S_U], state[i, S_V] = x, y


def pile_factor(ku: int, kv: int) -> int:
    """``S`` of the module docstring in units of ``2**-PILE_BITS``, rounded
    up with a margin: the largest sum ``sum_{k=1..m} a^(m-k) b^k``, which is
    ``b (a^m - b^m) / (a - b)`` (``m b^m`` where ``a = b``), largest at
    ``m = ln(ln b / ln a) / ln(a / b)`` (``-1 / ln b``)."""
    a, b = kv / UNITY, ku / UNITY
    if b <= 0:
        return 0
    if a >= 1:
        return math.ceil(b / (1 - b) * 2**PILE_BITS * (1 + 1e-9)) + 1  # (the current's whole sum)

    def f(m: int) -> float:
        if m < 1:
            return 0.0
        return m * b**m if math.isclose(a, b, rel_tol=1e-12) else b * (a**m - b**m) / (a - b)

    if math.isclose(a, b, rel_tol=1e-12):
        top = -1 / math.log(b)
    else:
        top = math.log(math.log(b) / math.log(a)) / math.log(a / b)
    best = max(f(1), f(math.floor(top)), f(math.ceil(top)))
    return math.ceil(best * 2**PILE_BITS * (1 + 1e-9)) + 1
