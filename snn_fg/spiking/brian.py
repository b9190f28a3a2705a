"""Brian2 simulation of an unrolled network.

All LIF cells of all populations live in one ``NeuronGroup`` (named ``lif``,
per-cell constants), all input pixels in one ``SpikeGeneratorGroup``
(``inp``), and the synapses in a handful of ``Synapses`` objects, one per
(source group, receptor, delay). Few objects with fixed names means few
generated code objects, so Cython compiles them once and then reuses its
cache (``~/.cython/brian_extensions``) across runs and inputs.

A projection's ``sign`` picks the receptor: +1 adds to ``I_exc``, -1 to
``I_inh``; the kernel's own signs are kept (the DoG and bicubic kernels have
negative lobes, which a current-based synapse represents directly), so a
kernel's positive and negative parts share one time constant and its
balance is preserved.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import ParameterError
from .inputs import InputSpikes
from .unroll import Unrolled

#: CUBA LIF state, advanced once per step by :data:`_STEP` with per-cell decay
#: factors ``d = exp(-dt / tau)`` computed once (Brian2's exponential Euler
#: would evaluate three exponentials per cell and step; the update is the same:
#: each variable decays exactly over the step, ``v`` towards
#: ``v_rest + I_exc - I_inh`` with the currents of the step's start).
_EQS = """
v : volt
I_exc : volt
I_inh : volt
d_m : 1 (constant)
d_exc : 1 (constant)
d_inh : 1 (constant)
v_rest : volt (constant)
v_reset : volt (constant)
v_th : volt (constant)
t_ref : second (constant)
n_spikes : integer
"""
#: v is clamped while refractory (Brian2's ``unless refractory``); the
#: currents keep decaying.
_STEP = """
v = v + int(not_refractory) * (1 - d_m) * (v_rest - v + I_exc - I_inh)
I_exc = I_exc * d_exc
I_inh = I_inh * d_inh
"""


@dataclass
class Layout:
    """Where each population's cells sit in the Brian2 groups."""

    offsets: dict            # population -> first index in 'lif' (LIF) or 'inp' (sources)
    sizes: dict
    n_lif: int
    n_inp: int
    pop_of_lif: np.ndarray = field(repr=False)   # population index of each lif cell
    names: list = field(default_factory=list)    # LIF population names, in order


def layout(un: Unrolled, inp: InputSpikes) -> Layout:
    offsets, sizes, names = {}, {}, []
    n = 0
    h, w = un.network.frame_shape
    for p in un.network.populations:
        k = un.n_cells(p.name)
        sizes[p.name] = k
        if p.neuron is None:
            offsets[p.name] = 0 if p.role == "input_on" else h * w
            continue
        offsets[p.name] = n
        names.append(p.name)
        n += k
    pop_of = np.zeros(n, np.int32)
    for i, name in enumerate(names):
        pop_of[offsets[name]:offsets[name] + sizes[name]] = i
    return Layout(offsets, sizes, n, 2 * h * w, pop_of, names)


def choose_codegen(target: str = "auto") -> str:
    """Set Brian2's code generation target; returns the one in use.

    ``auto`` lets Brian2 try Cython (a test compile) and fall back to numpy;
    ``cython`` / ``numpy`` force one.
    """
    from brian2 import prefs
    if target not in ("auto", "cython", "numpy"):
        raise ParameterError(f"codegen={target!r}: must be 'auto', 'cython' or 'numpy'")
    if target == "auto":
        try:
            from brian2.codegen.runtime.cython_rt import CythonCodeObject
            target = "cython" if CythonCodeObject.is_available() else "numpy"
        except Exception:   # no Cython / no compiler
            target = "numpy"
    prefs.codegen.target = target
    return target


@dataclass
class SimResult:
    """Spike counts (and optionally spike trains) of one simulation."""

    counts: np.ndarray                 # spikes per LIF cell in [count_from, duration)
    count_window_ms: float
    layout: Layout
    spike_i: np.ndarray | None          # all LIF spikes (index, time ms) if recorded
    spike_t: np.ndarray | None
    timings: dict
    codegen: str
    n_synapses: dict                   # Brian2 object name -> synapses
    final_state: dict = field(default_factory=dict)   # variable -> per-cell value at the end (mV)


