"""The exported network on SpiNNaker with sPyNNaker, and its mapping on a virtual board.

STANDALONE like :mod:`snn_fg.pynn.network` (numpy and the standard
library; copied into every PyNN export as ``fg_spinnaker.py``). ``run.py
--simulator spinnaker`` builds the network with :class:`SpiNNakerNetwork`;
``--virtual-board`` (:func:`use_virtual_board`) has sPyNNaker partition,
place, route and write the data of the network for a SpiNN-5 machine
without hardware, and :func:`mapping_summary` says what it used.

Connectors. A projection that the export's plan (``spinnaker.json``, made by
:mod:`snn_fg.export.spinnaker`) gives to ``ConvolutionConnector`` goes
through it: one 2-D kernel per (target channel, source channel) plane with
zero padding and a stride on the target, positive weights on the excitatory
receptor and negative ones on the inhibitory receptor; every other
projection is an explicit ``FromListConnector``.

Layout. sPyNNaker convolves between 2-D populations (``Grid2D``: cell
(row r, column c) of a rows x cols grid is PyNN cell ``r * cols + c``, our
own flat order). Our populations hold ``channels`` cells per grid point,
channel-major, so a population a convolution touches is

* ``stacked``: one Grid2D population of cols x (channels * rows) when every
  convolution it takes part in is 1 x 1 and channel-diagonal with one weight
  for all channels: such a kernel never reaches across channels, one
  connector carries the whole projection and the cell order is unchanged;
* ``split``: one Grid2D population per channel (``<name>_c<k>``), one
  connector per non-zero kernel plane; a FromListConnector projection to or
  from it is cut into one projection per pair of channels;

and every other population is one 1-D population. sPyNNaker cuts a 2-D
population into cores by tiles whose sides divide the grid's sides
(:func:`core_tile`).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

try:  # inside snn_fg
    from .cells import grid_delay, list_rows, population_spikes, split_receptors
    from .network import TIME_SHIFT_STEPS, PyNNNetwork
except ImportError:  # inside an export folder
    from fg_cells import grid_delay, list_rows, population_spikes, split_receptors
    from fg_network import TIME_SHIFT_STEPS, PyNNNetwork

#: sPyNNaker's default cells per core for IF_curr_exp
CELLS_PER_CORE = 256
#: chips of one SpiNN-5 board
SPINN5_CHIPS = 48
VIRTUAL_CFG = """# Written by the snn-fg export's run.py --virtual-board: sPyNNaker maps the
# network for SpiNN-5 boards without hardware (a virtual machine of as many
# boards as the network needs).
[Machine]
virtual_board = True
version = 5

