"""The NEST backend: the network unrolled for one input, built with PyNN
(``pyNN.nest``) and simulated by NEST.

The same cells and synapses as the Brian2 backend (:mod:`snn_fg.lowering.unroll`),
built by :class:`snn_fg.pynn.network.PyNNNetwork`, the code every PyNN
export runs: ``IF_curr_exp`` cells with ``cm = tau_m`` (so nA = our mV),
synapses split between the two receptors by the sign of their drive
(charge-preserving), delays on the time grid (at least one step), NEST's
exact integration of the CUBA LIF. It is the independent re-simulation that
checks the exports: same description, another simulator.

The split is the one approximation between this network and Brian2's: a
DoG or bicubic kernel's negative lobes reach the cell through the other
receptor's time constant. ``receptors="signed"`` leaves it out (each
projection on its own receptor of ``iaf_psc_exp_multisynapse``, signed
weights) and gives Brian2's spike counts on the synthetic discs; it is not
what a board runs.

Install with ``pip install -e ".[nest]"`` (PyNN and the ``nest-simulator``
wheel). ``threads`` sets NEST's ``local_num_threads``, raised where the
network has more cells than NEST can address on one thread (524,223 per
thread: :func:`~snn_fg.pynn.network.nest_threads`); the wheel has no MPI.
"""

from __future__ import annotations

import contextlib
import time

import numpy as np

from .. import validate as check
from ..errors import install_hint
from ..lowering.unroll import Unrolled
from ..network.graph import Network
from ..pynn.network import NEST_MAX_LOCAL_SENDERS, PyNNNetwork
from ..pynn.simulator import import_simulator
from ..results.progress import bar as progress_bar
from . import cancel
from .base import Backend, RunSettings, SimulationResult, importable, lif_populations, source_offsets, unrolled

#: simulated milliseconds between two returns to Python (progress, Ctrl-C)
CHUNK_MS = 25.0
#: spike trains are recorded up to this many cells (NEST: 32 KB per recorded cell)
SPIKE_RECORD_MAX_CELLS = 30_000


class NestBackend(Backend):
    """NEST 3 through PyNN 0.13.

    Parameters
    ----------
    threads : int
        NEST threads (``local_num_threads``); at least as many as the
        network's cells need (NEST addresses 2**19 - 1 spike-sending cells
        per thread and silently mixes up the rest). The threads used are in
        the result's ``stats["nest_threads"]``.
    portable : bool
        Connect and record through PyNN's own ``FromListConnector`` and
        ``record`` instead of NEST's array calls (slow; the path a
        non-NEST PyNN simulator takes).
    receptors : {"split", "signed"}
        ``split`` (default): what every PyNN export runs, ``IF_curr_exp``
        cells whose two receptors each take one sign, so a kernel's lobes of
        the other sign move to the other receptor with the same charge
        (:func:`~snn_fg.pynn.network.split_receptors`); ``signed``: the
        description exactly (NEST's ``iaf_psc_exp_multisynapse``, signed
        weights on each projection's own receptor), Brian2's network in
        another simulator. Not with ``portable``.
    weight_bits : int, optional
        Quantise every projection's weights to signed integers of this many
        bits with one scale factor per projection
        (:func:`snn_fg.lowering.quantise.projection_scales`).
    """

    fixed_summation_order = False
    name = "nest"
    requires = install_hint("nest")

    def __init__(
        self, *, threads: int = 1, portable: bool = False, receptors: str = "split", weight_bits: int | None = None
    ):
        self.threads = check.integer("NestBackend", "threads", threads, lo=1)
        self.portable = bool(portable)
        self.receptors = check.choice("NestBackend", "receptors", receptors, ("split", "signed"))
        if self.portable and self.receptors == "signed":
            check.fail("NestBackend", "receptors", receptors, "needs NEST's own calls: not with portable=True")
        self.weight_bits = (
            None if weight_bits is None else check.integer("NestBackend", "weight_bits", weight_bits, lo=2, hi=32)
        )

    @classmethod
    def available(cls):
        return importable("pyNN", "nest", install=cls.requires)

    def describe(self) -> dict:
        return {
            "name": self.name,
            "threads": self.threads,
            "portable": self.portable,
            "receptors": self.receptors,
            "weight_bits": self.weight_bits,
        }

    def simulate(self, network: Network, inputs, settings: RunSettings) -> SimulationResult:
        t0 = time.perf_counter()
        un, stats, timings = unrolled(network, inputs, settings, self.weight_bits)
        sim = import_simulator("nest")  # (quietly, as an export's run.py)
        net = _build(sim, un, inputs, settings, self, timings)
        try:
            settings.say("simulating in NEST")
            with _progress(settings) as report:

                def each_chunk(done_ms):
                    if report is not None:
                        report(done_ms)
                    cancel.check()

                timings["run"] = net.run(settings.duration_ms, CHUNK_MS, each_chunk)
            counts, spikes, binned, state = _collect(net, un, settings)
            stats["nest_synapses"] = dict(net.n_synapses)
            stats["nest_threads"] = net.threads
        finally:
            net.end()
        timings["total"] = time.perf_counter() - t0
        sites = {p.name: un.sites[p.name] for p in lif_populations(network)}
        return SimulationResult.of_run(
            settings,
            network=network,
            backend=self.name,
            sites=sites,
            counts=counts,
            spikes=spikes if settings.record_spikes else None,
            state=state,
            binned_counts=binned,
            timings_s=timings,
            stats=stats,
        )


