"""Stages 5-8 of the rate model, event-driven (see ``docs/model.md``).

Border-ownership activity lives on the few pixels that carry events, so the
state is kept per *entry* (one active pixel of one channel) and every stage
costs what those entries touch:

* grouping (stage 7): each entry adds its input times its 49 x 49 von Mises
  kernel into the grouping cells' linear input ``AL``/``AD``. Only the
  *change* since the previous iteration is added; once feedback saturates most
  entries stop changing and cost nothing (when most entries change, e.g. in
  the first two iterations of a busy level, a Fourier pass is cheaper and is
  used instead);
* feedback (stage 8) is needed only where ``S`` is positive (elsewhere the
  border-ownership cells are clipped to 0), and a coarser level's feedback
  only at the bicubic taps that the finer levels' entries read when it is
  resized up to them. Per level, the feedback correlation is gathered at those
  sites, or computed densely in the Fourier domain where that is cheaper (a
  cost model; on busy frames the small coarse levels go dense); the resize is
  evaluated at the entries only, with OpenCV's own interpolation weights.

The arithmetic is the reference's (the same kernels, the same rectification
and competition, float64) with one exception: the dense feedback correlation
of a level runs in single precision (half the time of that stage, which is
the largest). Its values are weighted by 0.5 ** (k - l) and enter only a
saturating sigmoid: on the six shared BSDS frames the outputs move by at most
3e-4 (fg, values in [-2, 2]) and 2e-3 (grouping, values up to ~350) against
the all-float64 form, and Pearson r to the authors' outputs is the same to 10
digits.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import numpy as np

from ... import validate as check
from ...backends import cancel
from ...backends.cores import usable_cores
from ...params import ModelParams
from . import _sparse_kernels as nbk
from .fourier import irfft_crop, padded_shape, rfft_rows
from .grouping_state import GroupingState
from .grouping_tables import Entries, cubic_taps, kernel_tables, vm_hat, vm_hat_single

# np.allclose's tolerances: the reference leaves inhibition out for an
# orientation whose BL1 and BD2 maps are allclose.
_RTOL = 1e-5
_ATOL = 1e-8
# Gathering a feedback value costs one multiply-add per kernel entry; a dense
# Fourier-domain pass costs about as much as this many multiply-adds per grid
# cell and transform (measured here: 20-25). It decides, per level, whether
# the feedback correlation is gathered at the sites that need it or computed
# everywhere.
_FFT_COST_PER_CELL = 24.0
_FFT_COST_PER_CELL_SINGLE = 12.0  # the same in single precision
# Threads sharing the levels (this project's machines have 2 cores).
_THREADS = min(2, usable_cores())


def _feedback_gain(z, alpha):
    with np.errstate(over="ignore"):  # exp overflow -> sigmoid 0, as intended
        return 1.0 + alpha * (1.0 / (1.0 + np.exp(-z)) - 0.5)


class _Level:
    """State of one pyramid level: per-entry B values and padded AL/AD/GL/GD maps."""

    def __init__(self, entries: Entries, shape, pad: int, alpha: float):
        self.e = entries
        self.shape = tuple(shape)
        self.pad = pad
        # Where S <= 0 the clipped products S*f and S*(2-f) are 0 for any gain
        # in [0, 2] (alpha <= 2): those entries need no feedback.
        self.need = np.flatnonzero(entries.s > 0) if alpha <= 2 else np.arange(entries.s.size)
        self.bl = entries.s.copy()
        self.bd = entries.s.copy()
        self.v_l = np.zeros_like(entries.s)
        self.v_d = np.zeros_like(entries.s)
        padded = (shape[0] + 2 * pad, shape[1] + 2 * pad)
        self.a_l, self.a_d = np.zeros(padded), np.zeros(padded)
        self.g_l, self.g_d = np.zeros(padded), np.zeros(padded)
        self.sites = None  # where the feedback correlation is gathered (None: dense)
        self.x = None  # feedback correlation at the sites (dense array, sites filled)

    def interior(self, a):
        p = self.pad
        return a[p : p + self.shape[0], p : p + self.shape[1]]


class SparseGrouping(GroupingState):
    """Stages 5-8 on entries; :meth:`run` iterates, then read the state.

    Parameters
    ----------
    entries : list of Entries
        The S maps' active pixels per level, finest first.
    shapes : list of (int, int)
        The level shapes.
    params : ModelParams
    """

    def __init__(self, entries, shapes, params: ModelParams = ModelParams()):
        self.params = params
        self.n = params.n_ori
        tables = kernel_tables(float(params.r0), params.n_ori)
        self.scatter_k, self.gather_k = tables[:2], tables[2:]
        self.ksize = tables[0][0].shape[-1]
        # mean multiply-adds of one scatter or gather (both kernels' supports)
        self.support = sum(float((hi - lo).sum()) for _, lo, hi in self.gather_k) / (2 * self.n)
        pad = self.ksize // 2
        self.levels = [_Level(e, s, pad, params.alpha) for e, s in zip(entries, shapes)]
        self.z_bias = None  #: added to the finest level's pooled feedback signal (the side cue; None: none)

    # -- stage 7 --------------------------------------------------------
    def _inhibition(self, lv: _Level) -> np.ndarray:
        """Per-channel inhibition weight: ``w_inh`` unless BL1 and BD2 of the
        orientation are allclose (then 0), the same for both families."""
        n, e = self.n, lv.e
        lo = e.ch < n
        differs = np.abs(lv.bl[lo] - lv.bd[lo]) > _ATOL + _RTOL * np.abs(lv.bd[lo])
        inhibit = np.bincount(e.ch[lo][differs], minlength=n)[:n] > 0
        return np.where(np.tile(inhibit, 2), self.params.w_inh, 0.0)

    def _dense_cost(self, lv: _Level, transforms: int, per_cell: float = _FFT_COST_PER_CELL) -> float:
        fs = padded_shape(lv.shape, self.ksize // 2, self.ksize)
        return per_cell * transforms * fs[0] * fs[1]

    def _group(self, lv: _Level) -> None:
        iw = self._inhibition(lv)[lv.e.ch]
        v_l = lv.bl - iw * lv.bd
        v_d = lv.bd - iw * lv.bl
        d_l, d_d = v_l - lv.v_l, v_d - lv.v_d
        changed = np.count_nonzero((d_l != 0) | (d_d != 0))
        if changed * self.support > self._dense_cost(lv, 2 * self.n + 2):
            self._group_dense(lv, v_l, v_d)
        else:
            (kl, lol, hil), (kd, lod, hid) = self.scatter_k
            nbk.scatter(lv.a_l, lv.a_d, lv.e.rows, lv.e.cols, lv.e.ch, d_l, d_d, kl, kd, lol, hil, lod, hid)
        lv.v_l, lv.v_d = v_l, v_d
        self._compete(lv)

    def _compete(self, lv: _Level) -> None:
        """The grouping maps from their linear inputs: rectified, and light
        against dark winner-take-all per pixel."""
        nbk.winner_take_all(lv.g_l, lv.g_d, lv.a_l, lv.a_d, lv.pad)

    def _group_dense(self, lv: _Level, v_l, v_d) -> None:
        """``AL``/``AD`` recomputed in the Fourier domain (when most entries
        changed, e.g. the first iterations): lo channels reach ``AL`` through
        ``m2`` and ``AD`` through ``m1``, hi channels the other way round."""
        n, e = self.n, lv.e
        fs = padded_shape(lv.shape, self.ksize // 2, self.ksize)
        k1, k2 = vm_hat(float(self.params.r0), n, fs)

        def spectrum(v):
            maps = np.zeros((2 * n,) + lv.shape)
            maps[e.ch, e.rows, e.cols] = v
            return rfft_rows(maps, fs)

        hat_l = spectrum(v_l)
        # The common cases need one set of transforms: no inhibition (v_d = v_l)
        # and full inhibition with w_inh = 1 (v_d = -v_l).
        hat_d = hat_l if np.array_equal(v_d, v_l) else -hat_l if np.array_equal(v_d, -v_l) else spectrum(v_d)
        a_l = np.sum(hat_l[:n] * k2, axis=0) + np.sum(hat_l[n:] * k1, axis=0)
        a_d = np.sum(hat_d[:n] * k1, axis=0) + np.sum(hat_d[n:] * k2, axis=0)
        a = irfft_crop(np.stack([a_l, a_d]), fs, lv.shape)
        # Only the interior is read (by the competition); the border keeps stale values.
        lv.interior(lv.a_l)[...] = a[0]
        lv.interior(lv.a_d)[...] = a[1]

    # -- stage 8 --------------------------------------------------------
    def _plan_feedback(self) -> None:
        """Per level, where its feedback correlation is needed (its own
        positive entries and the bicubic taps of every finer level's ones) and
        whether gathering it there is cheaper than one dense Fourier pass."""
        support = self.support
        for k, lv in enumerate(self.levels):
            dense = self._dense_cost(lv, 2 * self.n + 2, _FFT_COST_PER_CELL_SINGLE)
            lv.sites = None
            if lv.need.size * support >= dense:
                continue
            if k == 0:  # nothing finer pools from the finest level: its own entries
                need = lv.need
                lv.sites = (lv.e.rows[need], lv.e.cols[need], lv.e.ch[need])
                lv.x = np.zeros((2 * self.n,) + lv.shape)
                continue
            mark = np.zeros((2 * self.n,) + lv.shape, bool)
            mark[lv.e.ch[lv.need], lv.e.rows[lv.need], lv.e.cols[lv.need]] = True
            for fine in self.levels[:k]:
                rs, _ = cubic_taps(lv.shape[0], fine.shape[0])
                cs, _ = cubic_taps(lv.shape[1], fine.shape[1])
                nd = fine.need
                nbk.mark_taps(mark, fine.e.rows[nd], fine.e.cols[nd], fine.e.ch[nd], rs, cs)
            if np.count_nonzero(mark) * support < dense:
                ch, r, c = np.nonzero(mark)
                lv.sites = (r.astype(np.int64), c.astype(np.int64), ch.astype(np.int64))
                lv.x = np.zeros((2 * self.n,) + lv.shape)

    def _correlate(self, lv: _Level) -> np.ndarray:
        """``(2n, h, w)``: ``d1 = GL*m1 - GD*m2`` then ``d2 = GL*m2 - GD*m1``,
        everywhere (Fourier domain) or only at the level's planned sites."""
        if lv.sites is not None:
            rows, cols, ch = lv.sites
            vals = np.empty(rows.size)
            (kl, lol, hil), (kd, lod, hid) = self.gather_k
            nbk.gather(vals, lv.g_l, lv.g_d, rows, cols, ch, kl, kd, lol, hil, lod, hid)
            lv.x[ch, rows, cols] = vals
            return lv.x
        return self._correlate_dense(lv)

    def _correlate_dense(self, lv: _Level) -> np.ndarray:
        fs = padded_shape(lv.shape, self.ksize // 2, self.ksize)
        k1, k2 = vm_hat_single(float(self.params.r0), self.n, fs)
        g = rfft_rows(np.stack([lv.interior(lv.g_l), lv.interior(lv.g_d)]).astype(np.float32), fs)
        d = np.concatenate([g[0] * k1 - g[1] * k2, g[0] * k2 - g[1] * k1])
        return irfft_crop(d, fs, lv.shape)

    def _feedback(self, x: list, i: int) -> None:
        """Stage 8 at level ``i``: pool the levels ``k >= i`` at its entries and update B."""
        p = self.params
        lv = self.levels[i]
        e, need = lv.e, lv.need
        rows, cols, ch = e.rows[need], e.cols[need], e.ch[need]
        acc = x[i][ch, rows, cols]
        for k in range(i + 1, len(self.levels)):
            rs, rw = cubic_taps(self.levels[k].shape[0], lv.shape[0])
            cs, cw = cubic_taps(self.levels[k].shape[1], lv.shape[1])
            nbk.pool_add(acc, rows, cols, ch, x[k], rs, rw, cs, cw, p.pyramid_decay ** (k - i))
        if i == 0 and self.z_bias is not None:
            acc += self.z_bias[need]
        f = _feedback_gain(acc, p.alpha)
        s = e.s[need]
        lv.bl = np.zeros_like(e.s)
        lv.bd = np.zeros_like(e.s)
        # f(-z) = 2 - f(z). Clip the product, not the gain: S itself can be
        # negative at coarse levels (bicubic undershoot of the edge map).
        lv.bl[need] = np.maximum(s * f, 0.0)
        lv.bd[need] = np.maximum(s * (2.0 - f), 0.0)

    def _level_step(self, lv: _Level) -> np.ndarray:
        self._group(lv)
        return self._correlate(lv)

    def _step(self, pool) -> None:
        # Levels are independent within each half-step; the compiled loops and
        # the FFTs release the GIL, so two threads share the levels (largest
        # first) and the result does not depend on the schedule.
        order = np.argsort([-lv.shape[0] * lv.shape[1] for lv in self.levels], kind="stable")
        x = [None] * len(self.levels)
        for i, xi in zip(order, pool.map(lambda i: self._level_step(self.levels[i]), order)):
            x[i] = xi
        list(pool.map(lambda i: self._feedback(x, i), order))

    def continue_from(self, previous: SparseGrouping, carry: float = 1.0) -> SparseGrouping:
        """Start where ``previous`` stopped instead of from no feedback.

        ``previous`` is the engine of the frame before (same level shapes and
        parameters). Its grouping maps give this frame's first feedback, so the
        border-ownership values ``B`` begin as ``S f(z)`` of the old grouping
        rather than ``S`` (``f = 1``). Stage 8 of the previous run pooled the same
        maps, so continuing a frame from its own state after ``n`` iterations and
        running ``m`` more gives the ``n + m``-iteration maps.

        By default each frame starts afresh, as in the paper. This is the
        model run over a recording the way a network that is never reset
        runs it, e.g. to separate what the spiking network's continuous run
        inherits from the model from what comes from spiking. Returns
        ``self``; call :meth:`run` next. The iteration counts of the two may
        differ; the other parameters must not. ``carry`` in [0, 1] scales the
        grouping maps carried over (what is left of them after a partial
        forgetting); 0 starts from ``f = 1`` with ``B = max(S, 0)``.
        """
        carry = check.number("SparseGrouping.continue_from", "carry", carry, lo=0, hi=1)

        if [lv.shape for lv in previous.levels] != [lv.shape for lv in self.levels]:
            check.fail(
                "SparseGrouping.continue_from",
                None,
                None,
                "the previous frame's levels have other shapes "
                f"({[lv.shape for lv in previous.levels]} against {[lv.shape for lv in self.levels]})",
            )
        if replace(previous.params, iterations=self.params.iterations) != self.params:
            check.fail(
                "SparseGrouping.continue_from",
                None,
                None,
                "the previous frame ran with other parameters (only the iteration count may differ)",
            )
        for lv, old in zip(self.levels, previous.levels):
            np.multiply(old.g_l, carry, out=lv.g_l)
            np.multiply(old.g_d, carry, out=lv.g_d)
        return self.feedback_step()

    def group_step(self) -> SparseGrouping:
        """Stage 7 alone at every level: the grouping maps from the current ``B``."""
        for lv in self.levels:
            self._group(lv)
        return self

    def feedback_step(self) -> SparseGrouping:
        """Stage 8 alone at every level: ``B`` from the current grouping maps."""
        self._plan_feedback()
        x = [self._correlate(lv) for lv in self.levels]
        for i in range(len(self.levels)):
            self._feedback(x, i)
        return self

    def feedback_correlations(self) -> list[np.ndarray]:
        """Per level, the dense ``(2n, h, w)`` correlation of its own grouping
        maps that stage 8 pools (``z1`` channels first, then ``z2``), before
        any coarser level is added."""
        return [self._correlate_dense(lv) for lv in self.levels]

    def pooled_z(self) -> np.ndarray:
        """The pooled feedback input ``z`` of stage 8 at the finest level's
        entries (``z1`` for channels below ``n_ori``, ``z2`` above; ``S`` is 1
        at every one of them), from the current grouping maps, with :attr:`z_bias`."""
        self._plan_feedback()
        x = [self._correlate(lv) for lv in self.levels]
        lv, p = self.levels[0], self.params
        e = lv.e
        z = x[0][e.ch, e.rows, e.cols].copy()
        for k in range(1, len(self.levels)):
            rs, rw = cubic_taps(self.levels[k].shape[0], lv.shape[0])
            cs, cw = cubic_taps(self.levels[k].shape[1], lv.shape[1])
            nbk.pool_add(z, e.rows, e.cols, e.ch, x[k], rs, rw, cs, cw, p.pyramid_decay**k)
        return z if self.z_bias is None else z + self.z_bias

    def run(self, progress=None) -> SparseGrouping:
        """Iterate stages 7 and 8 ``params.iterations`` times (``progress`` wraps the range)."""
        steps = range(self.params.iterations)
        if progress is not None:
            steps = progress(steps)
        self._plan_feedback()
        with ThreadPoolExecutor(max_workers=_THREADS) as pool:
            for _ in steps:
                self._step(pool)
                cancel.check()
        return self
