"""Declarative description of the spiking figure-ground network.

This module is the single source of truth for the spiking form of the model:
the Brian2 builder (:mod:`snn_fg.spiking`) consumes it, and an exporter
(NIR, PyNN) can consume it too. It is modelled on NIR: a graph of frozen
dataclass nodes, each validated in ``__post_init__`` with errors that name the
node at fault, and a JSON-friendly ``to_dict`` / ``from_dict`` round trip.

Nodes
-----
* :class:`Neuron` - a current-based leaky integrate-and-fire (CUBA LIF)
  neuron: ``tau_m dv/dt = v_rest - v + I_exc - I_inh``, each synaptic current
  decays exponentially (``tau_exc``, ``tau_inh``) and jumps by the synaptic
  weight (mV) at each presynaptic spike; spike at ``v > v_th``, reset to
  ``v_reset``, refractory ``t_ref``.
* :class:`Population` - cells on the grid of one pyramid level, with
  ``channels`` cells per grid point (directions, orientations), a ``stride``
  (the grid point ``(i, j)`` sits at level pixel ``(stride*i, stride*j)``) and
  a ``sites`` rule saying which cells a simulator must instantiate for a given
  input (see :data:`SITE_RULES`).
* :class:`Kernel` - a weight-shared kernel ``(C_out, C_in, kh, kw)``, stored as
  a named reference to a function of :mod:`snn_fg.network.kernels` with its
  arguments (or as an explicit array); it is materialised with
  :meth:`Kernel.array` and unrolled only inside a simulator.
* :class:`Conv` - a weight-shared projection between two populations of the
  same level: convolution or correlation, zero or wrap-around padding, offsets
  measured in level pixels (so strided grids are handled exactly).
* :class:`Resize` - a projection between pyramid levels that applies the
  pyramid's own interpolation (OpenCV bicubic/bilinear) channel by channel.
* :class:`Network` - the graph, with the :class:`~snn_fg.params.ModelParams`
  it was built from and the frame shape.

:func:`build_network` builds the default network (every stage of
``docs/model.md``) from a :class:`ModelParams`, a frame shape and the spiking
constants in :class:`NetworkParams`.

Sign convention: the synaptic weight of a connection is
``sign * gain_mv * K`` where ``K`` is the kernel value; positive weights go to
``I_exc``, negative ones to ``I_inh`` (so a kernel with negative lobes, like
the DoG or bicubic interpolation, is split between the two currents).
"""
from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import SnnFgError
from ..frames.pyramid import level_shape
from ..params import ModelParams
from .kernels import dog_kernels, von_mises_masks

SCHEMA = "snn-fg.network/1"

#: Which cells of a population a simulator instantiates for a given input:
#:
#: ``all``          every cell of the grid (spike sources);
#: ``edges``        every channel at grid points where the level's edge map
#:                  (``resize(pos | neg)``, stage 2) is at least
#:                  ``Network.support_min`` (level 1: every event pixel). This
#:                  is the model's own mask ``S = edges * ...`` (stage 4);
#: ``edges&drive``  the ``edges`` cells whose excitatory input alone can reach
#:                  threshold: the mean current that the positive weights
#:                  from ``site_sources`` would give if their sources fired at
#:                  their nominal rate (input pixels with events:
#:                  ``input_rate_hz``; relays: ``input_rate_hz`` times the
#:                  resized event frame) reaches ``drive_min`` times the
#:                  threshold. Inhibition only lowers the mean current, so a
#:                  cell left out could not fire on average;
#: ``reachable``    cells that receive at least one excitatory connection from
#:                  an instantiated cell of ``site_sources`` (or of any source
#:                  when ``site_sources`` is empty) that can fire;
#: ``needed``       cells with at least one connection onto an instantiated
#:                  target.
SITE_RULES = ("all", "edges", "edges&drive", "reachable", "needed")

#: Roles name what a population computes; the decoder uses them to find the
#: border-ownership and grouping populations of each level.
ROLES = (
    "input_on", "input_off",            # spike sources (event camera), level 1
    "relay_on", "relay_off",            # resized event frames (stage 2), levels >= 2
    "simple",                           # S cells, 2*n_ori directions (stages 3-4)
    "untuned",                          # event pixels without any oriented response (stage 4)
    "bo_L1", "bo_L2", "bo_D1", "bo_D2",  # border ownership, n_ori orientations (stage 5)
    "group_L", "group_D",               # grouping cells (stage 7)
    "fb_z1p", "fb_z1n", "fb_z2p", "fb_z2n",  # feedback z = VL1-VD2, VL2-VD1 as rectified pairs (stage 8)
)

KERNEL_REFS = ("dog", "von_mises", "channel_map", "array")


class DescriptionError(SnnFgError, ValueError):
    """A network description is inconsistent; the message names the node."""


def _bad(obj: str, why: str):
    raise DescriptionError(f"{obj}: {why}")


def _finite(obj, name, v, lo=None, lo_open=False):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        _bad(obj, f"{name}={v!r} must be a finite number")
    if lo is not None and (v < lo or (lo_open and v == lo)):
        _bad(obj, f"{name}={v!r} must be {'>' if lo_open else '>='} {lo}")
    return float(v)


def _posint(obj, name, v, lo=1):
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
        _bad(obj, f"{name}={v!r} must be an integer >= {lo}")
    return int(v)


def _shape2(obj, name, v):
    try:
        t = tuple(int(x) for x in v)
    except (TypeError, ValueError):
        _bad(obj, f"{name}={v!r} must be two positive integers (rows, cols)")
    if len(t) != 2 or min(t) < 1 or any(float(a) != b for a, b in zip(v, t)):
        _bad(obj, f"{name}={v!r} must be two positive integers (rows, cols)")
    return t


