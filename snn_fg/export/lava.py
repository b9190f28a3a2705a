"""``snn-fg export --format lava``: the whole network as Lava processes, run in
Loihi 2's fixed-point arithmetic by Lava's own bit-accurate models.

The export folder holds

* ``run.py`` - the program (Lava, its scipy and numpy only; Python 3.10, as
  ``lava-nc`` 0.10 wants) that builds the network, reads ``input.npz``
  (``snn-fg events --write-spikes``), runs ``fixed_pt`` (or ``floating_pt``,
  or the numpy reference) and writes ``counts.npz`` for ``snn-fg decode``
  (:mod:`snn_fg.lava.run`);
* ``fg_lava.py`` (the processes: :mod:`snn_fg.lava.network`), ``fg_loihi.py``
  (the arithmetic: :mod:`snn_fg.lava.fixed`), ``fg_reference.py`` (the same
  in numpy: :mod:`snn_fg.lava.reference`), ``fg_synapses.py``,
  ``fg_tables.py``, ``fg_inputs.py`` and ``fg_files.py`` (the synapses from the tables, the
  input file, the output files written whole: shared with the PyNN export);
* ``network.json`` - populations with their Loihi 2 registers (``du``,
  ``dv``, ``vth``, ``bias_mant``, ``bias_exp``, refractory steps and the
  unit they are in: :mod:`snn_fg.lowering.loihi2`), projections with their
  weight exponent, mantissa factor and delay, our Loihi 2 resource report,
  and the snn-fg description it was made from; ``tables.npz`` - the
  weight-shared tables (as the PyNN export's);
* ``requirements.txt`` and ``README.md`` (how to make the environment and run it).

Each population is one Lava LIF process (with the refractory period, a
counting LIF of this export's: Lava 0.10 has no fixed-point refractory
LIF); each projection one Lava ``DelaySparse`` (every projection has a delay
of at least one step) with 8-bit weights and its own weight exponent; the
input and the window clock ``RingBuffer`` s. ``run.py --count-only`` writes
``resources.json``: the processes, neurons and synapses Lava holds, beside
our report's Loihi 2 figures.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from .. import lava as standalone
from .. import pynn as pynn_standalone
from ..lowering.loihi2 import lower
from ..network.graph import Network
from .board import board_network
from .folder import INPUT_STEP, LAVA_ENV, MAPS_STEP, export_meta, readme_fields, weight_tables, write_folder

SCHEMA = "snn-fg.lava/1"
#: the PyNN export's standalone modules a Lava export carries too
SHARED = {"tables.py": "fg_tables.py", "inputs.py": "fg_inputs.py", "files.py": "fg_files.py"}
#: the environment run.py needs (lava-nc 0.10 supports Python 3.8-3.10)
REQUIREMENTS = "# Python 3.10: lava-nc 0.10 supports Python 3.8-3.10\nlava-nc==0.10.0\n"
LAVA_NOTE = (
    "Lava: Loihi 2's 24-bit state, 12-bit decays and 8-bit weights with one exponent per projection "
    "(fg_loihi.py); each population's unit is set so that its current can never wrap around, "
    "its voltage saturates at the same range; refractory periods by this export's LIF model (Lava 0.10 "
    "has none in fixed point)."
)


def entry_extras(net: Network):
    """``(population_extra, projection_extra)``: what the Lava export adds to ``network.json``'s
    entries of the board network ``net``: each population's and projection's Loihi 2 registers."""
    low = lower(net)
    return (
        lambda p: {"lava": None if p.neuron is None else low.neurons[p.name].to_dict()},
        lambda pr: {"lava": low.synapses[pr.name].to_dict()},
    )


def lava_model(network: Network, *, command: str | None = None, sensor_shape=None) -> tuple[dict, dict]:
    """``(network.json data, tables.npz arrays)`` of the board network in Loihi 2's registers."""
    from .report import resource_report

    net = board_network(network)
    population_extra, projection_extra = entry_extras(net)
    entries, arrays = weight_tables(net, projection_extra)
    rep = resource_report(network, sensor_shape=sensor_shape)
    meta = export_meta(
        net,
        entries,
        schema=SCHEMA,
        dt_ms=net.dt_ms,
        command=command,
        sensor_shape=sensor_shape,
        population_extra=population_extra,
        weight_bits=8,
        loihi2_report={"totals": rep["totals"], "loihi2": rep["targets"]["loihi2"]},
    )
    meta["notes"].append(LAVA_NOTE)
    return meta, arrays


