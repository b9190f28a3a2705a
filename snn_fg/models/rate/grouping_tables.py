"""What the event-driven grouping stage (:mod:`snn_fg.models.rate.grouping`) works on:
its per-level state (:class:`Entries`, :class:`GroupingResult`) and its
kernels, computed once per size: the von Mises scatter and gather tables,
their Fourier transforms, and OpenCV's bicubic resize as taps."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np

from ...network.kernels import von_mises_masks
from ...params import ModelParams
from . import _sparse_kernels as nbk
from .fourier import place, rfft


@dataclass
class GroupingResult:
    """Border-ownership and grouping maps per level after the iterations (dense)."""

    s: list  # (2n, h, w) per level
    bl1: list  # (n, h, w) per level; likewise bl2, bd1, bd2
    bl2: list
    bd1: list
    bd2: list
    gl: list  # (h, w) per level; likewise gd
    gd: list


@dataclass(frozen=True)
class Entries:
    """The active pixels of one level: entry ``e`` is ``S[ch[e]][rows[e], cols[e]] = s[e]``."""

    rows: np.ndarray
    cols: np.ndarray
    ch: np.ndarray
    s: np.ndarray

    @classmethod
    def from_dense(cls, s_map: np.ndarray) -> Entries:
        """Entries of a dense ``(2n, h, w)`` S map (its non-zero values)."""
        ch, r, c = np.nonzero(s_map)
        return cls(r.astype(np.int64), c.astype(np.int64), ch.astype(np.int64), s_map[ch, r, c].astype(np.float64))


@functools.lru_cache(maxsize=8)
def kernel_tables(r0: float, n_ori: int):
    """Scatter and gather kernels per channel (``lo`` = orientations ``0..n-1``,
    ``hi`` = ``n..2n-1``), each with its row ranges.

    Gather (feedback, correlation at the entry): lo ``d1 = GL*m1 - GD*m2``,
    hi ``d2 = GL*m2 - GD*m1``. Scatter (grouping, the transpose, so kernels
    flipped): lo adds into ``AL`` through ``m2`` and ``AD`` through ``m1``,
    hi the other way round.
    """
    m1, m2 = von_mises_masks(ModelParams(r0=r0, n_ori=n_ori))
    lo_hi = (np.concatenate([m2, m1]), np.concatenate([m1, m2]))
    scatter = [np.ascontiguousarray(k[:, ::-1, ::-1]) for k in lo_hi]
    gather = [np.ascontiguousarray(k) for k in lo_hi[::-1]]
    return tuple((k, *nbk.row_ranges(k)) for k in scatter + gather)


@functools.lru_cache(maxsize=64)
def vm_hat(r0: float, n_ori: int, fshape: tuple[int, int]):
    m1, m2 = von_mises_masks(ModelParams(r0=r0, n_ori=n_ori))
    return rfft(place(m1, fshape, flip=True), fshape), rfft(place(m2, fshape, flip=True), fshape)


@functools.lru_cache(maxsize=64)
def vm_hat_single(r0: float, n_ori: int, fshape: tuple[int, int]):
    """:func:`vm_hat` in single precision, for the dense feedback correlation."""
    return tuple(k.astype(np.complex64) for k in vm_hat(r0, n_ori, fshape))


@functools.lru_cache(maxsize=512)
def cubic_taps(n_src: int, n_dst: int) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV's bicubic resize of one axis from ``n_src`` to ``n_dst`` samples
    as ``(start, weights)``: target ``t`` is ``sum_a weights[t, a] * src[start[t] + a]``.

    The weights are read off ``cv2.resize`` itself (it is linear), so border
    handling and coefficient rounding are OpenCV's.
    """
    m = cv2.resize(np.eye(n_src), (n_src, n_dst), interpolation=cv2.INTER_CUBIC)
    taps = min(4, n_src)
    nz = m != 0
    first = nz.argmax(axis=1)
    last = n_src - 1 - nz[:, ::-1].argmax(axis=1)
    if np.any(last - first >= taps):
        raise AssertionError("OpenCV's bicubic resize reached beyond 4 taps")
    start = np.clip(first, 0, n_src - taps).astype(np.int64)
    weights = np.take_along_axis(m, start[:, None] + np.arange(taps), axis=1)
    return start, np.ascontiguousarray(weights)
