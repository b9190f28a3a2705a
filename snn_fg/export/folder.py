"""What every export folder holds, written once for the PyNN, the Lava and the NIR (snnTorch) export:
the weight-shared tables (identical ones stored once), ``network.json`` (what
``snn-fg events --write-spikes`` and ``snn-fg decode`` read), the README's
common facts, and the folder written whole, keeping an ``input.npz`` that
still serves it. What an export folder may hold (:data:`EXPORT_FOLDER`: the export's own files and
what the programs run in it write there) is what ``snn-fg export --force`` may replace, and what it
keeps (the environment a Lava export's README has the user make there, :data:`LAVA_ENV`); a folder
holding anything else is refused (:mod:`snn_fg.results.outputs`), and so is one holding run.py's
counts (a simulator's or a board's run, kept from deletion)."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np

from .. import __version__, lava, pynn
from .. import validate as check
from ..backends import cancel
from ..errors import InputError
from ..lowering.kernel_tables import ConvTable, geometry, table, table_fields
from ..network.graph import Network
from ..results.atomic import OutputFolder
from ..results.marks import made_by_snn_fg
from ..results.outputs import FolderKind
from .snntorch_loop import COPIED as SNNTORCH_COPIED
from .synapses import projection_counts

#: the input file ``snn-fg events --write-spikes`` writes into an export by the README's loop
INPUT_NAME = "input.npz"
#: the first and last steps of every export folder's README (its ``{input_step}`` and ``{maps_step}``):
#: the input spikes written for the export, and the maps decoded from the counts its run.py writes
INPUT_STEP = f"1. Input: `snn-fg events RECORDING --start-ms 100 --window-ms 85 --write-spikes {INPUT_NAME} --export .`"
MAPS_STEP = "3. Maps: `snn-fg decode counts.npz --export . --out maps` writes `maps/maps.npz` and `maps/maps.png`"
#: what an input spike file holds, and what run.py's output (counts) always holds
INPUT_KEYS = ("indices", "steps", "dt_ms", "period_steps", "shape")
COUNTS_KEYS = ("duration_ms", "dt_ms", "count_from_ms")


def _arrays_of(entry: Path) -> set:
    """The array names of an ``.npz`` file (none for anything else, or one that cannot be read)."""
    if entry.suffix != ".npz" or not entry.is_file():
        return set()
    try:
        with np.load(entry) as d:
            return set(d.files)
    except (OSError, ValueError, EOFError):
        return set()


def _run_py_file(entry: Path) -> bool:
    """Whether ``entry`` is a file run.py reads or writes (an input spike file, its counts), by its arrays."""
    names = _arrays_of(entry)
    return set(INPUT_KEYS) <= names or set(COUNTS_KEYS) <= names


def _counts_files(folder: Path) -> list[str]:
    """The counts files run.py wrote into an export ``folder`` (a simulator's or a board's run), by their arrays."""
    if not folder.is_dir():
        return []
    return sorted(p.name for p in folder.iterdir() if set(COUNTS_KEYS) <= _arrays_of(p))


#: the Python 3.10 environment a Lava export's README tells the user to make inside the folder
LAVA_ENV = ".venv-lava"

#: the NIR graph a NIR export folder holds (snn_fg.export.nir_folder)
GRAPH_NAME = "model.nir"


def _export_entry(entry: Path) -> bool:
    """Whether an entry named as an export's is the export's: ``network.json`` by its schema (a JSON
    record snn-fg marks), every other one beside such a ``network.json`` (a user's own ``network.json``
    and ``run.py`` in a folder were replaced by --force, told by their names alone)."""
    if entry.name == "network.json":
        return made_by_snn_fg(entry)
    return made_by_snn_fg(entry.parent / "network.json")


#: what a PyNN, Lava or NIR export folder holds: the export's files, and what run.py and Python write in it (the
#: input and counts files, under any name; sPyNNaker's configuration and reports, the virtual board's
#: mapping.json, Lava's resources.json); the environment its README has the user make there is kept where
#: it is (before, a Lava export's --force re-export was refused for it)
EXPORT_FOLDER = FolderKind(
    "an snn-fg export",
    names=(
        *pynn.COPIED.values(),
        *lava.COPIED.values(),
        *SNNTORCH_COPIED.values(),
        GRAPH_NAME,
        "network.json",
        "tables.npz",
        "spinnaker.json",
        "requirements.txt",
        "README.md",
        INPUT_NAME,
        "__pycache__",
        "spinnaker",
        "mapping.json",
        "resources.json",
    ),
    marks=("network.json",),
    owns=_run_py_file,
    kept=(LAVA_ENV,),
    made=_export_entry,
)


def projection_entry(pr) -> dict:
    """What ``network.json`` says of a projection that the description gives directly (its ends, sign,
    gain and delay); :func:`weight_tables` adds what its table gives."""
    return {
        "name": pr.name,
        "source": pr.source,
        "target": pr.target,
        "sign": pr.sign,
        "gain_mv": pr.gain_mv,
        "delay_ms": pr.delay_ms,
    }


def population_entry(p, population_extra=None) -> dict:
    """What ``network.json`` says of a population (``population_extra(p)`` adds to it)."""
    return {
        "name": p.name,
        "role": p.role,
        "level": p.level,
        "size": p.size,
        **geometry(p),
        "neuron": None if p.neuron is None else p.neuron.to_dict(),
        **(population_extra(p) if population_extra else {}),
    }


def weight_tables(network: Network, projection_extra=None):
    """(projection entries, table arrays) with identical tables stored once; ``projection_extra(pr)``
    adds to each entry (a format's own fields)."""
    arrays, seen, entries = {}, {}, []
    for pr in network.projections:
        cancel.check()  # (Ctrl-C and SIGTERM stop the export between projections)
        tab = table(network, pr)
        if isinstance(tab, ConvTable):
            parts = {"taps": tab.taps.astype(np.int32), "values": tab.values}
        else:
            parts = {
                f"{a}_{b}": arr
                for a, m in (("rows", tab.rows), ("cols", tab.cols))
                for b, arr in (("idx", m[0].astype(np.int32)), ("val", m[1]))
            }
        digest = hashlib.sha1(b"".join(np.ascontiguousarray(a).tobytes() for a in parts.values())).hexdigest()
        if digest not in seen:
            seen[digest] = f"t{len(seen)}"
            arrays.update({f"{seen[digest]}_{k}": v for k, v in parts.items()})
        key = seen[digest]
        entries.append(
            {
                **projection_entry(pr),
                "table": key,
                "synapses": projection_counts(network, pr, tab).synapses,
                **table_fields(tab),
                **(projection_extra(pr) if projection_extra else {}),
            }
        )
    return entries, arrays


def frame_size(network: Network, shape=None) -> str:
    """``shape`` (rows, cols; default: the network's frame) in words, width x
    height as ``--sensor-size`` takes them: ``"32 x 24"``, or for a network that
    pools its input ``"102 x 80 blocks"``."""
    h, w = network.frame_shape if shape is None else shape
    return f"{w} x {h}" + (" blocks" if network.params.input_pool > 1 else "")


def frame_text(network: Network, sensor_shape=None) -> str:
    """The frame an export takes, in words: ``"a 32 x 24 sensor"``, or for a
    network that pools its input ``"a 304 x 240 sensor as 102 x 80 blocks of 3
    x 3 pixels"`` (without the sensor when ``sensor_shape``, rows and cols, is
    not known)."""
    pool = network.params.input_pool
    if pool == 1:
        return f"a {frame_size(network)} sensor"
    blocks = f"{frame_size(network)} of {pool} x {pool} pixels"
    return blocks if sensor_shape is None else f"a {sensor_shape[1]} x {sensor_shape[0]} sensor as {blocks}"


def export_meta(
    net: Network, entries: list, *, schema: str, dt_ms: float, command, sensor_shape, population_extra=None, **fields
) -> dict:
    """The ``network.json`` every export folder holds (what ``snn-fg events --write-spikes`` and
    ``snn-fg decode`` read): the board network ``net``'s populations (``population_extra(p)``
    adds to each), the projection ``entries``, the time step, the command that made it and the
    sensor; ``fields`` join them."""
    pops = [population_entry(p, population_extra) for p in net.populations]
    return {
        "schema": schema,
        "snn_fg_version": __version__,
        "dt_ms": dt_ms,
        "input_rate_hz": net.input_rate_hz,
        "export_command": command,
        "frame_shape": list(net.frame_shape),
        "sensor_shape": None if sensor_shape is None else list(sensor_shape),
        **fields,
        "populations": pops,
        "projections": entries,
        "notes": list(net.notes),
        "snn_fg_network": net.to_dict(),
    }


def readme_fields(network: Network, meta: dict, sensor_shape) -> dict:
    """What every export's README names: version, frame, size, levels, cells, sources, projections, notes."""
    pops = meta["populations"]
    return {
        "version": __version__,
        "frame": frame_text(network, sensor_shape),
        "size": frame_size(network),
        "levels": network.params.levels,
        "cells": sum(p["size"] for p in pops if p["neuron"]),
        "sources": sum(p["size"] for p in pops if not p["neuron"]),
        "prj": len(meta["projections"]),
        "notes": " ".join(meta["notes"]),
    }


def write_folder(
    out, *, force: bool, frame_shape, meta: dict, arrays: dict | None, copies: dict, texts: dict, files=None
) -> Path:
    """An export folder written whole (via a staging folder): ``network.json`` (``meta``),
    ``tables.npz`` (``arrays``; None: none), the standalone modules ``copies`` (path -> name in the
    folder), ``texts`` (name -> text) and ``files`` (name -> a function writing that file at the
    path it is given). With ``force`` an earlier export (:data:`EXPORT_FOLDER`) is
    replaced, keeping its ``input.npz`` when it serves the same frame and time step; one that holds
    run.py's counts (a run on a simulator or a board, which the new export could not decode) is refused."""
    counts = _counts_files(Path(out)) if force else []
    if counts:
        raise InputError(
            out,
            f"holds {', '.join(counts)}: run.py's counts from the export there (a simulator's or a board's run), "
            "which --force would delete; move them out of the folder or choose another output folder; "
            "nothing was deleted",
        )
    kept = reusable_input(Path(out) / INPUT_NAME, frame_shape, meta["dt_ms"]) if force else None
    with OutputFolder(out, force=force, kind=EXPORT_FOLDER) as folder:
        tmp = folder.dir
        if kept is not None:
            (tmp / INPUT_NAME).write_bytes(kept)
        (tmp / "network.json").write_text(json.dumps(meta, indent=1) + "\n")
        if arrays is not None:
            np.savez_compressed(tmp / "tables.npz", **arrays)
        for src, dst in copies.items():
            shutil.copyfile(src, tmp / dst)
        for name, text in texts.items():
            (tmp / name).write_text(text)
        for name, write in (files or {}).items():
            write(tmp / name)
    return Path(out)


def reusable_input(path: Path, frame_shape, dt_ms: float) -> bytes | None:
    """The bytes of an export's input file, if it serves an export of
    ``frame_shape`` at ``dt_ms`` too (a re-export with ``--force`` that only
    recalibrates the gains keeps it); ``None`` otherwise. The input's spikes
    depend on the frame and the time step only, not on the gains."""
    try:
        with check.load_npz(path, "run.py's input") as d:
            same = tuple(int(v) for v in d["shape"]) == tuple(frame_shape) and float(d["dt_ms"]) == float(dt_ms)
        return path.read_bytes() if same else None
    except (OSError, ValueError, KeyError):  # (none, or not one we can read: it goes with the folder)
        return None
