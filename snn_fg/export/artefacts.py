"""The exported artefacts kept in ``networks/``: the default iCub-size (304 x 240)
network as a NIR graph and its hardware resource report.

:func:`write_artefacts` regenerates them (``python experiments/spiking_export_network.py``
writes every file of ``networks/``); :func:`fingerprint` identifies the
description they were made from, so a test can check they are current
without regenerating them.
"""

from __future__ import annotations

import gzip
import json
import shutil
import tempfile
from pathlib import Path

from ..events.yarp import SENSOR_SIZE
from ..network import SpikingParams, build_network
from ..params import ModelParams
from ..results.atomic import atomic_path, save_text
from .board import fingerprint
from .nir import export_nir
from .report import report_table, resource_report

ICUB_SHAPE = SENSOR_SIZE[::-1]  # rows, cols of the iCub ATIS
NIR_NAME = "icub_304x240.nir.gz"  # gzipped: the HDF5 file is large (its size: networks/README.md)
REPORT_NAME = "icub_304x240_resources.json"
REPORT_TABLE = "icub_304x240_resources.txt"


def default_icub_network():
    return build_network(ModelParams(), ICUB_SHAPE, SpikingParams())


def _gzipped_nir(net, path: Path) -> Path:

    with tempfile.TemporaryDirectory() as tmp:
        raw = export_nir(net, Path(tmp) / "net.nir")
        with (
            atomic_path(path, suffix=".gz") as part,
            open(raw, "rb") as src,
            gzip.GzipFile(part, "wb", compresslevel=9, mtime=0) as dst,
        ):
            shutil.copyfileobj(src, dst)
    return path


def write_artefacts(folder) -> list[Path]:
    """Write the NIR graph, the resource report (JSON) and its table into ``folder``."""
    folder = Path(folder)
    net = default_icub_network()
    rep = resource_report(net)
    rep["network_sha256"] = fingerprint(net)
    written = [
        _gzipped_nir(net, folder / NIR_NAME),
        save_text(folder / REPORT_NAME, json.dumps(rep, indent=1) + "\n"),
        save_text(folder / REPORT_TABLE, report_table(rep) + "\n"),
    ]
    return written
