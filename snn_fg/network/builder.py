"""The spiking figure-ground network, built stage by stage from the model's
parameters: :func:`build_network`.

Every population is named ``<role>_<level>`` and every projection
``<source>_to_<target>`` (excitatory) or ``<source>_inh_<target>``
(inhibitory). How each stage of the model becomes populations and
projections, and where the network departs from the rate model, is written
out in ``docs/model.md``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .. import validate as check
from ..frames.pyramid import check_levels, level_shape
from ..params import ModelParams
from .gains import Gains
from .graph import Network
from .nodes import Kernel, Population
from .projections import Conv, Resize
from .side_cells import side_cue
from .spiking_params import CELL_KINDS, SIMPLE_RATE_HZ, UNTUNED_RATE_HZ, SpikingParams

FAMILIES = ("L1", "L2", "D1", "D2")
#: Stage 5: the half of the simple cells each family reads (0: directions
#: ``o``, 1: directions ``o + n_ori``): BL1[o] = S[o], BL2[o] = S[o+n],
#: BD1[o] = S[o+n], BD2[o] = S[o].
FAMILY_HALF = {"L1": 0, "L2": 1, "D1": 1, "D2": 0}
#: The family sharing a simple cell with each family (the two compete).
PARTNER = {"L1": "D2", "D2": "L1", "L2": "D1", "D1": "L2"}
#: The feedback signals z1 = VL1 - VD2 and z2 = VL2 - VD1, each carried by a
#: rectified pair of feedback cells (``p``: positive part, ``n``: negative).
FEEDBACK_HALVES = ("1p", "1n", "2p", "2n")
OPPOSITE_HALF = {"1p": "1n", "1n": "1p", "2p": "2n", "2n": "2p"}
#: Stage 7: (border-ownership family, grouping polarity, von Mises half,
#: sign): gL1 = (BL1 - w BD2) (*) m2, gL2 = (BL2 - w BD1) (*) m1,
#: gD1 = (BD1 - w BL2) (*) m2, gD2 = (BD2 - w BL1) (*) m1.
GROUPING_INPUTS = (
    ("L1", "L", 2, 1),
    ("L2", "L", 1, 1),
    ("D2", "L", 2, -1),
    ("D1", "L", 1, -1),
    ("D1", "D", 2, 1),
    ("D2", "D", 1, 1),
    ("L2", "D", 2, -1),
    ("L1", "D", 1, -1),
)
#: Stage 8: each feedback half as (grouping polarity, half) excitatory minus
#: (grouping polarity, half) inhibitory: z1 = GL (*) m1 - GD (*) m2,
#: z2 = GL (*) m2 - GD (*) m1, and their negatives.
FEEDBACK_INPUTS = {
    "1p": (("L", 1), ("D", 2)),
    "1n": (("D", 2), ("L", 1)),
    "2p": (("L", 2), ("D", 1)),
    "2n": (("D", 1), ("L", 2)),
}
#: Stage 8: the feedback half (for, against) each border-ownership family:
#: z1 favours BL1 and opposes BD2, z2 favours BL2 and opposes BD1.
FEEDBACK_TO_FAMILY = {"L1": ("1p", "1n"), "D2": ("1n", "1p"), "L2": ("2p", "2n"), "D1": ("2n", "2p")}

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


def _channel_map(n_out: int, n_in: int, pairs, weight: float = 1.0) -> Kernel:
    return Kernel(ref="channel_map", args={"n_out": n_out, "n_in": n_in, "entries": [[o, i, weight] for o, i in pairs]})


def _dog_half(polarity: int, n: int) -> Kernel:
    """DoG kernels from one input polarity to all ``2n`` directions; only the
    polarity's own half (ON: ``0..n-1``, OFF: ``n..2n-1``) is non-zero."""
    return Kernel(
        ref="dog", args={"directions": [k if polarity * n <= k < (polarity + 1) * n else None for k in range(2 * n)]}
    )


def _von_mises(half: int, layout: str) -> Kernel:
    return Kernel(ref="von_mises", args={"half": half, "layout": layout})


