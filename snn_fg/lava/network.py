"""The exported network as Lava processes, and the run configuration.

STANDALONE: numpy, scipy and Lava (``lava-nc`` 0.10, Python 3.10) only;
copied into every Lava export as ``fg_lava.py``. What each process computes
is in ``fg_loihi.py`` (:mod:`snn_fg.lava.fixed`).

* every population of cells is one :class:`CountingLIF`: Lava's ``LIF``
  with its registers, a refractory period and a spike counter. Its process
  models are Lava's own LIF models (``PyLifModelBitAcc`` in fixed point,
  ``PyLifModelFloat`` in floating point) with two additions: a cell that
  spiked keeps its voltage for ``refractory_steps`` steps, as Lava's
  floating-point ``LIFRefractory`` does (Lava 0.10 has no fixed-point one),
  and each cell's spikes are counted from step ``count_from`` on, so that
  a run needs no recording process per population;
* every projection is one Lava ``DelaySparse`` (its weights ``2 m``, its
  weight exponent, 8 bits, its delay on every synapse), run by Lava's own
  models except that the weights stacked by delay are kept from one step to
  the next (:class:`_StackedOnce`);
* the input's and the window clock's spike sources are Lava ``RingBuffer`` s.
"""

from __future__ import annotations

import numpy as np
from lava.magma.core.decorator import implements, requires, tag
from lava.magma.core.model.py.type import LavaPyType
from lava.magma.core.process.variable import Var
from lava.magma.core.resources import CPU
from lava.magma.core.run_configs import Loihi2SimCfg
from lava.magma.core.sync.protocols.loihi_protocol import LoihiProtocol
from lava.proc.io.source import RingBuffer
from lava.proc.lif.models import PyLifModelBitAcc, PyLifModelFloat
from lava.proc.lif.process import LIF
from lava.proc.sparse.models import PyDelaySparseModelBitAcc, PyDelaySparseModelFloat
from lava.proc.sparse.process import DelaySparse
from scipy.sparse import csr_matrix

try:  # inside snn_fg (the tests import it there)
    from . import fixed
except ImportError:  # inside an export folder
    import fg_loihi as fixed

#: run.py's --arithmetic -> Lava's select_tag
TAGS = {"fixed": "fixed_pt", "float": "floating_pt"}


class CountingLIF(LIF):
    """Lava's LIF with a refractory period of ``refractory_steps`` steps and
    a count of each cell's spikes at Lava steps ``>= count_from`` (``counts``)."""

    def __init__(self, *, shape, refractory_steps: int = 0, count_from: int = 1, **kwargs):
        super().__init__(shape=shape, refractory_steps=int(refractory_steps), count_from=int(count_from), **kwargs)
        self.counts = Var(shape=shape, init=0)
        self.refractory_end = Var(shape=shape, init=0)


class _RefractoryCounting:
    """What :class:`CountingLIF`'s models add to Lava's LIF models."""

    def __init__(self, proc_params):
        super().__init__(proc_params)
        self.refractory_steps = proc_params["refractory_steps"]
        self.count_from = proc_params["count_from"]

    def subthr_dynamics(self, activation_in):
        frozen = self.refractory_end >= self.time_step
        held = self.v[frozen].copy()
        super().subthr_dynamics(activation_in)
        self.v[frozen] = held

    def reset_voltage(self, spike_vector):
        super().reset_voltage(spike_vector)
        fired = spike_vector.astype(bool)
        self.refractory_end[fired] = self.time_step + self.refractory_steps
        if self.time_step >= self.count_from:
            self.counts[fired] += 1


@implements(proc=CountingLIF, protocol=LoihiProtocol)
@requires(CPU)
@tag("fixed_pt")
class PyCountingLifFixed(_RefractoryCounting, PyLifModelBitAcc):
    implements_process = None  # (Lava refuses a subclass of a model of another process otherwise)
    counts: np.ndarray = LavaPyType(np.ndarray, np.int32)
    refractory_end: np.ndarray = LavaPyType(np.ndarray, np.int32)


@implements(proc=CountingLIF, protocol=LoihiProtocol)
@requires(CPU)
@tag("floating_pt")
class PyCountingLifFloat(_RefractoryCounting, PyLifModelFloat):
    implements_process = None
    counts: np.ndarray = LavaPyType(np.ndarray, np.int32)
    refractory_end: np.ndarray = LavaPyType(np.ndarray, np.int32)


class _StackedOnce:
    """Lava's DelaySparse models stack the weights by delay (``get_delay_wgts_mat``)
    anew at every step, which for a million synapses takes about a second; the
    weights do not change, so these models stack them once. What they compute
    is the same (``calc_act``: the stacked matrix times the spikes)."""

    def calc_act(self, s_in):
        if getattr(self, "_stacked", None) is None:
            self._stacked = self.get_delay_wgts_mat(self.weights, self.delays, self.a_buff.shape[-1] - 1)
        return np.reshape(self._stacked.dot(s_in), (self.a_buff.shape[-1], self.weights.shape[0])).T


@implements(proc=DelaySparse, protocol=LoihiProtocol)
@requires(CPU)
@tag("fixed_pt")
class PyDelaySparseStackedFixed(_StackedOnce, PyDelaySparseModelBitAcc):
    implements_process = None


@implements(proc=DelaySparse, protocol=LoihiProtocol)
@requires(CPU)
@tag("floating_pt")
class PyDelaySparseStackedFloat(_StackedOnce, PyDelaySparseModelFloat):
    implements_process = None


