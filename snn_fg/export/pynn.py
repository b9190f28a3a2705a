"""``snn-fg export --format pynn``: the whole network as a self-contained PyNN model.

The export folder holds

* ``run.py`` - the script (PyNN and numpy only) that builds the network,
  reads an input spike file, simulates and writes every population's spikes
  (:mod:`snn_fg.pynn.run`);
* ``fg_network.py`` - the network in PyNN (a verbatim copy of
  :mod:`snn_fg.pynn.network`, which the NEST backend also runs), with
  ``fg_readout.py``, its run and read-out (:mod:`snn_fg.pynn.readout`), and
  ``fg_cells.py``, its cells and synapses in PyNN's terms (:mod:`snn_fg.pynn.cells`);
* ``fg_tables.py`` - explicit synapses from the weight-shared tables (a
  verbatim copy of :mod:`snn_fg.pynn.tables`); ``fg_inputs.py`` - the input
  spike file's reader (:mod:`snn_fg.pynn.inputs`);
* ``fg_spinnaker.py`` - the network on sPyNNaker with its
  ``ConvolutionConnector`` s, and its mapping on a virtual board
  (:mod:`snn_fg.pynn.spinnaker`); ``fg_memory.py`` - what a NEST run
  will cost, from measurement (:mod:`snn_fg.pynn.memory`);
  ``fg_simulator.py`` - PyNN's simulator module imported without PyNN's
  warnings about its optional NEST extensions (:mod:`snn_fg.pynn.simulator`);
  ``fg_files.py`` - the files run.py writes, each whole (:mod:`snn_fg.pynn.files`);
* ``network.json`` - populations (grids, neuron constants), projections
  (ends, sign, gain, delay, per-projection weight scale, synapse count) and the snn-fg
  description it was made from; ``tables.npz`` - the weight-shared tables
  (kernel taps, interpolation matrices; identical tables stored once);
* ``spinnaker.json`` (``target="spinnaker"``, ``--target spinnaker``, only) -
  which projections sPyNNaker's ``ConvolutionConnector`` carries on SpiNNaker
  and why the others cannot, and the resource report's estimate of the cores
  and chips (set beside sPyNNaker's own mapping by
  ``run.py --simulator spinnaker --virtual-board``);
* ``README.md`` - how to run it.

Every projection is unrolled by ``run.py`` at build time: the files stay a
few MB for any sensor size.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .. import pynn as standalone
from .. import validate as check
from ..backends.base import SimulationResult, lif_populations
from ..errors import InputError
from ..lowering.input_spikes import InputSpikes
from ..lowering.quantise import projection_scales
from ..network.graph import Network
from ..results.marks import MARK
from .board import board_network
from .folder import (
    INPUT_STEP,
    MAPS_STEP,
    export_meta,
    readme_fields,
    weight_tables,
    write_folder,
)
from .report import spinnaker_estimate
from .spinnaker import spinnaker_plan

SCHEMA = "snn-fg.pynn/1"
TARGETS = ("generic", "spinnaker")


def pynn_model(
    network: Network,
    *,
    dt_ms: float | None = None,
    weight_bits: int | None = None,
    target: str = "generic",
    command: str | None = None,
    sensor_shape=None,
) -> tuple[dict, dict]:
    """``(network.json data, tables.npz arrays)`` of the board network; ``command``:
    the ``snn-fg export`` command that made it, recorded (without ``--input-rate-hz``);
    ``sensor_shape`` (rows, cols): the sensor it was made for, if known."""
    dt_ms = network.time_step(dt_ms, "pynn_model")
    net = board_network(network)
    population_extra, projection_extra = entry_extras(net, weight_bits)
    entries, arrays = weight_tables(net, projection_extra)
    meta = export_meta(
        net,
        entries,
        population_extra=population_extra,
        schema=SCHEMA,
        dt_ms=dt_ms,
        weight_bits=weight_bits,
        command=command,
        sensor_shape=sensor_shape,
        target=target,
    )
    return meta, arrays


def entry_extras(net: Network, weight_bits: int | None):
    """``(population_extra, projection_extra)``: what the PyNN export adds to ``network.json``'s
    entries of the board network ``net`` (each projection's weight scale for ``weight_bits``, 0: float)."""
    scales = projection_scales(net, weight_bits) if weight_bits else {}
    return None, lambda pr: {"scale_mv": scales.get(pr.name, 0.0)}


README = """# PyNN model of the snn-fg figure-ground network

Made by `snn-fg export --format pynn` (snn-fg {version}) for {frame},
{levels} pyramid levels: {cells:,} neurons, {sources:,} spike sources, {prj} projections
(target: {target}; weights: {bits}). Needs PyNN, numpy and a PyNN simulator; no snn-fg.

{input_step}
   (a recording's window, an image or an event frame, cut to {size}, on {dt} ms steps;
   sizes are width x height).
2. Run: `python run.py --input input.npz --out counts.npz --simulator nest --duration-ms 400`
   (`--count-from-ms`, default half the run). It says first how much memory and time
   to expect (the measured figures are in `fg_memory.py`) and stops with one line when
   the network will not fit the machine's memory.
{maps_step}, as `snn-fg run` does.

On SpiNNaker (an export made with `--target spinnaker`, which writes
`spinnaker.json`): `python run.py ... --simulator spinnaker` (sPyNNaker,
`pip install -e ".[spinnaker]"` or `sPyNNaker==1!7.4.1`). The projections
`spinnaker.json` gives to `ConvolutionConnector` go through it, the others
through `FromListConnector`. Without a board, `python run.py --simulator spinnaker
--virtual-board [--map-only]` has sPyNNaker map the network onto virtual SpiNN-5
boards (its configuration and reports in `spinnaker/`) and writes `mapping.json`:
chips and cores used beside the export's estimate.

Approximations (see `network.json` notes): {notes}
"""


def export_pynn(
    network: Network,
    out,
    *,
    dt_ms: float | None = None,
    weight_bits: int | None = None,
    target: str = "generic",
    force: bool = False,
    command: str | None = None,
    sensor_shape=None,
) -> Path:
    """Write the PyNN model of ``network`` into the new folder ``out``.

    Parameters
    ----------
    network : Network
        The description (exported whole, see :func:`~snn_fg.export.board.board_network`).
    out : path
        Folder to write (written whole via a staging folder; an existing
        non-empty folder is replaced only with ``force``).
    dt_ms : float, optional
        Simulation time step of the model (default: the network's own).
    weight_bits : int, optional
        Quantise weights to this many bits (one scale per projection).
    target : {"generic", "spinnaker"}
        Recorded in ``network.json``; ``"spinnaker"`` also writes ``spinnaker.json``,
        the plan ``run.py --simulator spinnaker`` needs (as ``snn-fg export --help`` says).
    command : str, optional
        The ``snn-fg export`` command that made it, recorded in ``network.json``
        (``snn-fg events --write-spikes`` says how to re-export it calibrated
        to an input's rate). The gains are the network's: calibrate it first
        (:meth:`~snn_fg.network.Network.calibrated`) for another input rate;
        ``network.json``'s ``input_rate_hz`` says which.
    sensor_shape : (rows, cols), optional
        The sensor it is made for (a network that pools its input has a
        smaller frame), recorded in ``network.json`` and named in its README.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from snn_fg.network import build_network
    >>> from snn_fg.params import ModelParams
    >>> d = export_pynn(build_network(ModelParams(levels=2), (40, 52)), pathlib.Path(tempfile.mkdtemp()) / "m")
    >>> [p.name for p in sorted(d.iterdir()) if p.suffix != ".py"]
    ['README.md', 'network.json', 'tables.npz']
    >>> print(*sorted(p.name for p in d.glob("*.py")))  # doctest: +NORMALIZE_WHITESPACE
    fg_cells.py fg_files.py fg_inputs.py fg_memory.py fg_network.py fg_readout.py fg_simulator.py
    fg_spinnaker.py fg_tables.py run.py
    """
    check.choice("export_pynn", "target", target, TARGETS)
    dt_ms = network.time_step(dt_ms, "export_pynn")
    meta, arrays = pynn_model(
        network, dt_ms=dt_ms, weight_bits=weight_bits, target=target, command=command, sensor_shape=sensor_shape
    )
    copies = {standalone.HERE / src: dst for src, dst in standalone.COPIED.items()}
    readme = README.format(
        input_step=INPUT_STEP,
        maps_step=MAPS_STEP,
        **readme_fields(network, meta, sensor_shape),
        target=target,
        bits=f"{weight_bits}-bit" if weight_bits else "float",
        dt=dt_ms,
    )
    texts = {"README.md": readme}
    if target == "spinnaker":  # (before, every export held it although the help said --target spinnaker writes it)
        board = board_network(network)
        plan = {**spinnaker_plan(board), "estimate": spinnaker_estimate(board, dt_ms)}
        texts["spinnaker.json"] = json.dumps(plan, indent=1) + "\n"
    return write_folder(
        out, force=force, frame_shape=network.frame_shape, meta=meta, arrays=arrays, copies=copies, texts=texts
    )


def save_input(inputs, path, dt_ms: float, origin: dict | None = None) -> Path:
    """Write :class:`~snn_fg.lowering.input_spikes.InputSpikes` as ``run.py``'s
    input file; ``origin`` (what the spikes were made from: input, window,
    where the crop lies on the sensor) goes with them as JSON text, for
    ``snn-fg decode`` to tell (:func:`input_origin`)."""
    extra = {} if origin is None else {"origin": np.array(json.dumps(origin))}
    np.savez(
        path,
        indices=inputs.indices.astype(np.int64),
        steps=inputs.steps.astype(np.int64),
        dt_ms=dt_ms,
        period_steps=-1 if inputs.period_steps is None else int(inputs.period_steps),
        shape=np.array(inputs.shape),
        written_by=np.array(MARK),  # (so that --force knows it for ours: results.outputs)
        **extra,
    )
    return Path(path)


def input_origin(path) -> dict | None:
    """What :func:`save_input` kept of where an input file's spikes come
    from (None: an input file written without it, or no such file)."""
    try:
        with np.load(path) as d:
            return json.loads(str(d["origin"])) if "origin" in d.files else None
    except (OSError, ValueError):
        return None


def read_input(path):
    """``run.py``'s input file as :class:`~snn_fg.lowering.input_spikes.InputSpikes`
    (what :func:`save_input` wrote; the active-pixel masks and the mean rate
    are recomputed from the spikes)."""
    d = check.load_npz(path, "the input.npz of snn-fg events --write-spikes")
    h, w = (int(v) for v in d["shape"])
    idx, steps, period = d["indices"].astype(np.int64), d["steps"].astype(np.int64), int(d["period_steps"])
    n = h * w
    on, off = np.zeros(n, bool), np.zeros(n, bool)
    on[idx[idx < n]] = True
    off[idx[(idx >= n) & (idx < 2 * n)] - n] = True
    span_s = ((period if period > 0 else int(steps.max(initial=0)) + 1) * float(d["dt_ms"])) / 1000.0
    rate = idx.size / max(int(on.sum() + off.sum()), 1) / span_s
    return InputSpikes(
        (h, w),
        idx,
        steps,
        period if period > 0 else None,
        on.reshape(h, w),
        off.reshape(h, w),
        float(rate),
        0,
        "pynn-input",
    )


def read_counts(network: Network, path):
    """``run.py``'s output as a :class:`~snn_fg.backends.SimulationResult`
    of the board network (every cell), ready for :func:`snn_fg.models.spiking.decode.decode`."""
    net = board_network(network)
    d = check.load_npz(path, "the counts.npz an export's run.py writes")
    pops = lif_populations(net)
    if "indices" in d.files and "steps" in d.files:
        raise InputError(
            path,
            "an input spike file (run.py's --input), not the counts run.py writes: run "
            "python run.py --input FILE --out counts.npz in the export's folder, then decode "
            "counts.npz",
        )
    missing = [
        k for k in ("duration_ms", "dt_ms", "count_from_ms", *(f"count_{q.name}" for q in pops)) if k not in d.files
    ]
    if missing:
        raise InputError(
            path,
            f"not a run.py counts file of this export: no {', '.join(missing[:3])}"
            + (f" and {len(missing) - 3} more" if len(missing) > 3 else ""),
        )
    for p in pops:
        have = int(np.asarray(d[f"count_{p.name}"]).size)
        if have != p.size:
            h, w = net.frame_shape
            raise InputError(
                path,
                f"not the counts of this export: count_{p.name} holds {have:,} cells, where this export's "
                f"{p.name} has {p.size:,} (its frame is {w} x {h}): counts of another export, or of this one "
                "before it was made again?",
            )
    duration, start = float(d["duration_ms"]), float(d["count_from_ms"])
    spikes = {p.name: (d[f"cell_{p.name}"], d[f"t_{p.name}"]) for p in pops} if f"cell_{pops[0].name}" in d else None
    return SimulationResult(
        network=net,
        backend="pynn-export",
        sites={p.name: np.arange(p.size) for p in pops},
        counts={p.name: d[f"count_{p.name}"].astype(np.int64) for p in pops},
        count_window_ms=duration - start,
        simulated_ms=duration,
        dt_ms=float(d["dt_ms"]),
        spikes=spikes,
    )