# --------------------------------------------------------------------------
# Nodes
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class Neuron:
    """CUBA LIF neuron parameters (milliseconds and millivolts)."""

    tau_m_ms: float = 10.0
    tau_exc_ms: float = 5.0
    tau_inh_ms: float = 10.0
    v_rest_mv: float = 0.0
    v_reset_mv: float = 0.0
    v_th_mv: float = 10.0
    t_ref_ms: float = 2.0
    model: str = "cuba_lif"

    def __post_init__(self):
        obj = f"Neuron(model={self.model!r})"
        if self.model != "cuba_lif":
            _bad(obj, "model must be 'cuba_lif'")
        for name in ("tau_m_ms", "tau_exc_ms", "tau_inh_ms"):
            object.__setattr__(self, name, _finite(obj, name, getattr(self, name), 0, lo_open=True))
        object.__setattr__(self, "t_ref_ms", _finite(obj, "t_ref_ms", self.t_ref_ms, 0))
        for name in ("v_rest_mv", "v_reset_mv", "v_th_mv"):
            object.__setattr__(self, name, _finite(obj, name, getattr(self, name)))
        if self.v_th_mv <= self.v_rest_mv or self.v_th_mv <= self.v_reset_mv:
            _bad(obj, f"v_th_mv={self.v_th_mv} must lie above v_rest_mv and v_reset_mv")

    @property
    def max_rate_hz(self) -> float:
        """Refractory ceiling of the firing rate (inf without refractoriness)."""
        return math.inf if self.t_ref_ms == 0 else 1000.0 / self.t_ref_ms

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "Neuron":
        return cls(**_known(cls, d, "Neuron"))


