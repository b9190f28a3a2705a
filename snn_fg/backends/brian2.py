"""The Brian2 backend: the network unrolled for one input and simulated in Brian2.

All LIF cells of all populations live in one ``NeuronGroup`` (``lif``,
per-cell constants), all input pixels in one ``SpikeGeneratorGroup``
(``inp``), and the synapses in a handful of ``Synapses`` objects, one per
(source group, receptor, delay). Few objects with fixed names mean few
generated code objects, which Cython compiles once per machine and then
reuses from its cache (``~/.cython/brian_extensions``) for every network and
input.

A projection's ``sign`` picks the receptor (+1 ``I_exc``, -1 ``I_inh``); the
kernel's own signs are kept, so a kernel with negative lobes keeps its
balance under one time constant.
"""

from __future__ import annotations

import contextlib
import logging
import time

import numpy as np

from .. import validate as check
from ..lowering.unroll import Unrolled
from ..network.graph import Network
from . import cancel
from .base import (
    Backend,
    RunSettings,
    SimulationResult,
    importable,
    lif_populations,
    receptor,
    receptor_weights,
    segments,
    source_offsets,
    unrolled,
)

#: CUBA LIF state, advanced once per step by :data:`_STEP` with the exact
#: per-cell propagators of :meth:`~snn_fg.network.nodes.Neuron.propagators`,
#: computed once (Brian2's exponential Euler would evaluate three
#: exponentials per cell and step, and integrate the currents' charge only
#: approximately).
_EQS = """
v : volt
I_exc : volt
I_inh : volt
d_m : 1 (constant)
d_exc : 1 (constant)
d_inh : 1 (constant)
p_exc : 1 (constant)
p_inh : 1 (constant)
v_rest : volt (constant)
v_reset : volt (constant)
v_th : volt (constant)
t_ref : second (constant)
n_spikes : integer
n_all : integer
"""
#: v is clamped while refractory; the currents keep decaying.
_STEP = """
v = v + int(not_refractory) * ((1 - d_m) * (v_rest - v) + p_exc * I_exc - p_inh * I_inh)
I_exc = I_exc * d_exc
I_inh = I_inh * d_inh
"""
CODEGEN = ("auto", "cython", "numpy")


@contextlib.contextmanager
def _brian2_session(codegen: str):
    """Brian2 preferences and log level for one run, restored afterwards."""
    # (brian2 is imported where it is used: seconds to import, and only runs on this backend need it)
    from brian2 import prefs

    logger = logging.getLogger("brian2")
    saved = (
        prefs.codegen.target,
        prefs.codegen.runtime.cython.multiprocess_safe,
        prefs.core.stop_on_keyboard_interrupt,
        logger.level,
    )
    target = codegen
    if target == "auto":
        try:
            from brian2.codegen.runtime.cython_rt import CythonCodeObject

            target = "cython" if CythonCodeObject.is_available() else "numpy"
        except Exception:  # no Cython or no compiler
            target = "numpy"
    try:
        prefs.codegen.target = target
        prefs.codegen.runtime.cython.multiprocess_safe = True
        # Ctrl-C must interrupt the run, not end it early with partial counts
        prefs.core.stop_on_keyboard_interrupt = False
        logger.setLevel(logging.WARNING)
        yield target
    finally:
        (
            prefs.codegen.target,
            prefs.codegen.runtime.cython.multiprocess_safe,
            prefs.core.stop_on_keyboard_interrupt,
        ) = saved[:3]
        logger.setLevel(saved[3])
        # A run left by an exception (Ctrl-C) leaves Brian2's class-wide
        # "running" flag set; its SIGINT handler (installed at import) would
        # then turn every later Ctrl-C in this process into a silent "stop"
        # request, so that other code (e.g. the fast backend) can never be
        # interrupted. No Brian2 run is in progress once we are here.
        from brian2.core.network import Network as _Brian2Network

        _Brian2Network._globally_running = False


