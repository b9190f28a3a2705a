"""The side cue's cells (``ModelParams.side_cue``, :mod:`snn_fg.models.rate.side_cue`),
added to a network by the builder (:func:`side_cue`)."""

from __future__ import annotations

from .gains import GainsMv
from .kernels import side_cue_kernels
from .nodes import Kernel
from .spiking_params import CELL_RATE_HZ, SIDE_CUE_REF


def side_cue(bld) -> None:
    """At the cue's level, a rectified pair of cells per orientation,
    ``side_p`` = rect(Q) and ``side_n`` = rect(-Q), Q the half-disc
    difference of the level's event density (its ON and OFF inputs or
    relays), each firing ``CELL_RATE_HZ`` at ``Q = SIDE_CUE_REF``; resized
    onto the level-1 feedback cells, Q adds to z1 and subtracts from z2 by
    ``side_cue`` units of the model's z, at ``z_hz`` Hz of a feedback pair per
    unit (read through the feedback cells' rate curve at ``CELL_RATE_HZ``).
    Nothing when ``side_cue`` is 0. ``bld``: the builder of
    :class:`~snn_fg.network.builder.Builder`, after every level and the pooling."""
    p, sp = bld.params, bld.sp
    if not p.side_cue:
        return
    level, n = p.cue_level, p.n_ori
    fb = bld.neurons["feedback"]  # the side cells are feedback cells too: a rate that follows the drive
    per_hz = fb.drive_for_rate(CELL_RATE_HZ) / CELL_RATE_HZ  # mV of drive per Hz of such a cell
    gain_in = per_hz * CELL_RATE_HZ / (SIDE_CUE_REF * sp.input.input_rate_hz * fb.tau_exc_ms / 1000.0)
    gain_out = p.side_cue * SIDE_CUE_REF * sp.gains.z_hz * per_hz / (CELL_RATE_HZ * fb.tau_exc_ms / 1000.0)
    kernel = side_cue_kernels(p)[:, None]
    inputs = ("input_on", "input_off", "relay_on", "relay_off")  # the level's ON and OFF inputs, as built
    sources = [q.name for q in bld.pops if q.level == level and q.role in inputs]
    cues = {}
    for half, sign in (("p", 1), ("n", -1)):
        cues[half] = bld.pop(f"side_{half}", level, channels=n, neuron=fb, sites="all")
        for src in sources:
            bld.conv(src, cues[half], Kernel(ref="array", args={"data": sign * kernel}), gain=gain_in, calibrated=True)
    # z1 = 1p - 1n gains Q, z2 = 2p - 2n loses it
    for half, into in (("p", {"1p": 1, "1n": -1, "2p": -1, "2n": 1}), ("n", {"1p": -1, "1n": 1, "2p": 1, "2n": -1})):
        for k, sign in into.items():
            bld.resize(
                cues[half],
                bld.named(f"feedback_{k}", 1),
                sign=sign,
                interpolation="linear",
                gain=gain_out * (1.0 if sign > 0 else GainsMv.balance(fb)),
            )
