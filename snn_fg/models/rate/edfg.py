"""The rate (non-spiking) event-driven figure-ground model, stages 1-9.

This is "the reference" of ``docs/model.md``: every spiking result is compared
with it. It is written for speed without changing the maths:

* the oriented responses (stage 3) are needed only where events are; they
  are summed there directly over the non-zero input pixels, or, when a level
  has many active pixels, as products in the Fourier domain (``scipy.fft``,
  float64) on a fast grid whose periodic padding makes the wrap-around border;
* stages 5-8 are event-driven (:mod:`snn_fg.models.rate.grouping`): their cost
  follows the pixels that carry events and the changes between iterations,
  not the frame size.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ... import validate as check
from ...frames.check import event_frame
from ...frames.pool import pool_frame, unpool_maps
from ...frames.pyramid import check_levels, level_shape, pyramid, resize
from ...network.kernels import dog_kernels
from ...params import ModelParams
from ...results.maps import Maps
from ._sparse_kernels import dog_at
from .fourier import irfft, padded_shape, place, rfft
from .grouping import SparseGrouping
from .grouping_tables import Entries, GroupingResult
from .pooled import grouping_engine
from .side_cue import side_cue_bias

__all__ = [
    "GroupingResult",
    "RateState",
    "border_ownership_grouping",
    "event_simple_cells",
    "orientation_index",
    "oriented_responses",
    "readout",
    "run_edfg",
    "run_edfg_state",
]


# --------------------------------------------------------------------------
# Stages 3-4: oriented responses and the orientation matrix
# --------------------------------------------------------------------------
@functools.lru_cache(maxsize=64)
def _dog_hat(s1, s2, half_width, step, n_ori, fshape):
    p = ModelParams(dog_s1=s1, dog_s2=s2, dog_half_width=half_width, dog_step=step, n_ori=n_ori)
    return rfft(place(dog_kernels(p), fshape, flip=False), fshape)


def oriented_responses(pos: np.ndarray, neg: np.ndarray, params: ModelParams = ModelParams()) -> np.ndarray:
    """Thresholded DoG responses, shape ``(2*n_ori, H, W)`` (stage 3).

    Directions ``0..n_ori-1`` see ``pos``, the rest ``neg``; convolution with
    wrap-around borders; values below ``edge_threshold`` (then below
    ``sum_threshold``) are zeroed.
    """
    shape = pos.shape
    half = dog_kernels(params).shape[-1] // 2
    # A linear convolution of the periodically padded input equals the
    # circular one on the frame, and runs on a fast FFT grid.
    fshape = padded_shape(shape, 2 * half)
    k_hat = _dog_hat(params.dog_s1, params.dog_s2, params.dog_half_width, params.dog_step, params.n_ori, fshape)
    n = params.n_ori
    src = np.pad(np.stack([pos, neg]).astype(np.float64), ((0, 0), (half, half), (half, half)), mode="wrap")
    src = rfft(src, fshape)
    crop = (Ellipsis, slice(half, half + shape[0]), slice(half, half + shape[1]))
    resp = np.empty((2 * n,) + shape)
    resp[:n] = irfft(src[0] * k_hat[:n], fshape)[crop]
    resp[n:] = irfft(src[1] * k_hat[n:], fshape)[crop]
    resp[resp < params.edge_threshold] = 0.0
    resp[resp < params.sum_threshold] = 0.0
    return resp


def orientation_index(resp: np.ndarray, params: ModelParams = ModelParams()) -> tuple[np.ndarray, np.ndarray]:
    """Winning direction per pixel and its border-ownership index (stage 4).

    Returns ``(winner, index)``: ``winner`` is the arg-max direction of
    ``|resp|`` (first wins ties, so all-zero pixels get 0), ``index`` is the
    normal's index ``(winner + n_dir/4) mod n_dir``. ``resp`` is
    ``(n_dir, ...)``: a map or the responses of a list of pixels.
    """
    winner = np.argmax(np.abs(resp), axis=0)
    n_dir = params.n_dir
    theta = winner * (2 * np.pi / n_dir)
    index = (np.round(theta / (2 * np.pi) * n_dir).astype(int) + n_dir // 4) % n_dir
    return winner, index


# Cost model of the responses at a level, in units of one kernel tap tested
# at one pixel of the sparse loop: a non-zero input adds ~3 units (its
# multiply-adds), a dense Fourier pass ~2.6 units per grid cell and transform
# (both measured here on the shared frames).
_TAP_COST_PER_NONZERO = 3.0
_FFT_COST_PER_CELL = 2.6


@functools.lru_cache(maxsize=8)
def _dog_table(s1, s2, half_width, step, n_ori):
    p = ModelParams(dog_s1=s1, dog_s2=s2, dog_half_width=half_width, dog_step=step, n_ori=n_ori)
    return np.ascontiguousarray(np.moveaxis(dog_kernels(p), 0, -1))


def responses_at(pos, neg, rows, cols, params: ModelParams = ModelParams()) -> np.ndarray:
    """:func:`oriented_responses` at the listed pixels only, ``(2*n_ori, pixels)``.

    Costs a look-up per kernel tap and pixel (a multiply-add per direction
    where the input is non-zero) instead of a pass over the whole frame.
    """
    table = _dog_table(params.dog_s1, params.dog_s2, params.dog_half_width, params.dog_step, params.n_ori)
    out = np.zeros((rows.size, params.n_dir))
    dog_at(
        out, rows, cols, np.ascontiguousarray(pos, dtype=np.float64), np.ascontiguousarray(neg, dtype=np.float64), table
    )
    out[out < params.edge_threshold] = 0.0
    out[out < params.sum_threshold] = 0.0
    return out.T


def _level_responses(pos, neg, rows, cols, params):
    """Thresholded responses at ``(rows, cols)``: gathered there, or from a
    dense pass when that is cheaper (many active pixels)."""
    size = dog_kernels(params).shape[-1]
    fs = padded_shape(pos.shape, size - 1)
    density = (np.count_nonzero(pos) + np.count_nonzero(neg)) / pos.size
    sparse = rows.size * size * size * (1 + _TAP_COST_PER_NONZERO * density)
    if sparse < _FFT_COST_PER_CELL * (2 + params.n_dir) * fs[0] * fs[1]:
        return responses_at(pos, neg, rows, cols, params)
    return oriented_responses(pos, neg, params)[:, rows, cols]


def event_entries(pos, neg, params: ModelParams = ModelParams()):
    """Stages 1-4 as entries: the active pixels of the S maps per level.

    Returns ``(entries, shapes)``: ``entries[l]`` lists the pixels where the
    level's edge map is non-zero, each with its orientation index as channel
    and the edge value as ``s`` (``S[o] = edges * (index == o)``).
    """
    pos = np.asarray(pos, dtype=np.float64)
    neg = np.asarray(neg, dtype=np.float64)
    edges = ((pos != 0) | (neg != 0)).astype(np.float64)
    per_octave = params.levels_per_octave
    pyr_pos = pyramid(pos, params.levels, per_octave)
    pyr_neg = pyramid(neg, params.levels, per_octave)
    pyr_edges = pyramid(edges, params.levels, per_octave)
    entries = []
    for i in range(params.levels):
        rows, cols = np.nonzero(pyr_edges[i])
        rows, cols = rows.astype(np.int64), cols.astype(np.int64)
        _, index = orientation_index(_level_responses(pyr_pos[i], pyr_neg[i], rows, cols, params), params)
        entries.append(Entries(rows, cols, index.astype(np.int64), pyr_edges[i][rows, cols]))
    shapes = [level_shape(pos.shape, level, per_octave) for level in range(1, params.levels + 1)]
    return entries, shapes


def event_simple_cells(pos, neg, params: ModelParams = ModelParams()):
    """Stages 1-4: S maps per pyramid level from an event frame.

    Returns ``(s_levels, resp1, winner1)``: ``s_levels[l]`` is ``(2*n_ori, h, w)``
    with ``S[o] = edges * (index == o)``; ``resp1``/``winner1`` are the level-1
    responses and winning directions.
    """
    entries, shapes = event_entries(pos, neg, params)
    resp1 = oriented_responses(np.asarray(pos, dtype=np.float64), np.asarray(neg, dtype=np.float64), params)
    winner1 = orientation_index(resp1, params)[0]
    s_levels = []
    for e, shape in zip(entries, shapes):
        s = np.zeros((params.n_dir,) + tuple(shape))
        s[e.ch, e.rows, e.cols] = e.s
        s_levels.append(s)
    return s_levels, resp1, winner1


def border_ownership_grouping(s_levels, params: ModelParams = ModelParams(), progress=None) -> GroupingResult:
    """Stages 5-8: iterate grouping cells and feedback on the S pyramid (dense in, dense out); no side cue
    (it reads events, which the S pyramid no longer holds)."""
    if params.side_cue:
        check.fail(
            "border_ownership_grouping",
            "side_cue",
            params.side_cue,
            "must be 0: the side cue reads events, and the frame-based model (fbfg) has none",
        )
    entries = [Entries.from_dense(s) for s in s_levels]
    shapes = [s.shape[1:] for s in s_levels]
    return grouping_engine(params)(entries, shapes, params).run(progress).dense()


def readout(g: GroupingResult, params: ModelParams, full_shape) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stage 9: level-1 figure-ground field ``(fg_x, fg_y)`` and the grouping map."""
    n = params.n_ori
    b1 = g.bl1[0] + g.bd1[0]
    b2 = g.bl2[0] + g.bd2[0]
    ang = 2 * np.pi * np.arange(n) / (2 * n) - np.pi / 2
    diff = b2 - b1
    fg_x = np.tensordot(np.cos(ang), diff, axes=1)
    fg_y = np.tensordot(np.sin(ang), diff, axes=1)
    grouping = np.zeros(full_shape)
    for gl, gd in zip(g.gl, g.gd):
        grouping += resize(gl + gd, full_shape, "linear")
    return fg_x, fg_y, grouping