class _Builder:
    """Collects populations and projections level by level."""

    def __init__(self, params: ModelParams, frame_shape, sp: SpikingParams):
        self.params, self.frame_shape, self.sp = params, frame_shape, sp
        self.gains = Gains.of(params, sp)
        self.pops: list[Population] = []
        self.prjs: list = []
        self.neurons = {kind: getattr(sp, kind) for kind in CELL_KINDS}

    def pop(self, role, level, *, shape=None, site_sources=(), **fields) -> str:
        """Add population ``<role>_<level>`` (``fields``: those of :class:`Population`)."""
        name = f"{role}_{level}"
        shape = shape or level_shape(self.frame_shape, level, self.params.levels_per_octave)
        self.pops.append(
            Population(name=name, role=role, level=level, level_shape=shape, site_sources=tuple(site_sources), **fields)
        )
        return name

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
                delay_ms=self.sp.delay_ms if delay is None else delay,
                **fields,
            )
        )

    def conv(self, src, dst, kernel, **fields):
        """Add a :class:`Conv` of ``kernel`` (``fields``: see :meth:`_projection`)."""
        self._projection(Conv, src, dst, kernel=kernel, **fields)

    def resize(self, src, dst, **fields):
        """Add a :class:`Resize` (``fields``: see :meth:`_projection`)."""
        self._projection(Resize, src, dst, **fields)

    def gate_mv(self, kernels) -> float:
        """Depth (mV) of a simple cell's gate: the largest mean current its
        kept DoG taps can deliver with every source at the input rate, plus
        ``gate_margin`` thresholds."""
        worst = 0.0
        for kernel in kernels:
            k = kernel.array(self.params)
            kept = np.where(np.abs(k) >= self.sp.prune_dog * np.abs(k).max(), k, 0.0)
            worst = max(worst, float(np.clip(kept, 0, None).sum(axis=(1, 2, 3)).max()))
        simple = self.sp.simple
        drive = worst * self.gains.dog * self.sp.input_rate_hz * simple.tau_exc_ms / 1000.0
        return drive + self.sp.gate_margin * simple.v_th_mv

    # -- stages ------------------------------------------------------------
    def inputs(self, level):
        """Level 1: spike sources; coarser levels: relays following the bicubic-resized frame (stage 2)."""
        if level == 1:
            return self.pop("input_on", 1), self.pop("input_off", 1)
        relays = []
        for polarity in ("on", "off"):
            name = self.pop(f"relay_{polarity}", level, neuron=self.neurons["relay"], sites="reachable")
            self.resize(
                f"input_{polarity}_1", name, gain=self.gains.relay, interpolation="cubic", prune=self.sp.prune_resize
            )
            relays.append(name)
        return tuple(relays)

    def simple_cells(self, level, on, off):
        """Stages 3-4: DoG convolution (wrap-around) from ON for directions
        ``0..n-1`` and OFF for the rest; lateral inhibition between the
        directions at a pixel stands for the arg-max.

        At level 1 a simple cell exists only where its pixel had an event
        (``S = edges * ...``): it rests ``gate`` below its usual resting
        potential, more than any DoG drive can make up, and its own pixel's
        input (either polarity) gives that back."""
        n, n_dir = self.params.n_ori, self.params.n_dir
        kernels = [_dog_half(polarity, n) for polarity in (0, 1)]
        neuron = self.neurons["simple"]
        gate = self.gate_mv(kernels) if level == 1 else 0.0
        if gate:
            neuron = dataclasses.replace(neuron, v_rest_mv=neuron.v_rest_mv - gate)
        s = self.pop("simple", level, channels=n_dir, neuron=neuron, sites="edges&drive", edge_mask=True)
        for kernel, src in zip(kernels, (on, off)):
            self.conv(
                src,
                s,
                kernel,
                gain=self.gains.dog,
                mode="conv",
                padding="wrap",
                prune=self.sp.prune_dog,
                calibrated=True,
            )
        if gate:
            copies = self.sp.gate_copies
            for src in (on, off):
                for i in range(copies):
                    self.conv(
                        src,
                        s,
                        _channel_map(n_dir, 1, [(k, 0) for k in range(n_dir)]),
                        verb="gates" if i == 0 else f"gates{i}",
                        gain=gate / copies / (self.sp.input_rate_hz * neuron.tau_exc_ms / 1000.0),
                        delay=self.sp.delay_ms + i * self.sp.gate_spread_ms,
                        calibrated=True,
                    )
        others = [(a, b) for a in range(n_dir) for b in range(n_dir) if a != b]
        self.conv(s, s, _channel_map(n_dir, n_dir, others), sign=-1, gain=self.gains.simple_inh_simple)
        return s

    def untuned_cells(self, level, on, off, s):
        """Stage 4's rule for event pixels without an oriented response: an
        untuned cell is excited by its pixel's input after ``delay_untuned_ms``
        and silenced by any simple cell there."""
        u = self.pop("untuned", level, neuron=self.neurons["untuned"], sites="edges", edge_mask=True)
        g_u = self.gains.input_to_untuned(self.sp, level)
        for src in (on, off):
            self.conv(src, u, _channel_map(1, 1, [(0, 0)]), gain=g_u, delay=self.sp.delay_untuned_ms, calibrated=True)
        n_dir = self.params.n_dir
        self.conv(
            s, u, _channel_map(1, n_dir, [(0, k) for k in range(n_dir)]), sign=-1, gain=self.gains.simple_inh_untuned
        )
        return u

    def bo_gate_mv(self) -> float:
        """Depth (mV) of a border-ownership cell's gate: the largest mean
        current the feedback half for it can deliver (every feedback cell at
        its refractory ceiling, interpolation weights summing to at most 1)
        plus ``bo_gate_margin`` thresholds. The cell rests that far below its
        usual resting potential and its simple-cell input gives it back, so
        feedback modulates a border-ownership cell only where its simple cell
        is active: ``B = S * f(z)`` with ``S`` binary (stage 8)."""
        if self.gains.feedback_to_bo <= 0:
            return 0.0
        bo, fb = self.sp.bo, self.sp.feedback
        strongest = self.gains.feedback_to_bo * fb.max_rate_hz * bo.tau_exc_ms / 1000.0
        return strongest + self.sp.bo_gate_margin * bo.v_th_mv

    def border_ownership(self, level, s, u):
        """Stage 5: family ``f`` reads simple-cell index ``o`` (L1, D2) or
        ``o + n`` (L2, D1), the index being the direction turned a quarter
        (``k -> (k + n/2) mod 2n``); untuned pixels take index ``n/2``. The
        feedforward weights carry the gate (:meth:`bo_gate_mv`) back at the
        simple and untuned cells' reference rates."""
        n, n_dir = self.params.n_ori, self.params.n_dir
        gate = self.bo_gate_mv()
        neuron = self.neurons["bo"]
        if gate:
            neuron = dataclasses.replace(neuron, v_rest_mv=neuron.v_rest_mv - gate)
        tau_s = neuron.tau_exc_ms / 1000.0
        b = {
            f: self.pop(
                f"bo_{f}", level, channels=n, neuron=neuron, sites="reachable", site_sources=(s, u), edge_mask=True
            )
            for f in FAMILIES
        }
        same = [(o, o) for o in range(n)]
        for f in FAMILIES:
            half = FAMILY_HALF[f] * n
            self.conv(
                s,
                b[f],
                _channel_map(n, n_dir, [(o, (o + half - n // 2) % n_dir) for o in range(n)]),
                gain=self.gains.simple_to_bo + gate / (SIMPLE_RATE_HZ * tau_s),
            )
            if half == 0:
                self.conv(
                    u,
                    b[f],
                    _channel_map(n, 1, [(n // 2, 0)]),
                    gain=self.gains.untuned_to_bo + gate / (UNTUNED_RATE_HZ * tau_s),
                )
            if self.gains.bo_inh_bo > 0:
                self.conv(b[PARTNER[f]], b[f], _channel_map(n, n, same), sign=-1, gain=self.gains.bo_inh_bo)
        return b

    def excess_cells(self, level, b):
        """The excess of each border-ownership family over its partner at the
        same simple cell, ``rect(B_f - B_partner)``: zero while the pair is
        still symmetric, the winner's activity once feedback has chosen.

        With ``excess_stride`` s > 1 an excess cell sits on every s-th pixel
        and takes the excess of the block around it, ``rect(mean B_f - mean
        B_partner)`` (a ``block_mean`` kernel): s**2 times fewer cells, read
        by the grouping cells through every s-th tap of their kernel."""
        n, st = self.params.n_ori, self.sp.excess_stride
        same = (
            _channel_map(n, n, [(o, o) for o in range(n)])
            if st == 1
            else Kernel(ref="block_mean", args={"channels": n, "stride": st})
        )
        x = {
            f: self.pop(
                f"excess_{f}",
                level,
                channels=n,
                stride=st,
                neuron=self.neurons["excess"],
                sites="reachable",
                site_sources=(b[f],),
                edge_mask=st == 1,
            )
            for f in FAMILIES
        }
        gain = self.gains.bo_to_excess * st
        for f in FAMILIES:
            self.conv(b[f], x[f], same, gain=gain)
            self.conv(b[PARTNER[f]], x[f], same, sign=-1, gain=gain * Gains.balance(self.neurons["excess"]))
        return x

    def grouping_cells(self, level, b):
        """Stage 7: von Mises correlation of the border-ownership cells; light
        and dark compete.

        ``(B_own - w B_rival) (*) m`` of the model, with the rival family
        counted through its excess cells (``rival_inhibition="excess"``, the
        default): a rival inhibits only where it beats its own partner, so
        grouping runs uninhibited while every pair is still symmetric, as the
        model's first iteration does, and with the model's inhibition once
        feedback has chosen. ``"direct"``: the rival cells inhibit as they are."""
        st = self.sp.grouping_stride
        g = {
            pol: self.pop(
                f"group_{pol}",
                level,
                stride=st,
                neuron=self.neurons["group"],
                sites="reachable",
                site_sources=tuple(b.values()),
            )
            for pol in ("L", "D")
        }
        w = self.params.w_inh
        by_excess = w > 0 and self.sp.rival_inhibition == "excess"
        rivals = self.excess_cells(level, b) if by_excess else b
        # a strided excess lattice is read through every s-th tap: s**2 makes up the rest, s of it in
        # the excess cells' own gain (a block crossed by an edge holds about s of its s**2 pixels)
        sparse = self.sp.excess_stride if by_excess else 1
        for fam, pol, half, sign in GROUPING_INPUTS:
            if sign < 0 and w == 0:
                continue
            gain = self.gains.bo_to_group * (1.0 if sign > 0 else w * sparse * Gains.balance(self.neurons["group"]))
            self.conv(
                (b if sign > 0 else rivals)[fam],
                g[pol],
                _von_mises(half, "gather"),
                sign=sign,
                gain=gain,
                prune=self.sp.prune_vm,
            )
        if self.params.grouping_polarity == "compete":
            for a, c in (("L", "D"), ("D", "L")):
                self.conv(g[a], g[c], _channel_map(1, 1, [(0, 0)]), sign=-1, gain=self.gains.group_inh_group)
        return g

    def feedback_cells(self, level, b, g):
        """Stage 8 at one level: feedback cells carry z1 = VL1 - VD2 and
        z2 = VL2 - VD1 as rectified pairs on the grouping lattice (every
        stride-th tap is used, hence the stride**2); the half against a
        border-ownership cell inhibits it, the half for it excites it."""
        st = self.sp.grouping_stride
        gain = self.gains.group_to_feedback * st * st
        z = {
            k: self.pop(
                f"feedback_{k}",
                level,
                channels=self.params.n_ori,
                stride=st,
                neuron=self.neurons["feedback"],
                sites="needed",
            )
            for k in FEEDBACK_HALVES
        }
        for k in FEEDBACK_HALVES:
            (pol_for, half_for), (pol_against, half_against) = FEEDBACK_INPUTS[k]
            self.conv(g[pol_for], z[k], _von_mises(half_for, "scatter"), gain=gain, prune=self.sp.prune_vm)
            self.conv(
                g[pol_against],
                z[k],
                _von_mises(half_against, "scatter"),
                sign=-1,
                gain=gain * Gains.balance(self.neurons["feedback"]),
                prune=self.sp.prune_vm,
            )
        for fam, (k_for, k_against) in FEEDBACK_TO_FAMILY.items():
            for k, sign, gain in ((k_for, 1, self.gains.feedback_to_bo), (k_against, -1, self.gains.feedback_inh_bo)):
                if gain > 0:
                    self.resize(
                        z[k],
                        b[fam],
                        sign=sign,
                        gain=gain,
                        interpolation=self.sp.feedback_interpolation,
                        delay=self.sp.delay_feedback_ms,
                    )

    def pooled_feedback(self, level, g):
        """Stage 8 with pooled grouping polarities (``grouping_polarity="pool"``):
        besides the wiring of :meth:`feedback_cells` (z1 = GL (*) m1 - GD (*) m2),
        each feedback cell reads the other polarity through the same halves
        (+ GD (*) m1 - GL (*) m2), so that it carries z1 = G (*) m1 - G (*) m2
        with G = GL + GD (likewise z2 and the negative halves)."""
        st = self.sp.grouping_stride
        gain = self.gains.group_to_feedback * st * st
        other = {"L": "D", "D": "L"}
        for k in FEEDBACK_HALVES:
            (pol_for, half_for), (pol_against, half_against) = FEEDBACK_INPUTS[k]
            z = f"feedback_{k}_{level}"
            self.conv(g[other[pol_for]], z, _von_mises(half_for, "scatter"), gain=gain, prune=self.sp.prune_vm)
            self.conv(
                g[other[pol_against]],
                z,
                _von_mises(half_against, "scatter"),
                sign=-1,
                gain=gain * Gains.balance(self.neurons["feedback"]),
                prune=self.sp.prune_vm,
            )

    def window_clock(self):
        """The window clock: one spike source that fires as each window of a
        recording starts and inhibits every grouping cell, so that the light
        and dark grouping cells compete afresh in every window (without it the
        family that won one window keeps winning the next: the winner-take-all
        has hysteresis). Its weight is ``clock_inh_group`` thresholds of
        inhibitory current, spread evenly over the cells by a 1 x 1 Resize."""
        clock = self.pop("clock", 1, shape=(1, 1))
        for level in range(1, self.params.levels + 1):
            for pol in ("L", "D"):
                self.resize(
                    clock,
                    f"group_{pol}_{level}",
                    sign=-1,
                    interpolation="linear",
                    gain=self.sp.clock_inh_group * self.sp.group.v_th_mv,
                )

    def pooling(self):
        """Stage 8 across levels, top-down: z_l += decay * resize(z_{l+1}), for
        both halves of each pair (the opposite half subtracts)."""
        for level in range(1, self.params.levels):
            for k in FEEDBACK_HALVES:
                dst = f"feedback_{k}_{level}"
                self.resize(
                    f"feedback_{k}_{level + 1}",
                    dst,
                    gain=self.gains.pool,
                    interpolation=self.sp.pool_interpolation,
                    prune=self.sp.prune_resize,
                )
                self.resize(
                    f"feedback_{OPPOSITE_HALF[k]}_{level + 1}",
                    dst,
                    sign=-1,
                    gain=self.gains.pool * Gains.balance(self.neurons["feedback"]),
                    interpolation=self.sp.pool_interpolation,
                    prune=self.sp.prune_resize,
                )


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
    bld = _Builder(params, frame_shape, spiking)
    for level in range(1, params.levels + 1):
        on, off = bld.inputs(level)
        s = bld.simple_cells(level, on, off)
        u = bld.untuned_cells(level, on, off, s)
        b = bld.border_ownership(level, s, u)
        g = bld.grouping_cells(level, b)
        bld.feedback_cells(level, b, g)
        if params.grouping_polarity == "pool":
            bld.pooled_feedback(level, g)
    bld.pooling()
    side_cue(bld)
    if spiking.clock_inh_group > 0:
        bld.window_clock()
    return Network(
        params=params,
        frame_shape=frame_shape,
        populations=tuple(bld.pops),
        projections=tuple(bld.prjs),
        input_rate_hz=spiking.input_rate_hz,
        support_min=spiking.support_min,
        drive_min=spiking.drive_min,
        input_refractory_ms=spiking.input_refractory_ms,
        dt_ms=spiking.dt_ms,
        notes=NOTES,
    )
