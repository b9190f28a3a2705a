"""Constants of the spiking network that the rate model does not have:
:class:`SpikingParams`, in five parts.

* :class:`Neurons` - one LIF neuron per kind of cell;
* :class:`Input` - the input rate the gains are set for, the level-1 gate,
  the input's refractory period and the instantiation hints;
* :class:`Connectivity` - lattices, interpolation, kernel pruning and the
  rival family's inhibition;
* :class:`Gains` - how strongly each kind of projection drives its targets;
* :class:`Timing` - the time step and the delays.

Gains are dimensionless: a gain of ``g`` on a projection means ``g`` firing
thresholds of mean current in the target when the source fires at its
reference rate (one of the rates below); :mod:`snn_fg.network.gains` turns
them into millivolts per spike. Projection-shaped gains are named after the
projection they set: ``<source>_to_<target>`` for excitation and
``<source>_inh_<target>`` for inhibition.

A part is changed as a whole or field by field::

    sp = SpikingParams(time=Timing(dt_ms=1.0))
    sp = sp.replace(connectivity=sp.connectivity.replace(prune_dog=0.3))

The flat form of earlier releases (``SpikingParams(dt_ms=1.0)``,
``sp.replace(prune_dog=0.3)``, ``sp.dt_ms``) still works and warns
(``DeprecationWarning``); its stored form (one mapping of every field) still
loads (:meth:`SpikingParams.from_dict`), and :meth:`SpikingParams.to_dict`
writes the parts.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
from typing import ClassVar

from .. import validate as check
from .graph import DEFAULT_DT_MS, DRIVE_MIN, INPUT_RATE_HZ, INPUT_REFRACTORY_MS, SUPPORT_MIN
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
#: fields checked as whole numbers >= 1, and as numbers > 0 (every other number is >= 0)
_COUNTS = ("grouping_stride", "excess_stride", "gate_copies")
_POSITIVE = ("input_rate_hz", "dt_ms")


class _Part(Node):
    """A part of :class:`SpikingParams`: its fields checked by one rule per
    kind of field, and changed with :meth:`replace`."""

    def __post_init__(self):
        owner = type(self).__name__
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name in CELL_KINDS:
                if not isinstance(v, Neuron):
                    check.fail(owner, f.name, v, "must be a Neuron")
            elif f.name in _COUNTS:
                check.integer(owner, f.name, v, lo=1)
            elif f.name == "rival_inhibition":
                check.choice(owner, f.name, v, RIVAL_INHIBITION)
            elif f.name.endswith("_interpolation"):
                check.choice(owner, f.name, v, INTERPOLATIONS)
            elif f.name.startswith("prune_"):
                object.__setattr__(self, f.name, check.number(owner, f.name, v, lo=0, hi=1, hi_open=True))
            else:
                object.__setattr__(self, f.name, check.number(owner, f.name, v, lo=0, lo_open=f.name in _POSITIVE))

    def replace(self, **changes):
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True, kw_only=True)
class Neurons(_Part):
    """One :class:`~snn_fg.network.nodes.Neuron` per kind of cell
    (:data:`CELL_KINDS`): ``simple``, ``untuned``, ``relay``, ``bo`` (border
    ownership), ``excess``, ``group``, ``feedback``.

    Every kind has one synaptic time constant, 5 ms for excitation and
    inhibition alike, so that the negative lobes of a kernel (DoG, von Mises
    differences, interpolation), which a board receives through the
    inhibitory current, act as in the signed sum the simulators use, and so
    that a board with one current decay per neuron (Loihi 2) takes every
    population as it is. The feedback cells carry ``z`` as a rate through
    the top-down chain of stage 8, so their rate must stay proportional to
    their drive over the range ``z`` takes (a rectified pair at 100-600 Hz,
    a tail to 2 kHz on BSDS frames): their refractory period is one step at
    the default time step (0.5 ms), which keeps the rate per threshold of
    drive at 38-40 Hz from 100 to 400 Hz (34 Hz at 620 Hz). How each choice
    was measured: ``docs/model.md``.
    """

    _nested: ClassVar[dict] = {kind: Neuron for kind in CELL_KINDS}

    simple: Neuron = Neuron(tau_m_ms=10.0, t_ref_ms=4.0)
    untuned: Neuron = Neuron(tau_m_ms=10.0, t_ref_ms=4.0)
    relay: Neuron = Neuron(tau_m_ms=200.0, t_ref_ms=1.0)
    bo: Neuron = Neuron(tau_m_ms=10.0, t_ref_ms=5.0)
    excess: Neuron = Neuron(tau_m_ms=10.0, t_ref_ms=5.0)
    group: Neuron = Neuron(tau_m_ms=20.0, t_ref_ms=2.0)
    feedback: Neuron = Neuron(tau_m_ms=20.0, t_ref_ms=0.5)


@dataclass(frozen=True, kw_only=True)
class Input(_Part):
    """The input and which cells an input makes.

    ``input_rate_hz``: mean rate of an input pixel with events that the
    input gains are set for: at this rate a simple cell's mean current
    reaches threshold exactly when its DoG response reaches
    ``ModelParams.edge_threshold`` (stage 3); ``input_refractory_ms``: the
    input adapter's refractory period per spike source
    (:attr:`Network.input_refractory_ms`; 0: every event); ``gate_margin``:
    how far (thresholds) a level-1 simple cell without an event at its pixel
    stays below threshold under the strongest possible DoG drive;
    ``gate_copies``, ``gate_spread_ms``: the gate arrives as that many equal
    parts, ``gate_spread_ms`` apart (a smoother current: one large-weight
    input would add a ripple of about 2 mV at 200 Hz); ``support_min``:
    coarse levels have simple and untuned cells only where the resized edge
    map reaches this value; ``drive_min``: the ``edges&drive`` instantiation
    hint's fraction of the way from reset to threshold (below 1: a margin,
    so that a cell left out cannot fire on fluctuations either; 0.85 keeps
    the spikes of every instantiated cell equal to those of the whole
    network in the tests).
    """

    input_rate_hz: float = INPUT_RATE_HZ
    input_refractory_ms: float = INPUT_REFRACTORY_MS
    gate_margin: float = 1.0
    gate_copies: int = 5
    gate_spread_ms: float = 1.0
    support_min: float = SUPPORT_MIN
    drive_min: float = DRIVE_MIN


@dataclass(frozen=True, kw_only=True)
class Connectivity(_Part):
    """Which cells exist and which taps connect them.

    ``grouping_stride``: grouping and feedback cells sit on every
    ``grouping_stride``-th level pixel along each axis; ``excess_stride``:
    the same for the excess cells, each then taking its block's mean excess
    (1: one per border-ownership cell); ``pool_interpolation``:
    interpolation of the top-down pooling of feedback signals from level
    ``l+1`` to ``l`` (the rate model: cubic); ``feedback_interpolation``:
    from the feedback cells' lattice onto the border-ownership cells;
    ``prune_dog``, ``prune_vm``, ``prune_resize``: kernel taps under this
    fraction of the kernel's largest absolute value are left out;
    ``rival_inhibition``: ``excess`` (the rival family inhibits grouping
    cells through excess cells, ``rect(B_rival - B_partner)``) or ``direct``
    (through its own cells: the ablation).
    """

    grouping_stride: int = 2
    excess_stride: int = 1
    pool_interpolation: str = "linear"
    feedback_interpolation: str = "linear"
    prune_dog: float = 0.05
    prune_vm: float = 0.05
    prune_resize: float = 0.0
    rival_inhibition: str = "excess"


@dataclass(frozen=True, kw_only=True)
class Gains(_Part):
    """How strongly each kind of projection drives its targets
    (dimensionless, see the module docstring; reference rate in brackets).

    ``simple_inh_simple``: lateral inhibition between the directions at a
    pixel [100 Hz]; ``input_to_untuned``: an untuned cell's excitation at its
    reference edge value (1 at level 1, ``support_min`` above);
    ``simple_inh_untuned`` [50 Hz]; ``simple_to_bo`` [50 Hz] (on top of the
    gate it gives back); ``untuned_to_bo`` [150 Hz]; ``bo_inh_bo``: between
    the two border-ownership cells sharing a simple cell (0: none, so that
    only feedback tells them apart) [100 Hz]; ``feedback_to_bo`` and
    ``feedback_inh_bo``: the feedback half for (exciting) and against
    (inhibiting) a border-ownership cell [100 Hz] (``feedback_to_bo`` 0.125:
    at the feedback cells' 2 kHz ceiling the excitation is 2.5 thresholds,
    which keeps the gate that must cover it shallow, and with it how much a
    border-ownership cell depends on its simple cell's exact rate);
    ``bo_to_excess`` [100 Hz]; ``bo_to_group`` per unit kernel weight
    [100 Hz]; ``group_inh_group``: light and dark grouping cells [100 Hz];
    ``group_to_feedback`` per unit kernel weight [100 Hz]; ``pool_gain``: the
    top-down pooling of stage 8, in units of the model's (1: a level hands
    the next finer one ``pyramid_decay`` times the drive of its feedback
    cells, read from their rate through the LIF's own rate curve at 100 Hz).

    ``bo_gate_margin``: a border-ownership cell rests below its usual resting
    potential by the largest mean current the feedback half for it can
    deliver plus this many thresholds, and its simple-cell input gives that
    back (so feedback modulates only where the simple cell is active).

    ``clock_inh_group``: thresholds of inhibitory current that the window
    clock, one spike source firing as each window of a recording starts
    (where windows overlap, once every window length:
    :class:`~snn_fg.models.spiking.stream_input.StreamLayout`), puts on
    every grouping cell (0: no clock). It must hold the grouping cells
    silent until the feedback's inhibition of the border-ownership
    cells that lost the previous window has faded (``feedback_inh_bo``
    thresholds per 100 Hz of the feedback half against them: about 120
    thresholds from a pair at 600 Hz, the 90th percentile on a BSDS frame,
    decaying with the border-ownership cells' ``tau_inh``, 5 ms: about 27 ms
    to half a threshold); otherwise the family that won one window wins the
    next whatever its input (``experiments.validation.window_clock``). A
    frame never fires it.

    ``z_hz`` (the side cue, ``ModelParams.side_cue``, of the natural-scene
    variant): Hz of a level-1 feedback pair (``p - n``) per unit of the rate
    model's pooled feedback signal ``z`` (1: the two have the same quartiles
    at the level-1 entries of a tuning-half BSDS image, ``docs/model.md``);
    the side cue's cells hand the feedback pairs ``side_cue * z_hz`` Hz per
    unit of the cue.
    """

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
    bo_gate_margin: float = 0.5
    clock_inh_group: float = 300.0
    z_hz: float = 1.0


@dataclass(frozen=True, kw_only=True)
class Timing(_Part):
    """The time step and the delays (ms).

    ``dt_ms``: the time step the network is made for
    (:attr:`Network.dt_ms`; default :data:`~snn_fg.network.graph.DEFAULT_DT_MS`).
    ``delay_ms`` for every projection but: ``delay_untuned_ms`` (excitation
    of the untuned cells, so that oriented simple cells fire first and
    silence them) and ``delay_feedback_ms`` (feedback onto border-ownership
    cells). All are at most 20 ms, physiological and representable on the
    neuromorphic targets at a 0.5 ms step.
    """

    dt_ms: float = DEFAULT_DT_MS
    delay_ms: float = 1.0
    delay_untuned_ms: float = 8.0
    delay_feedback_ms: float = 1.0


#: the parts of :class:`SpikingParams`, by the name it holds them under
PARTS: dict[str, type[_Part]] = {
    "neurons": Neurons,
    "input": Input,
    "connectivity": Connectivity,
    "gains": Gains,
    "time": Timing,
}
#: each field of the flat form (every constant in one mapping, before the parts) -> the part that holds it
FLAT_FIELDS: dict[str, str] = {f.name: part for part, kind in PARTS.items() for f in dataclasses.fields(kind)}


def grouped(fields: dict, owner: str = "SpikingParams") -> dict:
    """``fields`` with every field of the flat form moved into its part
    (``{"dt_ms": 1.0}`` -> ``{"time": {"dt_ms": 1.0}}``); parts given whole
    are kept, and a field given both ways is refused."""
    out = {k: (dict(v) if k in PARTS and isinstance(v, dict) else v) for k, v in fields.items() if k not in FLAT_FIELDS}
    for name, v in fields.items():
        if name in FLAT_FIELDS:
            part = out.setdefault(FLAT_FIELDS[name], {})
            if not isinstance(part, dict) or name in part:
                check.fail(owner, name, v, f"is given twice, flat and in its part {FLAT_FIELDS[name]!r}")
            part[name] = v
    return out


@dataclass(frozen=True, init=False)
class SpikingParams(Node):
    """Spiking constants of the default network (:func:`~snn_fg.network.build_network`),
    in parts: ``neurons`` (:class:`Neurons`), ``input`` (:class:`Input`),
    ``connectivity`` (:class:`Connectivity`), ``gains`` (:class:`Gains`) and
    ``time`` (:class:`Timing`); each defaults to its class's defaults.

    Examples
    --------
    >>> sp = SpikingParams(time=Timing(dt_ms=1.0))
    >>> sp.time.dt_ms, sp.connectivity.grouping_stride
    (1.0, 2)
    >>> sp.replace(gains=sp.gains.replace(clock_inh_group=0.0)).gains.clock_inh_group
    0.0
    """

    _nested: ClassVar[dict] = PARTS

    neurons: Neurons
    input: Input
    connectivity: Connectivity
    gains: Gains
    time: Timing

    def __init__(self, **parts):
        flat = {k: parts.pop(k) for k in list(parts) if k in FLAT_FIELDS}
        for k in parts:
            if k not in PARTS:
                raise TypeError(f"SpikingParams() got an unexpected keyword argument {k!r}")
        for name, kind in PARTS.items():
            part = parts.get(name)
            if part is None:
                part = kind()
            elif not isinstance(part, kind):
                check.fail("SpikingParams", name, part, f"must be a {kind.__name__}")
            object.__setattr__(self, name, part)
        if flat:
            _deprecated(f"SpikingParams({', '.join(flat)}=...)")
            for name, changes in grouped(flat).items():
                object.__setattr__(self, name, getattr(self, name).replace(**changes))

    def replace(self, **changes) -> SpikingParams:
        """These constants with whole parts (``time=Timing(...)``) changed."""
        return dataclasses.replace(self, **changes)

    def __getattr__(self, name):  # (only for a name the object does not have: the flat form's fields)
        part = FLAT_FIELDS.get(name)
        if part is None:
            raise AttributeError(f"'SpikingParams' object has no attribute {name!r}")
        _deprecated(f"SpikingParams.{name}", f"SpikingParams.{part}.{name}")
        return getattr(getattr(self, part), name)

    @classmethod
    def from_dict(cls, d: dict) -> SpikingParams:
        """The constants a mapping stores: the parts (what :meth:`to_dict`
        writes), or the flat form earlier releases wrote (every field in one
        mapping, as runs recorded it in their ``params``); a part or field
        left out takes its default."""
        if isinstance(d, dict) and any(k in FLAT_FIELDS for k in d):
            d = grouped(d)
        return super().from_dict(d)


def _deprecated(what: str, instead: str = "the parts (SpikingParams(time=Timing(dt_ms=...)))") -> None:
    warnings.warn(
        f"{what}: the flat form of SpikingParams is deprecated; use {instead}", DeprecationWarning, stacklevel=3
    )
