"""Fourier-domain convolution helpers of the rate model (float64, ``scipy.fft``)."""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft

_WORKERS = 1


def place(kernel: np.ndarray, shape: tuple[int, int], flip: bool) -> np.ndarray:
    """Lay a centred odd kernel on a periodic grid of ``shape`` (folding if larger).

    ``flip=False`` gives the layout for a convolution, ``flip=True`` for a
    correlation (offset ``d`` placed at ``-d``).
    """
    n_r, n_c = kernel.shape[-2:]
    dr = np.arange(n_r) - n_r // 2
    dc = np.arange(n_c) - n_c // 2
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


def rfft(x: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """2-D real FFT over the last two axes, zero-padded to ``shape``."""
    return sfft.rfft2(x, s=shape, axes=(-2, -1), workers=_WORKERS)


def irfft(x: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Inverse of :func:`rfft` on a grid of ``shape`` (not cropped)."""
    return sfft.irfft2(x, s=shape, axes=(-2, -1), workers=_WORKERS)


def padded_shape(shape: tuple[int, int], margin: int, at_least: int = 0) -> tuple[int, int]:
    """A fast FFT grid with at least ``margin`` extra cells per axis (and at
    least ``at_least`` cells), so a kernel reaching ``margin`` cells out does
    not wrap into the result."""
    return tuple(sfft.next_fast_len(max(n + margin, at_least), real=True) for n in shape)


def rfft_rows(x: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """:func:`rfft` of data smaller than the grid: the first pass runs over the
    data's rows only (the padding rows are zero), the second adds the padding."""
    x = sfft.rfft(x, n=shape[1], axis=-1, workers=_WORKERS)
    return sfft.fft(x, n=shape[0], axis=-2, workers=_WORKERS)


def irfft_crop(x: np.ndarray, shape: tuple[int, int], crop: tuple[int, int]) -> np.ndarray:
    """:func:`irfft` on a grid of ``shape`` keeping ``[:crop[0], :crop[1]]``;
    the second pass runs over the kept rows only."""
    x = sfft.ifft(x, axis=-2, workers=_WORKERS)[..., : crop[0], :]
    return sfft.irfft(x, n=shape[1], axis=-1, workers=_WORKERS)[..., : crop[1]]
