"""Connectivity kernels of the model, as pure numpy functions.

* :func:`dog_kernels` - the oriented difference-of-Gaussians kernels of the
  simple cells (stage 3 of ``docs/model.md``), one per direction.
* :func:`von_mises_masks` - the pair of half-ring kernels that connect
  border-ownership cells to grouping cells (stage 6).
* :func:`side_cue_kernels` - half discs that weigh the event density on one
  side of a border against the other (the side cue of the natural-scene
  variant).

These are the weight-shared convolutions of the network description; the rate
model applies them as convolutions/correlations, the spiking simulator unrolls
them into synapses.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np
from scipy.special import i0

from ..frames.pyramid import level_scale
from ..params import ModelParams


def _gauss2d(u_r, u_c, var_r, var_c):
    return np.exp(-0.5 * (u_r**2 / var_r + u_c**2 / var_c)) / (2 * np.pi * np.sqrt(var_r * var_c))


@functools.lru_cache(maxsize=16)
def _dog_kernels_cached(s1, s2, half_width, step, n_dir):
    n = int(round(2 * half_width / step)) + 1
    u = -half_width + step * np.arange(n)
    ur, uc = np.meshgrid(u, u, indexing="ij")
    base = _gauss2d(ur, uc, *s2) - _gauss2d(ur, uc, *s1)
    c = (n - 1) / 2
    out = np.empty((n_dir, n, n))
    for k in range(n_dir):
        m = cv2.getRotationMatrix2D((c, c), 360.0 * k / n_dir, 1.0)
        out[k] = cv2.warpAffine(base, m, (n, n), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    out.setflags(write=False)
    return out


def dog_kernels(params: ModelParams = ModelParams()) -> np.ndarray:
    """Oriented DoG kernels, shape ``(2*n_ori, n, n)`` (read-only, float64).

    Direction ``k`` is the base kernel ``N(S2) - N(S1)`` rotated by
    ``360*k/(2*n_ori)`` degrees counter-clockwise as displayed, about the
    centre pixel, with bilinear interpolation and zeros outside.
    """
    return _dog_kernels_cached(params.dog_s1, params.dog_s2, params.dog_half_width, params.dog_step, params.n_dir)


@functools.lru_cache(maxsize=16)
def _von_mises_cached(r0, n_ori):
    half = int(round(3 * r0))
    x = np.arange(-half, half + 1, dtype=float)
    y = np.arange(half, -half - 1, -1, dtype=float)
    xx, yy = np.meshgrid(x, y)
    r = np.hypot(xx, yy)
    phi = np.arctan2(yy, xx)
    bessel = i0(r - r0)
    m1 = np.empty((n_ori,) + r.shape)
    m2 = np.empty_like(m1)
    eps = np.finfo(float).eps
    for o in range(n_ori):
        theta0 = np.pi * o / n_ori + np.pi / 2
        a = np.exp(r0 * np.cos(phi - theta0)) / bessel
        b = np.exp(r0 * np.cos(phi - theta0 - np.pi)) / bessel
        a[r == 0] = 0
        b[r == 0] = 0
        a /= a.max()
        b /= b.max()
        m1[o] = a * (a - b > eps)
        m2[o] = b * (b - a > eps)
    m1.setflags(write=False)
    m2.setflags(write=False)
    return m1, m2


def von_mises_masks(params: ModelParams = ModelParams()) -> tuple[np.ndarray, np.ndarray]:
    """The two half-ring von Mises kernels ``(m1, m2)``, each ``(n_ori, n, n)``.

    Rows run from ``y = +3 R0`` (top) to ``-3 R0``, columns from ``x = -3 R0``
    to ``+3 R0``. ``m1[o]`` weights the side at angle ``theta0 = pi*o/n_ori + pi/2``
    (y up), ``m2[o]`` the opposite side; the two are disjoint.
    """
    return _von_mises_cached(float(params.r0), params.n_ori)


def half_disc(radius: float, theta: float) -> np.ndarray:
    """A square kernel (rows down, columns right) holding ``+1 / area`` on the
    half disc of ``radius`` towards angle ``theta`` (radians; x right, y up)
    and ``-1 / area`` on the other half; pixels within 1 px of the dividing
    line are left out, ``area`` is one half's pixel count. Correlated with a
    map, it gives the map's mean on ``theta``'s side minus its mean on the other."""
    k = int(np.ceil(radius))
    rows, cols = np.mgrid[-k : k + 1, -k : k + 1]
    # rounded: cos(pi/2) is 6e-17, not 0, which would keep one pixel row of the line on each side by its sign
    along = np.round(cols * np.cos(theta) - rows * np.sin(theta), 9)
    inside = (rows**2 + cols**2 <= radius**2) & (np.abs(along) >= 1)
    return np.where(inside, np.sign(along), 0.0) / max(inside.sum() / 2, 1)


def side_cue_radius(params: ModelParams) -> float:
    """The side cue's half-disc radius in pixels of the level it reads (``params.cue_level``)."""
    return params.side_cue_radius * level_scale(params.cue_level, params.levels_per_octave)


def side_cue_kernels(params: ModelParams = ModelParams()) -> np.ndarray:
    """Half discs ``(n_ori, n, n)`` for the side cue at ``params.cue_level``:
    orientation ``o``'s is positive on side 1, the side that ``m1[o]`` of
    :func:`von_mises_masks` covers (angle ``pi*o/n_ori + pi/2``, y up).
    Correlated with a map (zero outside it), each gives the map's mean on
    side 1 minus its mean on side 2, counting outside the map as empty."""
    r = side_cue_radius(params)
    return np.stack([half_disc(r, np.pi * o / params.n_ori + np.pi / 2) for o in range(params.n_ori)])
