"""A projection's weight-shared table: what an export stores and a board
holds, unrolled into synapses only where they are made.

* :class:`ConvTable` - the kept kernel taps ``(c_out, c_in, dr, dc)`` and
  their values: target channel ``c_out`` at level pixel ``p`` reads source
  channel ``c_in`` at ``p + (dr, dc)`` (a ``conv``-mode kernel is flipped
  here once);
* :class:`ResizeTable` - the two 1-D interpolation matrices, sparse.

:func:`table_fields` are the fields an export's ``network.json`` gives a
projection's table beside it, which :mod:`snn_fg.pynn.tables` and
:mod:`snn_fg.lava.synapses` read.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..network.graph import Network
from ..network.nodes import Population
from ..network.projections import Conv, Projection
from .connect import kernel_taps
from .interp import interp_matrix, sparse_rows


def geometry(pop: Population) -> dict:
    """What the standalone unroller needs to know of a population."""
    return {
        "level_shape": tuple(pop.level_shape),
        "grid": tuple(pop.grid),
        "stride": pop.stride,
        "channels": pop.channels,
    }


@dataclass(frozen=True)
class ConvTable:
    """Kept taps of a Conv: rows ``(c_out, c_in, dr, dc)`` and kernel values."""

    taps: np.ndarray
    values: np.ndarray
    wrap: bool
    kept_mass: float


@dataclass(frozen=True)
class ResizeTable:
    """A Resize's 1-D matrices as per-row (index, value) arrays; products under ``k_min`` are left out."""

    rows: tuple
    cols: tuple
    k_min: float


def table(network: Network, pr: Projection):
    """The weight-shared table of projection ``pr``."""
    if isinstance(pr, Conv):
        co, ci, dr, dc, kv, kept = kernel_taps(pr, network)
        return ConvTable(
            np.stack([co, ci, dr, dc], axis=1).astype(np.int64), kv.astype(np.float64), pr.padding == "wrap", kept
        )
    src, tgt = network.population(pr.source), network.population(pr.target)
    mats = [
        interp_matrix(src.level_shape[a], tgt.level_shape[a], src.stride, tgt.stride, pr.interpolation) for a in (0, 1)
    ]
    peak = float(np.abs(mats[0]).max() * np.abs(mats[1]).max())
    return ResizeTable(sparse_rows(mats[0]), sparse_rows(mats[1]), pr.prune * peak if pr.prune > 0 else 0.0)


def table_fields(tab) -> dict:
    """The table's kind and its one parameter, as ``network.json`` records them."""
    if isinstance(tab, ConvTable):
        return {"type": "conv", "wrap": tab.wrap}
    return {"type": "resize", "k_min": tab.k_min}
