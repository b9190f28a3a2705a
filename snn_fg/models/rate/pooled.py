"""Stages 5-8 with the grouping polarities pooled, and the choice of engine.

:class:`PooledGrouping` is the grouping of the natural-scene variant
(:mod:`snn_fg.models.rate.natural`, ``ModelParams.grouping_polarity = "pool"``):
no light/dark competition, the feedback reads the sum of both polarities'
grouping maps. :func:`grouping_engine` picks it or the paper's
:class:`~snn_fg.models.rate.grouping.SparseGrouping` from the parameters, for every
model that runs stages 5-8 (:mod:`snn_fg.models.rate.edfg`).
"""

from __future__ import annotations

import numpy as np

from ...params import ModelParams
from .grouping import SparseGrouping


class PooledGrouping(SparseGrouping):
    """Stages 5-8 with pooled grouping polarities (``grouping_polarity="pool"``).

    Both padded grouping maps of a level hold ``G = max(AL, 0) + max(AD, 0)``,
    so the feedback correlation of stage 8, ``GL (*) m1 - GD (*) m2``, reads
    ``G (*) m1 - G (*) m2``. :meth:`grouping_maps` gives ``(G, 0)``, so the
    grouping map of the read-out is ``G`` once, as the spiking form's light
    plus dark grouping rates are.
    """

    def _compete(self, lv) -> None:
        p, (h, w) = lv.pad, lv.shape
        inner = (slice(p, p + h), slice(p, p + w))
        g = np.maximum(lv.a_l[inner], 0.0) + np.maximum(lv.a_d[inner], 0.0)
        lv.g_l[inner] = g
        lv.g_d[inner] = g

    def grouping_maps(self) -> list[tuple[np.ndarray, np.ndarray]]:
        return [(gl, np.zeros_like(gl)) for gl, _ in super().grouping_maps()]


def grouping_engine(params: ModelParams) -> type[SparseGrouping]:
    """The stages 5-8 engine for ``params.grouping_polarity``."""
    return PooledGrouping if params.grouping_polarity == "pool" else SparseGrouping
