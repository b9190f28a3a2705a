"""The network a board holds, and its weight-shared synapse tables.

A neuromorphic board runs one fixed network for every input, so an export
holds the *whole* description: every cell of every population
(:func:`board_network`). The one input-dependent part of the description,
the coarse levels' edge mask (``Population.edge_mask``: cells exist only
where the resized edge map of the input reaches ``support_min``), cannot be
part of a fixed network; the board network has those cells everywhere, and
the export's notes say so (its cost is measured in
``experiments/results/export_fidelity.md``). The gated populations carry
the mask too; for them it only leaves out cells that cannot fire, so
dropping it changes nothing but the cell count.

Each projection becomes a table that needs no unrolling to store
(:mod:`snn_fg.lowering.kernel_tables`: :class:`ConvTable` of a Conv's kept
taps, :class:`ResizeTable` of a Resize's two 1-D matrices).

:func:`whole_pairs` unrolls a table into explicit synapses with the
standalone code the PyNN export runs (:mod:`.pynn_tables`).
"""

from __future__ import annotations

import dataclasses
import hashlib

import numpy as np

from ..lowering.kernel_tables import ConvTable, ResizeTable, geometry, table
from ..network.graph import Network
from ..network.projections import Projection
from ..pynn.tables import conv_pairs, resize_pairs

__all__ = [
    "ConvTable",
    "ResizeTable",
    "board_network",
    "fingerprint",
    "geometry",
    "table",
    "table_values",
    "whole_pairs",
]

BOARD_NOTE = (
    "Export: the board network has every cell of every population; the coarse levels' edge mask "
    "(cells only where the input's resized edge map >= support_min) depends on the input and is "
    "left out."
)


def fingerprint(network: Network) -> str:
    """SHA-256 of a description's JSON: which network an artefact was made from."""
    return hashlib.sha256(network.to_json(indent=None).encode()).hexdigest()


def board_network(network: Network) -> Network:
    """The whole, input-independent network: ``edge_mask`` dropped (noted)."""
    if not any(p.edge_mask for p in network.populations):
        return network
    pops = tuple(dataclasses.replace(p, edge_mask=False) for p in network.populations)
    return dataclasses.replace(network, populations=pops, notes=network.notes + (BOARD_NOTE,))


def whole_pairs(network: Network, pr: Projection, tab=None):
    """Explicit synapses ``(pre, post, K)`` of ``pr`` between the whole
    source and target populations (flat cell indices)."""
    tab = table(network, pr) if tab is None else tab
    src, tgt = network.population(pr.source), network.population(pr.target)
    if isinstance(tab, ConvTable):
        return conv_pairs(tab.taps, tab.values, geometry(src), geometry(tgt), tab.wrap)
    return resize_pairs(tab.rows, tab.cols, src.channels, geometry(src), geometry(tgt), tab.k_min)


def table_values(tab) -> np.ndarray:
    """Every distinct kernel (or interpolation product) value the table can give."""
    if isinstance(tab, ConvTable):
        return tab.values
    (_, rv), (_, cv) = tab.rows, tab.cols
    vals = np.unique(np.round(np.outer(np.unique(rv[rv != 0]), np.unique(cv[cv != 0])).ravel(), 12))
    return vals[(vals != 0) & (np.abs(vals) >= tab.k_min)]