@dataclass
class RateState:
    """Everything the rate model computed, for inspection and tests.

    The model itself evaluates responses only at active pixels; the dense
    level-1 maps ``resp``/``winner`` and the dense ``grouping_result`` are
    built on first use. ``pos``/``neg`` are the frame the model saw (pooled
    when ``params.input_pool > 1``); the maps are at the sensor's size.
    """

    pos: np.ndarray
    neg: np.ndarray
    params: ModelParams
    engine: SparseGrouping  # stages 5-8 state after the iterations
    fg_x: np.ndarray
    fg_y: np.ndarray
    grouping: np.ndarray

    @functools.cached_property
    def resp(self) -> np.ndarray:
        """Level-1 thresholded responses ``(n_dir, H, W)``."""
        return oriented_responses(np.asarray(self.pos, np.float64), np.asarray(self.neg, np.float64), self.params)

    @functools.cached_property
    def winner(self) -> np.ndarray:
        """Level-1 winning direction ``(H, W)``."""
        return orientation_index(self.resp, self.params)[0]

    @property
    def grouping_result(self) -> GroupingResult:
        """Stages 5-8 as dense maps per level (built on each use)."""
        return self.engine.dense()

    def maps(self, **extra_params) -> Maps:
        """The model's output: float32 maps and the parameters (plus ``extra_params``)."""
        return Maps(
            fg_x=self.fg_x.astype(np.float32),
            fg_y=self.fg_y.astype(np.float32),
            grouping=self.grouping.astype(np.float32),
            params={"model": "rate", **self.params.to_dict(), **extra_params},
        )


