"""A Lava export's synapses: every projection unrolled from its weight-shared
table into ``(pre, post, W)`` with ``W = 2 m`` the stored 8-bit mantissas
(:func:`snn_fg.lava.fixed.mantissas`); what the Lava processes and the
numpy reference are both built from.

STANDALONE (numpy only; copied into every Lava export as ``fg_synapses.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

try:  # inside snn_fg
    from ..pynn.tables import conv_pairs, load_tables, resize_pairs
    from .fixed import mantissas
except ImportError:  # inside an export folder
    from fg_loihi import mantissas
    from fg_tables import conv_pairs, load_tables, resize_pairs


@dataclass(frozen=True)
class Connection:
    """One projection's synapses ``pre -> post`` (cell indices), stored
    weights ``w2m`` (``2 m``, int64), weight exponent and delay in steps."""

    name: str
    source: str
    target: str
    pre: np.ndarray
    post: np.ndarray
    w2m: np.ndarray
    weight_exp: int
    delay_steps: int


def connection(pr: dict, pops: dict, tab) -> Connection:
    """Projection ``pr`` (an entry of ``network.json``) with its table ``tab``
    as a :class:`Connection`; synapses whose mantissa rounds to 0 are left out."""
    src, tgt = pops[pr["source"]], pops[pr["target"]]
    if pr["type"] == "conv":
        pre, post, k = conv_pairs(tab[0], tab[1], src, tgt, pr["wrap"])
    else:
        pre, post, k = resize_pairs(tab[0], tab[1], src["channels"], src, tgt, pr["k_min"])
    lava = pr["lava"]
    m = mantissas(pr["sign"] * pr["gain_mv"] * k, lava["factor"])
    keep = m != 0
    return Connection(
        pr["name"],
        pr["source"],
        pr["target"],
        pre[keep],
        post[keep],
        2 * m[keep],
        int(lava["weight_exp"]),
        int(lava["delay_steps"]),
    )


def connections(meta: dict, tables) -> list:
    """Every projection of an export as a :class:`Connection`, in ``network.json``'s order."""
    pops = {p["name"]: p for p in meta["populations"]}
    tabs = load_tables(meta, tables)
    return [connection(pr, pops, tabs[pr["name"]]) for pr in meta["projections"]]