[Reports]
default_report_file_path = {reports}
write_partitioner_reports = True
write_application_graph_placer_report = True
write_sdram_usage_report_per_chip = True
"""


def use_virtual_board(folder) -> Path:
    """Point sPyNNaker at a configuration of our own in ``folder`` (virtual
    SpiNN-5 board, sPyNNaker's reports in ``folder/reports``); call before importing
    ``pyNN.spiNNaker``.

    sPyNNaker reads one user configuration from ``/etc/xdg``, the user's
    config folder or home, and writes a template into the home folder when
    there is none; for this process those three places are sub-folders of
    ``folder``, so the user's own configuration (that of a real board) is
    neither read nor touched.
    """
    root = Path(folder).resolve()
    for sub in ("config", "home", "site"):
        (root / sub).mkdir(parents=True, exist_ok=True)
    (root / "config" / ".spynnaker.cfg").write_text(VIRTUAL_CFG.format(reports=root))
    os.environ.update(XDG_CONFIG_HOME=str(root / "config"), XDG_CONFIG_DIRS=str(root / "site"), HOME=str(root / "home"))
    return root


def skip_data_generation():
    """Stop sPyNNaker's run after its mapping (partitioning, placement,
    routing, key allocation): its loading step, which on a virtual board is
    the generation of every core's data (in Python, one FromListConnector
    synapse at a time: 162 of the 184 s of a 32 x 24, 2-level export), is
    skipped. Patches the simulator class (``SpiNNaker._do_load``), for this
    process only."""
    from spynnaker.pyNN.spinnaker import SpiNNaker

    SpiNNaker._do_load = lambda self: None


def spynnaker_timings() -> dict:
    """Seconds sPyNNaker spent mapping and generating data (its provenance database)."""
    from spinn_front_end_common.interface.provenance import GlobalProvenance, TimerCategory

    with GlobalProvenance() as db:
        return {
            "mapping": db.get_category_timer_sum(TimerCategory.MAPPING) / 1e3,
            "data_generation": db.get_timer_sum_by_algorithm("Graph data specification writer") / 1e3,
        }


def core_tile(cols: int, rows: int, most: int = CELLS_PER_CORE) -> tuple:
    """The (cols, rows) tile of at most ``most`` cells, its sides dividing
    the grid's, with the most cells (sPyNNaker's rule for 2-D populations)."""
    div = [[d for d in range(1, n + 1) if n % d == 0] for n in (cols, rows)]
    return max(((a, b) for a in div[0] for b in div[1] if a * b <= most), key=lambda t: (t[0] * t[1], t[0]))


def conv_kernels(taps, values, src: dict, tgt: dict, padding) -> np.ndarray:
    """The kernels ``(c_out, c_in, 2 pr + 1, 2 pc + 1)`` sPyNNaker's
    ConvolutionConnector applies for a weight-shared table (``taps`` rows
    ``(c_out, c_in, dr, dc)``: target channel c_out at level pixel p reads
    source channel c_in at p + (dr, dc)).

    sPyNNaker (``local_only_conv_impl.c``) gives target ``p`` (with stride
    ``S``) from source lattice cell ``q`` the weight ``K[pad + S p - q]``, so
    a tap at lattice offset ``d`` is ``K[pad - d]``; taps off the source
    lattice reach no cell.
    """
    pr, pc = (int(v) for v in padding)
    s = int(src["stride"])
    k = np.zeros((tgt["channels"], src["channels"], 2 * pr + 1, 2 * pc + 1))
    for (co, ci, dr, dc), v in zip(np.asarray(taps), np.asarray(values)):
        if dr % s or dc % s:
            continue
        k[co, ci, pr - dr // s, pc - dc // s] += v
    return k


def stackable(kernels: np.ndarray) -> bool:
    """A 1 x 1 channel-diagonal kernel with one weight: one connector over stacked channels."""
    c_out, c_in, h, w = kernels.shape
    if (h, w) != (1, 1) or c_out != c_in:
        return False
    k = kernels[:, :, 0, 0]
    return not np.any(k - np.diag(np.diag(k))) and np.all(np.diag(k) == k[0, 0])


def layout(populations: dict, conv) -> dict:
    """Population name -> ``grid`` (one channel), ``stacked`` or ``split`` for
    every population a convolution touches (module docstring); ``conv``
    holds ``(source, target, kernels)`` of each convolution."""
    out = {}
    for a, b, k in conv:
        for name in (a, b):
            single = populations[name]["channels"] == 1
            want = "grid" if single else ("stacked" if stackable(k) else "split")
            if out.get(name) != "split":
                out[name] = want
    changed = True
    while changed:  # a stacked end meeting a split end of one projection splits too
        changed = False
        for a, b, _ in conv:
            if {out[a], out[b]} == {"stacked", "split"}:
                out[a] = out[b] = "split"
                changed = True
    return out


def plan_kernels(meta: dict, tables: dict, plan: dict) -> dict:
    """Projection name -> ``(source, target, kernels)`` of each projection the
    plan gives to ConvolutionConnector (``tables``: name -> (taps, values))."""
    pops = {p["name"]: p for p in meta["populations"]}
    out = {}
    for e in plan["projections"]:
        if e["connector"] == "ConvolutionConnector":
            taps, values = tables[e["name"]]
            out[e["name"]] = (
                e["source"],
                e["target"],
                conv_kernels(taps, values, pops[e["source"]], pops[e["target"]], e["padding"]),
            )
    return out


class SpiNNakerNetwork(PyNNNetwork):
    """:class:`PyNNNetwork` on sPyNNaker with the 2-D populations and
    ConvolutionConnectors of :func:`layout` (``layout`` name -> kind;
    ``populations`` name -> the export's population entry). sPyNNaker
    chooses how many cores process a population's synapses beside the one
    that updates its cells; ``combined_cores`` has it use that one for both."""

    def __init__(self, sim, *, layout: dict, populations: dict, combined_cores: bool = False, **kw):
        super().__init__(sim, portable=True, **kw)
        if combined_cores:  # neurons and their synapses on one core, as the resource report counts them
            sim.set_number_of_synapse_cores(sim.IF_curr_exp, 0)
        # sPyNNaker 7 sizes cores itself unless told; a synaptic row (one source
        # cell's synapses onto one core) then outgrows its 256-synapse limit
        sim.set_number_of_neurons_per_core(sim.IF_curr_exp, CELLS_PER_CORE)
        self.layout, self.meta = dict(layout), populations
        self.parts: dict = {}  # split population -> one Population per channel
        self.n_convolution_connectors = 0

    def _grid(self, name):
        p = self.meta[name]
        rows, cols = p["grid"]
        return (cols, rows * p["channels"]) if self.layout[name] == "stacked" else (cols, rows)

    def _make(self, name, celltype):
        kind = self.layout.get(name)
        if kind is None:
            return self.sim.Population(self.meta[name]["size"], celltype, label=name)
        cols, rows = self._grid(name)
        pops = []
        for c in range(self.meta[name]["channels"] if kind == "split" else 1):
            pop = self.sim.Population(
                cols * rows,
                celltype,
                structure=self.sim.Grid2D(cols / rows),
                label=f"{name}_c{c}" if kind == "split" else name,
            )
            pop.set_max_atoms_per_core(core_tile(cols, rows))
            pops.append(pop)
        if kind == "split":
            self.parts[name] = pops
        return pops if kind == "split" else pops[0]

    def add_cells(self, name: str, size: int, neuron: dict):
        p = self._cell_parameters(name, neuron)
        self.pops[name] = self._make(name, self.sim.IF_curr_exp(**p))
        for pop in self.parts.get(name, [self.pops[name]]):
            pop.initialize(v=p["v_rest"])

    def add_sources(self, name: str, steps_per_cell: list):
        """Spike sources (sPyNNaker takes plain lists of spike times)."""
        times = [((np.asarray(s, np.float64) + 1 + TIME_SHIFT_STEPS) * self.dt).tolist() for s in steps_per_cell]
        # one empty list for a source without spikes: sPyNNaker 7.4.1's spike density check
        # fails on a list of empty lists (IndexError in _check_density_double_list)
        self.pops[name] = self._make(name, self.sim.SpikeSourceArray(spike_times=times if any(times) else []))

    def _from_list(self, source, target, pre, post, w, delay, receptor):
        if source not in self.parts and target not in self.parts:
            return super()._from_list(source, target, pre, post, w, delay, receptor)
        n_pre, n_post = (
            self.meta[n]["size"] // self.meta[n]["channels"] if n in self.parts else self.meta[n]["size"]
            for n in (source, target)
        )
        cp, cq = pre // n_pre, post // n_post
        key = cp * (cq.max() + 1) + cq
        for k in np.unique(key):
            sel = key == k
            a = self.parts[source][cp[sel][0]] if source in self.parts else self.pops[source]
            b = self.parts[target][cq[sel][0]] if target in self.parts else self.pops[target]
            rows = list_rows(pre[sel] % n_pre, post[sel] % n_post, w[sel], delay)
            self.sim.Projection(
                a,
                b,
                self.sim.FromListConnector(rows, column_names=["weight", "delay"]),
                self.sim.StaticSynapse(),
                receptor_type=receptor,
            )

    def convolve(self, source: str, target: str, drive: np.ndarray, *, sign: int, delay_ms: float, strides: int) -> int:
        """ConvolutionConnector projections of the kernels ``drive`` (mV:
        :func:`conv_kernels` times ``sign * gain_mv``, quantised as deployed);
        returns how many connectors."""
        exc, mag = split_receptors(drive, sign, *self.taus[target])
        w = np.where(exc, mag, -mag)
        dyn = self.sim.Convolution(delay=grid_delay(delay_ms, self.dt))
        pr, pc = (s // 2 for s in w.shape[2:])
        if pr != pc:  # sPyNNaker orders a kernel's weights by (x, y) in Python and (row, col) on the chip
            raise ValueError(
                f"{source} -> {target}: a {w.shape[2]} x {w.shape[3]} kernel; only square kernels "
                "have one weight order in sPyNNaker"
            )
        if self.layout[source] == "stacked" or self.layout[target] == "stacked":
            planes = [(None, None, w[0, 0])]
        else:
            planes = [(o, i, w[o, i]) for o, i in zip(*np.nonzero(np.abs(w).sum((2, 3))))]
        for o, i, k in planes:
            a = self.parts[source][i] if source in self.parts else self.pops[source]
            b = self.parts[target][o] if target in self.parts else self.pops[target]
            conn = self.sim.ConvolutionConnector(k, strides=int(strides), padding=(pc, pr))
            self.sim.Projection(a, b, conn, dyn)
        self.n_convolution_connectors += len(planes)
        return len(planes)

    def record(self, names, *, spikes: bool = True, count_edges_ms=()):
        self.recorded, self._events, self._counts = list(names), None, {}
        for name in names:
            for pop in self.parts.get(name, [self.pops[name]]):
                pop.record("spikes")

    def _portable_spikes(self, name: str):
        if name not in self.parts:
            return super()._portable_spikes(name)
        n = self.meta[name]["size"] // self.meta[name]["channels"]
        got = [population_spikes(pop) for pop in self.parts[name]]
        return (np.concatenate([cell + c * n for c, (cell, _) in enumerate(got)]), np.concatenate([t for _, t in got]))


def mapping_summary(names) -> dict:
    """What sPyNNaker's mapping used: the chips holding the network's cores
    (not counting the monitor cores sPyNNaker puts on every chip of the
    machine), its cores by population of ``names`` (a split population's
    channels under its name) and by kind of core, the system's cores, and
    the machine it mapped onto."""
    from spinn_front_end_common.data import FecDataView

    by_pop, by_kind, system, chips = {}, {}, {}, set()
    for pl in FecDataView.iterate_placemements():
        app = pl.vertex.app_vertex
        label = getattr(app, "label", None) or ""
        owner = next((n for n in names if label == n or label.startswith(f"{n}_c")), None)
        kind = type(pl.vertex).__name__
        if owner is None:
            system[kind] = system.get(kind, 0) + 1
            if kind == "ExtraMonitorSupportMachineVertex":  # one on every chip of the machine
                continue
        else:
            by_pop[owner] = by_pop.get(owner, 0) + 1
            by_kind[kind] = by_kind.get(kind, 0) + 1
        chips.add((pl.x, pl.y))
    machine = FecDataView.get_machine()
    return {
        "chips_used": len(chips),
        "cores_used": sum(by_pop.values()) + sum(system.values()),
        "cores_network": sum(by_pop.values()),
        "fits": len(chips) <= SPINN5_CHIPS,
        "machine_chips": machine.n_chips,
        "machine_boards": -(-machine.n_chips // SPINN5_CHIPS),
        "cores_by_kind": by_kind,
        "cores_system": system,
        "cores_by_population": by_pop,
        "reports": FecDataView.get_run_dir_path(),
    }
