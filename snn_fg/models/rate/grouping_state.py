"""The state of stages 5-8 in and out of the event-driven engine
(:class:`~snn_fg.models.rate.grouping.SparseGrouping`): as dense maps
(:meth:`GroupingState.dense`, the form the spiking decoder also fills), set
from such maps (:meth:`GroupingState.load`, another implementation's state),
and read out as stage 9's maps (:meth:`GroupingState.readout`)."""

from __future__ import annotations

import numpy as np

from ...frames.pyramid import resize
from .grouping_tables import GroupingResult


class GroupingState:
    """Reading and setting the engine's state; the engine keeps its ``levels``
    (each with its entries ``e``, ``bl``, ``bd`` and padded grouping maps) and ``n``."""

    def load(self, state: GroupingResult, border: bool = True, grouping: bool = True) -> GroupingState:
        """Set the border-ownership values ``B`` (at this engine's entries)
        and/or the grouping maps from dense maps in the form of :meth:`dense`,
        e.g. a spiking network's decoded rates, so that the model's own
        stages (:meth:`group_step`, :meth:`feedback_step`) can be applied to
        another implementation's state. Values are taken as they are (Hz
        stay Hz). Returns ``self``."""
        n = self.n
        for k, lv in enumerate(self.levels):
            e = lv.e
            if border:
                hi = e.ch >= n
                o = np.where(hi, e.ch - n, e.ch)
                at = (o, e.rows, e.cols)
                lv.bl = np.where(hi, state.bl2[k][at], state.bl1[k][at]).astype(np.float64)
                lv.bd = np.where(hi, state.bd1[k][at], state.bd2[k][at]).astype(np.float64)
            if grouping:
                lv.interior(lv.g_l)[...] = state.gl[k]
                lv.interior(lv.g_d)[...] = state.gd[k]
        return self

    def grouping_maps(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """``(GL, GD)`` per level (copies, ``(h, w)``)."""
        return [(lv.interior(lv.g_l).copy(), lv.interior(lv.g_d).copy()) for lv in self.levels]

    def _dense_family(self, lv, values, family_hi: bool):
        n, e = self.n, lv.e
        out = np.zeros((n,) + lv.shape)
        sel = (e.ch >= n) if family_hi else (e.ch < n)
        np.add.at(out, (e.ch[sel] - (n if family_hi else 0), e.rows[sel], e.cols[sel]), values[sel])
        return out

    def dense(self) -> GroupingResult:
        """The state as dense maps (the form the spiking decoder also fills)."""
        res = GroupingResult([], [], [], [], [], [], [])
        for lv, (gl, gd) in zip(self.levels, self.grouping_maps()):
            s = np.zeros((2 * self.n,) + lv.shape)
            np.add.at(s, (lv.e.ch, lv.e.rows, lv.e.cols), lv.e.s)
            res.s.append(s)
            res.bl1.append(self._dense_family(lv, lv.bl, False))
            res.bd2.append(self._dense_family(lv, lv.bd, False))
            res.bl2.append(self._dense_family(lv, lv.bl, True))
            res.bd1.append(self._dense_family(lv, lv.bd, True))
            res.gl.append(gl)
            res.gd.append(gd)
        return res

    def readout(self, full_shape) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Stage 9 from the entries: level-1 ``(fg_x, fg_y)`` and the grouping map."""
        n, lv = self.n, self.levels[0]
        e = lv.e
        hi = e.ch >= n
        o = np.where(hi, e.ch - n, e.ch)
        # B2 - B1 at orientation o: lo entries carry BD2 - BL1, hi ones BL2 - BD1.
        diff = np.where(hi, lv.bl - lv.bd, lv.bd - lv.bl)
        ang = 2 * np.pi * np.arange(n) / (2 * n) - np.pi / 2
        flat = e.rows * lv.shape[1] + e.cols
        size = lv.shape[0] * lv.shape[1]
        fg_x = np.bincount(flat, np.cos(ang)[o] * diff, minlength=size).reshape(lv.shape)
        fg_y = np.bincount(flat, np.sin(ang)[o] * diff, minlength=size).reshape(lv.shape)
        grouping = np.zeros(full_shape)
        for gl, gd in self.grouping_maps():
            grouping += resize(gl + gd, full_shape, "linear")
        return fg_x, fg_y, grouping