README = """# Lava model of the snn-fg figure-ground network

Made by `snn-fg export --format lava` (snn-fg {version}) for {frame}, {levels} pyramid
levels: {cells:,} neurons in {lif} LIF processes, {sources:,} spike sources, {prj} DelaySparse
connections with 8-bit weights, stepped at {dt} ms. Needs Python 3.10 and Lava (lava-nc 0.10);
no snn-fg. Make its environment once:

    python3.10 -m venv {env}   # pyenv: ~/.pyenv/versions/3.10.13/bin/python -m venv {env}
    {env}/bin/pip install -r requirements.txt

{input_step}
   (cut to {size}, on {dt} ms steps; sizes are width x height).
2. Run: `{env}/bin/python run.py --input input.npz --out counts.npz --duration-ms 150`
   (Lava's bit-accurate fixed point, `Loihi2SimCfg(select_tag="fixed_pt")`; `--arithmetic
   float` for its floating point on the same numbers, `--simulator reference` for the same
   fixed point in numpy alone; `--count-from-ms`, default half the run).
{maps_step}.

`{env}/bin/python run.py --count-only` writes `resources.json`: the processes, neurons and
synapses Lava holds, beside snn-fg's Loihi 2 report.

Approximations (see `network.json` notes): {notes}
"""


def export_lava(
    network: Network,
    out,
    *,
    force: bool = False,
    command: str | None = None,
    sensor_shape=None,
    dt_ms: float | None = None,
) -> Path:
    """Write the Lava model of ``network`` into the new folder ``out``.

    Parameters
    ----------
    network : Network
        The description (exported whole, at its own time step; its populations
        must have one synaptic time constant each, as Loihi 2's neuron has).
    out : path
        Folder to write (whole, via a staging folder; an existing non-empty
        folder is replaced only with ``force``, which keeps its ``input.npz``
        when the frame and time step are the same).
    command : str, optional
        The ``snn-fg export`` command that made it, recorded in ``network.json``.
    sensor_shape : (rows, cols), optional
        The sensor it is made for, recorded and named in its README.
    dt_ms : float, optional
        The time step (default: the network's own); the registers are for it.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from snn_fg.network.recipes import RECIPES
    >>> d = export_lava(RECIPES["compact"].build((48, 64)), pathlib.Path(tempfile.mkdtemp()) / "m")
    >>> sorted(p.name for p in d.iterdir())  # doctest: +NORMALIZE_WHITESPACE
    ['README.md', 'fg_files.py', 'fg_inputs.py', 'fg_lava.py', 'fg_loihi.py', 'fg_reference.py', 'fg_synapses.py',
     'fg_tables.py', 'network.json', 'requirements.txt', 'run.py', 'tables.npz']
    """
    network = dataclasses.replace(network, dt_ms=network.time_step(dt_ms, "export_lava"))
    meta, arrays = lava_model(network, command=command, sensor_shape=sensor_shape)
    copies = {standalone.HERE / src: dst for src, dst in standalone.COPIED.items()}
    copies.update({pynn_standalone.HERE / src: dst for src, dst in SHARED.items()})
    readme = README.format(
        input_step=INPUT_STEP,
        maps_step=MAPS_STEP,
        **readme_fields(network, meta, sensor_shape),
        lif=sum(1 for p in meta["populations"] if p["neuron"]),
        dt=meta["dt_ms"],
        env=LAVA_ENV,
    )
    texts = {"requirements.txt": REQUIREMENTS, "README.md": readme}
    return write_folder(
        out, force=force, frame_shape=network.frame_shape, meta=meta, arrays=arrays, copies=copies, texts=texts
    )