def run_config(arithmetic: str) -> Loihi2SimCfg:
    """Lava's CPU simulation in ``fixed`` or ``float`` arithmetic, with this module's LIF and DelaySparse models."""
    models = {
        "fixed": {CountingLIF: PyCountingLifFixed, DelaySparse: PyDelaySparseStackedFixed},
        "float": {CountingLIF: PyCountingLifFloat, DelaySparse: PyDelaySparseStackedFloat},
    }
    return Loihi2SimCfg(select_tag=TAGS[arithmetic], exception_proc_model_map=models[arithmetic])


def lif_process(pop: dict, arithmetic: str, count_from: int) -> CountingLIF:
    """One population's :class:`CountingLIF` with its registers (``network.json``'s ``lava``)."""
    lava, n = pop["lava"], int(pop["size"])
    regs = {k: int(lava[k]) for k in ("du", "dv", "bias_mant", "bias_exp", "vth")}
    if arithmetic == "float":
        f = fixed.float_constants(**regs)
        regs = {"du": f["du"], "dv": f["dv"], "bias_mant": f["bias"], "bias_exp": 0, "vth": f["vth"]}
    return CountingLIF(
        shape=(n,),
        du=regs["du"],
        dv=regs["dv"],
        vth=regs["vth"],
        bias_mant=np.full(n, regs["bias_mant"]),
        bias_exp=np.full(n, regs["bias_exp"]),
        refractory_steps=int(lava["refractory_steps"]),
        count_from=count_from,
        name=pop["name"],
    )


def connection_process(conn, n_pre: int, n_post: int, arithmetic: str) -> DelaySparse:
    """One projection (a :class:`~snn_fg.lava.synapses.Connection`) as a Lava ``DelaySparse``."""
    w = conn.w2m if arithmetic == "fixed" else fixed.float_weights(conn.w2m, conn.weight_exp)
    weights = csr_matrix((w, (conn.post, conn.pre)), shape=(n_post, n_pre))
    delays = csr_matrix((np.full(conn.pre.size, conn.delay_steps), (conn.post, conn.pre)), shape=(n_post, n_pre))
    return DelaySparse(
        weights=weights,
        delays=delays,
        weight_exp=int(conn.weight_exp) if arithmetic == "fixed" else 0,
        num_weight_bits=8,
        name=conn.name,
    )


def source_process(name: str, steps_per_cell: list, n_steps: int) -> RingBuffer:
    """A source population's spikes as a ``RingBuffer``: our step ``n`` is sent at Lava's step ``n + 1``."""
    data = np.zeros((max(len(steps_per_cell), 1), n_steps), np.int32)
    for i, s in enumerate(steps_per_cell):
        s = np.asarray(s, np.int64)
        data[i, s[s < n_steps]] = 1
    proc = RingBuffer(data=data)
    proc.name = name
    return proc


class LavaNetwork:
    """The export's processes, connected: ``cells`` (name -> :class:`CountingLIF`),
    ``sources`` (name -> ``RingBuffer``) and ``connections`` (``DelaySparse`` s)."""

    def __init__(self, meta: dict, conns: list, source_steps: list, *, n_steps: int, count_from: int, arithmetic: str):
        self.arithmetic = arithmetic
        pops = {p["name"]: p for p in meta["populations"]}
        self.cells, self.sources, offset = {}, {}, 0
        for p in meta["populations"]:
            if p["neuron"] is None:
                self.sources[p["name"]] = source_process(p["name"], source_steps[offset : offset + p["size"]], n_steps)
                offset += p["size"]
            else:  # Lava's step count_from + 1 is our step count_from
                self.cells[p["name"]] = lif_process(p, arithmetic, count_from + 1)
        self.connections = []
        for c in conns:
            if not c.pre.size:
                continue
            proc = connection_process(c, pops[c.source]["size"], pops[c.target]["size"], arithmetic)
            out = self.cells.get(c.source) or self.sources[c.source]
            out.s_out.connect(proc.s_in)
            proc.a_out.connect(self.cells[c.target].a_in)
            self.connections.append(proc)

    def run(self, n_steps: int, report=None, chunk: int = 25):
        """Run ``n_steps`` steps in Lava, ``chunk`` at a time (``report(done)`` after each)."""
        from lava.magma.core.run_conditions import RunSteps

        anchor = next(iter(self.cells.values()))
        cfg, done = run_config(self.arithmetic), 0
        while done < n_steps:
            k = min(chunk, n_steps - done)
            anchor.run(condition=RunSteps(num_steps=k), run_cfg=cfg)
            done += k
            if report is not None:
                report(done)

    def counts(self) -> dict:
        """Population name -> each cell's spike count (after :meth:`run`)."""
        return {name: np.asarray(p.counts.get(), np.int64) for name, p in self.cells.items()}

    def stop(self):
        next(iter(self.cells.values())).stop()

    def resources(self) -> dict:
        """Processes, neurons and synapses as Lava holds them (before a run)."""
        syn = [int(csr_matrix(c.weights.init).nnz) for c in self.connections]
        return {
            "processes": {
                "LIF (CountingLIF)": len(self.cells),
                "DelaySparse": len(self.connections),
                "RingBuffer": len(self.sources),
                "total": len(self.cells) + len(self.connections) + len(self.sources),
            },
            "neurons": int(sum(p.a_in.shape[0] for p in self.cells.values())),
            "spike_sources": int(sum(p.s_out.shape[0] for p in self.sources.values())),
            "synapses": int(sum(syn)),
            "max_synapses_per_process": int(max(syn, default=0)),
        }
