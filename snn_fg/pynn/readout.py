"""What a :class:`~snn_fg.pynn.network.PyNNNetwork` did, read in our clock:
recorders of spikes, spike counts at given times and the cells' state, the
run itself, and the spikes, counts and state read back.

STANDALONE, as :mod:`snn_fg.pynn.network` (copied into every PyNN export as
``fg_readout.py``): numpy and the standard library only. The time shift
between our steps and NEST's stamps is explained in that module's docstring.
"""

from __future__ import annotations

import time

import numpy as np

try:  # inside snn_fg
    from .cells import counts_in, population_spikes
except ImportError:  # inside an export folder
    from fg_cells import counts_in, population_spikes

#: input spikes are presented this many time steps late (NEST refuses a
#: spike time at 0 and PyNN's spike sources deliver through a parrot neuron
#: one min_delay later); recorded times are shifted back
TIME_SHIFT_STEPS = 2
#: NEST's native units: pA per nA and pF per nF
NEST_UNIT = 1000.0
#: state variable -> (NEST recordable, PyNN recordable, factor to nA = mV from NEST's unit)
#: a spike counter: no leak to speak of, no threshold, each input of weight 1 adds 1 mV
COUNTER = {
    "tau_m": 1e12,
    "C_m": 1.0,
    "E_L": 0.0,
    "V_reset": 0.0,
    "V_th": 1e30,
    "V_m": 0.0,
    "t_ref": 0.0,
    "V_min": -1e30,
    "I_e": 0.0,
}
STATE_NAMES = {
    "v": ("V_m", "v", 1.0),
    "I_exc": ("I_syn_ex", "isyn_exc", 1 / NEST_UNIT),
    "I_inh": ("I_syn_in", "isyn_inh", 1 / NEST_UNIT),
}
#: the NEST recordables of iaf_psc_exp_multisynapse (``signed_receptors``): one current per receptor
SIGNED_STATE_NAMES = {"v": "V_m", "I_exc": "I_syn_1", "I_inh": "I_syn_2"}