def simulate(un: Unrolled, inp: InputSpikes, duration_ms: float, dt_ms: float, count_from_ms: float,
             codegen: str = "auto", record_spikes: bool = True, progress: bool = True,
             free: bool = True, log=None, final_state=()) -> SimResult:
    """Build the Brian2 network for ``un`` fed by ``inp`` and run it.

    ``free`` drops each projection's unrolled arrays once Brian2 holds them
    (keeps peak memory down at full scale). ``final_state`` names LIF
    variables (``v``, ``I_exc``, ``I_inh``) whose values at the end are
    returned in millivolts.
    """
    import brian2 as b2
    from brian2 import ms, mV

    logging.getLogger("brian2").setLevel(logging.WARNING)
    timings = {}
    t0 = time.perf_counter()
    target = choose_codegen(codegen)
    b2.prefs.codegen.runtime.cython.multiprocess_safe = True
    lay = layout(un, inp)
    dt = dt_ms * ms
    pops = [un.network.population(n) for n in lay.names]

    def per_cell(attr):
        vals = np.array([getattr(p.neuron, attr) for p in pops], dtype=np.float64)
        return vals[lay.pop_of_lif]

    lif = b2.NeuronGroup(max(lay.n_lif, 1), _EQS, threshold="v > v_th", reset="v = v_reset\n"
                         "n_spikes += int(t >= t_count)", refractory="t_ref",
                         dt=dt, name="lif", namespace={"t_count": count_from_ms * ms})
    # the state update runs where Brian2 puts its own: before thresholds and synapses
    lif.run_regularly(_STEP, when="groups", name="lif_step")
    if lay.n_lif:
        lif.d_m = np.exp(-dt_ms / per_cell("tau_m_ms"))
        lif.d_exc = np.exp(-dt_ms / per_cell("tau_exc_ms"))
        lif.d_inh = np.exp(-dt_ms / per_cell("tau_inh_ms"))
        lif.v_rest = per_cell("v_rest_mv") * mV
        lif.v_reset = per_cell("v_reset_mv") * mV
        lif.v_th = per_cell("v_th_mv") * mV
        lif.t_ref = per_cell("t_ref_ms") * ms
        lif.v = per_cell("v_rest_mv") * mV
    gen = b2.SpikeGeneratorGroup(lay.n_inp, inp.indices.astype(np.int64), inp.steps * dt,
                                 period=(inp.period_steps * dt if inp.period_steps else 0 * ms),
                                 dt=dt, name="inp", sorted=False)
    objects = [lif, gen]
    # group synapses by (source group, receptor, delay)
    groups: dict = {}
    pop_by = {p.name: p for p in un.network.populations}
    for conn in un.connections:
        pr = conn.projection
        if conn.n == 0:
            continue
        src = pop_by[pr.source]
        key = ("inp" if src.neuron is None else "lif", "exc" if pr.sign > 0 else "inh", round(pr.delay_ms, 6))
        groups.setdefault(key, []).append(conn)
    n_syn = {}
    t_build = time.perf_counter()
    for (src_name, rec, delay), conns in sorted(groups.items()):
        name = f"syn_{src_name}_{rec}_{str(delay).replace('.', 'p')}ms"
        pre = np.concatenate([c.pre.astype(np.int32) + np.int32(lay.offsets[c.projection.source]) for c in conns])
        post = np.concatenate([c.post.astype(np.int32) + np.int32(lay.offsets[c.projection.target]) for c in conns])
        w = np.concatenate([np.abs(c.w) if rec == "inh" else c.w for c in conns])
        if free:
            for c in conns:
                c.free()
        syn = b2.Synapses(gen if src_name == "inp" else lif, lif, "w : volt",
                          on_pre=f"I_{rec}_post += w", delay=delay * ms, dt=dt, name=name)
        syn.connect(i=pre, j=post)
        syn.w = w * mV
        n_syn[name] = int(pre.size)
        del pre, post, w
        objects.append(syn)
        if log:
            log(f"  {name}: {n_syn[name]:,} synapses")
    timings["build_s"] = time.perf_counter() - t_build
    mon = None
    if record_spikes and lay.n_lif:
        mon = b2.SpikeMonitor(lif, name="spikes")
        objects.append(mon)
    net = b2.Network(*objects)
    report = None
    bar = None
    if progress:
        try:
            from tqdm import tqdm
            bar = tqdm(total=round(duration_ms), unit="ms", desc="spiking network", leave=False)
            state = {"last": 0}

            def report(elapsed, completed, start, duration):    # noqa: ARG001 - Brian2's signature
                now = int(round(float(completed) * duration_ms))
                bar.update(now - state["last"])
                state["last"] = now
        except ImportError:
            report = "text"
    t_run = time.perf_counter()
    try:
        net.run(duration_ms * ms, report=report, report_period=2 * b2.second, namespace={})
    finally:
        if bar is not None:
            bar.close()
    timings["run_s"] = time.perf_counter() - t_run
    counts = np.asarray(lif.n_spikes[:], dtype=np.int64)[:lay.n_lif] if lay.n_lif else np.zeros(0, np.int64)
    si = st = None
    if mon is not None:
        si = np.asarray(mon.i[:], dtype=np.int64)
        st = np.asarray(mon.t[:] / ms, dtype=np.float64)
    state = {name: np.asarray(getattr(lif, name)[:] / mV, dtype=np.float64)[:lay.n_lif] for name in final_state}
    timings["total_s"] = time.perf_counter() - t0
    return SimResult(counts, duration_ms - count_from_ms, lay, si, st, timings, target, n_syn, state)
