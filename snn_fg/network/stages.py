"""The model's stages as populations and projections, one function per stage,
each adding to the network a :class:`~snn_fg.network.builder.Builder` is
making: the input relays (stage 2), simple and untuned cells (stages 3-4),
border-ownership cells (stage 5), excess and grouping cells (stage 7), the
feedback cells and their pooling across levels (stage 8), and the window
clock. Each stage takes the populations it reads from the stages before it,
as the builder made them (:meth:`~snn_fg.network.builder.Builder.named`,
by role and level).

Which cells read which is :mod:`.wiring`.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .gains import GainsMv
from .nodes import Kernel
from .spiking_params import SIMPLE_RATE_HZ, UNTUNED_RATE_HZ
from .wiring import (
    FAMILIES,
    FAMILY_HALF,
    FEEDBACK_HALVES,
    FEEDBACK_INPUTS,
    FEEDBACK_TO_FAMILY,
    GROUPING_INPUTS,
    OPPOSITE_HALF,
    PARTNER,
    channel_map,
    dog_half,
    von_mises,
)


def inputs(bld, level):
    """Level 1: spike sources; coarser levels: relays following the bicubic-resized frame (stage 2)."""
    if level == 1:
        return bld.pop("input_on", 1), bld.pop("input_off", 1)
    relays = []
    for polarity in ("on", "off"):
        name = bld.pop(f"relay_{polarity}", level, neuron=bld.neurons["relay"], sites="reachable")
        bld.resize(
            bld.named(f"input_{polarity}", 1),
            name,
            gain=bld.gains_mv.relay,
            interpolation="cubic",
            prune=bld.sp.connectivity.prune_resize,
        )
        relays.append(name)
    return tuple(relays)


def gate_mv(bld, kernels) -> float:
    """Depth (mV) of a simple cell's gate: the largest mean current its
    kept DoG taps can deliver with every source at the input rate, plus
    ``gate_margin`` thresholds."""
    worst = 0.0
    for kernel in kernels:
        k = kernel.array(bld.params)
        kept = np.where(np.abs(k) >= bld.sp.connectivity.prune_dog * np.abs(k).max(), k, 0.0)
        worst = max(worst, float(np.clip(kept, 0, None).sum(axis=(1, 2, 3)).max()))
    simple = bld.sp.neurons.simple
    drive = worst * bld.gains_mv.dog * bld.sp.input.input_rate_hz * simple.tau_exc_ms / 1000.0
    return drive + bld.sp.input.gate_margin * simple.v_th_mv


def simple_cells(bld, level, on, off):
    """Stages 3-4: DoG convolution (wrap-around) from ON for directions
    ``0..n-1`` and OFF for the rest; lateral inhibition between the
    directions at a pixel stands for the arg-max.

    At level 1 a simple cell exists only where its pixel had an event
    (``S = edges * ...``): it rests ``gate`` below its usual resting
    potential, more than any DoG drive can make up, and its own pixel's
    input (either polarity) gives that back."""
    n, n_dir = bld.params.n_ori, bld.params.n_dir
    kernels = [dog_half(polarity, n) for polarity in (0, 1)]
    neuron = bld.neurons["simple"]
    gate = gate_mv(bld, kernels) if level == 1 else 0.0
    if gate:
        neuron = dataclasses.replace(neuron, v_rest_mv=neuron.v_rest_mv - gate)
    s = bld.pop("simple", level, channels=n_dir, neuron=neuron, sites="edges&drive", edge_mask=True)
    for kernel, src in zip(kernels, (on, off)):
        bld.conv(
            src,
            s,
            kernel,
            gain=bld.gains_mv.dog,
            mode="conv",
            padding="wrap",
            prune=bld.sp.connectivity.prune_dog,
            calibrated=True,
        )
    if gate:
        copies = bld.sp.input.gate_copies
        for src in (on, off):
            for i in range(copies):
                bld.conv(
                    src,
                    s,
                    channel_map(n_dir, 1, [(k, 0) for k in range(n_dir)]),
                    verb="gates" if i == 0 else f"gates{i}",
                    gain=gate / copies / (bld.sp.input.input_rate_hz * neuron.tau_exc_ms / 1000.0),
                    delay=bld.sp.time.delay_ms + i * bld.sp.input.gate_spread_ms,
                    calibrated=True,
                )
    others = [(a, b) for a in range(n_dir) for b in range(n_dir) if a != b]
    bld.conv(s, s, channel_map(n_dir, n_dir, others), sign=-1, gain=bld.gains_mv.simple_inh_simple)
    return s


def untuned_cells(bld, level, on, off, s):
    """Stage 4's rule for event pixels without an oriented response: an
    untuned cell is excited by its pixel's input after ``delay_untuned_ms``
    and silenced by any simple cell there."""
    u = bld.pop("untuned", level, neuron=bld.neurons["untuned"], sites="edges", edge_mask=True)
    g_u = bld.gains_mv.input_to_untuned(bld.sp, level)
    for src in (on, off):
        bld.conv(src, u, channel_map(1, 1, [(0, 0)]), gain=g_u, delay=bld.sp.time.delay_untuned_ms, calibrated=True)
    n_dir = bld.params.n_dir
    bld.conv(s, u, channel_map(1, n_dir, [(0, k) for k in range(n_dir)]), sign=-1, gain=bld.gains_mv.simple_inh_untuned)
    return u


def bo_gate_mv(bld) -> float:
    """Depth (mV) of a border-ownership cell's gate: the largest mean
    current the feedback half for it can deliver (every feedback cell at
    its refractory ceiling, interpolation weights summing to at most 1)
    plus ``bo_gate_margin`` thresholds. The cell rests that far below its
    usual resting potential and its simple-cell input gives it back, so
    feedback modulates a border-ownership cell only where its simple cell
    is active: ``B = S * f(z)`` with ``S`` binary (stage 8)."""
    if bld.gains_mv.feedback_to_bo <= 0:
        return 0.0
    bo, fb = bld.sp.neurons.bo, bld.sp.neurons.feedback
    strongest = bld.gains_mv.feedback_to_bo * fb.max_rate_hz * bo.tau_exc_ms / 1000.0
    return strongest + bld.sp.gains.bo_gate_margin * bo.v_th_mv


def border_ownership(bld, level, s, u):
    """Stage 5: family ``f`` reads simple-cell index ``o`` (L1, D2) or
    ``o + n`` (L2, D1), the index being the direction turned a quarter
    (``k -> (k + n/2) mod 2n``); untuned pixels take index ``n/2``. The
    feedforward weights carry the gate (:func:`bo_gate_mv`) back at the
    simple and untuned cells' reference rates."""
    n, n_dir = bld.params.n_ori, bld.params.n_dir
    gate = bo_gate_mv(bld)
    neuron = bld.neurons["bo"]
    if gate:
        neuron = dataclasses.replace(neuron, v_rest_mv=neuron.v_rest_mv - gate)
    tau_s = neuron.tau_exc_ms / 1000.0
    b = {
        f: bld.pop(f"bo_{f}", level, channels=n, neuron=neuron, sites="reachable", site_sources=(s, u), edge_mask=True)
        for f in FAMILIES
    }
    same = [(o, o) for o in range(n)]
    for f in FAMILIES:
        half = FAMILY_HALF[f] * n
        bld.conv(
            s,
            b[f],
            channel_map(n, n_dir, [(o, (o + half - n // 2) % n_dir) for o in range(n)]),
            gain=bld.gains_mv.simple_to_bo + gate / (SIMPLE_RATE_HZ * tau_s),
        )
        if half == 0:
            bld.conv(
                u,
                b[f],
                channel_map(n, 1, [(n // 2, 0)]),
                gain=bld.gains_mv.untuned_to_bo + gate / (UNTUNED_RATE_HZ * tau_s),
            )
        if bld.gains_mv.bo_inh_bo > 0:
            bld.conv(b[PARTNER[f]], b[f], channel_map(n, n, same), sign=-1, gain=bld.gains_mv.bo_inh_bo)
    return b


def excess_cells(bld, level, b):
    """The excess of each border-ownership family over its partner at the
    same simple cell, ``rect(B_f - B_partner)``: zero while the pair is
    still symmetric, the winner's activity once feedback has chosen.

    With ``excess_stride`` s > 1 an excess cell sits on every s-th pixel
    and takes the excess of the block around it, ``rect(mean B_f - mean
    B_partner)`` (a ``block_mean`` kernel): s**2 times fewer cells, read
    by the grouping cells through every s-th tap of their kernel."""
    n, st = bld.params.n_ori, bld.sp.connectivity.excess_stride
    same = (
        channel_map(n, n, [(o, o) for o in range(n)])
        if st == 1
        else Kernel(ref="block_mean", args={"channels": n, "stride": st})
    )
    x = {
        f: bld.pop(
            f"excess_{f}",
            level,
            channels=n,
            stride=st,
            neuron=bld.neurons["excess"],
            sites="reachable",
            site_sources=(b[f],),
            edge_mask=st == 1,
        )
        for f in FAMILIES
    }
    gain = bld.gains_mv.bo_to_excess * st
    for f in FAMILIES:
        bld.conv(b[f], x[f], same, gain=gain)
        bld.conv(b[PARTNER[f]], x[f], same, sign=-1, gain=gain * GainsMv.balance(bld.neurons["excess"]))
    return x


def grouping_cells(bld, level, b):
    """Stage 7: von Mises correlation of the border-ownership cells; light
    and dark compete.

    ``(B_own - w B_rival) (*) m`` of the model, with the rival family
    counted through its excess cells (``rival_inhibition="excess"``, the
    default): a rival inhibits only where it beats its own partner, so
    grouping runs uninhibited while every pair is still symmetric, as the
    model's first iteration does, and with the model's inhibition once
    feedback has chosen. ``"direct"``: the rival cells inhibit as they are."""
    st = bld.sp.connectivity.grouping_stride
    g = {
        pol: bld.pop(
            f"group_{pol}",
            level,
            stride=st,
            neuron=bld.neurons["group"],
            sites="reachable",
            site_sources=tuple(b.values()),
        )
        for pol in ("L", "D")
    }
    w = bld.params.w_inh
    by_excess = w > 0 and bld.sp.connectivity.rival_inhibition == "excess"
    rivals = excess_cells(bld, level, b) if by_excess else b
    # a strided excess lattice is read through every s-th tap: s**2 makes up the rest, s of it in
    # the excess cells' own gain (a block crossed by an edge holds about s of its s**2 pixels)
    sparse = bld.sp.connectivity.excess_stride if by_excess else 1
    for fam, pol, half, sign in GROUPING_INPUTS:
        if sign < 0 and w == 0:
            continue
        gain = bld.gains_mv.bo_to_group * (1.0 if sign > 0 else w * sparse * GainsMv.balance(bld.neurons["group"]))
        bld.conv(
            (b if sign > 0 else rivals)[fam],
            g[pol],
            von_mises(half, "gather"),
            sign=sign,
            gain=gain,
            prune=bld.sp.connectivity.prune_vm,
        )
    if bld.params.grouping_polarity == "compete":
        for a, c in (("L", "D"), ("D", "L")):
            bld.conv(g[a], g[c], channel_map(1, 1, [(0, 0)]), sign=-1, gain=bld.gains_mv.group_inh_group)
    return g


def feedback_cells(bld, level, b, g) -> dict:
    """Stage 8 at one level: feedback cells carry z1 = VL1 - VD2 and
    z2 = VL2 - VD1 as rectified pairs on the grouping lattice (every
    stride-th tap is used, hence the stride**2); the half against a
    border-ownership cell inhibits it, the half for it excites it."""
    st = bld.sp.connectivity.grouping_stride
    gain = bld.gains_mv.group_to_feedback * st * st
    z = {
        k: bld.pop(
            f"feedback_{k}",
            level,
            channels=bld.params.n_ori,
            stride=st,
            neuron=bld.neurons["feedback"],
            sites="needed",
        )
        for k in FEEDBACK_HALVES
    }
    for k in FEEDBACK_HALVES:
        (pol_for, half_for), (pol_against, half_against) = FEEDBACK_INPUTS[k]
        bld.conv(g[pol_for], z[k], von_mises(half_for, "scatter"), gain=gain, prune=bld.sp.connectivity.prune_vm)
        bld.conv(
            g[pol_against],
            z[k],
            von_mises(half_against, "scatter"),
            sign=-1,
            gain=gain * GainsMv.balance(bld.neurons["feedback"]),
            prune=bld.sp.connectivity.prune_vm,
        )
    for fam, (k_for, k_against) in FEEDBACK_TO_FAMILY.items():
        for k, sign, gain in ((k_for, 1, bld.gains_mv.feedback_to_bo), (k_against, -1, bld.gains_mv.feedback_inh_bo)):
            if gain > 0:
                bld.resize(
                    z[k],
                    b[fam],
                    sign=sign,
                    gain=gain,
                    interpolation=bld.sp.connectivity.feedback_interpolation,
                    delay=bld.sp.time.delay_feedback_ms,
                )
    return z


def pooled_feedback(bld, level, g, z):
    """Stage 8 with pooled grouping polarities (``grouping_polarity="pool"``):
    besides the wiring of :func:`feedback_cells` (z1 = GL (*) m1 - GD (*) m2),
    into the feedback cells ``z`` it made,
    each feedback cell reads the other polarity through the same halves
    (+ GD (*) m1 - GL (*) m2), so that it carries z1 = G (*) m1 - G (*) m2
    with G = GL + GD (likewise z2 and the negative halves)."""
    st = bld.sp.connectivity.grouping_stride
    gain = bld.gains_mv.group_to_feedback * st * st
    other = {"L": "D", "D": "L"}
    for k in FEEDBACK_HALVES:
        (pol_for, half_for), (pol_against, half_against) = FEEDBACK_INPUTS[k]
        bld.conv(g[other[pol_for]], z[k], von_mises(half_for, "scatter"), gain=gain, prune=bld.sp.connectivity.prune_vm)
        bld.conv(
            g[other[pol_against]],
            z[k],
            von_mises(half_against, "scatter"),
            sign=-1,
            gain=gain * GainsMv.balance(bld.neurons["feedback"]),
            prune=bld.sp.connectivity.prune_vm,
        )


def window_clock(bld):
    """The window clock: one spike source that fires as each window of a
    recording starts (where windows overlap, once every window length: see
    :class:`~snn_fg.models.spiking.stream_input.StreamLayout`) and inhibits
    every grouping cell, so that the light and dark grouping cells compete
    afresh in every window (without it the family that won one window keeps
    winning the next: the winner-take-all has hysteresis). Its weight is
    ``clock_inh_group`` thresholds of inhibitory current, spread evenly over
    the cells by a 1 x 1 Resize."""
    clock = bld.pop("clock", 1, shape=(1, 1))
    for level in range(1, bld.params.levels + 1):
        for pol in ("L", "D"):
            bld.resize(
                clock,
                bld.named(f"group_{pol}", level),
                sign=-1,
                interpolation="linear",
                gain=bld.sp.gains.clock_inh_group * bld.sp.neurons.group.v_th_mv,
            )


def pooling(bld):
    """Stage 8 across levels, top-down: z_l += decay * resize(z_{l+1}), for
    both halves of each pair (the opposite half subtracts)."""
    for level in range(1, bld.params.levels):
        for k in FEEDBACK_HALVES:
            dst = bld.named(f"feedback_{k}", level)
            bld.resize(
                bld.named(f"feedback_{k}", level + 1),
                dst,
                gain=bld.gains_mv.pool,
                interpolation=bld.sp.connectivity.pool_interpolation,
                prune=bld.sp.connectivity.prune_resize,
            )
            bld.resize(
                bld.named(f"feedback_{OPPOSITE_HALF[k]}", level + 1),
                dst,
                sign=-1,
                gain=bld.gains_mv.pool * GainsMv.balance(bld.neurons["feedback"]),
                interpolation=bld.sp.connectivity.pool_interpolation,
                prune=bld.sp.connectivity.prune_resize,
            )
