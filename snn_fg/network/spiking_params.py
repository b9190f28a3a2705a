"""Constants of the spiking network that the rate model does not have:
:class:`SpikingParams`.

Gains are dimensionless: a gain of ``g`` on a projection means ``g`` firing
thresholds of mean current in the target when the source fires at its
reference rate (one of the rates below); :mod:`snn_fg.network.builder` turns
them into millivolts per spike. Projection-shaped gains are named after the
projection they set: ``<source>_to_<target>`` for excitation and
``<source>_inh_<target>`` for inhibition.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

from .. import validate as check
from .graph import DEFAULT_DT_MS
from .nodes import Neuron, Node

#: Reference presynaptic rates (Hz) of the dimensionless gains.
SIMPLE_RATE_HZ = 50.0  # a simple cell that wins at its pixel
UNTUNED_RATE_HZ = 150.0  # untuned cells fire faster than simple cells
CELL_RATE_HZ = 100.0  # border-ownership, grouping and feedback cells
#: The side cue's value (a half disc's mean event density minus the other's) at which its cells fire CELL_RATE_HZ.
SIDE_CUE_REF = 0.02

INTERPOLATIONS = ("cubic", "linear")
#: how the rival border-ownership family inhibits grouping cells (see the builder)
RIVAL_INHIBITION = ("excess", "direct")


#: the kinds of cell the network has, each with its own neuron constants
CELL_KINDS = ("simple", "untuned", "relay", "bo", "excess", "group", "feedback")


@dataclass(frozen=True, kw_only=True)
class SpikingParams(Node):
    """Spiking constants of the default network (:func:`~snn_fg.network.build_network`).

    Input and instantiation
        ``input_rate_hz``: mean rate of an input pixel with events that the
        input gains are set for: at this rate a simple cell's mean current
        reaches threshold exactly when its DoG response reaches
        ``ModelParams.edge_threshold`` (stage 3); ``gate_margin``: how far
        (thresholds) a level-1 simple cell without an event at its pixel
        stays below threshold under the strongest possible DoG drive;
        ``gate_copies``, ``gate_spread_ms``: the gate arrives as that many
        equal parts, ``gate_spread_ms`` apart (a smoother current: one
        large-weight input would add a ripple of about 2 mV at 200 Hz);
        ``support_min``: coarse levels have simple and untuned cells only
        where the resized edge map reaches this value; ``drive_min``: the
        ``edges&drive`` instantiation hint's fraction of the way from reset
        to threshold (below 1: a margin, so that a cell left out cannot fire
        on fluctuations either; 0.85 keeps the spikes of every instantiated
        cell equal to those of the whole network in the tests);
        ``input_refractory_ms``: the input adapter's refractory period per
        spike source (:attr:`Network.input_refractory_ms`; 0: every event);
        ``dt_ms``: the time step the network is made for
        (:attr:`Network.dt_ms`).
    Geometry
        ``grouping_stride``: grouping and feedback cells sit on every
        ``grouping_stride``-th level pixel along each axis; ``excess_stride``:
        the same for the excess cells, each then taking its block's mean
        excess (1: one per border-ownership cell);
        ``pool_interpolation``: interpolation of the top-down pooling of
        feedback signals from level ``l+1`` to ``l`` (the rate model: cubic);
        ``feedback_interpolation``: from the feedback cells' lattice onto the
        border-ownership cells; ``prune_dog``, ``prune_vm``, ``prune_resize``:
        kernel taps under this fraction of the kernel's largest |value| are
        left out.
    Delays (ms)
        ``delay_ms`` for every projection but: ``delay_untuned_ms``
        (excitation of the untuned cells, so that oriented simple cells fire
        first and silence them) and ``delay_feedback_ms`` (feedback onto
        border-ownership cells). All are at most 20 ms, physiological and
        representable on the neuromorphic targets at dt = 0.5 ms.
    Feedback and rival inhibition
        ``bo_gate_margin``: a border-ownership cell rests below its usual
        resting potential by the largest mean current the feedback half for it
        can deliver plus this many thresholds, and its simple-cell input gives
        that back (so feedback modulates only where the simple cell is
        active); ``rival_inhibition``: ``excess`` (the rival family inhibits
        grouping cells through excess cells, ``rect(B_rival - B_partner)``) or
        ``direct`` (through its own cells: the ablation).
    Window clock (recordings)
        ``clock_inh_group``: thresholds of inhibitory current that the window
        clock, one spike source firing as each window of a recording starts,
        puts on every grouping cell (0: no clock). It must hold the grouping
        cells silent until the feedback's inhibition of the border-ownership
        cells that lost the previous window has faded (``feedback_inh_bo``
        thresholds per 100 Hz of the feedback half against them: about 120
        thresholds from a pair at 600 Hz, the 90th percentile on a BSDS
        frame, decaying with the border-ownership cells' ``tau_inh``, 5 ms:
        about 27 ms to half a threshold); otherwise the family that won one window
        wins the next whatever its input (``experiments.validation.window_clock``).
        A frame never fires it.
    Side cue (``ModelParams.side_cue``, the natural-scene variant)
        ``z_hz``: Hz of a level-1 feedback pair (``p - n``) per unit of the
        rate model's pooled feedback signal ``z`` (1: the two have the same
        quartiles at the level-1 entries of a tuning-half BSDS image,
        ``docs/model.md``); the side cue's cells hand the feedback pairs
        ``side_cue * z_hz`` Hz per unit of the cue.
    Neurons
        One :class:`~snn_fg.network.nodes.Neuron` per kind of cell
        (:data:`CELL_KINDS`): ``simple``, ``untuned``, ``relay``, ``bo``
        (border ownership), ``excess``, ``group``, ``feedback``. Every kind
        has one synaptic time constant, 5 ms for excitation and inhibition
        alike, so that the negative lobes of a kernel (DoG, von Mises
        differences, interpolation), which a board receives through the
        inhibitory current, act as in the signed sum the simulators use
        (with the earlier 10 ms inhibition the export on NEST flipped the
        light/dark competition of a ``dvs.es`` window), and so that a board
        with one current decay per neuron (Loihi 2) takes every population
        as it is. The untuned cells had 50 ms inhibition until 24 Nov 2026;
        with 5 ms the maps moved by at most 0.4 deg against the rate model
        on held-out images and the synthetic scenes, 2.1 deg on the demo
        scene (``experiments.validation.spiking_heldout``). The feedback
        cells carry ``z`` as a rate through the top-down chain of stage 8, so
        their rate must stay proportional to their drive over the range
        ``z`` takes (a rectified pair at 100-600 Hz, a tail to 2 kHz on BSDS
        frames): their refractory period is one step at the default
        ``dt`` (0.5 ms), which keeps the rate per threshold of drive at
        38-40 Hz from 100 to 400 Hz (34 Hz at 620 Hz). With the earlier
        4 ms it fell from 26 Hz at 100 Hz to 10 Hz at 200 Hz, so the strong
        part of ``z`` was clipped at every level it passed through.
    Gains (dimensionless, see the module docstring; reference rate in brackets)
        ``simple_inh_simple``: lateral inhibition between the directions at a
        pixel [100 Hz]; ``input_to_untuned``: an untuned cell's excitation at
        its reference edge value (1 at level 1, ``support_min`` above);
        ``simple_inh_untuned`` [50 Hz]; ``simple_to_bo`` [50 Hz] (on top of
        the gate it gives back); ``untuned_to_bo`` [150 Hz]; ``bo_inh_bo``:
        between the two border-ownership cells sharing a simple cell (0: none,
        so that only feedback tells them apart) [100 Hz]; ``feedback_to_bo``
        and ``feedback_inh_bo``: the feedback half for (exciting) and against
        (inhibiting) a border-ownership cell [100 Hz] (``feedback_to_bo``
        0.125: at the feedback cells' 2 kHz ceiling the excitation is 2.5
        thresholds, what 1.0 gave at the 250 Hz ceiling of the earlier 4 ms
        cell, so the gate that must cover it, and with it how much a
        border-ownership cell depends on its simple cell's exact rate, stays
        as deep; 1.0 with the 0.5 ms cell made the gate 20.5 thresholds and
        left a quarter to a third of the rate model's vectors blank on BSDS
        frames); ``bo_to_excess``
        [100 Hz]; ``bo_to_group`` per unit kernel weight [100 Hz];
        ``group_inh_group``: light and dark grouping cells [100 Hz];
        ``group_to_feedback`` per unit kernel weight [100 Hz]; ``pool_gain``:
        the top-down pooling of stage 8, in units of the model's
        (1: a level hands the next finer one ``pyramid_decay`` times the drive
        of its feedback cells, read from their rate through the LIF's own rate
        curve at 100 Hz; 0.52 was the earlier calibration, which took the rate
        as ``I / (tau_m v_th)``).
    """

    _nested: ClassVar[dict] = {kind: Neuron for kind in CELL_KINDS}

    input_rate_hz: float = 200.0
    support_min: float = 0.3
    drive_min: float = 0.85
    input_refractory_ms: float = 0.0
    dt_ms: float = DEFAULT_DT_MS
    gate_margin: float = 1.0
    gate_copies: int = 5
    gate_spread_ms: float = 1.0
    grouping_stride: int = 2
    excess_stride: int = 1
    pool_interpolation: str = "linear"
    feedback_interpolation: str = "linear"
    prune_dog: float = 0.05
    prune_vm: float = 0.05
    prune_resize: float = 0.0
    delay_ms: float = 1.0
    delay_untuned_ms: float = 8.0
    delay_feedback_ms: float = 1.0
    rival_inhibition: str = "excess"
    bo_gate_margin: float = 0.5
    simple: Neuron = Neuron(tau_m_ms=10.0, t_ref_ms=4.0)
    untuned: Neuron = Neuron(tau_m_ms=10.0, t_ref_ms=4.0)
    relay: Neuron = Neuron(tau_m_ms=200.0, t_ref_ms=1.0)
    bo: Neuron = Neuron(tau_m_ms=10.0, t_ref_ms=5.0)
    excess: Neuron = Neuron(tau_m_ms=10.0, t_ref_ms=5.0)
    group: Neuron = Neuron(tau_m_ms=20.0, t_ref_ms=2.0)
    feedback: Neuron = Neuron(tau_m_ms=20.0, t_ref_ms=0.5)
    simple_inh_simple: float = 3.0
    input_to_untuned: float = 1.5
    simple_inh_untuned: float = 20.0
    simple_to_bo: float = 1.5
    untuned_to_bo: float = 6.0
    bo_inh_bo: float = 0.0
    feedback_to_bo: float = 0.125
    feedback_inh_bo: float = 20.0
    bo_to_group: float = 0.5
    group_inh_group: float = 0.5
    group_to_feedback: float = 0.4
    bo_to_excess: float = 2.0
    pool_gain: float = 1.0
    clock_inh_group: float = 300.0
    z_hz: float = 1.0

    def __post_init__(self):
        owner = "SpikingParams"
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name in CELL_KINDS:
                if not isinstance(v, Neuron):
                    check.fail(owner, f.name, v, "must be a Neuron")
            elif f.name in ("grouping_stride", "excess_stride", "gate_copies"):
                check.integer(owner, f.name, v, lo=1)
            elif f.name == "rival_inhibition":
                check.choice(owner, f.name, v, RIVAL_INHIBITION)
            elif f.name.endswith("_interpolation"):
                check.choice(owner, f.name, v, INTERPOLATIONS)
            elif f.name.startswith("prune_"):
                object.__setattr__(self, f.name, check.number(owner, f.name, v, lo=0, hi=1, hi_open=True))
            else:
                strict = f.name in ("input_rate_hz", "dt_ms")
                object.__setattr__(self, f.name, check.number(owner, f.name, v, lo=0, lo_open=strict))

    def replace(self, **changes) -> SpikingParams:
        return dataclasses.replace(self, **changes)
