"""The network in Loihi 2's integers: every register Lava's fixed-point LIF
and connections take (:mod:`snn_fg.lava.fixed` says what they compute).

A population's CUBA LIF (one synaptic time constant: Loihi 2's neuron has
one current) becomes:

* ``du = 4096 - 1 - round(4096 d_syn)`` and ``dv = 4096 - round(4096 d_m)``
  (``d = exp(-dt / tau)``; the current's decay has Loihi's offset of 1);
* a *unit* of ``unit_per_mv`` integer steps per mV of membrane potential,
  measured from the reset (``v = 0`` is ``v_reset``). It is as fine as the
  24-bit current allows without ever wrapping around: ``u_bound_mv``, the
  largest current the population can receive, is every source cell firing
  as often as its refractory period lets it (an input pixel every step,
  the window clock once), through every synapse of one sign at once
  (:func:`current_bound_mv`); ``2**23 - 1`` units span it. The unit is then
  rounded down so that the threshold is a whole 17-bit register:
  ``vth = (v_th - v_reset) * unit / 64`` exactly;
* ``bias = dv / 4096 * (v_rest - v_reset) * unit`` as ``bias_mant << bias_exp``,
  so that the potential rests at ``v_rest`` under Loihi's own decay;
* ``refractory_steps = R - 1`` for a refractory period of ``R`` steps (a cell
  that fires at step ``n`` may fire again at ``n + R``, as in our engines).

A projection becomes 8-bit mantissas ``m = round(drive * factor)`` (drive:
``sign * gain_mv * K`` in mV, as the description's weight) with one
``weight_exp`` ``e``: the connection adds ``2 m << e`` to ``a_in``, i.e.
``2 m 2**e << 6`` units to the target's current, which moves ``v`` as the
description's current jump ``p * drive`` does (``p``: the CUBA propagator
from current to voltage), so ``factor = p * unit / 2**(7 + e)``; ``e`` is the
smallest (at least -1, where ``2 m >> 1`` is still exact) that keeps the
projection's largest |drive| within 127. A projection's weights are
therefore 8-bit integers times a power of two of its target's unit: the
scale of the 8-bit weights of ``--weight-bits 8`` (the projection's peak
over 127) rounded up to such a power, 7 to 8 bits at the peak.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..lava import fixed
from ..network.graph import Network
from ..network.projections import Conv
from .connect import kernel_taps
from .interp import interp_matrix, sparse_rows
from .quantise import peak_weight


@dataclass(frozen=True, kw_only=True)
class LavaNeuron:
    """A population's registers (module docstring) and the unit they are in."""

    du: int
    dv: int
    vth: int
    bias_mant: int
    bias_exp: int
    refractory_steps: int
    unit_per_mv: float
    u_bound_mv: float

    def to_dict(self) -> dict:
        return dict(vars(self))


@dataclass(frozen=True, kw_only=True)
class LavaSynapses:
    """A projection's weight exponent, mantissas per mV of drive, and delay in steps."""

    weight_exp: int
    factor: float
    delay_steps: int

    def to_dict(self) -> dict:
        return dict(vars(self))


def refractory_steps(t_ref_ms: float, dt_ms: float) -> int:
    """``R``: a cell that fires at step ``n`` may fire again at ``n + R`` (at least 1), as Brian2 counts it."""
    return max(int((t_ref_ms + 1e-3 * dt_ms) / dt_ms), 1)


def delay_steps(delay_ms: float, dt_ms: float) -> int:
    """A delay in whole steps (at least one)."""
    return max(int(np.round(round(delay_ms, 6) / dt_ms)), 1)


def decays(neuron, dt_ms: float) -> tuple[int, int]:
    """``(du, dv)`` of a neuron at ``dt_ms`` (module docstring); refuses two synaptic time constants."""
    if not math.isclose(neuron.tau_exc_ms, neuron.tau_inh_ms, rel_tol=1e-9):
        raise ValueError(
            f"Loihi 2's LIF has one synaptic current: tau_exc_ms {neuron.tau_exc_ms:g} and tau_inh_ms "
            f"{neuron.tau_inh_ms:g} differ"
        )
    f = neuron.propagators(dt_ms)
    du = fixed.DECAY_UNITY - fixed.DU_OFFSET - round(fixed.DECAY_UNITY * f["d_exc"])
    dv = fixed.DECAY_UNITY - round(fixed.DECAY_UNITY * f["d_m"])
    return min(max(du, 0), fixed.DECAY_MAX), min(max(dv, 0), fixed.DECAY_MAX)


def _fan_in_mantissas(network: Network, pr, factor: float) -> tuple[int, int]:
    """The largest summed positive and negative mantissa (``sum |m|``) one
    target cell of ``pr`` receives when every source of ``pr`` spikes at
    once, its drives rounded to mantissas with ``factor``."""
    if isinstance(pr, Conv):
        co, _, _, _, k, _ = kernel_taps(pr, network)
        m = fixed.mantissas(pr.sign * pr.gain_mv * k, factor)
        return int(np.bincount(co, np.maximum(m, 0)).max(initial=0)), int(
            np.bincount(co, np.maximum(-m, 0)).max(initial=0)
        )
    src, tgt = network.population(pr.source), network.population(pr.target)
    (_, rv), (_, cv) = (
        sparse_rows(interp_matrix(src.level_shape[x], tgt.level_shape[x], src.stride, tgt.stride, pr.interpolation))
        for x in (0, 1)
    )
    m = fixed.mantissas(pr.sign * pr.gain_mv * rv[:, None, :, None] * cv[None, :, None, :], factor)
    return int(np.maximum(m, 0).sum((2, 3)).max(initial=0)), int(np.maximum(-m, 0).sum((2, 3)).max(initial=0))