class Brian2Backend(Backend):
    """Brian2 (runtime mode, Cython code generation when a compiler is present).

    Parameters
    ----------
    codegen : {"auto", "cython", "numpy"}
        Brian2's code generation target; ``auto`` uses Cython when it works.
    free : bool
        Drop each projection's unrolled arrays once Brian2 holds its copy
        (keeps peak memory down at full scale).
    """

    name = "brian2"
    requires = "brian2 (a core dependency: reinstall snn-fg)"

    def __init__(self, *, codegen: str = "auto", free: bool = True):
        self.codegen = check.choice("Brian2Backend", "codegen", codegen, CODEGEN)
        self.free = bool(free)
        self.used_codegen = None

    @classmethod
    def available(cls):
        return importable("brian2", install="pip install brian2")

    def describe(self) -> dict:
        return {"name": self.name, "codegen": self.used_codegen or self.codegen}

    def simulate(self, network: Network, inputs, settings: RunSettings) -> SimulationResult:
        t0 = time.perf_counter()
        un, stats, timings = unrolled(network, inputs, settings)
        with _brian2_session(self.codegen) as target:
            self.used_codegen = target
            counts, spikes, state, binned, objects = self._run(un, inputs, settings, timings)
        stats["backend_objects"] = objects  # (its Synapses objects: name -> synapses)
        timings["total"] = time.perf_counter() - t0
        sites = {p.name: un.sites[p.name] for p in lif_populations(network)}
        return SimulationResult.of_run(
            settings,
            network=network,
            backend=self.name,
            sites=sites,
            counts=counts,
            spikes=spikes,
            state=state,
            timings_s=timings,
            stats=stats,
            binned_counts=binned,
        )

    def _run(self, un: Unrolled, inputs, settings: RunSettings, timings: dict):
        import brian2 as b2
        from brian2 import ms, mV

        net = un.network
        pops = lif_populations(net)
        offsets, n_lif = {}, 0
        for p in pops:
            offsets[p.name] = n_lif
            n_lif += un.n_cells(p.name)
        offsets.update(source_offsets(net))
        pop_of = np.repeat(np.arange(len(pops)), [un.n_cells(p.name) for p in pops])
        dt = settings.dt_ms * ms
        lif = _neuron_group(pops, pop_of, n_lif, settings)
        gen = b2.SpikeGeneratorGroup(
            inputs.n_sources,
            inputs.indices.astype(np.int64),
            inputs.steps * dt,
            period=(inputs.period_steps * dt if inputs.period_steps else 0 * ms),
            dt=dt,
            name="inp",
            sorted=False,
        )
        t_build = time.perf_counter()
        synapses, n_syn = self._synapses(un, offsets, lif, gen, dt, settings)
        timings["build"] = time.perf_counter() - t_build
        objects = [lif, gen, *synapses]
        monitor = None
        if settings.record_spikes and n_lif:
            monitor = b2.SpikeMonitor(lif, name="spikes")
            objects.append(monitor)
        network = b2.Network(*objects)
        settings.say(
            "compiling and simulating (Brian2 compiles its code once per machine: the first run "
            "takes a minute or two longer)"
        )
        t_run = time.perf_counter()
        snapshots = _simulate(network, lif, n_lif, settings)
        timings["run"] = time.perf_counter() - t_run
        all_counts = np.asarray(lif.n_spikes[:], dtype=np.int64)[:n_lif]
        counts = {p.name: all_counts[offsets[p.name] : offsets[p.name] + un.n_cells(p.name)] for p in pops}
        spikes = None
        if monitor is not None:
            cell = np.asarray(monitor.i[:], dtype=np.int64)
            t_ms = np.asarray(monitor.t[:] / ms, dtype=np.float64)
            which = pop_of[cell] if cell.size else cell
            spikes = {p.name: (cell[which == k] - offsets[p.name], t_ms[which == k]) for k, p in enumerate(pops)}
        binned = None
        if snapshots:
            per_bin = np.diff(np.stack(snapshots), axis=0)
            binned = {p.name: per_bin[:, offsets[p.name] : offsets[p.name] + un.n_cells(p.name)] for p in pops}
        state = {}
        for var in settings.record_state:
            values = np.asarray(getattr(lif, var)[:] / mV, dtype=np.float64)[:n_lif]
            for p in pops:
                state.setdefault(p.name, {})[var] = values[offsets[p.name] : offsets[p.name] + un.n_cells(p.name)]
        return counts, spikes, state, binned, n_syn

    def _synapses(self, un: Unrolled, offsets, lif, gen, dt, settings):
        """One ``Synapses`` object per (source group, receptor, delay)."""
        import brian2 as b2
        from brian2 import ms, mV

        groups: dict = {}
        for conn in un.connections:
            if conn.n == 0:
                continue
            pr = conn.projection
            src_group = "inp" if un.network.population(pr.source).is_source else "lif"
            key = (src_group, receptor(pr.sign), round(pr.delay_ms, 6))
            groups.setdefault(key, []).append(conn)
        objects, n_syn = [], {}
        for (src_group, current, delay), conns in sorted(groups.items()):
            name = f"syn_{src_group}_{current}_{str(delay).replace('.', 'p')}ms"
            pre = np.concatenate([c.pre.astype(np.int32) + np.int32(offsets[c.projection.source]) for c in conns])
            post = np.concatenate([c.post.astype(np.int32) + np.int32(offsets[c.projection.target]) for c in conns])
            w = np.concatenate([receptor_weights(c.projection.sign, c.w) for c in conns])
            if self.free:
                for c in conns:
                    c.free()
            syn = b2.Synapses(
                gen if src_group == "inp" else lif,
                lif,
                "w : volt",
                on_pre=f"I_{current}_post += w",
                delay=delay * ms,
                dt=dt,
                name=name,
            )
            syn.connect(i=pre, j=post)
            syn.w = w * mV
            n_syn[name] = int(pre.size)
            objects.append(syn)
        return objects, n_syn