@dataclass(frozen=True)
class Population:
    """Cells of one pyramid level, ``channels`` per grid point.

    ``level_shape`` is the (rows, cols) of the pyramid level; the population's
    grid is that level subsampled by ``stride`` (grid point ``(i, j)`` at
    level pixel ``(stride*i, stride*j)``). ``neuron`` is ``None`` for spike
    sources (role ``input_on``/``input_off``).
    """

    name: str
    role: str
    level: int
    level_shape: tuple[int, int]
    channels: int = 1
    stride: int = 1
    neuron: Neuron | None = None
    sites: str = "all"
    site_sources: tuple = ()

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier():
            _bad(f"Population({self.name!r})", "name must be a Python identifier")
        obj = f"Population '{self.name}'"
        if self.role not in ROLES:
            _bad(obj, f"role={self.role!r} is not one of {ROLES}")
        _posint(obj, "level", self.level)
        object.__setattr__(self, "level_shape", _shape2(obj, "level_shape", self.level_shape))
        _posint(obj, "channels", self.channels)
        _posint(obj, "stride", self.stride)
        if self.sites not in SITE_RULES:
            _bad(obj, f"sites={self.sites!r} is not one of {SITE_RULES}")
        if isinstance(self.site_sources, str) or not all(isinstance(x, str) for x in self.site_sources):
            _bad(obj, f"site_sources={self.site_sources!r} must be a sequence of population names")
        object.__setattr__(self, "site_sources", tuple(self.site_sources))
        source = self.role.startswith("input")
        if source and self.neuron is not None:
            _bad(obj, "a spike source (role input_*) has no neuron model")
        if not source and not isinstance(self.neuron, Neuron):
            _bad(obj, f"role {self.role!r} needs a Neuron, got {self.neuron!r}")
        if source and (self.level != 1 or self.stride != 1 or self.channels != 1):
            _bad(obj, "spike sources live on level 1 with stride 1 and one channel")

    @property
    def grid(self) -> tuple[int, int]:
        """(rows, cols) of the population's own grid."""
        s = self.stride
        return (-(-self.level_shape[0] // s), -(-self.level_shape[1] // s))

    @property
    def shape(self) -> tuple[int, int, int]:
        """(channels, rows, cols) of the full (un-pruned) population."""
        return (self.channels,) + self.grid

    @property
    def size(self) -> int:
        return int(np.prod(self.shape))

    def to_dict(self) -> dict:
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d["level_shape"] = list(self.level_shape)
        d["site_sources"] = list(self.site_sources)
        d["neuron"] = None if self.neuron is None else self.neuron.to_dict()
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "Population":
        d = _known(cls, d, f"Population {d.get('name')!r}")
        if d.get("neuron") is not None:
            d["neuron"] = Neuron.from_dict(d["neuron"])
        return cls(**d)


def _canonical_json(v, obj) -> str:
    """JSON text of ``v`` with sorted keys: frozen, hashable and comparable."""
    def default(x):
        if isinstance(x, np.ndarray):
            return x.tolist()
        if isinstance(x, np.generic):
            return x.item()
        raise TypeError(type(x).__name__)
    try:
        return json.dumps(v, sort_keys=True, default=default, allow_nan=False)
    except (TypeError, ValueError) as exc:
        _bad(obj, f"args are not JSON-serialisable ({exc})")


@dataclass(frozen=True)
class Kernel:
    """A weight-shared kernel of shape ``(C_out, C_in, kh, kw)``.

    ``ref`` names how to make it:

    * ``dog``: ``args = {"directions": [k or None, ...]}`` - the oriented DoG
      kernels :func:`~snn_fg.network.kernels.dog_kernels` of those directions,
      one output channel each (``None``: an all-zero channel), one input channel;
    * ``von_mises``: ``args = {"half": 1 | 2, "layout": "gather" | "scatter"}``
      - the half rings ``m1``/``m2`` of
      :func:`~snn_fg.network.kernels.von_mises_masks`; ``gather`` sums the
      ``n_ori`` input channels into one output (B -> G), ``scatter`` sends one
      input to ``n_ori`` outputs (G -> feedback);
    * ``channel_map``: ``args = {"n_out", "n_in", "entries": [[o, i, w], ...]}``
      - a 1 x 1 kernel connecting channel ``i`` to channel ``o`` with weight ``w``;
    * ``array``: ``args = {"data": nested list (C_out, C_in, kh, kw)}``.

    Arguments are stored as canonical JSON text (frozen, comparable);
    :meth:`array` needs the
    :class:`ModelParams` the network was built from.
    """

    ref: str
    args: Any = "{}"

    def __post_init__(self):
        obj = f"Kernel(ref={self.ref!r})"
        if self.ref not in KERNEL_REFS:
            _bad(obj, f"ref must be one of {KERNEL_REFS}")
        args = self.args
        if isinstance(args, str):
            try:
                args = json.loads(args)
            except ValueError:
                _bad(obj, f"args text is not JSON: {self.args[:60]!r}")
        else:
            args = json.loads(_canonical_json(args, obj))
        if not isinstance(args, dict):
            _bad(obj, f"args must be a mapping, got {self.args!r}")
        need = {"dog": {"directions"}, "von_mises": {"half", "layout"},
                "channel_map": {"n_out", "n_in", "entries"}, "array": {"data"}}[self.ref]
        if set(args) != need:
            _bad(obj, f"args must have exactly the keys {sorted(need)}, got {sorted(args)}")
        if self.ref == "von_mises":
            if args["half"] not in (1, 2):
                _bad(obj, f"half={args['half']!r} must be 1 or 2")
            if args["layout"] not in ("gather", "scatter"):
                _bad(obj, f"layout={args['layout']!r} must be 'gather' or 'scatter'")
        if self.ref == "channel_map":
            n_out, n_in = args["n_out"], args["n_in"]
            _posint(obj, "n_out", n_out)
            _posint(obj, "n_in", n_in)
            for e in args["entries"]:
                if len(e) != 3 or not (0 <= e[0] < n_out and 0 <= e[1] < n_in):
                    _bad(obj, f"entry {list(e)} must be [out < {n_out}, in < {n_in}, weight]")
                _finite(obj, "entry weight", e[2])
        if self.ref == "dog":
            dirs = list(args["directions"])
            if not any(k is not None for k in dirs):
                _bad(obj, "directions must name at least one direction (None = an all-zero channel)")
            if any(k is not None and (isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 0)
                   for k in dirs):
                _bad(obj, f"directions {dirs} must be non-negative integers or None")
        if self.ref == "array":
            a = np.asarray(args["data"], dtype=float)
            if a.ndim != 4 or not np.all(np.isfinite(a)):
                _bad(obj, f"data must be a finite 4-D array (C_out, C_in, kh, kw), got shape {a.shape}")
            if a.shape[2] % 2 == 0 or a.shape[3] % 2 == 0:
                _bad(obj, f"data must have odd spatial size, got {a.shape[2:]}")
        object.__setattr__(self, "args", _canonical_json(args, obj))

    @property
    def arguments(self) -> dict:
        return json.loads(self.args)

    def array(self, params: ModelParams) -> np.ndarray:
        """The kernel as a float64 array ``(C_out, C_in, kh, kw)``."""
        a = self.arguments
        if self.ref == "dog":
            k = dog_kernels(params)
            dirs = a["directions"]
            bad = [d for d in dirs if d is not None and not d < k.shape[0]]
            if bad:
                _bad("Kernel(ref='dog')", f"directions {bad} outside 0..{k.shape[0] - 1}")
            out = np.zeros((len(dirs), 1) + k.shape[1:])
            for c, dd in enumerate(dirs):
                if dd is not None:
                    out[c, 0] = k[dd]
            return out
        if self.ref == "von_mises":
            m = von_mises_masks(params)[a["half"] - 1]
            return (m[None] if a["layout"] == "gather" else m[:, None]).copy()
        if self.ref == "channel_map":
            out = np.zeros((a["n_out"], a["n_in"], 1, 1))
            for o, i, w in a["entries"]:
                out[o, i, 0, 0] += w
            return out
        return np.asarray(a["data"], dtype=float)

    def to_dict(self) -> dict:
        return {"ref": self.ref, "args": self.arguments}

    @classmethod
    def from_dict(cls, d: dict) -> "Kernel":
        d = _known(cls, d, "Kernel")
        return cls(d["ref"], d.get("args", {}))


def _check_projection_common(self, obj):
    if not isinstance(self.name, str) or not self.name:
        _bad(obj, "name must be a non-empty string")
    if self.sign not in (1, -1):
        _bad(obj, f"sign={self.sign!r} must be +1 or -1")
    object.__setattr__(self, "gain_mv", _finite(obj, "gain_mv", self.gain_mv, 0))
    object.__setattr__(self, "delay_ms", _finite(obj, "delay_ms", self.delay_ms, 0))
    object.__setattr__(self, "prune", _finite(obj, "prune", self.prune, 0))
    if self.prune >= 1:
        _bad(obj, f"prune={self.prune} must be < 1 (fraction of the largest |weight|)")


@dataclass(frozen=True)
class Conv:
    """Weight-shared projection between two populations of the same level.

    For a target cell at level pixel ``P_t`` and a kernel tap at offset ``d``
    (kernel index minus centre), the source cell sits at ``P_t + d`` for a
    correlation (``mode='corr'``) and at ``P_t - d`` for a convolution. With
    ``padding='wrap'`` positions are taken modulo the level shape (taps that
    fold onto the same source add up); with ``'zero'`` positions outside the
    level are dropped. Source positions off the source's stride lattice are
    dropped. Taps with ``|K| < prune * max|K|`` are left out.
    """

    name: str
    source: str
    target: str
    kernel: Kernel
    mode: str = "corr"
    padding: str = "zero"
    sign: int = 1
    gain_mv: float = 1.0
    delay_ms: float = 0.5
    prune: float = 0.0

    def __post_init__(self):
        obj = f"Conv '{self.name}'"
        _check_projection_common(self, obj)
        if self.mode not in ("conv", "corr"):
            _bad(obj, f"mode={self.mode!r} must be 'conv' or 'corr'")
        if self.padding not in ("zero", "wrap"):
            _bad(obj, f"padding={self.padding!r} must be 'zero' or 'wrap'")
        if not isinstance(self.kernel, Kernel):
            _bad(obj, f"kernel must be a Kernel, got {type(self.kernel).__name__}")

    def to_dict(self) -> dict:
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d["kernel"] = self.kernel.to_dict()
        d["type"] = "conv"
        return d


@dataclass(frozen=True)
class Resize:
    """Interpolation from one population's grid onto another's, channel by channel.

    Cell ``(c, i, j)`` of the target receives from cell ``(c, i', j')`` of the
    source with weight ``A_r[i, i'] * A_c[j, j']``. The target grid point at
    level pixel ``x = stride_t * i`` maps to the source level's coordinate
    ``(x + 0.5) * N_src / N_tgt - 0.5`` (half-pixel centres, the level sizes'
    ratio), which is interpolated on the source's lattice (``cubic``:
    Keys a = -0.75; ``linear``), indices clamped at the border. Between two
    stride-1 grids this is exactly OpenCV's resize (stage 2, stage 8); the
    matrices are then taken from OpenCV itself. Source and target may share
    a level (resampling between strides).
    """

    name: str
    source: str
    target: str
    interpolation: str = "cubic"
    sign: int = 1
    gain_mv: float = 1.0
    delay_ms: float = 0.5
    prune: float = 0.0

    def __post_init__(self):
        obj = f"Resize '{self.name}'"
        _check_projection_common(self, obj)
        if self.interpolation not in ("cubic", "linear"):
            _bad(obj, f"interpolation={self.interpolation!r} must be 'cubic' or 'linear'")

    def to_dict(self) -> dict:
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d["type"] = "resize"
        return d


def _projection_from_dict(d: dict):
    d = dict(d)
    kind = d.pop("type", None)
    if kind == "conv":
        d = _known(Conv, d, f"Conv {d.get('name')!r}")
        d["kernel"] = Kernel.from_dict(d["kernel"])
        return Conv(**d)
    if kind == "resize":
        return Resize(**_known(Resize, d, f"Resize {d.get('name')!r}"))
    _bad(f"projection {d.get('name')!r}", f"type={kind!r} must be 'conv' or 'resize'")


def _known(cls, d, obj):
    if not isinstance(d, dict):
        _bad(obj, f"expected a mapping, got {type(d).__name__}")
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = set(d) - names
    if unknown:
        _bad(obj, f"unknown field(s) {sorted(unknown)}")
    return dict(d)


# --------------------------------------------------------------------------
# The graph
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class Network:
    """A validated network graph.

    ``support_min`` is the edge-map threshold of the ``edges`` site rule;
    ``input_rate_hz`` the per-pixel input rate the gains are calibrated for;
    ``notes`` free-form documentation (deviations from the rate model...).
    """

    params: ModelParams
    frame_shape: tuple[int, int]
    populations: tuple
    projections: tuple
    support_min: float = 0.3
    input_rate_hz: float = 200.0
    drive_min: float = 1.0
    notes: tuple = ()

    def __post_init__(self):
        obj = "Network"
        object.__setattr__(self, "drive_min", _finite(obj, "drive_min", self.drive_min, 0))
        if not isinstance(self.params, ModelParams):
            _bad(obj, f"params must be a ModelParams, got {type(self.params).__name__}")
        object.__setattr__(self, "frame_shape", _shape2(obj, "frame_shape", self.frame_shape))
        object.__setattr__(self, "populations", tuple(self.populations))
        object.__setattr__(self, "projections", tuple(self.projections))
        object.__setattr__(self, "notes", tuple(self.notes))
        object.__setattr__(self, "support_min", _finite(obj, "support_min", self.support_min, 0))
        object.__setattr__(self, "input_rate_hz",
                           _finite(obj, "input_rate_hz", self.input_rate_hz, 0, lo_open=True))
        pops = {}
        for p in self.populations:
            if not isinstance(p, Population):
                _bad(obj, f"populations must be Population nodes, got {type(p).__name__}")
            if p.name in pops:
                _bad(f"Population '{p.name}'", "name used twice")
            want = level_shape(self.frame_shape, p.level)
            if p.level > self.params.levels:
                _bad(f"Population '{p.name}'", f"level {p.level} > params.levels={self.params.levels}")
            if p.level_shape != want:
                _bad(f"Population '{p.name}'",
                     f"level_shape {p.level_shape} differs from level {p.level} of a "
                     f"{self.frame_shape} frame, {want}")
            pops[p.name] = p
        for p in self.populations:
            for q in p.site_sources:
                if q not in pops:
                    _bad(f"Population '{p.name}'", f"site_sources names {q!r}, which is not a population")
        names = set()
        for pr in self.projections:
            if not isinstance(pr, (Conv, Resize)):
                _bad(obj, f"projections must be Conv or Resize nodes, got {type(pr).__name__}")
            what = f"{type(pr).__name__} '{pr.name}'"
            if pr.name in names or pr.name in pops:
                _bad(what, "name used twice")
            names.add(pr.name)
            for end in ("source", "target"):
                if getattr(pr, end) not in pops:
                    _bad(what, f"{end} {getattr(pr, end)!r} is not a population")
            src, tgt = pops[pr.source], pops[pr.target]
            if tgt.neuron is None:
                _bad(what, f"target '{tgt.name}' is a spike source and cannot receive connections")
            if isinstance(pr, Conv):
                if src.level != tgt.level:
                    _bad(what, f"source '{src.name}' (level {src.level}) and target '{tgt.name}' "
                               f"(level {tgt.level}) must share a level; use a Resize between levels")
                k = pr.kernel.array(self.params)
                if k.shape[0] != tgt.channels:
                    _bad(what, f"kernel has {k.shape[0]} output channels but target '{tgt.name}' "
                               f"has {tgt.channels}")
                if k.shape[1] != src.channels:
                    _bad(what, f"kernel has {k.shape[1]} input channels but source '{src.name}' "
                               f"has {src.channels}")
                if pr.padding == "wrap" and (src.stride != 1 or tgt.stride != 1):
                    _bad(what, "wrap-around padding needs stride 1 on both ends")
            else:
                if src.channels != tgt.channels:
                    _bad(what, f"source '{src.name}' has {src.channels} channels, target "
                               f"'{tgt.name}' {tgt.channels}; a Resize maps channel to channel")

    # -- lookups ---------------------------------------------------------
    def population(self, name: str) -> Population:
        for p in self.populations:
            if p.name == name:
                return p
        raise DescriptionError(f"Network: no population named {name!r}")

    def by_role(self, role: str, level: int | None = None) -> list[Population]:
        return [p for p in self.populations if p.role == role and (level is None or p.level == level)]

    def incoming(self, name: str) -> list:
        return [pr for pr in self.projections if pr.target == name]

    def outgoing(self, name: str) -> list:
        return [pr for pr in self.projections if pr.source == name]

    # -- serialisation ---------------------------------------------------
    def to_dict(self) -> dict:
        return {
            "schema": SCHEMA,
            "params": self.params.to_dict(),
            "frame_shape": list(self.frame_shape),
            "support_min": self.support_min,
            "input_rate_hz": self.input_rate_hz,
            "drive_min": self.drive_min,
            "notes": list(self.notes),
            "populations": [p.to_dict() for p in self.populations],
            "projections": [pr.to_dict() for pr in self.projections],
        }

    @classmethod
    def from_dict(cls, d: dict) -> "Network":
        if not isinstance(d, dict):
            _bad("Network", f"expected a mapping, got {type(d).__name__}")
        if d.get("schema") != SCHEMA:
            _bad("Network", f"schema {d.get('schema')!r} is not {SCHEMA!r}")
        extra = set(d) - {"schema", "params", "frame_shape", "support_min", "input_rate_hz",
                          "drive_min", "notes", "populations", "projections"}
        if extra:
            _bad("Network", f"unknown field(s) {sorted(extra)}")
        return cls(
            params=ModelParams.from_dict(d["params"]),
            frame_shape=tuple(d["frame_shape"]),
            populations=tuple(Population.from_dict(p) for p in d["populations"]),
            projections=tuple(_projection_from_dict(p) for p in d["projections"]),
            support_min=d.get("support_min", 0.3),
            input_rate_hz=d.get("input_rate_hz", 200.0),
            drive_min=d.get("drive_min", 1.0),
            notes=tuple(d.get("notes", ())),
        )

    def to_json(self, indent: int | None = 1) -> str:
        return json.dumps(self.to_dict(), indent=indent)

    @classmethod
    def from_json(cls, text: str) -> "Network":
        return cls.from_dict(json.loads(text))

    def summary(self) -> str:
        lines = [f"Network for a {self.frame_shape[0]} x {self.frame_shape[1]} frame, "
                 f"{self.params.levels} levels: {len(self.populations)} populations, "
                 f"{len(self.projections)} projections"]
        for p in self.populations:
            lines.append(f"  {p.name:10s} {p.role:10s} level {p.level:2d} grid {p.grid} x{p.channels} "
                         f"stride {p.stride} sites={p.sites}")
        return "\n".join(lines)


# --------------------------------------------------------------------------
# Spiking constants of the default network
# --------------------------------------------------------------------------
_INTERP = ("cubic", "linear")


@dataclass(frozen=True)
class NetworkParams:
    """Constants of the spiking network that :class:`ModelParams` does not hold.

    Dimensionless gains are expressed so that ``1.0`` means "one firing
    threshold of mean current at a reference presynaptic rate" (the rate is
    named with each gain); :func:`build_network` turns them into millivolts.

    input_rate_hz: per-pixel input rate the gains are calibrated for: at this
        rate a simple cell's mean current reaches threshold exactly when its
        DoG response reaches ``ModelParams.edge_threshold`` (stage 3).
    support_min: coarse levels instantiate S/U/B cells only where the resized
        edge map reaches this value (level 1: every event pixel).
    drive_min: the ``edges&drive`` site rule's fraction of threshold.
    grouping_stride: grouping and feedback cells sit on every
        ``grouping_stride``-th level pixel along each axis.
    pool_interpolation: interpolation of the top-down pooling
        ``V_{l+1} -> V_l`` (the rate model: cubic).
    fb_interpolation: interpolation of the feedback cells' lattice onto the
        border-ownership cells.
    prune_dog, prune_vm, prune_resize: kernel taps below this fraction of the
        kernel's largest |weight| are left out.
    delay_ms: delay of every projection except the two below.
    delay_untuned_ms: delay of the untuned cells' excitation (lets oriented
        simple cells fire first and silence them).
    delay_opposite_ms: delay of the opposite-family inhibition onto grouping
        cells (stands in for the rate model's first iteration, which runs
        without that inhibition).
    delay_feedback_ms: delay of the feedback onto border-ownership cells.
    wta_s: lateral inhibition between directions at a pixel (per 100 Hz).
    untuned_drive: excitation of an untuned cell at its reference edge value
        (1 at level 1, ``support_min`` above).
    untuned_inh: inhibition of an untuned cell per 50 Hz of a simple cell.
    sb_drive: border-ownership drive per 50 Hz of its simple cell.
    ub_drive: border-ownership drive per 150 Hz of an untuned cell (untuned
        cells fire faster than simple cells; this keeps the B cells they
        drive below their refractory ceiling).
    t_ref_untuned_ms: refractory period of the untuned cells.
    bb_inh: mutual inhibition of the two B cells sharing a simple cell (per 100 Hz).
    fb_exc, fb_inh: feedback from the own family's pooled cells (excitatory)
        and the opposite family's (inhibitory), per 100 Hz.
    bg_gain: B -> grouping, per 100 Hz and unit kernel weight.
    gg_inh: mutual inhibition between light and dark grouping cells (per 100 Hz).
    gv_gain: grouping -> feedback, per 100 Hz and unit kernel weight.
    tau_* / t_ref_* / v_th_mv: neuron constants (see :class:`Neuron`).
    """

    input_rate_hz: float = 200.0
    support_min: float = 0.3
    drive_min: float = 1.0
    grouping_stride: int = 2
    pool_interpolation: str = "linear"
    fb_interpolation: str = "linear"
    prune_dog: float = 0.05
    prune_vm: float = 0.05
    prune_resize: float = 0.0
    delay_ms: float = 1.0
    delay_untuned_ms: float = 8.0
    delay_opposite_ms: float = 70.0
    delay_feedback_ms: float = 25.0
    v_th_mv: float = 10.0
    tau_exc_ms: float = 5.0
    tau_inh_ms: float = 10.0
    tau_m_simple_ms: float = 10.0
    t_ref_simple_ms: float = 4.0
    tau_m_relay_ms: float = 200.0
    t_ref_relay_ms: float = 1.0
    tau_m_bo_ms: float = 10.0
    t_ref_bo_ms: float = 5.0
    tau_m_group_ms: float = 20.0
    t_ref_group_ms: float = 1.0
    tau_m_fb_ms: float = 20.0
    t_ref_fb_ms: float = 1.0
    tau_inh_untuned_ms: float = 50.0
    t_ref_untuned_ms: float = 4.0
    wta_s: float = 3.0
    untuned_drive: float = 1.5
    untuned_inh: float = 20.0
    sb_drive: float = 6.0
    ub_drive: float = 6.0
    bb_inh: float = 1.0
    fb_exc: float = 0.0
    fb_inh: float = 100.0
    bg_gain: float = 2.0
    gg_inh: float = 0.5
    gv_gain: float = 0.1

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            obj = f"NetworkParams.{f.name}"
            if f.name == "grouping_stride":
                _posint("NetworkParams", f.name, v)
                continue
            if f.name in ("pool_interpolation", "fb_interpolation"):
                if v not in _INTERP:
                    _bad(obj, f"={v!r} must be one of {_INTERP}")
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                _bad(obj, f"={v!r} must be a finite number >= 0")
            object.__setattr__(self, f.name, float(v))
        for name in ("input_rate_hz", "v_th_mv", "tau_exc_ms", "tau_inh_ms", "tau_inh_untuned_ms") + tuple(
                f.name for f in dataclasses.fields(self) if f.name.startswith("tau_m_")):
            if getattr(self, name) <= 0:
                _bad(f"NetworkParams.{name}", f"={getattr(self, name)!r} must be > 0")
        for name in ("prune_dog", "prune_vm", "prune_resize"):
            if getattr(self, name) >= 1:
                _bad(f"NetworkParams.{name}", f"={getattr(self, name)!r} must be < 1")

    def replace(self, **changes) -> "NetworkParams":
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "NetworkParams":
        return cls(**_known(cls, d, "NetworkParams"))


# --------------------------------------------------------------------------
# The default network
# --------------------------------------------------------------------------
FAMILIES = ("L1", "L2", "D1", "D2")
#: family -> (simple-cell channels it reads, offset), stage 5:
#: BL1[o] = S[o], BL2[o] = S[o+n], BD1[o] = S[o+n], BD2[o] = S[o]
_FAMILY_S_OFFSET = {"L1": 0, "L2": 1, "D1": 1, "D2": 0}
#: the family sharing a simple cell (the two compete), stage 8
PARTNER = {"L1": "D2", "D2": "L1", "L2": "D1", "D1": "L2"}
#: rectified halves of the two feedback signals z1 = VL1 - VD2, z2 = VL2 - VD1
ZPAIRS = ("1p", "1n", "2p", "2n")


def _cmap(n_out, n_in, pairs, w=1.0):
    return Kernel("channel_map", {"n_out": n_out, "n_in": n_in, "entries": [[o, i, w] for o, i in pairs]})


def _dog_half(polarity: int, n: int) -> Kernel:
    """DoG kernels from one input polarity to all 2n directions; only the
    polarity's own half (ON: 0..n-1, OFF: n..2n-1) is non-zero."""
    return Kernel("dog", {"directions": [k if polarity * n <= k < (polarity + 1) * n else None
                                         for k in range(2 * n)]})


def build_network(params: ModelParams = ModelParams(), frame_shape=(321, 481),
                  net: NetworkParams = NetworkParams()) -> Network:
    """The spiking figure-ground network for frames of ``frame_shape``.

    Per level ``l`` (suffix ``_l``):

    * level 1: spike sources ``on``/``off`` (one per pixel and polarity);
      levels >= 2: relays ``ron_l``/``roff_l`` (LIF cells with a long membrane
      time constant, so that their rate follows the bicubic-resized event
      frame of stage 2);
    * ``S_l`` (2*n_ori directions): DoG convolution (wrap-around, stage 3) from
      the ON source/relay for directions ``0..n_ori-1``, OFF for the rest;
      lateral inhibition between the directions at a pixel (the arg-max of
      stage 4);
    * ``U_l``: one "untuned" cell per support pixel, excited by the pixel's own
      input after ``delay_untuned_ms`` and silenced by any simple cell there.
      It reproduces the reference's rule that an event pixel without any
      oriented response takes direction 0 (border-ownership index n/2);
    * ``BL1_l, BL2_l, BD1_l, BD2_l`` (n_ori orientations each): driven by the
      simple cell of index ``o`` (``L1``, ``D2``) or ``o + n_ori`` (``L2``,
      ``D1``) after the quarter-turn of stage 4 (direction ``k`` -> index
      ``(k + n/2) mod 2n``); the two cells sharing a simple cell inhibit each
      other; feedback (stage 8): the half of ``z`` against a cell inhibits it
      (and, if ``fb_exc > 0``, the half for it excites it);
    * ``GL_l, GD_l`` (stride ``grouping_stride``): von Mises correlation from
      the B cells (stage 7), opposite family inhibitory and delayed; light and
      dark inhibit each other;
    * ``Z1p_l, Z1n_l, Z2p_l, Z2n_l`` (stride ``grouping_stride``): the
      feedback signals of stage 8, ``z1 = VL1 - VD2`` and ``z2 = VL2 - VD1``,
      each as a rectified pair (``p`` = positive part, ``n`` = negative part),
      pooled top-down: ``z_l = G (*) m - G' (*) m' + decay * resize(z_{l+1})``.
    """
    if not isinstance(params, ModelParams):
        _bad("build_network", f"params must be a ModelParams, got {type(params).__name__}")
    if not isinstance(net, NetworkParams):
        _bad("build_network", f"net must be a NetworkParams, got {type(net).__name__}")
    frame_shape = _shape2("build_network", "frame_shape", frame_shape)
    n = params.n_ori
    n_dir = params.n_dir
    if n % 2:
        _bad("build_network", f"ModelParams.n_ori={n} must be even (index n/2 is the untuned cells' orientation)")
    th = net.v_th_mv
    r_in = net.input_rate_hz
    tau_e = net.tau_exc_ms / 1000.0
    tau_i = net.tau_inh_ms / 1000.0
    d = net.delay_ms
    st = net.grouping_stride

    def lif(tau_m, t_ref, tau_inh=None):
        return Neuron(tau_m_ms=tau_m, tau_exc_ms=net.tau_exc_ms,
                      tau_inh_ms=net.tau_inh_ms if tau_inh is None else tau_inh,
                      v_th_mv=th, t_ref_ms=t_ref)

    simple = lif(net.tau_m_simple_ms, net.t_ref_simple_ms)
    untuned = lif(net.tau_m_simple_ms, net.t_ref_untuned_ms, net.tau_inh_untuned_ms)
    relay = lif(net.tau_m_relay_ms, net.t_ref_relay_ms)
    bo = lif(net.tau_m_bo_ms, net.t_ref_bo_ms)
    grp = lif(net.tau_m_group_ms, net.t_ref_group_ms)
    fb = lif(net.tau_m_fb_ms, net.t_ref_fb_ms)

    # Gains in mV per unit kernel weight. A presynaptic rate r through a
    # weight w adds w * r * tau_syn to the mean synaptic current.
    g_in = th / (params.edge_threshold * r_in * tau_e)        # S threshold <-> edge_threshold
    g_relay = th * net.tau_m_relay_ms / net.tau_exc_ms        # a unit-weight spike = one threshold of charge
    g_sb = net.sb_drive * th / (50.0 * tau_e)
    g_ub = net.ub_drive * th / (150.0 * tau_e)
    g_fb_e = net.fb_exc * th / (100.0 * tau_e)
    g_fb_i = net.fb_inh * th / (100.0 * tau_i)
    g_bg = net.bg_gain * th / (100.0 * tau_e)
    g_gv = net.gv_gain * th / (100.0 * tau_e)
    g_wta = net.wta_s * th / (100.0 * tau_i)
    g_bb = net.bb_inh * th / (100.0 * tau_i)
    g_gg = net.gg_inh * th / (100.0 * tau_i)
    g_su = net.untuned_inh * th / (50.0 * net.tau_inh_untuned_ms / 1000.0)
    # A subtraction (opposite family, the other half of a z pair) must weigh
    # what it subtracts as much as the excitation: its current decays with
    # tau_inh instead of tau_exc, so its gain is scaled by tau_exc / tau_inh.
    sub = net.tau_exc_ms / net.tau_inh_ms
    # Pooling V_{l+1} -> V_l: a feedback cell's rate is ~ I / (tau_m * v_th), so
    # this gain hands decay * (its input current) on to the finer level.
    g_pool = params.pyramid_decay * net.tau_m_fb_ms * th / net.tau_exc_ms

    pops: list[Population] = []
    prjs: list = []

    def pop(name, role, level, channels=1, stride=1, neuron=None, sites="all", site_sources=()):
        pops.append(Population(name, role, level, level_shape(frame_shape, level), channels, stride, neuron,
                               sites, tuple(site_sources)))
        return name

    def conv(name, src, dst, kernel, sign, gain, delay=d, mode="corr", padding="zero", prune=0.0):
        prjs.append(Conv(name, src, dst, kernel, mode, padding, sign, gain, delay, prune))

    lo = [(o, o) for o in range(n)]
    for l in range(1, params.levels + 1):
        # ---- input / relays ------------------------------------------------
        if l == 1:
            on = pop("on", "input_on", 1)
            off = pop("off", "input_off", 1)
        else:
            on = pop(f"ron_{l}", "relay_on", l, neuron=relay, sites="reachable")
            off = pop(f"roff_{l}", "relay_off", l, neuron=relay, sites="reachable")
            for src, dst in (("on", on), ("off", off)):
                prjs.append(Resize(f"{src}_to_{dst}", src, dst, "cubic", 1, g_relay, d, net.prune_resize))
        # ---- simple cells (stages 3-4) -------------------------------------
        s = pop(f"S_{l}", "simple", l, n_dir, neuron=simple, sites="edges&drive")
        conv(f"{on}_to_{s}", on, s, _dog_half(0, n), 1, g_in, mode="conv", padding="wrap", prune=net.prune_dog)
        conv(f"{off}_to_{s}", off, s, _dog_half(1, n), 1, g_in, mode="conv", padding="wrap", prune=net.prune_dog)
        conv(f"{s}_wta", s, s, _cmap(n_dir, n_dir, [(a, b) for a in range(n_dir) for b in range(n_dir) if a != b]),
             -1, g_wta)
        # ---- untuned cells -------------------------------------------------
        u = pop(f"U_{l}", "untuned", l, neuron=untuned, sites="edges")
        e_ref = 1.0 if l == 1 else max(net.support_min, 1e-3)
        g_u = net.untuned_drive * th / (e_ref * r_in * tau_e)
        for src in (on, off):
            conv(f"{src}_to_{u}", src, u, _cmap(1, 1, [(0, 0)]), 1, g_u, delay=net.delay_untuned_ms)
        conv(f"{s}_inh_{u}", s, u, _cmap(1, n_dir, [(0, k) for k in range(n_dir)]), -1, g_su)
        # ---- border-ownership cells (stage 5) ------------------------------
        b = {f: pop(f"B{f}_{l}", f"bo_{f}", l, n, neuron=bo, sites="reachable", site_sources=(s, u))
             for f in FAMILIES}
        for f in FAMILIES:
            off_s = _FAMILY_S_OFFSET[f] * n
            # index o (stage 4) is direction (o - n/2) mod 2n: a quarter turn
            conv(f"{s}_to_{b[f]}", s, b[f], _cmap(n, n_dir, [(o, (o + off_s - n // 2) % n_dir) for o in range(n)]),
                 1, g_sb)
            if off_s == 0:   # untuned pixels take index n/2, read by L1 and D2
                conv(f"{u}_to_{b[f]}", u, b[f], _cmap(n, 1, [(n // 2, 0)]), 1, g_ub)
            conv(f"{b[PARTNER[f]]}_inh_{b[f]}", b[PARTNER[f]], b[f], _cmap(n, n, lo), -1, g_bb)
        # ---- grouping cells (stage 7) --------------------------------------
        gl = pop(f"GL_{l}", "group_L", l, 1, st, grp, "reachable", tuple(b.values()))
        gd = pop(f"GD_{l}", "group_D", l, 1, st, grp, "reachable", tuple(b.values()))
        w = params.w_inh
        # gL1 = (BL1 - w BD2) (*) m2, gL2 = (BL2 - w BD1) (*) m1,
        # gD1 = (BD1 - w BL2) (*) m2, gD2 = (BD2 - w BL1) (*) m1
        for f, g, half, sign in (("L1", gl, 2, 1), ("L2", gl, 1, 1), ("D2", gl, 2, -1), ("D1", gl, 1, -1),
                                 ("D1", gd, 2, 1), ("D2", gd, 1, 1), ("L2", gd, 2, -1), ("L1", gd, 1, -1)):
            if sign < 0 and w == 0:
                continue
            conv(f"{b[f]}_to_{g}", b[f], g, Kernel("von_mises", {"half": half, "layout": "gather"}), sign,
                 g_bg * (1.0 if sign > 0 else w * sub), delay=d if sign > 0 else net.delay_opposite_ms,
                 prune=net.prune_vm)
        conv(f"{gl}_inh_{gd}", gl, gd, _cmap(1, 1, [(0, 0)]), -1, g_gg)
        conv(f"{gd}_inh_{gl}", gd, gl, _cmap(1, 1, [(0, 0)]), -1, g_gg)
        # ---- feedback (stage 8) ----------------------------------------------
        # z1[o] = VL1 - VD2 = GL (*) m1 - GD (*) m2 drives BL1 up and BD2 down,
        # z2[o] = VL2 - VD1 = GL (*) m2 - GD (*) m1 drives BL2 up and BD1 down,
        # each pooled over the coarser levels. A signed z is carried by a
        # rectified pair of cells (z+ and z-). Grouping and feedback cells
        # share a lattice, so only every stride-th tap is used and stride**2
        # compensates for the sparser sampling.
        z = {k: pop(f"Z{k}_{l}", f"fb_z{k}", l, n, st, fb, "needed") for k in ZPAIRS}
        for k, (g_pos, half_pos, g_neg, half_neg) in {
                "1p": (gl, 1, gd, 2), "1n": (gd, 2, gl, 1),
                "2p": (gl, 2, gd, 1), "2n": (gd, 1, gl, 2)}.items():
            conv(f"{g_pos}_to_{z[k]}", g_pos, z[k], Kernel("von_mises", {"half": half_pos, "layout": "scatter"}),
                 1, g_gv * st * st, prune=net.prune_vm)
            conv(f"{g_neg}_inh_{z[k]}", g_neg, z[k], Kernel("von_mises", {"half": half_neg, "layout": "scatter"}),
                 -1, g_gv * st * st * sub, prune=net.prune_vm)
        # B cells: the side z favours is excited (optional), the other inhibited
        for f, (zk_for, zk_against) in {"L1": ("1p", "1n"), "D2": ("1n", "1p"),
                                        "L2": ("2p", "2n"), "D1": ("2n", "2p")}.items():
            if g_fb_e > 0:
                prjs.append(Resize(f"{z[zk_for]}_to_{b[f]}", z[zk_for], b[f], net.fb_interpolation, 1, g_fb_e,
                                   net.delay_feedback_ms))
            if g_fb_i > 0:
                prjs.append(Resize(f"{z[zk_against]}_inh_{b[f]}", z[zk_against], b[f], net.fb_interpolation, -1,
                                   g_fb_i, net.delay_feedback_ms))
    # top-down pooling: z_l += decay * resize(z_{l+1}), for both halves of each pair
    for l in range(1, params.levels):
        for k, other in (("1p", "1n"), ("1n", "1p"), ("2p", "2n"), ("2n", "2p")):
            prjs.append(Resize(f"Z{k}_{l + 1}_to_Z{k}_{l}", f"Z{k}_{l + 1}", f"Z{k}_{l}", net.pool_interpolation,
                               1, g_pool, d, net.prune_resize))
            prjs.append(Resize(f"Z{other}_{l + 1}_inh_Z{k}_{l}", f"Z{other}_{l + 1}", f"Z{k}_{l}",
                               net.pool_interpolation, -1, g_pool * sub, d, net.prune_resize))
    notes = (
        "Deviation: the multiplicative feedback S*f(z) of stage 8 is additive here: z = VL1 - VD2 (and "
        "VL2 - VD1) is carried by a rectified pair of cells; the half against a B cell inhibits it (and with "
        "fb_exc > 0 the half for it excites it), and the two B cells sharing a simple cell inhibit each other. "
        "A B cell without simple-cell input has no drive, so feedback alone cannot make it fire.",
        "Deviation: the rate model's first iteration runs without opposite-family inhibition; here that "
        "inhibition arrives delay_opposite_ms later than the excitation.",
        "Deviation: coarse-level S/U/B cells exist only where the resized edge map >= support_min, and "
        "their activity does not scale with the edge value.",
        "Deviation: grouping and feedback cells sit on a stride-grouping_stride lattice; pooling across "
        "scales is top-down (z_l = G_l (*) m - G_l (*) m' + decay * resize(z_{l+1})) with pool_interpolation.",
    )
    return Network(params, frame_shape, tuple(pops), tuple(prjs), net.support_min, r_in, net.drive_min, notes)
