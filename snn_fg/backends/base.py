"""The seam between a network description and whatever simulates it.

Everything above it (decoding, figures, the command line, experiments)
speaks only of :class:`SimulationResult`; everything below it (a backend)
consumes only a :class:`~snn_fg.network.Network` and the input spikes
(:class:`~snn_fg.lowering.input_spikes.InputSpikes`). A backend subclasses
:class:`Backend`, implements :meth:`Backend.simulate`, and is registered by
name in :mod:`snn_fg.backends` - the way PyNN keeps one neutral model in
``pyNN.common`` and one package per simulator.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from .. import validate as check
from ..lowering.unroll import INSTANTIATE
from ..network.graph import Network
from ..network.nodes import Population

#: Per-cell state variables a backend can report at the end of a run (mV).
STATE_VARIABLES = ("v", "I_exc", "I_inh")


@dataclass(frozen=True, kw_only=True)
class RunSettings:
    """How to run a simulation (independent of the backend).

    Parameters
    ----------
    duration_ms : float
        Simulated time.
    dt_ms : float
        Time step, given by the caller (it has no default here: a run takes
        the network's own step unless told otherwise,
        :meth:`~snn_fg.network.Network.time_step`).
    count_from_ms : float
        Spikes from this time on are counted (the counting window ends at
        ``duration_ms``).
    record_spikes : bool
        Keep every spike's cell and time (for rasters), not only counts.
    record_state : tuple of str
        State variables (:data:`STATE_VARIABLES`) whose final values to report.
    instantiate : {"input", "all"}
        ``input``: a backend that instantiates cells may create only those the
        input can use (the populations' site hints); ``all``: every cell.
    count_bins_ms : tuple of float, optional
        Edges ``t_0 < t_1 < ... < t_n`` (ms, within ``[0, duration_ms]``) of
        counting bins: the backend also reports each cell's spikes in every
        bin ``[t_k, t_k+1)`` (:attr:`SimulationResult.binned_counts`), so that
        one continuous run over a recording yields one map per window.
    on_bin : callable, optional
        With ``count_bins_ms``: ``on_bin(k, result)`` receives bin ``k`` as
        a :class:`SimulationResult` of its own (its counts, and its spikes if
        recorded) as soon as the backend has it. A backend that hands bins
        over this way may forget them: its final result then has no
        ``binned_counts`` and no ``spikes``, and its memory need not grow
        with the run. One that does not keeps them, and :func:`each_bin`
        replays them, so that the caller sees the same bins either way.
    sites : dict, optional
        Fixed cells (flat indices) of some populations (hand-built circuits).
    log : callable, optional
        Receives one-line progress messages (``None``: silent).
    progress : bool
        Show a progress bar while simulating.
    """

    duration_ms: float
    dt_ms: float
    count_from_ms: float = 0.0
    record_spikes: bool = True
    record_state: tuple = ()
    instantiate: str = "input"
    count_bins_ms: tuple | None = None
    on_bin: Callable | None = None
    sites: dict | None = None
    log: Callable | None = None
    progress: bool = False

    def __post_init__(self):
        owner = "RunSettings"
        object.__setattr__(
            self, "duration_ms", check.number(owner, "duration_ms", self.duration_ms, lo=0, lo_open=True)
        )
        object.__setattr__(self, "dt_ms", check.number(owner, "dt_ms", self.dt_ms, lo=0, lo_open=True))
        object.__setattr__(
            self,
            "count_from_ms",
            check.number(owner, "count_from_ms", self.count_from_ms, lo=0, hi=self.duration_ms, hi_open=True),
        )
        check.choice(owner, "instantiate", self.instantiate, INSTANTIATE)
        if self.count_bins_ms is not None:
            given = np.asarray(self.count_bins_ms)
            plain = given.ndim == 1 and given.dtype.kind in "iuf"
            # (True is no time, though numpy takes it as 1)
            if plain and not isinstance(self.count_bins_ms, np.ndarray):
                plain = not set(map(type, self.count_bins_ms)) & {bool, np.bool_}
            times = given.astype(np.float64) + 0.0 if plain else None
            if (
                times is not None
                and np.isfinite(times).all()
                and (times >= 0).all()
                and (times <= self.duration_ms).all()
            ):
                edges = tuple(times.tolist())  # (a recording laid out for an hour of 10 ms hops has 720,000)
            else:  # (one by one, for the error that names the first bad one)
                edges = tuple(
                    check.number(owner, "count_bins_ms", t, lo=0, hi=self.duration_ms) for t in self.count_bins_ms
                )
            if len(edges) < 2 or (np.diff(edges) <= 0).any():
                check.fail(owner, "count_bins_ms", self.count_bins_ms, "must be two or more increasing times")
            object.__setattr__(self, "count_bins_ms", edges)
        for v in self.record_state:
            check.choice(owner, "record_state", v, STATE_VARIABLES)
        object.__setattr__(self, "record_state", tuple(self.record_state))

    @property
    def count_window_ms(self) -> float:
        return self.duration_ms - self.count_from_ms

    def say(self, message: str):
        if self.log is not None:
            self.log(message)


class SparseCounts(Mapping):
    """A counting bin's spike counts kept as its spikes, for a backend whose bins
    hold a few thousand spikes among ~1e6 cells (the fast engine's): population ->
    each cell's spikes (int32) when read, and, without making those arrays,
    :meth:`into`, which adds the bin's spikes to an array of every cell of the
    run's numbering (``cells`` long; ``parts``: population -> the slice of it its
    cells take; ``steps``: the bin's time steps). A window's reader adds such
    bins spike by spike; other bins (plain dicts) it adds array by array."""

    cells: int
    parts: dict
    steps: int

    @abstractmethod
    def into(self, out: np.ndarray) -> None:
        """Add the bin's spikes to ``out``."""


@dataclass
class SimulationResult:
    """What one simulation produced, whichever backend ran it.

    Per LIF population (spike sources are not included): ``sites`` the
    instantiated cells (sorted flat indices into the population's
    ``(channels, rows, cols)`` shape; every cell for a backend that
    instantiates all), ``counts`` the spikes of each of those cells in the
    counting window, ``spikes`` (if recorded) every spike as
    ``(cell, t_ms)`` with ``cell`` indexing ``sites``, and ``state`` the
    requested final state variables (mV). With ``RunSettings.count_bins_ms``,
    ``binned_counts[name]`` is an int array ``(n_bins, n_cells)``: the spikes
    of each cell in each bin. ``stats`` holds what the backend
    knows about its own build (synapses per target population, kept kernel
    mass per projection, and ``backend_objects``: the simulator objects it made, name -> their synapses).
    """

    network: Network
    backend: str
    sites: dict
    counts: dict
    count_window_ms: float
    simulated_ms: float
    dt_ms: float
    spikes: Mapping | None = None  # a dict, or the fast engine's read-only SpikeTrains
    state: dict = field(default_factory=dict)
    binned_counts: dict | None = None
    count_bins_ms: tuple | None = None
    timings_s: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)

    @classmethod
    def of_run(cls, settings: RunSettings, **fields) -> SimulationResult:
        """The result of a run made with ``settings``: its counting window,
        duration, step and bins from them, the rest from ``fields``."""
        return cls(
            count_window_ms=settings.count_window_ms,
            simulated_ms=settings.duration_ms,
            dt_ms=settings.dt_ms,
            count_bins_ms=settings.count_bins_ms,
            **fields,
        )

    @property
    def populations(self) -> list[str]:
        """Names of the simulated (LIF) populations, in network order."""
        return [p.name for p in self.network.populations if p.name in self.counts]

    def of_role(self, role: str, level: int | None = None) -> list[str]:
        return [p.name for p in self.network.by_role(role, level) if p.name in self.counts]

    def rates(self, name: str) -> np.ndarray:
        """Firing rate (Hz) of each instantiated cell of ``name`` in the counting window."""
        return self.counts[name] / (self.count_window_ms / 1000.0)

    def grid(self, name: str, values: np.ndarray | None = None) -> np.ndarray:
        """Per-cell ``values`` (default: rates) on the population's whole
        ``(channels, rows, cols)`` grid, 0 where no cell was instantiated."""
        pop = self.network.population(name)
        out = np.zeros(pop.size)
        out[self.sites[name]] = self.rates(name) if values is None else values
        return out.reshape(pop.shape)

    @property
    def total_cells(self) -> int:
        return int(sum(s.size for s in self.sites.values()))


def spikes_between(spikes, a_ms: float, b_ms: float):
    """The spikes with ``a_ms <= t < b_ms`` of a result's ``spikes``
    (``name -> (cell, t_ms)``; ``None`` stays ``None``)."""
    if spikes is None:
        return None
    if hasattr(spikes, "between"):  # (trains that find a span without a pass over every spike)
        return spikes.between(a_ms, b_ms)
    out = {}
    for n, (c, t) in spikes.items():
        inside = (t >= a_ms) & (t < b_ms)
        out[n] = (c[inside], t[inside])
    return out


def each_bin(result: SimulationResult):
    """``(k, bin_result)`` for each counting bin a result kept
    (``binned_counts``): what a backend that streams its bins hands to
    ``RunSettings.on_bin`` as it goes."""
    edges = result.count_bins_ms
    for k in range(len(edges) - 1):
        yield (
            k,
            bin_result(
                result,
                {n: c[k] for n, c in result.binned_counts.items()},
                edges[k],
                edges[k + 1],
                spikes_between(result.spikes, edges[k], edges[k + 1]),
            ),
        )


def bin_result(template: SimulationResult, counts: dict, a_ms: float, b_ms: float, spikes) -> SimulationResult:
    """The result of one counting bin ``[a_ms, b_ms)``: ``template``'s
    network, cells and backend with the bin's counts and spikes."""
    return SimulationResult(
        network=template.network,
        backend=template.backend,
        sites=template.sites,
        counts=counts,
        count_window_ms=b_ms - a_ms,
        simulated_ms=template.simulated_ms,
        dt_ms=template.dt_ms,
        spikes=spikes,
        stats=template.stats,
    )


def source_masks(network: Network, on: np.ndarray, off: np.ndarray) -> dict:
    """Spike-source name -> bool mask of pixels with input, by role (the
    window clock needs none: :func:`~snn_fg.lowering.unroll.choose_sites`
    keeps its one cell)."""
    return {
        network.one("input_on", 1).name: np.asarray(on, bool),
        network.one("input_off", 1).name: np.asarray(off, bool),
    }


def input_masks(network: Network, inputs) -> dict:
    """The masks an unrolling backend gives :func:`~snn_fg.lowering.unroll.unroll`
    for ``inputs``: ``active``, :func:`source_masks` of its ``on`` and ``off``
    (the edge masks are made from them), and ``fired``, those of the sources
    that fire where the input knows them to be fewer (the ``fired`` of
    :class:`~snn_fg.lowering.input_spikes.InputSpikes`: a recording read whole;
    the cells are chosen for them), else None."""
    fired = getattr(inputs, "fired", None)
    return {
        "active": source_masks(network, inputs.on, inputs.off),
        "fired": None if fired is None else source_masks(network, *fired),
    }


def unrolled(network: Network, inputs, settings: RunSettings, weight_bits: int | None = None):
    """``(unrolled network, stats, timings)`` of a backend that makes explicit synapses (Brian2,
    NEST): the network unrolled for ``inputs`` with the run's sites and instantiation, its weights
    quantised to ``weight_bits`` where given, its synapses counted (``stats``: ``synapses_in``,
    ``kept_kernel_mass``) and timed (``timings["unroll"]``), its size said (``settings.say``)."""
    import time

    from ..lowering.quantise import quantise_unrolled
    from ..lowering.unroll import unroll

    t0 = time.perf_counter()
    settings.say("unrolling the network for this input")
    un = unroll(network, **input_masks(network, inputs), sites=settings.sites, instantiate=settings.instantiate)
    if weight_bits is not None:
        quantise_unrolled(un, weight_bits)
    stats = {"synapses_in": un.synapses_in(), "kept_kernel_mass": un.kept_mass()}
    timings = {"unroll": time.perf_counter() - t0}
    settings.say(
        f"network for this input: {sum(map(un.n_cells, un.sites)):,} cells, "
        f"{sum(stats['synapses_in'].values()):,} synapses (unrolled in {timings['unroll']:.1f} s)"
    )
    return un, stats, timings


def source_offsets(network: Network) -> dict:
    """Spike-source name -> first input index: inputs number the ON pixels
    ``0..H*W-1``, the OFF pixels ``H*W..2*H*W-1`` (row-major) and the
    window clock ``2*H*W`` (:data:`~snn_fg.lowering.input_spikes.InputSpikes.clock_index`)."""
    h, w = network.frame_shape
    out = {network.one("input_on", 1).name: 0, network.one("input_off", 1).name: h * w}
    out.update({p.name: 2 * h * w for p in network.by_role("clock")})
    return out


def lif_populations(network: Network) -> list[Population]:
    return [p for p in network.populations if not p.is_source]


def receptor(sign: int) -> str:
    """The current a projection of ``sign`` feeds: ``exc`` (``I_exc``) or ``inh``."""
    return "exc" if sign > 0 else "inh"


def receptor_weights(sign: int, w_mv: np.ndarray) -> np.ndarray:
    """What each synapse of a projection of ``sign`` adds to its current
    (mV), from its signed weights ``w_mv``: ``I_exc`` gets the signed weight
    (a kernel's negative lobes stay negative), ``I_inh`` its magnitude."""
    return w_mv if sign > 0 else np.abs(w_mv)


def segments(settings: RunSettings) -> list[tuple[int, bool]]:
    """``(end_step, snapshot)`` of each run segment: a simulation stops at
    every counting-bin edge (to read its spike counters) and at the end."""

    edges = np.rint(np.asarray(settings.count_bins_ms or (), dtype=np.float64) / settings.dt_ms).astype(np.int64)
    ends = np.union1d(edges, [round(settings.duration_ms / settings.dt_ms)])
    return list(zip(ends.tolist(), np.isin(ends, edges).tolist()))


def importable(*modules: str, install: str) -> tuple[bool, str]:
    """A backend's :meth:`Backend.available`: ``(True, "")`` when every one
    of ``modules`` can be imported, else ``(False, install)``."""
    from importlib.util import find_spec

    return (True, "") if all(find_spec(m) is not None for m in modules) else (False, install)


class Backend(ABC):
    """A simulator that runs a network description on input spikes.

    Subclasses set ``name`` (the registry key), ``requires`` (what to install
    if it is missing, one line) and implement :meth:`simulate`; options are
    keyword arguments of their constructor, refused when unknown.
    """

    name: ClassVar[str] = ""
    requires: ClassVar[str] = ""
    #: whether the inputs reaching one cell in one step are summed in an order
    #: that does not depend on how many other cells exist; where it does
    #: (NEST), float rounding can move a spike at the threshold's edge
    fixed_summation_order: ClassVar[bool] = True
    #: ``RunSettings.instantiate`` when the caller leaves it to the backend
    #: (the spiking API asks for ``input`` on an event frame's regular trains,
    #: whatever this says): ``input`` where cells cost per synapse (unrolled),
    #: ``all`` where choosing them per input would cost more than they do
    default_instantiate: ClassVar[str] = "input"
    #: whether :meth:`simulate` takes a recording's input a segment at a time
    #: (a :class:`~snn_fg.lowering.input_stream.SegmentedInput`); otherwise
    #: it is handed the whole run's :class:`~snn_fg.lowering.input_spikes.InputSpikes`
    streams_input: ClassVar[bool] = False

    @classmethod
    def available(cls) -> tuple[bool, str]:
        """Whether the backend can run here, and if not, what to install."""
        return True, ""

    @abstractmethod
    def simulate(self, network: Network, inputs, settings: RunSettings) -> SimulationResult:
        """Simulate ``network`` fed by ``inputs`` (InputSpikes, or a
        SegmentedInput where :attr:`streams_input`) as ``settings`` say."""

    def describe(self) -> dict:
        """What to record about this backend in a run's parameters."""
        return {"name": self.name}
