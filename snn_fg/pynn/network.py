"""The figure-ground network in PyNN: populations, synapses, input, run.

STANDALONE: this module imports only numpy and the standard library (PyNN
is passed in as the ``sim`` module), because it is copied verbatim into
every PyNN export (``snn-fg export --format pynn``), where it must run on a
machine without snn_fg (NEST here, sPyNNaker on SpiNNaker). The NEST backend
(:mod:`snn_fg.backends.nest`) builds its network with the same code, so the
exported model and the backend are one implementation.

How a cell and a synapse map onto PyNN (``IF_curr_exp``, receptors,
refractoriness): :mod:`snn_fg.pynn.cells`.

``signed_receptors=True`` (NEST's array calls only, not portable) builds
the description exactly instead: NEST's ``iaf_psc_exp_multisynapse`` with
each projection on its own receptor and signed weights, so nothing moves
between time constants. That model refuses a synaptic time constant equal
to the membrane's; such a one is made larger by one part in 10^6.

Time: a cell that fires in our step ``n`` (stamped ``n dt``, as Brian2 does)
is stamped at the end of that step by NEST, ``(n + 1) dt``, and a synapse of
delay ``d`` moves the target's current at the stamp plus ``d`` in both. PyNN
on NEST needs input spikes after ``min_delay`` (= dt), so NEST runs
``TIME_SHIFT_STEPS`` steps ahead of our clock: an input spike of our step
``s`` is presented at ``(s + 1 + TIME_SHIFT_STEPS) dt`` (a spike generator's
time is its stamp) and every recorded spike time is reported with
``1 + TIME_SHIFT_STEPS`` steps taken off again. Delays shorter than one step
become one step (NEST's minimum delay).

Threads: NEST stores, for every synapse, the index of its presynaptic neuron
among the nodes of that neuron's thread in 19 bits (``TargetData``'s
``source_lid_`` in nestkernel/target_data.h). Release builds, the wheel
among them, do not check it (nest-simulator issue #1211): the index of a
neuron at 2**19 - 1 or above on its thread is cut to 19 bits, its spikes go
out through another neuron's synapses (checked here: a probe such a neuron
drives stays silent), and the run goes on with a wrong network.
:class:`PyNNNetwork` therefore takes as many threads as the spike-sending
cells need (:func:`nest_threads`) and refuses to create a cell past the limit.
"""

from __future__ import annotations

import numpy as np

try:  # inside snn_fg
    from .cells import cell_parameters, grid_delay, list_rows, split_receptors
    from .readout import NEST_UNIT, TIME_SHIFT_STEPS, Readout
except ImportError:  # inside an export folder
    from fg_cells import cell_parameters, grid_delay, list_rows, split_receptors
    from fg_readout import NEST_UNIT, TIME_SHIFT_STEPS, Readout

#: NEST addresses a spike-sending neuron by its index among its thread's
#: nodes in 19 bits (module docstring); the last index is a marker
NEST_MAX_LOCAL_SENDERS = 2**19 - 1
#: headroom for threads that get one or two nodes more than their share
NEST_LOCAL_MARGIN = 64