@contextlib.contextmanager
def _progress_bar(settings: RunSettings):
    """A factory of Brian2 ``report`` callbacks, one per run segment (steps
    ``start..end``), driving one progress bar (:mod:`snn_fg.results.progress`) in simulated ms (or giving None).

    The bar appears with Brian2's first report, once the code is compiled and
    the simulation runs, so it never sits at 0 % during the compilation."""
    if not settings.progress:
        yield lambda start, end: None
        return
    from ..results.progress import bar

    state = {"bar": None, "ms": 0}

    def segment(start, end):
        def report(elapsed, completed, t_start, duration):  # noqa: ARG001 - Brian2's signature
            if state["bar"] is None:
                state["bar"] = bar("simulating", "ms", round(settings.duration_ms))
            now = int(round((start + float(completed) * (end - start)) * settings.dt_ms))
            state["bar"].update(now - state["ms"])
            state["ms"] = now

        return report

    try:
        yield segment
    finally:
        if state["bar"] is not None:
            state["bar"].close()


def _neuron_group(pops, pop_of, n_lif: int, settings: RunSettings):
    """Every LIF cell of ``pops`` in one ``NeuronGroup`` (``pop_of``: each
    cell's population), with its population's constants and propagators."""
    import brian2 as b2
    from brian2 import ms, mV

    def per_cell(attr):
        return np.array([getattr(p.neuron, attr) for p in pops], dtype=np.float64)[pop_of]

    lif = b2.NeuronGroup(
        max(n_lif, 1),
        _EQS,
        threshold="v > v_th",
        reset="v = v_reset\nn_spikes += int(t >= t_count)\nn_all += 1",
        refractory="t_ref",
        dt=settings.dt_ms * ms,
        name="lif",
        namespace={"t_count": settings.count_from_ms * ms},
    )
    lif.run_regularly(_STEP, when="groups", name="lif_step")
    if n_lif:
        factors = [p.neuron.propagators(settings.dt_ms) for p in pops]
        for var in ("d_m", "d_exc", "d_inh", "p_exc", "p_inh"):
            setattr(lif, var, np.array([f[var] for f in factors], dtype=np.float64)[pop_of])
        lif.v_rest = per_cell("v_rest_mv") * mV
        lif.v_reset = per_cell("v_reset_mv") * mV
        lif.v_th = per_cell("v_th_mv") * mV
        lif.t_ref = per_cell("t_ref_ms") * ms
        lif.v = per_cell("v_rest_mv") * mV
    return lif


def _simulate(network, lif, n_lif: int, settings: RunSettings) -> list:
    """Run ``network`` segment by segment (:func:`~snn_fg.backends.base.segments`),
    with the progress bar and Ctrl-C checked in between; returns every
    cell's spike count at each counting-bin edge."""
    import brian2 as b2
    from brian2 import ms

    dt = settings.dt_ms * ms
    snapshots = []
    with _progress_bar(settings) as bar:
        done = 0
        for end, snapshot in segments(settings):
            if end > done:
                network.run((end - done) * dt, report=bar(done, end), report_period=2 * b2.second, namespace={})
                if int(round(float(network.t / dt))) < end:
                    raise KeyboardInterrupt(f"the simulation stopped at {float(network.t / ms):g} ms")
                cancel.check()
            done = end
            if snapshot:
                snapshots.append(np.asarray(lif.n_all[:], dtype=np.int64)[:n_lif])
    return snapshots