def _build(sim, un: Unrolled, inputs, settings: RunSettings, backend: NestBackend, timings: dict):
    t0 = time.perf_counter()
    net_d = un.network
    max_delay = max([c.projection.delay_ms for c in un.connections] + [settings.dt_ms])
    pixels = _source_pixels(un)
    cells = lif_populations(net_d)
    n_cells = sum(un.n_cells(p.name) for p in cells)
    net = PyNNNetwork(
        sim,
        dt_ms=settings.dt_ms,
        max_delay_ms=max_delay,
        threads=backend.threads,
        portable=backend.portable,
        signed_receptors=backend.receptors == "signed",
        n_cells=n_cells,
        n_sources=sum(px.size for px in pixels.values()),
    )
    if net.threads > backend.threads:
        settings.say(
            f"NEST on {net.threads} threads, not {backend.threads}: it addresses at most "
            f"{NEST_MAX_LOCAL_SENDERS:,} spike-sending cells per thread and this network has {n_cells:,}"
        )
    for p in cells:
        net.add_cells(p.name, un.n_cells(p.name), p.neuron.to_dict())
    used = _add_sources(net, un, inputs, settings, pixels)
    for conn in un.connections:
        if conn.n == 0:
            continue
        pr = conn.projection
        pre = used[pr.source][conn.pre] if pr.source in used else conn.pre
        net.connect(pr.source, pr.target, pre, conn.post, conn.w, sign=pr.sign, delay_ms=pr.delay_ms)
        conn.free()
    names = [p.name for p in cells]
    spikes = settings.record_spikes and n_cells <= SPIKE_RECORD_MAX_CELLS
    if settings.record_spikes and not spikes:
        settings.say(f"spike trains not recorded ({n_cells:,} cells; NEST keeps 32 KB per recorded cell): counts only")
    edges = {settings.count_from_ms, settings.duration_ms} | set(settings.count_bins_ms or ())
    net.record(names, spikes=spikes, count_edges_ms=edges)
    net.record_state(names, settings.record_state, settings.duration_ms)
    timings["build"] = time.perf_counter() - t0
    return net


def _source_pixels(un: Unrolled) -> dict:
    """Per spike-source population, the pixels with outgoing synapses (sorted)."""
    return {
        name: np.unique(
            np.concatenate(
                [c.pre for c in un.connections if c.projection.source == name] + [np.zeros(0, np.int32)]
            ).astype(np.int64)
        )
        for name in source_offsets(un.network)
    }


def _add_sources(net, un: Unrolled, inputs, settings: RunSettings, pixels: dict) -> dict:
    """One spike source per pixel of ``pixels`` (:func:`_source_pixels`);
    returns, per source population, the map from pixel to source index."""
    n_steps = int(round(settings.duration_ms / settings.dt_ms))
    idx, steps = inputs.spike_times_steps(n_steps)
    order = np.argsort(idx, kind="stable")
    idx, steps = idx[order], steps[order]
    used = {}
    for name, offset in source_offsets(un.network).items():
        px = pixels[name]
        lo = np.searchsorted(idx, offset + px, "left")
        hi = np.searchsorted(idx, offset + px, "right")
        net.add_sources(name, [steps[a:b] for a, b in zip(lo, hi)])
        remap = np.full(un.network.population(name).size, -1, np.int64)
        remap[px] = np.arange(px.size)
        used[name] = remap
    return used


def _collect(net, un: Unrolled, settings: RunSettings):
    counts, spikes, binned, state = {}, {}, None, {}
    edges = settings.count_bins_ms
    if edges:
        binned = {}
    recorded = bool(net.recorders) or not net.native
    for p in lif_populations(un.network):
        n = un.n_cells(p.name)
        counts[p.name] = net.counts(p.name, n, settings.count_from_ms, settings.duration_ms)
        if recorded:
            spikes[p.name] = net.spikes(p.name, n)
        if edges:
            binned[p.name] = np.stack([net.counts(p.name, n, a, b) for a, b in zip(edges, edges[1:])])
        if settings.record_state:
            state[p.name] = {v: net.state(p.name, n, v) for v in settings.record_state}
    return counts, spikes if recorded else None, binned, state


@contextlib.contextmanager
def _progress(settings: RunSettings):
    """A callback ``report(done_ms)`` driving a progress bar (:mod:`snn_fg.results.progress`; or None)."""
    if not settings.progress:
        yield None
        return

    bar = progress_bar("simulating (NEST)", "ms", round(settings.duration_ms))
    seen = {"ms": 0}

    def report(done_ms):
        now = int(round(done_ms))
        bar.update(now - seen["ms"])
        seen["ms"] = now

    try:
        yield report
    finally:
        bar.close()