def run_edfg_state(
    pos,
    neg,
    params: ModelParams = ModelParams(),
    progress=None,
    previous: RateState | None = None,
    carry: float = 1.0,
    *,
    on_blocks: bool = False,
) -> RateState:
    """Run stages 1-9 on an event frame and return every intermediate map.

    With ``previous`` (the state of the frame before, same shape) the
    grouping and feedback start where that frame stopped instead of afresh,
    with the fraction ``carry`` of its grouping maps
    (:meth:`~snn_fg.models.rate.grouping.SparseGrouping.continue_from`).
    With ``params.input_pool > 1`` the model runs on the pooled frame
    (:mod:`snn_fg.frames.pool`) and its maps come back at the sensor's size,
    or stay on the blocks with ``on_blocks``.
    """
    event_frame("run_edfg", pos, neg)
    sensor_edges = (np.asarray(pos) != 0) | (np.asarray(neg) != 0)
    pos, neg = pool_frame(pos, neg, params.input_pool)
    check_levels(np.shape(pos), params.levels, per_octave=params.levels_per_octave)
    entries, shapes = event_entries(pos, neg, params)
    engine = grouping_engine(params)(entries, shapes, params)
    if params.side_cue:
        e = entries[0]
        engine.z_bias = side_cue_bias(pos, neg, e.rows, e.cols, e.ch, params)
    if previous is not None:
        engine.continue_from(previous.engine, carry)
    engine.run(progress)
    fg_x, fg_y, grouping = engine.readout(np.shape(pos))
    if not on_blocks:
        fg_x, fg_y, grouping = unpool_maps(fg_x, fg_y, grouping, sensor_edges, params.input_pool)
    return RateState(pos, neg, params, engine, fg_x, fg_y, grouping)


def run_edfg(pos, neg, params: ModelParams = ModelParams(), progress=None, *, on_blocks: bool = False) -> Maps:
    """The rate reference model (stages 1-9 of ``docs/model.md``) on one event frame.

    Parameters
    ----------
    pos, neg : array (H, W)
        The event frame: 1 where the pixel's last event was ON (``pos``) or
        OFF (``neg``), 0 elsewhere (see :func:`snn_fg.events.events_to_frame`).
    params : ModelParams
        The model's parameters (default: the paper's).
    progress : callable, optional
        Wraps the iterations of stages 7-8 (e.g. ``tqdm``).
    on_blocks : bool
        With ``params.input_pool > 1``, keep the maps on the blocks the model
        saw instead of bringing them back to the sensor's size.

    Returns
    -------
    Maps
        ``fg_x``, ``fg_y`` (the figure-ground field, x right, y up) and
        ``grouping`` (float32, H x W), and ``params``.

    Examples
    --------
    >>> from snn_fg.events import image_to_frame
    >>> from snn_fg.scoring.metrics import grouping_peak_inside
    >>> from snn_fg.frames.scenes import disc
    >>> scene = disc(radius=16)
    >>> maps = run_edfg(*image_to_frame(scene.image))
    >>> maps.fg_x.shape, grouping_peak_inside(maps.grouping, scene)
    ((64, 64), True)
    """
    return run_edfg_state(pos, neg, params, progress, on_blocks=on_blocks).maps()