def _source_period(network: Network, name: str) -> float:
    """Fewest steps between two spikes of a cell of population ``name``: its
    refractory period; an input pixel every step, the window clock once (inf)."""
    pop = network.population(name)
    if pop.role == "clock":
        return math.inf
    return 1 if pop.neuron is None else refractory_steps(pop.neuron.t_ref_ms, network.dt_ms)


def current_bound(network: Network, target: str, du: int, synapses: dict) -> float:
    """The largest |current| (in the target's integer units) population
    ``target`` can receive through the mantissas and exponents ``synapses``
    (projection name -> :class:`LavaSynapses`): every source cell firing as
    often as its refractory period lets it, through every synapse of one sign at once."""
    d_u = (fixed.DECAY_UNITY - du - fixed.DU_OFFSET) / fixed.DECAY_UNITY
    pos = neg = 0.0
    for pr in network.projections:
        if pr.target != target:
            continue
        period = _source_period(network, pr.source)
        pile = 1.0 if math.isinf(period) else 1.0 / (1.0 - d_u**period)
        syn = synapses[pr.name]
        a, b = _fan_in_mantissas(network, pr, syn.factor)
        step = 2.0 ** (7 + syn.weight_exp)  # current units of one mantissa step
        pos, neg = pos + a * step * pile, neg + b * step * pile
    return max(pos, neg)


def _registers(network: Network, name: str, unit: float):
    """``(vth, unit, synapses into name)`` for a unit of at most ``unit`` rounded to a whole threshold register."""
    n = network.population(name).neuron
    height = n.v_th_mv - n.v_reset_mv
    vth = min(int(unit * height / 2**fixed.VTH_SHIFT), fixed.VTH_MAX)
    unit = vth * 2**fixed.VTH_SHIFT / height
    syn = {pr.name: lava_synapses(network, pr, unit) for pr in network.projections if pr.target == name}
    return vth, unit, syn


def lava_neuron(network: Network, name: str) -> tuple[LavaNeuron, dict]:
    """The registers of population ``name`` and the synapses into it (module docstring)."""
    n, dt = network.population(name).neuron, network.dt_ms
    try:
        du, dv = decays(n, dt)
    except ValueError as e:
        raise InputError(f"population '{name}'", str(e)) from None
    rest = n.v_rest_mv - n.v_reset_mv
    top = fixed.STATE_MAX - 1
    unit = top / max(n.v_th_mv - n.v_reset_mv, abs(rest))
    if rest != 0 and dv:
        unit = min(unit, fixed.BIAS_MANT_MAX * 2**fixed.BIAS_EXP_MAX / (dv / fixed.DECAY_UNITY * abs(rest)))
    for _ in range(40):  # the largest unit whose rounded mantissas keep the current inside 24 bits
        vth, unit, syn = _registers(network, name, unit)
        bound = current_bound(network, name, du, syn)
        if bound <= top:
            break
        unit *= top / bound * (1 - 1e-9)
    else:
        raise ValueError(f"population '{name}': no unit keeps its current inside {fixed.STATE_BITS} bits")
    bias = dv / fixed.DECAY_UNITY * rest * unit
    exp = next(e for e in range(fixed.BIAS_EXP_MAX + 1) if abs(round(bias / 2**e)) <= fixed.BIAS_MANT_MAX)
    neuron = LavaNeuron(
        du=du,
        dv=dv,
        vth=vth,
        bias_mant=int(round(bias / 2**exp)),
        bias_exp=exp,
        refractory_steps=refractory_steps(n.t_ref_ms, dt) - 1,
        unit_per_mv=unit,
        u_bound_mv=bound / unit,
    )
    return neuron, syn


def lava_synapses(network: Network, pr, unit_per_mv: float) -> LavaSynapses:
    """The weight exponent and mantissa factor of projection ``pr`` into a population of unit ``unit_per_mv``."""
    tgt = network.population(pr.target).neuron
    units = tgt.propagators(network.dt_ms)["p_exc"] * unit_per_mv  # current units per mV of drive
    peak = peak_weight(network, pr) * units
    e = max(-1, math.ceil(math.log2(peak / fixed.MANTISSA_MAX)) - 7) if peak > 0 else 0
    return LavaSynapses(
        weight_exp=e,
        factor=units / 2.0 ** (7 + e),
        delay_steps=fixed.lava_delay(delay_steps(pr.delay_ms, network.dt_ms)),
    )


@dataclass(frozen=True)
class LavaLowering:
    """Every population's :class:`LavaNeuron` and every projection's :class:`LavaSynapses`, by name."""

    neurons: dict
    synapses: dict


def lower(network: Network) -> LavaLowering:
    """The whole network in Loihi 2's integers, at its own time step."""
    neurons, synapses = {}, {}
    for p in network.populations:
        if p.neuron is not None:
            neurons[p.name], syn = lava_neuron(network, p.name)
            synapses.update(syn)
    return LavaLowering(neurons, synapses)
