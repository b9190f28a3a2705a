"""The spiking figure-ground network, built stage by stage from the model's
parameters: :func:`build_network`.

Every population is named ``<role>_<level>`` and every projection
``<source>_to_<target>`` (excitatory) or ``<source>_inh_<target>``
(inhibitory): :class:`Builder` gives the names, and a stage takes the
populations it reads by role and level from what the builder made
(:meth:`Builder.named`). The stages are :mod:`.stages` and :mod:`.side_cells`.
How each stage of the model becomes populations and projections, and where
the network departs from the rate model, is written out in ``docs/model.md``.
"""

from __future__ import annotations

from .. import validate as check
from ..frames.pyramid import check_levels, level_shape
from ..params import ModelParams
from . import stages
from .gains import GainsMv
from .graph import Network
from .nodes import Population
from .projections import Conv, Resize
from .side_cells import side_cue
from .spiking_params import CELL_KINDS, SpikingParams

NOTES = (
    "Mechanism: the gain f(z) of stage 8 is realised with a gate. z = VL1 - VD2 (and VL2 - VD1) is carried by a "
    "rectified pair of feedback cells; the half for a border-ownership cell excites it (the winning side is "
    "enhanced), the half against it inhibits it (the losing side suppressed). The cell rests below its usual "
    "resting potential by more than the feedback can give, and its simple cell gives that back, so for the "
    "model's binary S the product S*f(z) holds: feedback alone cannot make a cell fire.",
    "Mechanism: the rival family inhibits grouping cells through excess cells rect(B_rival - B_partner), which "
    "are silent while a pair is still equal: grouping starts uninhibited, as the model's first iteration does "
    "(there, by a test for equal maps), and is inhibited as in the model once feedback has chosen.",
    "Deviation: coarse-level simple, untuned and border-ownership cells exist only where the resized edge map "
    ">= support_min, and their activity does not scale with the edge value.",
    "Deviation: grouping and feedback cells sit on a stride-grouping_stride lattice; pooling across scales is "
    "top-down (z_l = G_l (*) m - G_l (*) m' + decay * resize(z_{l+1})) with pool_interpolation.",
    "Deviation: the network runs in continuous time until its counting window ends; the rate model stops after "
    "a fixed number of synchronous iterations, a point it has not converged at (see "
    "experiments/results/rate_iterations.md).",
)


class Builder:
    """Collects populations and projections level by level, and knows each
    population it made by role and level (:meth:`named`)."""

    def __init__(self, params: ModelParams, frame_shape, sp: SpikingParams):
        self.params, self.frame_shape, self.sp = params, frame_shape, sp
        self.gains_mv = GainsMv.of(params, sp)
        self.pops: list[Population] = []
        self.prjs: list = []
        self.neurons = {kind: getattr(sp.neurons, kind) for kind in CELL_KINDS}
        self._made: dict[tuple[str, int], str] = {}

    def pop(self, role, level, *, shape=None, site_sources=(), **fields) -> str:
        """Add population ``<role>_<level>`` (``fields``: those of :class:`Population`); returns its name."""
        name = f"{role}_{level}"
        shape = shape or level_shape(self.frame_shape, level, self.params.levels_per_octave)
        self.pops.append(
            Population(name=name, role=role, level=level, level_shape=shape, site_sources=tuple(site_sources), **fields)
        )
        self._made[role, level] = name
        return name

    def named(self, role: str, level: int) -> str:
        """The name of the population of ``role`` at ``level`` that this builder made."""
        try:
            return self._made[role, level]
        except KeyError:
            raise KeyError(f"the builder has made no {role!r} population at level {level} (yet)") from None

    def _projection(self, kind, src, dst, *, gain, delay=None, verb=None, **fields):
        """Add projection ``<src>_<verb>_<dst>`` (``to`` or ``inh`` by its sign) at the network's delay
        unless ``delay`` is given; ``fields``: those of ``kind``."""
        verb = verb or ("to" if fields.get("sign", 1) > 0 else "inh")
        self.prjs.append(
            kind(
                name=f"{src}_{verb}_{dst}",
                source=src,
                target=dst,
                gain_mv=gain,
                delay_ms=self.sp.time.delay_ms if delay is None else delay,
                **fields,
            )
        )

    def conv(self, src, dst, kernel, **fields):
        """Add a :class:`Conv` of ``kernel`` (``fields``: see :meth:`_projection`)."""
        self._projection(Conv, src, dst, kernel=kernel, **fields)

    def resize(self, src, dst, **fields):
        """Add a :class:`Resize` (``fields``: see :meth:`_projection`)."""
        self._projection(Resize, src, dst, **fields)


def build_network(
    params: ModelParams = ModelParams(), frame_shape=(321, 481), spiking: SpikingParams = SpikingParams()
) -> Network:
    """The spiking figure-ground network for frames of ``frame_shape``.

    Parameters
    ----------
    params : ModelParams
        The model's parameters (levels, orientations, R0, kernels...): the
        same object the rate model takes.
    frame_shape : (int, int)
        Rows and columns of the event frames the network will see.
    spiking : SpikingParams
        The spiking constants (neurons, gains, delays, lattices).

    Returns
    -------
    Network
        The validated description: per level, input sources or relays,
        simple, untuned, border-ownership (four families), grouping (light,
        dark) and feedback cells, and the projections between them.

    Examples
    --------
    >>> from snn_fg.network import build_network
    >>> from snn_fg.params import ModelParams
    >>> net = build_network(ModelParams(levels=2), (40, 52))
    >>> net.one("simple", 1).shape
    (16, 40, 52)
    >>> [p.name for p in net.incoming("group_L_1")][:2]
    ['bo_L1_1_to_group_L_1', 'bo_L2_1_to_group_L_1']
    """
    if not isinstance(params, ModelParams):
        check.fail("build_network", "params", type(params).__name__, "must be a ModelParams")
    if not isinstance(spiking, SpikingParams):
        check.fail("build_network", "spiking", type(spiking).__name__, "must be a SpikingParams")
    frame_shape = check.shape2("build_network", "frame_shape", frame_shape)
    check_levels(frame_shape, params.levels, "build_network", params.levels_per_octave)
    if params.n_ori % 2:
        check.fail(
            "build_network",
            "params.n_ori",
            params.n_ori,
            "must be even (index n_ori/2 is the untuned cells' orientation)",
        )
    bld = Builder(params, frame_shape, spiking)
    for level in range(1, params.levels + 1):
        on, off = stages.inputs(bld, level)
        s = stages.simple_cells(bld, level, on, off)
        u = stages.untuned_cells(bld, level, on, off, s)
        b = stages.border_ownership(bld, level, s, u)
        g = stages.grouping_cells(bld, level, b)
        z = stages.feedback_cells(bld, level, b, g)
        if params.grouping_polarity == "pool":
            stages.pooled_feedback(bld, level, g, z)
    stages.pooling(bld)
    side_cue(bld)
    if spiking.gains.clock_inh_group > 0:
        stages.window_clock(bld)
    return Network(
        params=params,
        frame_shape=frame_shape,
        populations=tuple(bld.pops),
        projections=tuple(bld.prjs),
        input_rate_hz=spiking.input.input_rate_hz,
        support_min=spiking.input.support_min,
        drive_min=spiking.input.drive_min,
        input_refractory_ms=spiking.input.input_refractory_ms,
        dt_ms=spiking.time.dt_ms,
        notes=NOTES,
    )
