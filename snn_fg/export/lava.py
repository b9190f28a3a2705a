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
  ``fg_tables.py`` and ``fg_inputs.py`` (the synapses from the tables, the
  input file: shared with the PyNN export);
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
import json
import shutil
from pathlib import Path

import numpy as np

from .. import __version__
from .. import lava as standalone
from .. import pynn as pynn_standalone
from ..lowering.loihi2 import lower
from ..network.graph import Network
from .board import board_network, geometry
from .pynn import INPUT_NAME, frame_size, frame_text, reusable_input, weight_tables

SCHEMA = "snn-fg.lava/1"
#: the PyNN export's standalone modules a Lava export carries too
SHARED = {"tables.py": "fg_tables.py", "inputs.py": "fg_inputs.py"}
#: the environment run.py needs (lava-nc 0.10 supports Python 3.8-3.10)
REQUIREMENTS = "# Python 3.10: lava-nc 0.10 supports Python 3.8-3.10\nlava-nc==0.10.0\n"
LAVA_NOTE = (
    "Lava: Loihi 2's 24-bit state, 12-bit decays and 8-bit weights with one exponent per projection "
    "(snn_fg/lava/fixed.py); each population's unit is set so that its current can never wrap around, "
    "its voltage saturates at the same range; refractory periods by this export's LIF model (Lava 0.10 "
    "has none in fixed point)."
)


def lava_model(network: Network, *, command: str | None = None, sensor_shape=None) -> tuple[dict, dict]:
    """``(network.json data, tables.npz arrays)`` of the board network in Loihi 2's registers."""
    from .report import resource_report

    net = board_network(network)
    low = lower(net)
    entries, arrays = weight_tables(net)
    for e in entries:
        e["lava"] = low.synapses[e["name"]].to_dict()
    pops = [
        {
            "name": p.name,
            "role": p.role,
            "level": p.level,
            "size": p.size,
            **geometry(p),
            "neuron": None if p.neuron is None else p.neuron.to_dict(),
            "lava": None if p.neuron is None else low.neurons[p.name].to_dict(),
        }
        for p in net.populations
    ]
    rep = resource_report(network, sensor_shape=sensor_shape)
    meta = {
        "schema": SCHEMA,
        "snn_fg_version": __version__,
        "dt_ms": net.dt_ms,
        "weight_bits": 8,
        "input_rate_hz": net.input_rate_hz,
        "export_command": command,
        "frame_shape": list(net.frame_shape),
        "sensor_shape": None if sensor_shape is None else list(sensor_shape),
        "populations": pops,
        "projections": entries,
        "notes": [*net.notes, LAVA_NOTE],
        "loihi2_report": {"totals": rep["totals"], "loihi2": rep["targets"]["loihi2"]},
        "snn_fg_network": net.to_dict(),
    }
    return meta, arrays


README = """# Lava model of the snn-fg figure-ground network

Made by `snn-fg export --format lava` (snn-fg {version}) for {frame}, {levels} pyramid
levels: {cells:,} neurons in {lif} LIF processes, {sources:,} spike sources, {prj} DelaySparse
connections with 8-bit weights, stepped at {dt} ms. Needs Python 3.10 and Lava (lava-nc 0.10);
no snn-fg. Make its environment once:

    python3.10 -m venv .venv-lava   # pyenv: ~/.pyenv/versions/3.10.13/bin/python -m venv .venv-lava
    .venv-lava/bin/pip install -r requirements.txt

1. Input: `snn-fg events RECORDING --start-ms 100 --window-ms 85 --write-spikes input.npz --export .`
   (cut to {size}, on {dt} ms steps; sizes are width x height).
2. Run: `.venv-lava/bin/python run.py --input input.npz --out counts.npz --duration-ms 150`
   (Lava's bit-accurate fixed point, `Loihi2SimCfg(select_tag="fixed_pt")`; `--arithmetic
   float` for its floating point on the same numbers, `--simulator reference` for the same
   fixed point in numpy alone; `--count-from-ms`, default half the run).
3. Maps: `snn-fg decode counts.npz --export . --out maps` writes `maps/maps.npz` and `maps/maps.png`.

`.venv-lava/bin/python run.py --count-only` writes `resources.json`: the processes, neurons and
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
    ['README.md', 'fg_inputs.py', 'fg_lava.py', 'fg_loihi.py', 'fg_reference.py', 'fg_synapses.py',
     'fg_tables.py', 'network.json', 'requirements.txt', 'run.py', 'tables.npz']
    """
    from ..atomic import OutputFolder

    if dt_ms is not None:
        network = dataclasses.replace(network, dt_ms=float(dt_ms))
    meta, arrays = lava_model(network, command=command, sensor_shape=sensor_shape)
    kept = reusable_input(Path(out) / INPUT_NAME, network.frame_shape, network.dt_ms) if force else None
    with OutputFolder(out, force=force) as folder:
        tmp = folder.dir
        if kept is not None:
            (tmp / INPUT_NAME).write_bytes(kept)
        (tmp / "network.json").write_text(json.dumps(meta, indent=1) + "\n")
        np.savez_compressed(tmp / "tables.npz", **arrays)
        for src, dst in standalone.COPIED.items():
            shutil.copyfile(standalone.HERE / src, tmp / dst)
        for src, dst in SHARED.items():
            shutil.copyfile(pynn_standalone.HERE / src, tmp / dst)
        (tmp / "requirements.txt").write_text(REQUIREMENTS)
        pops = meta["populations"]
        (tmp / "README.md").write_text(
            README.format(
                version=__version__,
                frame=frame_text(network, sensor_shape),
                size=frame_size(network),
                levels=network.params.levels,
                cells=sum(p["size"] for p in pops if p["neuron"]),
                lif=sum(1 for p in pops if p["neuron"]),
                sources=sum(p["size"] for p in pops if not p["neuron"]),
                prj=len(meta["projections"]),
                dt=meta["dt_ms"],
                notes=" ".join(meta["notes"]),
            )
        )
    return Path(out)
