"""The nodes of a network description: neurons, populations and kernels (the
projections between populations: :mod:`snn_fg.network.projections`).

Modelled on NIR's node family: frozen, keyword-only dataclasses, each
validated on construction with errors that name the node at fault, and
serialisation written once (:class:`Node`).

* :class:`Neuron` - a current-based leaky integrate-and-fire (CUBA LIF)
  neuron::

      tau_m dv/dt = v_rest - v + I_exc - I_inh
      tau_exc dI_exc/dt = -I_exc,  tau_inh dI_inh/dt = -I_inh

  A presynaptic spike through a synapse of weight ``w`` (mV) adds ``w`` to
  ``I_exc`` (``w > 0``) or ``|w|`` to ``I_inh`` (``w < 0``). When
  ``v > v_th`` the cell spikes, ``v`` is set to ``v_reset`` and held there
  for ``t_ref``; the currents keep decaying.
* :class:`Population` - the cells of one pyramid level: ``channels`` cells at
  every point of a grid that samples the level every ``stride`` pixels.
* :class:`Kernel` - a weight-shared kernel ``(C_out, C_in, kh, kw)`` named by
  reference to the model's own kernel functions, materialised on demand.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from .. import validate as check
from ..errors import ParameterError
from ..params import ModelParams
from .kernels import dog_kernels, von_mises_masks
from .roles import ROLES, SOURCE_ROLES

#: Which cells a simulator needs to instantiate for one input. This is an
#: optimisation hint for backends that unroll the network for an input, not
#: part of the model: cells it leaves out are cells that input cannot make
#: fire (see :mod:`snn_fg.lowering.sites`). A backend may instantiate every
#: cell instead and must then compute the same spikes.
#:
#: ``all``
#:     every cell (spike sources);
#: ``edges``
#:     every channel at grid points where the level's edge map reaches
#:     ``Network.support_min`` (level 1: every event pixel);
#: ``edges&drive``
#:     the ``edges`` cells whose excitation alone, with every source at its
#:     nominal rate, reaches ``Network.drive_min`` thresholds of mean current;
#: ``reachable``
#:     cells with an excitatory connection from an instantiated cell of
#:     ``site_sources`` (all sources if empty);
#: ``needed``
#:     cells with a connection onto an instantiated cell.
SITE_RULES = ("all", "edges", "edges&drive", "reachable", "needed")


def finite(owner, name, v, lo=None, lo_open=False):
    return check.number(owner, name, v, lo=lo, lo_open=lo_open)


class Node:
    """Serialisation shared by every node: ``to_dict`` writes each field
    (nested nodes as dicts, tuples as lists) and ``from_dict`` refuses
    unknown fields and rebuilds nested nodes. Subclasses name their nested
    node fields in ``_nested``."""

    _nested: ClassVar[dict] = {}

    @property
    def _owner(self) -> str:
        return type(self).__name__

    def to_dict(self) -> dict:
        out = {}
        for f in dataclasses.fields(self):
            if not f.init:
                continue
            v = getattr(self, f.name)
            if isinstance(v, Node):
                v = v.to_dict()
            elif isinstance(v, tuple):
                v = list(v)
            out[f.name] = v
        return out

    @classmethod
    def from_dict(cls, d: dict):
        owner = f"{cls.__name__} {d['name']!r}" if isinstance(d, dict) and "name" in d else cls.__name__
        if not isinstance(d, dict):
            check.fail(owner, None, None, f"expected a mapping, got {type(d).__name__}")
        names = {f.name for f in dataclasses.fields(cls) if f.init}
        check.known_keys(owner, d, names)
        d = dict(d)
        for key, node_type in cls._nested.items():
            if d.get(key) is not None:
                try:
                    d[key] = node_type.from_dict(d[key])
                except ParameterError as exc:  # (say whose: a population's neuron, not just "Neuron")
                    raise ParameterError(f"{owner}, its {key}: {exc}") from None
        return cls(**d)


@dataclass(frozen=True, kw_only=True)
class Neuron(Node):
    """CUBA LIF constants, in milliseconds and millivolts (see the module docstring).

    Excitation and inhibition decay alike by default (``tau_exc_ms ==
    tau_inh_ms``): a kernel with negative lobes split between the two
    currents, as a board must (:func:`snn_fg.pynn.network.split_receptors`),
    then acts exactly as its signed sum, so the export computes what the
    simulators compute."""

    tau_m_ms: float = 10.0
    tau_exc_ms: float = 5.0
    tau_inh_ms: float = 5.0
    v_rest_mv: float = 0.0
    v_reset_mv: float = 0.0
    v_th_mv: float = 10.0
    t_ref_ms: float = 2.0
    model: str = "cuba_lif"

    def __post_init__(self):
        owner = "Neuron"
        check.choice(owner, "model", self.model, ("cuba_lif",))
        for name in ("tau_m_ms", "tau_exc_ms", "tau_inh_ms"):
            object.__setattr__(self, name, finite(owner, name, getattr(self, name), 0, lo_open=True))
        object.__setattr__(self, "t_ref_ms", finite(owner, "t_ref_ms", self.t_ref_ms, 0))
        for name in ("v_rest_mv", "v_reset_mv", "v_th_mv"):
            object.__setattr__(self, name, finite(owner, name, getattr(self, name)))
        if self.v_th_mv <= self.v_rest_mv or self.v_th_mv <= self.v_reset_mv:
            check.fail(owner, "v_th_mv", self.v_th_mv, "must lie above v_rest_mv and v_reset_mv")

    def propagators(self, dt_ms: float) -> dict:
        """The exact update of the CUBA LIF equations over one step ``dt_ms``
        without spikes (as NEST's ``iaf_psc_exp`` integrates them)::

            v'     = v_rest + d_m (v - v_rest) + p_exc I_exc - p_inh I_inh
            I_exc' = d_exc I_exc,   I_inh' = d_inh I_inh

        with ``d = exp(-dt / tau)`` and ``p_s = tau_s / (tau_s - tau_m) *
        (d_s - d_m)`` (``dt / tau_m * d_m`` when ``tau_s == tau_m``). Every
        synaptic current then delivers exactly its continuous-time charge,
        whatever ``dt``: a forward step that moves ``v`` by
        ``(1 - d_m) * I`` over-counts it by about ``dt / (2 tau_s)``."""
        dt = check.number("Neuron.propagators", "dt_ms", dt_ms, lo=0, lo_open=True)
        d_m = math.exp(-dt / self.tau_m_ms)
        out = {"d_m": d_m}
        for syn, tau in (("exc", self.tau_exc_ms), ("inh", self.tau_inh_ms)):
            d_s = math.exp(-dt / tau)
            out[f"d_{syn}"] = d_s
            if math.isclose(tau, self.tau_m_ms, rel_tol=1e-9):
                out[f"p_{syn}"] = dt / self.tau_m_ms * d_m
            else:
                out[f"p_{syn}"] = tau / (tau - self.tau_m_ms) * (d_s - d_m)
        return out

    @property
    def max_rate_hz(self) -> float:
        """Refractory ceiling of the firing rate (inf without refractoriness)."""
        return math.inf if self.t_ref_ms == 0 else 1000.0 / self.t_ref_ms

    def drive_for_rate(self, rate_hz: float) -> float:
        """The steady drive (mV above ``v_rest`` that a constant current holds
        the membrane at, ``R I``) under which the cell fires at ``rate_hz``:
        the inverse of ``1 / (t_ref + tau_m ln((v_inf - v_reset) / (v_inf - v_th)))``."""
        rate_hz = check.number(
            "Neuron.drive_for_rate", "rate_hz", rate_hz, lo=0, lo_open=True, hi=self.max_rate_hz, hi_open=True
        )
        grow = math.exp((1000.0 / rate_hz - self.t_ref_ms) / self.tau_m_ms)
        v_inf = (grow * self.v_th_mv - self.v_reset_mv) / (grow - 1.0)
        return v_inf - self.v_rest_mv


@dataclass(frozen=True, kw_only=True)
class Population(Node):
    """Cells of one pyramid level, ``channels`` per grid point.

    ``level_shape`` is the (rows, cols) of the pyramid level; the
    population's grid samples it every ``stride`` pixels (grid point
    ``(i, j)`` sits at level pixel ``(stride*i, stride*j)``). ``neuron`` is
    ``None`` for spike sources. ``sites`` and ``site_sources`` are the
    instantiation hint of :data:`SITE_RULES`.

    ``edge_mask``: the cells exist only at level pixels where the level's
    resized edge map reaches ``Network.support_min`` (level 1: the event
    pixels). For coarse simple and untuned cells this is part of the model
    (the rate model weights coarse levels by that map), and the one part of
    the network that depends on the input: the spiking network does not
    compute it (see ``docs/model.md``). For the gated populations (level-1
    simple and untuned cells, border-ownership and excess cells) it leaves
    out only cells that cannot fire.
    """

    name: str
    role: str
    level: int
    level_shape: tuple[int, int]
    channels: int = 1
    stride: int = 1
    neuron: Neuron | None = None
    sites: str = "all"
    site_sources: tuple[str, ...] = ()
    edge_mask: bool = False

    _nested: ClassVar[dict] = {"neuron": Neuron}

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier():
            check.fail(f"Population({self.name!r})", None, None, "name must be a Python identifier")
        owner = f"Population '{self.name}'"
        check.choice(owner, "role", self.role, ROLES)
        check.integer(owner, "level", self.level, lo=1)
        object.__setattr__(self, "level_shape", check.shape2(owner, "level_shape", self.level_shape))
        check.integer(owner, "channels", self.channels, lo=1)
        check.integer(owner, "stride", self.stride, lo=1)
        check.choice(owner, "sites", self.sites, SITE_RULES)
        if isinstance(self.site_sources, str) or not all(isinstance(x, str) for x in self.site_sources):
            check.fail(owner, "site_sources", self.site_sources, "must be a sequence of population names")
        object.__setattr__(self, "site_sources", tuple(self.site_sources))
        check.flag(owner, "edge_mask", self.edge_mask)
        if self.is_source:
            if self.neuron is not None:
                check.fail(owner, None, None, "a spike source (role input_* or clock) has no neuron model")
            if self.level != 1 or self.stride != 1 or self.channels != 1:
                check.fail(owner, None, None, "spike sources live on level 1 with stride 1 and one channel")
            if self.role == "clock" and self.level_shape != (1, 1):
                check.fail(owner, "level_shape", self.level_shape, "must be (1, 1): the clock is one cell")
        elif not isinstance(self.neuron, Neuron):
            check.fail(owner, "neuron", self.neuron, f"is needed by role {self.role!r} (a Neuron)")

    @property
    def is_source(self) -> bool:
        return self.role in SOURCE_ROLES

    @property
    def grid(self) -> tuple[int, int]:
        """(rows, cols) of the population's own grid."""
        s = self.stride
        return (-(-self.level_shape[0] // s), -(-self.level_shape[1] // s))

    @property
    def shape(self) -> tuple[int, int, int]:
        """(channels, rows, cols) of the whole population."""
        return (self.channels,) + self.grid

    @property
    def size(self) -> int:
        return int(np.prod(self.shape))


def _json_plain(value, owner):
    """``value`` as plain JSON data (lists, dicts, numbers), rejecting what JSON cannot hold."""

    def default(x):
        if isinstance(x, np.ndarray):
            return x.tolist()
        if isinstance(x, np.generic):
            return x.item()
        raise TypeError(type(x).__name__)

    try:
        return json.loads(json.dumps(value, sort_keys=True, default=default, allow_nan=False))
    except (TypeError, ValueError) as exc:
        check.fail(owner, "args", value, f"is not JSON data ({exc})")


def _check_dog(owner, a):
    dirs = a["directions"]
    if not isinstance(dirs, list) or not any(k is not None for k in dirs):
        check.fail(owner, "directions", dirs, "must name at least one direction (None = an all-zero channel)")
    if any(k is not None and (isinstance(k, bool) or not isinstance(k, int) or k < 0) for k in dirs):
        check.fail(owner, "directions", dirs, "must be non-negative integers or None")


def _check_von_mises(owner, a):
    check.choice(owner, "half", a["half"], (1, 2))
    check.choice(owner, "layout", a["layout"], ("gather", "scatter"))


def _check_channel_map(owner, a):
    n_out = check.integer(owner, "n_out", a["n_out"], lo=1)
    n_in = check.integer(owner, "n_in", a["n_in"], lo=1)
    for e in a["entries"]:
        if not isinstance(e, list) or len(e) != 3 or not (0 <= e[0] < n_out and 0 <= e[1] < n_in):
            check.fail(owner, "entry", e, f"must be [out < {n_out}, in < {n_in}, weight]")
        check.number(owner, "entry weight", e[2])


def _check_block_mean(owner, a):
    check.integer(owner, "channels", a["channels"], lo=1)
    check.integer(owner, "stride", a["stride"], lo=1)


def _check_array(owner, a):
    arr = np.asarray(a["data"], dtype=float)
    if arr.ndim != 4 or not np.all(np.isfinite(arr)):
        check.fail(owner, "data", f"<array of shape {arr.shape}>", "must be a finite 4-D array (C_out, C_in, kh, kw)")
    if arr.shape[2] % 2 == 0 or arr.shape[3] % 2 == 0:
        check.fail(owner, "data", f"<array of shape {arr.shape}>", "must have an odd spatial size")


#: Kernel references: the argument names each takes and its check.
KERNEL_REFS = {
    "dog": ({"directions"}, _check_dog),
    "von_mises": ({"half", "layout"}, _check_von_mises),
    "channel_map": ({"n_out", "n_in", "entries"}, _check_channel_map),
    "block_mean": ({"channels", "stride"}, _check_block_mean),
    "array": ({"data"}, _check_array),
}


@dataclass(frozen=True, kw_only=True)
class Kernel(Node):
    """A weight-shared kernel of shape ``(C_out, C_in, kh, kw)``.

    ``ref`` names how to make it from ``args`` (plain JSON data):

    * ``dog``: ``{"directions": [k or None, ...]}`` - the oriented DoG
      kernels of :func:`~snn_fg.network.kernels.dog_kernels`, one output
      channel per entry (``None``: an all-zero channel), one input channel;
    * ``von_mises``: ``{"half": 1 | 2, "layout": "gather" | "scatter"}`` - the
      half rings ``m1``/``m2`` of :func:`~snn_fg.network.kernels.von_mises_masks`;
      ``gather`` sums ``n_ori`` input channels into one output (border
      ownership -> grouping), ``scatter`` sends one input to ``n_ori``
      outputs (grouping -> feedback);
    * ``channel_map``: ``{"n_out", "n_in", "entries": [[o, i, w], ...]}`` - a
      1 x 1 kernel connecting input channel ``i`` to output channel ``o``
      with weight ``w``;
    * ``block_mean``: ``{"channels": C, "stride": s}`` - onto a lattice of
      stride ``s``, each channel's mean over the ``s x s`` block around a
      lattice point, as a ``(2s-1) x (2s-1)`` tent (bilinear weights summing
      to 1): every source pixel hands ``1/s**2`` of itself to the lattice;
    * ``array``: ``{"data": nested list (C_out, C_in, kh, kw)}``.

    :meth:`array` materialises it for the :class:`ModelParams` of a network.
    """

    ref: str
    args: dict = field(default_factory=dict, hash=False)

    def __post_init__(self):
        owner = f"Kernel(ref={self.ref!r})"
        check.choice(owner, "ref", self.ref, tuple(KERNEL_REFS))
        if not isinstance(self.args, dict):
            check.fail(owner, "args", self.args, "must be a mapping")
        need, validate_args = KERNEL_REFS[self.ref]
        if set(self.args) != need:
            check.fail(owner, "args", sorted(self.args), f"must have exactly the keys {sorted(need)}")
        args = _json_plain(self.args, owner)
        validate_args(owner, args)
        object.__setattr__(self, "args", args)

    def array(self, params: ModelParams) -> np.ndarray:
        """The kernel as a float64 array ``(C_out, C_in, kh, kw)``."""
        a = self.args
        if self.ref == "dog":
            k = dog_kernels(params)
            bad = [d for d in a["directions"] if d is not None and d >= k.shape[0]]
            if bad:
                check.fail("Kernel(ref='dog')", "directions", bad, f"lie outside 0..{k.shape[0] - 1}")
            out = np.zeros((len(a["directions"]), 1) + k.shape[1:])
            for c, d in enumerate(a["directions"]):
                if d is not None:
                    out[c, 0] = k[d]
            return out
        if self.ref == "von_mises":
            m = von_mises_masks(params)[a["half"] - 1]
            return (m[None] if a["layout"] == "gather" else m[:, None]).copy()
        if self.ref == "channel_map":
            out = np.zeros((a["n_out"], a["n_in"], 1, 1))
            for o, i, w in a["entries"]:
                out[o, i, 0, 0] += w
            return out
        if self.ref == "block_mean":
            st = a["stride"]
            tent = 1.0 - np.abs(np.arange(1 - st, st)) / st
            out = np.zeros((a["channels"], a["channels"], 2 * st - 1, 2 * st - 1))
            out[np.arange(a["channels"]), np.arange(a["channels"])] = np.outer(tent, tent) / st**2
            return out
        return np.asarray(a["data"], dtype=float)
