"""The rate (non-spiking) event-driven figure-ground model, stages 1-9.

This is "the reference" of ``docs/model.md``: every spiking result is compared
with it. It is written for speed without changing the maths:

* every 2-D convolution/correlation is a product in the Fourier domain
  (``scipy.fft``, float64), with the circular or zero padding the reference
  uses, so the result equals a direct convolution to rounding error;
* the grouping stage uses the linearity of correlation: the feedback terms
  ``VL1 - VD2`` and ``VL2 - VD1`` are computed directly as one correlation of
  ``GL`` minus one of ``GD``, never as four separate maps;
* the cross-scale pooling resizes all orientations of a level in one OpenCV
  call (channels last).
"""
from __future__ import annotations

import functools
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft

from ..frames.pyramid import check_levels, pyramid, resize
from ..maps import Maps
from ..network.kernels import dog_kernels, von_mises_masks
from ..params import ModelParams

_WORKERS = 1
_THREADS = 2


# --------------------------------------------------------------------------
# Fourier-domain helpers
# --------------------------------------------------------------------------
def _place(kernel: np.ndarray, shape: tuple[int, int], flip: bool) -> np.ndarray:
    """Lay a centred odd kernel on a periodic grid of ``shape`` (folding if larger).

    ``flip=False`` gives the layout for a convolution, ``flip=True`` for a
    correlation (offset ``d`` placed at ``-d``).
    """
    n_r, n_c = kernel.shape[-2:]
    c_r, c_c = n_r // 2, n_c // 2
    dr = np.arange(n_r) - c_r
    dc = np.arange(n_c) - c_c
    if flip:
        dr, dc = -dr, -dc
    rows = dr % shape[0]
    cols = dc % shape[1]
    out = np.zeros(kernel.shape[:-2] + tuple(shape))
    # np.add.at folds offsets that land on the same cell (kernel wider than grid).
    idx_r, idx_c = np.meshgrid(rows, cols, indexing="ij")
    flat = out.reshape(kernel.shape[:-2] + (-1,))
    lin = (idx_r * shape[1] + idx_c).ravel()
    k = kernel.reshape(kernel.shape[:-2] + (-1,))
    if kernel.ndim == 2:
        np.add.at(flat, lin, k)
    else:
        for i in range(kernel.shape[0]):
            np.add.at(flat[i], lin, k[i])
    return out


def _rfft(x, shape):
    return sfft.rfft2(x, s=shape, axes=(-2, -1), workers=_WORKERS)


def _irfft(x, shape, crop):
    return sfft.irfft2(x, s=shape, axes=(-2, -1), workers=_WORKERS)[..., : crop[0], : crop[1]]


# --------------------------------------------------------------------------
# Stages 3-4: oriented responses and the orientation matrix
# --------------------------------------------------------------------------
@functools.lru_cache(maxsize=64)
def _dog_hat(s1, s2, half_width, step, n_ori, shape):
    p = ModelParams(dog_s1=s1, dog_s2=s2, dog_half_width=half_width, dog_step=step, n_ori=n_ori)
    return _rfft(_place(dog_kernels(p), shape, flip=False), shape)


def oriented_responses(pos: np.ndarray, neg: np.ndarray, params: ModelParams = ModelParams()) -> np.ndarray:
    """Thresholded DoG responses, shape ``(2*n_ori, H, W)`` (stage 3).

    Directions ``0..n_ori-1`` see ``pos``, the rest ``neg``; convolution with
    wrap-around borders; values below ``edge_threshold`` (then below
    ``sum_threshold``) are zeroed.
    """
    shape = pos.shape
    k_hat = _dog_hat(params.dog_s1, params.dog_s2, params.dog_half_width, params.dog_step,
                     params.n_ori, shape)
    n = params.n_ori
    src = _rfft(np.stack([pos, neg]).astype(np.float64), shape)
    resp = np.empty((2 * n,) + shape)
    resp[:n] = _irfft(src[0] * k_hat[:n], shape, shape)
    resp[n:] = _irfft(src[1] * k_hat[n:], shape, shape)
    resp[resp < params.edge_threshold] = 0.0
    resp[resp < params.sum_threshold] = 0.0
    return resp


