"""``snn-fg export --format nir --nir-profile snntorch --out DIR``: the graph snnTorch imports, in a
folder with its own loop, as the PyNN and Lava exports have theirs.

The export folder holds

* ``model.nir`` - the graph of the snnTorch profile (:mod:`.nir_snntorch`; ``--out FILE.nir``
  writes it alone);
* ``run.py`` - the program (torch, snnTorch, nir and numpy only) that reads ``input.npz``
  (``snn-fg events --write-spikes``), has snnTorch import the graph and nirtorch step it, and
  writes ``counts.npz`` for ``snn-fg decode`` (``snn_fg/export/snntorch_loop/run.py``), with
  ``fg_snntorch.py`` (the stepping and counting, :mod:`.snntorch_loop.counting`, which
  :func:`~snn_fg.export.snntorch_run.run_snntorch` runs too) and ``fg_inputs.py`` and
  ``fg_files.py`` (the input file and the output written whole: shared with the PyNN export);
* ``network.json`` - the populations and projections the graph holds (the profile's network,
  :func:`~snn_fg.export.nir_snntorch.snntorch_network`: every level on one grid, delays and
  refractory periods of one step, zero padding, no window clock), the snn-fg description they
  were derived from (``snn_fg_network``) and the profile's options (``nir_profile``), from which
  ``snn-fg decode`` derives that network again (:func:`graph_network`): the network the counts
  are decoded with and that ``--reference`` runs;
* ``README.md`` - how to run it.

The exact profile (``--format nir`` alone) has no consumer that runs it, so it stays a graph file.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from .. import pynn as pynn_standalone
from ..network.graph import Network
from . import snntorch_loop
from .board import board_network
from .folder import GRAPH_NAME, INPUT_STEP, MAPS_STEP, export_meta, projection_entry, readme_fields, write_folder
from .nir import nir_package
from .nir_snntorch import RESET_DRIVE, snntorch_network, to_nir_snntorch

SCHEMA = "snn-fg.nir-snntorch/1"
#: the PyNN export's standalone modules a NIR export folder carries too
SHARED = {"inputs.py": "fg_inputs.py", "files.py": "fg_files.py"}


def graph_network(description: Network, profile: dict) -> Network:
    """The network a NIR export folder's graph holds, from the description it was made from and the
    profile's options ``network.json`` records (``nir_profile``)."""
    return snntorch_network(
        description,
        profile["step_ms"],
        one_grid=profile["one_grid"],
        deeper_reset=profile["deeper_reset"],
        reset_drive=profile["reset_drive"],
    )


README = """# NIR graph of the snn-fg figure-ground network, with its loop in snnTorch

Made by `snn-fg export --format nir --nir-profile snntorch` (snn-fg {version}) for {frame},
{levels} pyramid levels{grid}: `{graph}` holds {cells:,} neurons as CubaLIF nodes and {prj} Conv2d
projections, one snnTorch step for each {dt} ms step; refractory periods {refractory}. Needs torch,
snnTorch, nir and numpy (`pip install torch==2.13.0 snntorch==1.0.0 nirtorch==2.6 nir==1.0.8`); no snn-fg.

{input_step}
   (cut to {size}, on {dt} ms steps; sizes are width x height).
2. Run: `python run.py --input input.npz --out counts.npz --duration-ms 400`
   (snnTorch's NIR import, stepped by nirtorch; `--count-from-ms`, default half the run).
{maps_step};
   `--reference fast` also runs the network the graph holds (`network.json`) with snn-fg's engine on
   the same input and says how the two agree.

The graph has no window clock (it fires between a recording's windows; the input is one window
replayed): run.py leaves the clock's spikes out of an input that has them.

Approximations (see `network.json` notes): {notes}
"""


def export_nir_folder(
    network: Network,
    out,
    *,
    step_ms: float | None = None,
    one_grid: bool = False,
    deeper_reset: bool = False,
    force: bool = False,
    command: str | None = None,
    sensor_shape=None,
) -> Path:
    """Write the snnTorch profile's graph of ``network`` with its loop into the new folder ``out``.

    Parameters
    ----------
    network : Network
        The description (exported whole, at ``step_ms``: default its own time step).
    out : path
        Folder to write, as :func:`~snn_fg.export.folder.write_folder` writes an export (``force``: over
        an earlier one).
    one_grid, deeper_reset : bool
        As :func:`~snn_fg.export.nir_snntorch.to_nir_snntorch` takes them.
    command : str, optional
        The ``snn-fg export`` command that made it, recorded in ``network.json``.
    sensor_shape : (rows, cols), optional
        The sensor it is made for, recorded and named in its README.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from snn_fg.network.recipes import RECIPES
    >>> net = RECIPES["compact"].build((48, 48))
    >>> d = export_nir_folder(net, pathlib.Path(tempfile.mkdtemp()) / "m", one_grid=True, deeper_reset=True)
    >>> sorted(p.name for p in d.iterdir())
    ['README.md', 'fg_files.py', 'fg_inputs.py', 'fg_snntorch.py', 'model.nir', 'network.json', 'run.py']
    """
    nir = nir_package()
    board = board_network(dataclasses.replace(network, dt_ms=network.time_step(step_ms, "export_nir_folder")))
    profile = {"step_ms": board.dt_ms, "one_grid": one_grid, "deeper_reset": deeper_reset, "reset_drive": RESET_DRIVE}
    held = graph_network(board, profile)
    graph = to_nir_snntorch(board, step_ms=board.dt_ms, one_grid=one_grid, deeper_reset=deeper_reset)
    meta = export_meta(
        held,
        [projection_entry(pr) for pr in held.projections],
        schema=SCHEMA,
        dt_ms=board.dt_ms,
        command=command,
        sensor_shape=sensor_shape,
        graph=GRAPH_NAME,
        nir_profile=profile,
    )
    meta["snn_fg_network"] = board.to_dict()  # (the profile's network is derived from it: 80 kB, not 12 MB)
    copies = {snntorch_loop.HERE / src: dst for src, dst in snntorch_loop.COPIED.items()}
    copies.update({pynn_standalone.HERE / src: dst for src, dst in SHARED.items()})
    readme = README.format(
        input_step=INPUT_STEP,
        maps_step=MAPS_STEP,
        **readme_fields(held, meta, sensor_shape),
        grid=" on one grid" if one_grid else "",
        graph=GRAPH_NAME,
        dt=board.dt_ms,
        refractory="as deeper resets" if deeper_reset else "of one step",
    )
    return write_folder(
        out,
        force=force,
        frame_shape=board.frame_shape,
        meta=meta,
        arrays=None,
        copies=copies,
        texts={"README.md": readme},
        files={GRAPH_NAME: lambda path: nir.write(path, graph)},
    )
