"""The weight of a spike on each kind of projection (:class:`GainsMv`), in terms
of its target cells' threshold and synaptic time constant: a gain of ``g``
thresholds of mean current at the reference rate of its source
(:mod:`snn_fg.network.spiking_params`)."""

from __future__ import annotations

from dataclasses import dataclass

from ..params import ModelParams
from .nodes import Neuron
from .spiking_params import CELL_RATE_HZ, SIMPLE_RATE_HZ, UNTUNED_RATE_HZ, SpikingParams


@dataclass(frozen=True)
class GainsMv:
    """Millivolts per spike (per unit kernel value) of each kind of projection."""

    dog: float  # input (or relay) -> simple cells, per unit DoG weight
    relay: float  # input -> relay, per unit interpolation weight
    simple_to_bo: float
    untuned_to_bo: float
    feedback_to_bo: float
    feedback_inh_bo: float
    bo_to_group: float
    group_to_feedback: float
    bo_to_excess: float
    simple_inh_simple: float
    bo_inh_bo: float
    group_inh_group: float
    simple_inh_untuned: float
    pool: float  # feedback cells of level l+1 -> level l

    @classmethod
    def of(cls, params: ModelParams, sp: SpikingParams) -> GainsMv:
        """Each gain in terms of its target cells' threshold and synaptic time constant."""

        def per_spike(gain, rate_hz, target: Neuron, receptor="exc"):
            """Weight that gives ``gain`` thresholds of mean current at ``rate_hz``."""
            tau_s = (target.tau_exc_ms if receptor == "exc" else target.tau_inh_ms) / 1000.0
            return gain * target.v_th_mv / (rate_hz * tau_s)

        s, u, bo, g, fb = sp.neurons.simple, sp.neurons.untuned, sp.neurons.bo, sp.neurons.group, sp.neurons.feedback
        return cls(
            # a DoG response of edge_threshold at the input rate is one threshold (stage 3)
            dog=s.v_th_mv / (params.edge_threshold * sp.input.input_rate_hz * (s.tau_exc_ms / 1000.0)),
            # one relay spike per unit of input: a unit-weight spike is one threshold of charge
            relay=sp.neurons.relay.v_th_mv * sp.neurons.relay.tau_m_ms / sp.neurons.relay.tau_exc_ms,
            simple_to_bo=per_spike(sp.gains.simple_to_bo, SIMPLE_RATE_HZ, bo),
            untuned_to_bo=per_spike(sp.gains.untuned_to_bo, UNTUNED_RATE_HZ, bo),
            feedback_to_bo=per_spike(sp.gains.feedback_to_bo, CELL_RATE_HZ, bo),
            feedback_inh_bo=per_spike(sp.gains.feedback_inh_bo, CELL_RATE_HZ, bo, "inh"),
            bo_to_group=per_spike(sp.gains.bo_to_group, CELL_RATE_HZ, g),
            group_to_feedback=per_spike(sp.gains.group_to_feedback, CELL_RATE_HZ, fb),
            bo_to_excess=per_spike(sp.gains.bo_to_excess, CELL_RATE_HZ, sp.neurons.excess),
            simple_inh_simple=per_spike(sp.gains.simple_inh_simple, CELL_RATE_HZ, s, "inh"),
            bo_inh_bo=per_spike(sp.gains.bo_inh_bo, CELL_RATE_HZ, bo, "inh"),
            group_inh_group=per_spike(sp.gains.group_inh_group, CELL_RATE_HZ, g, "inh"),
            simple_inh_untuned=sp.gains.simple_inh_untuned * u.v_th_mv / (SIMPLE_RATE_HZ * u.tau_inh_ms / 1000.0),
            # hands level l decay * the drive of the level-(l+1) cell: a feedback cell firing at
            # CELL_RATE_HZ is under the drive drive_for_rate(CELL_RATE_HZ) (2.6 thresholds for the
            # default cell, leak and refractoriness included; reading it as I / (tau_m v_th), 2
            # thresholds, passed on 0.23-0.41 of the coarse levels' share, docs/model.md stage 8)
            pool=sp.gains.pool_gain
            * params.pyramid_decay
            * fb.drive_for_rate(CELL_RATE_HZ)
            / (CELL_RATE_HZ * fb.tau_exc_ms / 1000.0),
        )

    @staticmethod
    def balance(target: Neuron) -> float:
        """``tau_exc / tau_inh`` of the target: an inhibitory current decays
        with ``tau_inh`` instead of ``tau_exc``, so a subtraction scaled by
        this weighs what it subtracts."""
        return target.tau_exc_ms / target.tau_inh_ms

    def input_to_untuned(self, sp: SpikingParams, level: int) -> float:
        """An untuned cell's excitation: ``input_to_untuned`` thresholds at its
        reference edge value (1 at level 1, ``support_min`` above)."""
        edge = 1.0 if level == 1 else max(sp.input.support_min, 1e-3)
        tau_e = sp.neurons.untuned.tau_exc_ms / 1000.0
        return sp.gains.input_to_untuned * sp.neurons.untuned.v_th_mv / (edge * sp.input.input_rate_hz * tau_e)