def orientation_index(resp: np.ndarray, params: ModelParams = ModelParams()) -> tuple[np.ndarray, np.ndarray]:
    """Winning direction per pixel and its border-ownership index (stage 4).

    Returns ``(winner, index)``: ``winner`` is the arg-max direction of
    ``|resp|`` (first wins ties, so all-zero pixels get 0), ``index`` is the
    normal's index ``(winner + n_dir/4) mod n_dir``.
    """
    winner = np.argmax(np.abs(resp), axis=0)
    n_dir = params.n_dir
    theta = winner * (2 * np.pi / n_dir)
    index = (np.round(theta / (2 * np.pi) * n_dir).astype(int) + n_dir // 4) % n_dir
    return winner, index


# --------------------------------------------------------------------------
# Stages 5-9
# --------------------------------------------------------------------------
@dataclass
class _Level:
    shape: tuple[int, int]
    fshape: tuple[int, int]      # padded Fourier grid for zero-padded correlation
    s_lo: np.ndarray             # S[o], o < n_ori          (n_ori, h, w)
    s_hi: np.ndarray             # S[o + n_ori]             (n_ori, h, w)
    k1: np.ndarray               # rfft of m1 (correlation layout)
    k2: np.ndarray               # rfft of m2


@functools.lru_cache(maxsize=64)
def _vm_hat(r0: float, n_ori: int, fshape: tuple[int, int]):
    m1, m2 = von_mises_masks(ModelParams(r0=r0, n_ori=n_ori))
    k1 = _rfft(_place(m1, fshape, flip=True), fshape)
    k2 = _rfft(_place(m2, fshape, flip=True), fshape)
    return k1, k2


def _fshape(shape, kernel_size):
    c = kernel_size // 2
    return tuple(sfft.next_fast_len(max(n + c, kernel_size), real=True) for n in shape)


def _feedback_gain(z, alpha):
    with np.errstate(over="ignore"):   # exp overflow -> sigmoid 0, as intended
        return 1.0 + alpha * (1.0 / (1.0 + np.exp(-z)) - 0.5)


def _allclose(a, b):
    return np.allclose(a, b, rtol=1e-5, atol=1e-8)


def event_simple_cells(pos, neg, params: ModelParams = ModelParams()):
    """Stages 1-4: S maps per pyramid level from an event frame.

    Returns ``(s_levels, resp1, winner1)``: ``s_levels[l]`` is ``(2*n_ori, h, w)``
    with ``S[o] = edges * (index == o)``; ``resp1``/``winner1`` are the level-1
    responses and winning directions.
    """
    pos = np.asarray(pos, dtype=np.float64)
    neg = np.asarray(neg, dtype=np.float64)
    edges = ((pos != 0) | (neg != 0)).astype(np.float64)
    pyr_pos = pyramid(pos, params.levels)
    pyr_neg = pyramid(neg, params.levels)
    pyr_edges = pyramid(edges, params.levels)
    s_levels = []
    resp1 = winner1 = None
    for l in range(params.levels):
        resp = oriented_responses(pyr_pos[l], pyr_neg[l], params)
        winner, index = orientation_index(resp, params)
        if l == 0:
            resp1, winner1 = resp, winner
        s_levels.append(pyr_edges[l][None] * (index[None] == np.arange(params.n_dir)[:, None, None]))
    return s_levels, resp1, winner1


@dataclass
class GroupingResult:
    """Border-ownership and grouping maps per level after the iterations."""

    s: list     # (2n, h, w) per level
    bl1: list   # (n, h, w) per level; likewise bl2, bd1, bd2
    bl2: list
    bd1: list
    bd2: list
    gl: list    # (h, w) per level; likewise gd
    gd: list


def border_ownership_grouping(s_levels, params: ModelParams = ModelParams(), progress=None) -> GroupingResult:
    """Stages 5-8: iterate grouping cells and feedback on the S pyramid."""
    n = params.n_ori
    m_size = von_mises_masks(params)[0].shape[-1]
    lv: list[_Level] = []
    for s in s_levels:
        shape = s.shape[1:]
        fshape = _fshape(shape, m_size)
        k1, k2 = _vm_hat(float(params.r0), n, fshape)
        lv.append(_Level(shape, fshape, s[:n], s[n:], k1, k2))

    # Border-ownership state: BL1 = s_lo*f(d1), BD2 = s_lo*f(-d1),
    #                         BL2 = s_hi*f(d2), BD1 = s_hi*f(-d2).
    bl1 = [L.s_lo.copy() for L in lv]
    bd2 = [L.s_lo.copy() for L in lv]
    bl2 = [L.s_hi.copy() for L in lv]
    bd1 = [L.s_hi.copy() for L in lv]
    gl = [np.zeros(L.shape) for L in lv]
    gd = [np.zeros(L.shape) for L in lv]
    x_levels = [None] * len(lv)
    w = params.w_inh

    def grouping_cells(i):
        """Stage 7 at level i: GL, GD from the border-ownership maps."""
        L = lv[i]
        inhibit = np.array([not _allclose(bl1[i][o], bd2[i][o]) for o in range(n)])
        iw = np.where(inhibit, w, 0.0)[:, None, None]
        # Inputs of the four correlations (opposite family subtracted where
        # inhibiting): gL1 = in_l1 (*) m2, gL2 = in_l2 (*) m1, gD1 = in_d1 (*) m2,
        # gD2 = in_d2 (*) m1. Two common cases need half the transforms: full
        # inhibition with w = 1 (in_d2 = -in_l1, in_d1 = -in_l2) and no
        # inhibition with equal families (the first iteration: in_d2 = in_l1).
        in_l1 = bl1[i] - iw * bd2[i]
        in_l2 = bl2[i] - iw * bd1[i]
        if w == 1.0 and inhibit.all():
            half = _rfft(np.concatenate([in_l1, in_l2]), L.fshape)
            f = np.concatenate([half, -half[n:], -half[:n]])
        elif not inhibit.any() and np.array_equal(bl1[i], bd2[i]) and np.array_equal(bl2[i], bd1[i]):
            half = _rfft(np.concatenate([in_l1, in_l2]), L.fshape)
            f = np.concatenate([half, half[n:], half[:n]])
        else:
            f = _rfft(np.concatenate([in_l1, in_l2, bd1[i] - iw * bl2[i], bd2[i] - iw * bl1[i]]),
                      L.fshape)
        gl_hat = np.sum(f[:n] * L.k2, axis=0) + np.sum(f[n:2 * n] * L.k1, axis=0)
        gd_hat = np.sum(f[2 * n:3 * n] * L.k2, axis=0) + np.sum(f[3 * n:] * L.k1, axis=0)
        g = np.maximum(_irfft(np.stack([gl_hat, gd_hat]), L.fshape, L.shape), 0.0)
        gl[i] = np.where(g[0] > g[1], g[0], 0.0)
        gd[i] = np.where(g[1] > g[0], g[1], 0.0)
        # The level's share of stage 8: VL1 - VD2 and VL2 - VD1 before pooling.
        fg_ = _rfft(np.stack([gl[i], gd[i]]), L.fshape)
        d1 = fg_[0] * L.k1 - fg_[1] * L.k2      # GL (*) m1 - GD (*) m2
        d2 = fg_[0] * L.k2 - fg_[1] * L.k1      # GL (*) m2 - GD (*) m1
        x = _irfft(np.concatenate([d1, d2]), L.fshape, L.shape)
        x_levels[i] = np.ascontiguousarray(np.moveaxis(x, 0, -1))  # h, w, 2n

    def feedback(i):
        """Stage 8 at level i: pool the levels k >= i and update the B maps."""
        L = lv[i]
        acc = np.zeros(L.shape + (2 * n,))
        for k in range(i, len(lv)):
            acc += params.pyramid_decay ** (k - i) * resize(x_levels[k], L.shape, "cubic")
        acc = np.moveaxis(acc, -1, 0)
        f1 = _feedback_gain(acc[:n], params.alpha)
        f2 = _feedback_gain(acc[n:], params.alpha)
        # f(-z) = 2 - f(z). Clip the product, not the gain: S itself can be
        # negative at coarse levels (bicubic undershoot of the edge map).
        bl1[i] = np.maximum(L.s_lo * f1, 0.0)
        bd2[i] = np.maximum(L.s_lo * (2.0 - f1), 0.0)
        bl2[i] = np.maximum(L.s_hi * f2, 0.0)
        bd1[i] = np.maximum(L.s_hi * (2.0 - f2), 0.0)

    steps = range(params.iterations)
    if progress is not None:
        steps = progress(steps)
    # numpy and pocketfft release the GIL: two threads, level 1 (about half
    # the work) on one, the coarser levels on the other.
    with ThreadPoolExecutor(max_workers=_THREADS) as pool:
        for _ in steps:
            list(pool.map(grouping_cells, range(len(lv))))
            list(pool.map(feedback, range(len(lv))))

    return GroupingResult(list(s_levels), bl1, bl2, bd1, bd2, gl, gd)


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
    """Everything the rate model computed, for inspection and tests."""

    resp: np.ndarray             # level-1 responses (n_dir, H, W)
    winner: np.ndarray           # level-1 winning direction (H, W)
    grouping_result: GroupingResult
    fg_x: np.ndarray
    fg_y: np.ndarray
    grouping: np.ndarray


def run_edfg_state(pos, neg, params: ModelParams = ModelParams(), progress=None) -> RateState:
    """Run stages 1-9 on an event frame and return every intermediate map."""
    check_levels(np.shape(pos), params.levels)
    s_levels, resp1, winner1 = event_simple_cells(pos, neg, params)
    g = border_ownership_grouping(s_levels, params, progress)
    fg_x, fg_y, grouping = readout(g, params, np.shape(pos))
    return RateState(resp1, winner1, g, fg_x, fg_y, grouping)


def run_edfg(pos, neg, params: ModelParams = ModelParams(), progress=None) -> Maps:
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

    Returns
    -------
    Maps
        ``fg_x``, ``fg_y`` (the figure-ground field, x right, y up) and
        ``grouping`` (float32, H x W), and ``params``.

    Examples
    --------
    >>> from snn_fg.events import image_to_frame
    >>> from snn_fg.metrics import grouping_peak_inside
    >>> from snn_fg.scenes import disc
    >>> scene = disc(radius=16)
    >>> maps = run_edfg(*image_to_frame(scene.image))
    >>> maps.fg_x.shape, grouping_peak_inside(maps.grouping, scene)
    ((64, 64), True)
    """
    st = run_edfg_state(pos, neg, params, progress)
    return Maps(fg_x=st.fg_x.astype(np.float32), fg_y=st.fg_y.astype(np.float32),
                grouping=st.grouping.astype(np.float32), params={"model": "rate", **params.to_dict()})