class Readout:
    """The recording and reading half of :class:`~snn_fg.pynn.network.PyNNNetwork`
    (it uses the network's ``sim``, ``dt``, ``pops``, ``native``, ``signed``,
    ``recorders`` and ``duration_ms``)."""

    def record(self, names, *, spikes: bool = True, count_edges_ms=()):
        """Record the populations ``names``: every spike (``spikes``), and on
        NEST the spike count of every cell at each time of ``count_edges_ms``.

        On NEST a cell connected to a recording device costs 32 KB (the device
        connection gets a block of its own; 10 GB for a full frame's cells),
        so counts come from one counter neuron per cell (a leak-free
        ``iaf_psc_delta`` each spike raises by 1 mV) read by multimeters at
        the count edges: ordinary synapses, a few bytes each.
        """
        self.recorded = list(names)
        self._events = None
        self._counts = {}
        if not self.native:
            for name in names:
                self.pops[name].record("spikes")
            return
        import nest  # (NEST is the nest extra: imported on NEST only)

        if spikes:
            rec = nest.Create("spike_recorder")
            for name in names:
                nest.Connect(self.pops[name], rec)
            self.recorders = {name: rec for name in names}
        edges = sorted({float(e) for e in count_edges_ms if e > 0})
        if not edges:
            return
        self._meters = []
        for e in edges:
            at = e + (TIME_SHIFT_STEPS + 1) * self.dt  # a spike reported before e has reached its counter
            self._meters.append(
                (
                    e,
                    nest.Create(
                        "multimeter",
                        params={"record_from": ["V_m"], "interval": self.dt, "start": at - self.dt, "stop": at},
                    ),
                )
            )
        self._counters = {}
        for name in names:
            n = len(self.pops[name])
            counter = nest.Create("iaf_psc_delta", n, params=COUNTER)
            nest.Connect(self.pops[name], counter, "one_to_one", syn_spec={"weight": 1.0, "delay": self.dt})
            for _, mm in self._meters:
                nest.Connect(mm, counter)
            self._counters[name] = int(counter[0].tolist()[0])

    def counts(self, name: str, size: int, start_ms: float, end_ms: float) -> np.ndarray:
        """Spikes of each cell with ``start_ms <= t < end_ms``."""
        if not getattr(self, "_counters", None):
            cell, t = self.spikes(name, size)
            return counts_in(cell, t, size, start_ms, end_ms)
        return self._count_at(name, size, end_ms) - self._count_at(name, size, start_ms)

    def _count_at(self, name, size, edge_ms):
        if edge_ms <= 0:
            return np.zeros(size, np.int64)
        if edge_ms not in self._counts:
            mm = next(m for e, m in self._meters if abs(e - edge_ms) < 1e-9)
            ev = mm.get("events")
            self._counts[edge_ms] = (np.asarray(ev["senders"], np.int64), np.rint(ev["V_m"]).astype(np.int64))
        ids, vals = self._counts[edge_ms]
        out = np.zeros(size, np.int64)
        cell = ids - self._counters[name]
        keep = (cell >= 0) & (cell < size)
        out[cell[keep]] = vals[keep]
        return out

    def run(self, duration_ms: float, chunk_ms: float = 50.0, report=None) -> float:
        """Simulate ``duration_ms`` (plus the input shift) in chunks;
        ``report(done_ms)`` after each that moves it on (``duration_ms`` once). Returns the wall time in seconds."""
        t0 = time.perf_counter()
        self.duration_ms = float(duration_ms)
        total = duration_ms + self.shift_ms + self.dt  # the last count edge is read one step later
        done = shown = 0.0
        while done < total - 1e-9:
            step = min(chunk_ms, total - done)
            self.sim.run(step)
            done += step
            if report is not None and min(done, duration_ms) > shown:  # (the steps past duration_ms: said once)
                shown = min(done, duration_ms)
                report(shown)
        return time.perf_counter() - t0

    def spikes(self, name: str, size: int):
        """``(cell, t_ms)`` of every recorded spike of ``name``, in time of the
        unshifted input, stamped like Brian2 (at the start of the step in
        which the cell fired; NEST stamps its end)."""
        if self.native:
            if self._events is None:
                ev = self.recorders[name].get("events")
                self._events = (np.asarray(ev["senders"], dtype=np.int64), np.asarray(ev["times"], np.float64))
            ids, t = self._events
            cell = ids - self.first[name]
            keep = (cell >= 0) & (cell < size)
            cell, t = cell[keep], t[keep]
        else:
            cell, t = self._portable_spikes(name)
        t = np.round(t / self.dt - TIME_SHIFT_STEPS - 1) * self.dt
        keep = (cell < size) & (t < self.duration_ms - 1e-9)  # NEST may run past the end
        cell, t = cell[keep], t[keep]
        order = np.lexsort((cell, t))
        return cell[order], t[order]

    def _portable_spikes(self, name: str):
        return population_spikes(self.pops[name])

    def record_state(self, names, variables, end_ms: float):
        """Record the final ``variables`` (``v``, ``I_exc``, ``I_inh``) of the populations ``names``."""
        self._state_vars = tuple(variables)
        if not variables:
            return
        if self.native:
            import nest

            mm = nest.Create(
                "multimeter",
                params={
                    "record_from": [self._nest_key(v) for v in variables],
                    "interval": self.dt,
                    "start": end_ms + self.shift_ms - self.dt,
                },
            )
            for name in names:
                nest.Connect(mm, self.pops[name])
            self._multimeter = mm
        else:
            for name in names:
                self.pops[name].record([STATE_NAMES[v][1] for v in variables])

    def _nest_key(self, variable: str) -> str:
        return SIGNED_STATE_NAMES[variable] if self.signed else STATE_NAMES[variable][0]

    def state(self, name: str, size: int, variable: str) -> np.ndarray:
        """Final ``v`` (mV) or synaptic current ``I_exc``/``I_inh`` (nA = mV;
        magnitudes, signed with ``signed_receptors``, as Brian2 keeps them) of
        each cell (:meth:`record_state` first)."""
        _, pynn_key, scale = STATE_NAMES[variable]
        nest_key = self._nest_key(variable)
        if self.native:
            ev = self._multimeter.get("events")
            cell = np.asarray(ev["senders"], np.int64) - self.first[name]
            keep = (cell >= 0) & (cell < size)
            vals = np.zeros(size)
            vals[cell[keep]] = np.asarray(ev[nest_key], np.float64)[keep]  # the last sample wins
        else:
            sig = next(a for a in self.pops[name].get_data(pynn_key).segments[0].analogsignals if a.name == pynn_key)
            vals = np.asarray(sig.magnitude, np.float64)[-1, :size] * (NEST_UNIT if variable != "v" else 1.0)
        if variable == "v":
            return vals
        if self.signed:  # signed currents: I_exc as it is, I_inh the inhibitory receptor's, negated
            return vals * scale * (1.0 if variable == "I_exc" else -1.0)
        return np.abs(vals) * scale
