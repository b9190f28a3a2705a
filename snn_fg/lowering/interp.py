"""Interpolation matrices of the pyramid's resizes, for unrolling
:class:`~snn_fg.network.projections.Resize` projections and for decoding strided
lattices. OpenCV's resize is separable, so a 2-D resize is one matrix per axis.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np


@functools.lru_cache(maxsize=256)
def resize_matrix(n_in: int, n_out: int, interpolation: str = "cubic") -> np.ndarray:
    """1-D matrix ``A`` (n_out x n_in) of OpenCV's resize along one axis.

    ``cv2.resize`` is separable, so resizing an image ``X`` (rows x cols) to
    (R, C) equals ``A_rows @ X @ A_cols.T`` (checked in the tests).
    """
    flag = {"cubic": cv2.INTER_CUBIC, "linear": cv2.INTER_LINEAR}[interpolation]
    eye = np.eye(n_in)
    if n_in == n_out:
        eye.setflags(write=False)
        return eye
    # resize along the rows only: (n_in rows, n_in cols) -> (n_out rows, n_in cols)
    out = cv2.resize(eye, (n_in, n_out), interpolation=flag)
    out = np.asarray(out, dtype=np.float64).reshape(n_out, n_in)
    out.setflags(write=False)
    return out


def _keys_cubic(t, a=-0.75):
    t = np.abs(t)
    return np.where(
        t <= 1, (a + 2) * t**3 - (a + 3) * t**2 + 1, np.where(t < 2, a * t**3 - 5 * a * t**2 + 8 * a * t - 4 * a, 0.0)
    )


@functools.lru_cache(maxsize=512)
def interp_matrix(n_src: int, n_tgt: int, s_src: int = 1, s_tgt: int = 1, interpolation: str = "cubic") -> np.ndarray:
    """1-D interpolation matrix from a source lattice onto a target lattice.

    ``n_src``, ``n_tgt`` are the level sizes along the axis, ``s_src``,
    ``s_tgt`` the lattice strides. Target lattice point ``i`` (level pixel
    ``s_tgt * i``) maps to source level coordinate
    ``(s_tgt*i + 0.5) * n_src / n_tgt - 0.5``, interpolated on the source
    lattice with clamped indices. With both strides 1 the matrix is OpenCV's
    own (:func:`resize_matrix`).
    """
    if s_src == 1 and s_tgt == 1:
        return resize_matrix(n_src, n_tgt, interpolation)
    l_src = -(-n_src // s_src)
    l_tgt = -(-n_tgt // s_tgt)
    x = s_tgt * np.arange(l_tgt, dtype=float)
    u = ((x + 0.5) * (n_src / n_tgt) - 0.5) / s_src
    f = np.floor(u)
    t = u - f
    a = np.zeros((l_tgt, l_src))
    rows = np.arange(l_tgt)
    taps = ((k, _keys_cubic(t - k)) for k in range(-1, 3)) if interpolation == "cubic" else ((0, 1.0 - t), (1, t))
    for k, w in taps:
        np.add.at(a, (rows, np.clip(f + k, 0, l_src - 1).astype(int)), w)
    a.setflags(write=False)
    return a


def sparse_rows(a: np.ndarray):
    """Per row of ``a``: column indices and values of its non-zeros, padded to
    a common width (index -1, value 0)."""
    nz = a != 0
    width = max(1, int(nz.sum(1).max()))
    idx = np.full((a.shape[0], width), -1, dtype=np.int64)
    val = np.zeros((a.shape[0], width))
    for r in range(a.shape[0]):
        c = np.nonzero(nz[r])[0]
        idx[r, : len(c)] = c
        val[r, : len(c)] = a[r, c]
    return idx, val