def nest_threads(senders: int, devices_first: int = 0, threads: int = 1) -> int:
    """The fewest NEST threads, at least ``threads``, on which ``senders``
    spike-sending neurons stay inside NEST's 19-bit thread-local index
    (module docstring). NEST deals nodes to threads in turn, so a thread
    holds at most ``ceil(senders / threads)`` of them; a device (spike
    generator, recorder) created before them takes one index on every
    thread (``devices_first``)."""
    room = NEST_MAX_LOCAL_SENDERS - NEST_LOCAL_MARGIN - int(devices_first)
    if room <= 0:
        raise ValueError(
            f"{devices_first:,} NEST devices created before the cells leave no room for them: create the cells first"
        )
    return max(int(threads), -(-int(senders) // room), 1)


class PyNNNetwork(Readout):
    """Populations of ``IF_curr_exp`` cells and spike sources in one PyNN
    simulator, connected by explicit synapse lists.

    ``n_cells`` and ``n_sources`` say how many cells and spike sources will
    be added: on NEST, ``threads`` is raised to what they need
    (:func:`nest_threads`; the threads used are ``self.threads``), and a
    cell that would still go past NEST's limit is refused.

    ``sim`` is the PyNN backend module (``pyNN.nest``, ``pyNN.spiNNaker``).
    On ``pyNN.nest`` cells, synapses and recorders are created by NEST's own
    array calls, with the cell parameters PyNN translates ``IF_curr_exp``
    into: PyNN keeps a Python object per cell and connects one target cell
    at a time (about 0.4 ms per cell here, minutes for the million cells of
    a full frame). ``portable=True`` uses PyNN's own ``Population``,
    ``FromListConnector`` and ``record`` everywhere (what other PyNN
    simulators run; the tests check both give the same spikes).

    Recording, running and reading back spikes, counts and state in our
    clock are :class:`Readout`'s (``fg_readout.py``).
    """

    def __init__(
        self,
        sim,
        *,
        dt_ms: float,
        max_delay_ms: float,
        threads: int = 1,
        portable: bool = False,
        signed_receptors: bool = False,
        n_cells: int = 0,
        n_sources: int = 0,
    ):
        self.sim = sim
        self.dt = float(dt_ms)
        self.native = (sim.__name__ == "pyNN.nest") and not portable
        if signed_receptors and not self.native:
            raise ValueError("signed_receptors needs NEST's own array calls (pyNN.nest, portable=False)")
        self.signed = bool(signed_receptors)
        max_delay = max(grid_delay(max_delay_ms, self.dt), 2 * self.dt)
        opts = {}
        self.on_nest = sim.__name__ == "pyNN.nest"
        self.threads = int(threads)
        self._senders = 0  # spike-sending neurons created (cells; parrots of portable sources)
        self._devices = 0  # devices created before the last of them
        if self.on_nest:
            # portable sources are a spike generator (a device) plus a parrot
            # neuron each; native ones are generators only
            senders = int(n_cells) + (0 if self.native else int(n_sources))
            self.threads = nest_threads(senders, 0 if self.native else int(n_sources), self.threads)
            # on_grid: PyNN's default on NEST is off-grid spiking, which swaps IF_curr_exp for iaf_psc_exp_ps
            # (spike times and refractoriness between steps): not the time-stepped cell the description means.
            # The network draws no random numbers: NEST's seed is fixed
            opts = {"threads": self.threads, "rng_seed": 1, "spike_precision": "on_grid"}
        sim.setup(timestep=self.dt, min_delay=self.dt, max_delay=max_delay, **opts)
        self.pops: dict = {}  # name -> PyNN Population (portable) or NEST NodeCollection (native)
        self.first: dict = {}  # native: name -> NEST id of its first node
        self.recorders: dict = {}
        self.n_synapses: dict = {}
        self.taus: dict = {}  # cells' name -> (tau_exc_ms, tau_inh_ms): how a synapse is split between receptors
        self.shift_ms = TIME_SHIFT_STEPS * self.dt
        self.duration_ms = 0.0

    def add_cells(self, name: str, size: int, neuron: dict):
        """``size`` LIF cells, starting at rest."""
        p = self._cell_parameters(name, neuron)
        size = max(int(size), 1)
        self._count_senders(name, size)
        if self.signed:
            import nest  # (NEST is the nest extra, and one simulator of several PyNN runs on: imported on NEST only)

            taus = [t * (1 + 1e-6) if t == p["tau_m"] else t for t in (p["tau_syn_E"], p["tau_syn_I"])]
            model = f"snnfg_{name}"
            nest.CopyModel(
                "iaf_psc_exp_multisynapse",
                model,
                {
                    "C_m": p["cm"] * NEST_UNIT,
                    "tau_m": p["tau_m"],
                    "t_ref": p["tau_refrac"],
                    "E_L": p["v_rest"],
                    "V_reset": p["v_reset"],
                    "V_th": p["v_thresh"],
                    "tau_syn": taus,
                    "I_e": 0.0,
                    "V_m": p["v_rest"],
                },
            )
            self._native_nodes(name, nest.Create(model, size))
        elif self.native:
            import nest

            ps = self.sim.IF_curr_exp(**p).native_parameters
            ps.shape = (1,)
            ps.evaluate(simplify=True)
            model = f"snnfg_{name}"
            nest.CopyModel("iaf_psc_exp", model, {**{k: float(v) for k, v in ps.items()}, "V_m": p["v_rest"]})
            self._native_nodes(name, nest.Create(model, size))
        else:
            pop = self.sim.Population(size, self.sim.IF_curr_exp(**p), label=name)
            pop.initialize(v=p["v_rest"])
            self.pops[name] = pop

    def _cell_parameters(self, name: str, neuron: dict) -> dict:
        """``IF_curr_exp`` parameters of population ``name``, whose synaptic time constants :meth:`connect` reads."""
        p = cell_parameters(neuron, self.dt)
        self.taus[name] = (p["tau_syn_E"], p["tau_syn_I"])
        return p

    def add_sources(self, name: str, steps_per_cell: list):
        """Spike sources, one per entry of ``steps_per_cell`` (time steps of its spikes)."""
        times = [(np.asarray(s, dtype=np.float64) + 1 + TIME_SHIFT_STEPS) * self.dt for s in steps_per_cell]
        if self.on_nest:
            self._devices += max(len(times), 1)
            if not self.native:  # PyNN's parrot neurons, which send
                self._count_senders(name, max(len(times), 1))
        if self.native:
            import nest

            # a spike generator's spike at t reaches a target at t + delay, as
            # PyNN's generator-plus-parrot pair (t - min_delay, then min_delay) does
            nodes = nest.Create("spike_generator", max(len(times), 1))
            if times:
                nodes.set([{"spike_times": t.tolist()} for t in times])
            self._native_nodes(name, nodes)
        else:
            self.pops[name] = self.sim.Population(
                max(len(times), 1),
                self.sim.SpikeSourceArray(spike_times=[self.sim.Sequence(t) for t in times] or [self.sim.Sequence([])]),
                label=name,
            )

    def _count_senders(self, name: str, size: int):
        """Refuse cells that NEST could not address on ``self.threads`` threads."""
        if not self.on_nest:
            return
        self._senders += int(size)
        need = nest_threads(self._senders, self._devices, self.threads)
        if need > self.threads:
            raise ValueError(
                f"population '{name}': {self._senders:,} spike-sending cells need at least {need} NEST "
                f"threads (NEST addresses {NEST_MAX_LOCAL_SENDERS:,} per thread and silently mixes "
                f"them up beyond), not {self.threads}: give n_cells/n_sources or more threads"
            )

    def _native_nodes(self, name, nodes):
        self.pops[name] = nodes
        self.first[name] = int(nodes[0].tolist()[0])

    def connect(self, source: str, target: str, pre, post, drive, *, sign: int, delay_ms: float):
        """Synapses ``pre[i] -> post[i]`` (cell indices) with signed drive in
        mV, split between the target's two receptors (see the module docstring)."""
        delay = grid_delay(delay_ms, self.dt)
        pre, post = np.asarray(pre, np.int64), np.asarray(post, np.int64)
        if self.signed:  # the projection's own receptor (1: excitatory, 2: inhibitory)
            # as Brian2 adds them (snn_fg.backends.base.receptor_weights): the
            # excitatory current takes the signed drive, the inhibitory one its magnitude
            drive = np.asarray(drive, np.float64)
            w = drive if sign > 0 else -np.abs(drive)
            keep = w != 0
            if keep.any():
                self._connect_nest(source, target, pre[keep], post[keep], w[keep], 1 if sign > 0 else 2, delay)
                self.n_synapses[target] = self.n_synapses.get(target, 0) + int(keep.sum())
            return
        exc, mag = split_receptors(drive, sign, *self.taus[target])
        for receptor, mask in (("excitatory", exc), ("inhibitory", ~exc)):
            keep = mask & (mag > 0)
            if not keep.any():
                continue
            # PyNN's (and NEST's) convention for current-based synapses: inhibitory weights are negative
            w = mag[keep] if receptor == "excitatory" else -mag[keep]
            if self.native:
                self._connect_nest(source, target, pre[keep], post[keep], w, 0, delay)
            else:
                self._from_list(source, target, pre[keep], post[keep], w, delay, receptor)
            self.n_synapses[target] = self.n_synapses.get(target, 0) + int(keep.sum())

    def _from_list(self, source, target, pre, post, w, delay, receptor):
        """PyNN's own synapses ``pre[i] -> post[i]`` of weight ``w`` on ``receptor``."""
        rows = list_rows(pre, post, w, delay)
        conn = self.sim.FromListConnector(rows, column_names=["weight", "delay"])
        self.sim.Projection(
            self.pops[source], self.pops[target], conn, self.sim.StaticSynapse(), receptor_type=receptor
        )

    def _connect_nest(self, source, target, pre, post, w_mv, port, delay):
        """NEST synapses of weight ``w_mv`` (nA = mV, signed) on receptor
        ``port`` (0: by the weight's sign, as ``iaf_psc_exp`` takes them)."""
        import nest

        w = w_mv * NEST_UNIT
        spec = {"receptor_type": port} if port else {}
        step = 1 << 22
        for a in range(0, pre.size, step):
            b = min(a + step, pre.size)
            nest.Connect(
                self.first[source] + pre[a:b],
                self.first[target] + post[a:b],
                "one_to_one",
                syn_spec={"synapse_model": "static_synapse", "weight": w[a:b], "delay": np.full(b - a, delay), **spec},
            )

    def end(self):
        self.sim.end()
