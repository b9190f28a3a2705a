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
import json
from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft

from ..frames.pyramid import level_shape, pyramid, resize
from ..maps import Maps
from ..network.kernels import dog_kernels, von_mises_masks
from ..params import ModelParams

_WORKERS = 2


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
def oriented_responses(pos: np.ndarray, neg: np.ndarray, params: ModelParams = ModelParams()) -> np.ndarray:
    """Thresholded DoG responses, shape ``(2*n_ori, H, W)`` (stage 3).

    Directions ``0..n_ori-1`` see ``pos``, the rest ``neg``; convolution with
    wrap-around borders; values below ``edge_threshold`` (then below
    ``sum_threshold``) are zeroed.
    """
    shape = pos.shape
    k_hat = _rfft(_place(dog_kernels(params), shape, flip=False), shape)
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


@dataclass
class RateState:
    """Everything the rate model computed, for inspection and tests."""

    resp: np.ndarray             # level-1 responses (n_dir, H, W)
    winner: np.ndarray           # level-1 winning direction (H, W)
    levels: list                 # per level: dict of S, B and G maps
    fg_x: np.ndarray
    fg_y: np.ndarray
    grouping: np.ndarray


def run_edfg_state(pos, neg, params: ModelParams = ModelParams(), progress=None) -> RateState:
    """Run stages 1-9 on an event frame and return every intermediate map."""
    pos = np.asarray(pos, dtype=np.float64)
    neg = np.asarray(neg, dtype=np.float64)
    edges = ((pos != 0) | (neg != 0)).astype(np.float64)
    n = params.n_ori
    full = pos.shape

    pyr_pos = pyramid(pos, params.levels)
    pyr_neg = pyramid(neg, params.levels)
    pyr_edges = pyramid(edges, params.levels)
    m_size = von_mises_masks(params)[0].shape[-1]

    lv: list[_Level] = []
    resp1 = winner1 = None
    for l in range(params.levels):
        resp = oriented_responses(pyr_pos[l], pyr_neg[l], params)
        winner, index = orientation_index(resp, params)
        if l == 0:
            resp1, winner1 = resp, winner
        e = pyr_edges[l]
        s = np.stack([e * (index == o) for o in range(2 * n)])
        fshape = _fshape(e.shape, m_size)
        k1, k2 = _vm_hat(float(params.r0), n, fshape)
        lv.append(_Level(e.shape, fshape, s[:n], s[n:], k1, k2))

    # Border-ownership state: BL1 = s_lo*f(d1), BD2 = s_lo*f(-d1),
    #                         BL2 = s_hi*f(d2), BD1 = s_hi*f(-d2).
    bl1 = [L.s_lo.copy() for L in lv]
    bd2 = [L.s_lo.copy() for L in lv]
    bl2 = [L.s_hi.copy() for L in lv]
    bd1 = [L.s_hi.copy() for L in lv]
    gl = [np.zeros(L.shape) for L in lv]
    gd = [np.zeros(L.shape) for L in lv]
    w = params.w_inh

    steps = range(params.iterations)
    if progress is not None:
        steps = progress(steps)
    for _ in steps:
        # Stage 7: grouping cells.
        for i, L in enumerate(lv):
            inhibit = np.array([not _allclose(bl1[i][o], bd2[i][o]) for o in range(n)])
            iw = np.where(inhibit, w, 0.0)[:, None, None]
            f_l1 = _rfft(bl1[i], L.fshape)
            f_d2 = _rfft(bd2[i], L.fshape)
            f_l2 = _rfft(bl2[i], L.fshape)
            f_d1 = _rfft(bd1[i], L.fshape)
            gl_hat = ((f_l1 - iw * f_d2) * L.k2 + (f_l2 - iw * f_d1) * L.k1).sum(axis=0)
            gd_hat = ((f_d1 - iw * f_l2) * L.k2 + (f_d2 - iw * f_l1) * L.k1).sum(axis=0)
            g = _irfft(np.stack([gl_hat, gd_hat]), L.fshape, L.shape)
            g = np.maximum(g, 0.0)
            gl[i] = np.where(g[0] > g[1], g[0], 0.0)
            gd[i] = np.where(g[1] > g[0], g[1], 0.0)

        # Stage 8: feedback, pooled across scales (k >= l, weight decay**(k-l)).
        x_levels = []
        for i, L in enumerate(lv):
            fg_ = _rfft(np.stack([gl[i], gd[i]]), L.fshape)
            d1 = fg_[0] * L.k1 - fg_[1] * L.k2      # GL*m1 - GD*m2  ->  VL1 - VD2
            d2 = fg_[0] * L.k2 - fg_[1] * L.k1      # GL*m2 - GD*m1  ->  VL2 - VD1
            x = _irfft(np.concatenate([d1, d2]), L.fshape, L.shape)
            x_levels.append(np.ascontiguousarray(np.moveaxis(x, 0, -1)))  # h, w, 2n
        for i, L in enumerate(lv):
            acc = np.zeros(L.shape + (2 * n,))
            for k in range(i, len(lv)):
                acc += params.pyramid_decay ** (k - i) * resize(x_levels[k], L.shape, "cubic")
            acc = np.moveaxis(acc, -1, 0)
            fd1 = _feedback_gain(acc[:n], params.alpha)
            fd1n = _feedback_gain(-acc[:n], params.alpha)
            fd2 = _feedback_gain(acc[n:], params.alpha)
            fd2n = _feedback_gain(-acc[n:], params.alpha)
            # Clip the product, not the gain: S itself can be negative at coarse
            # levels (bicubic undershoot of the edge map).
            bl1[i] = np.maximum(L.s_lo * fd1, 0.0)
            bd2[i] = np.maximum(L.s_lo * fd1n, 0.0)
            bl2[i] = np.maximum(L.s_hi * fd2, 0.0)
            bd1[i] = np.maximum(L.s_hi * fd2n, 0.0)

    # Stage 9: read-out at level 1.
    b1 = bl1[0] + bd1[0]
    b2 = bl2[0] + bd2[0]
    ang = 2 * np.pi * np.arange(n) / (2 * n) - np.pi / 2
    diff = b2 - b1
    fg_x = np.tensordot(np.cos(ang), diff, axes=1)
    fg_y = np.tensordot(np.sin(ang), diff, axes=1)
    grouping = np.zeros(full)
    for i in range(len(lv)):
        grouping += resize(gl[i] + gd[i], full, "linear")

    levels = [dict(s_lo=L.s_lo, s_hi=L.s_hi, bl1=bl1[i], bl2=bl2[i], bd1=bd1[i], bd2=bd2[i],
                   gl=gl[i], gd=gd[i]) for i, L in enumerate(lv)]
    return RateState(resp1, winner1, levels, fg_x, fg_y, grouping)


def run_edfg(pos, neg, params: ModelParams = ModelParams(), progress=None) -> Maps:
    """Event frame (``pos``, ``neg``) -> figure-ground and grouping maps."""
    st = run_edfg_state(pos, neg, params, progress)
    return Maps(fg_x=st.fg_x.astype(np.float32), fg_y=st.fg_y.astype(np.float32),
                grouping=st.grouping.astype(np.float32), params={"model": "rate", **params.to_dict()})
