"""Image pyramid of stage 2: level ``l`` is the frame scaled by ``(1/sqrt 2)**(l-1)``.

``per_octave`` (``ModelParams.levels_per_octave``) sets the step: 2 levels
per halving of the scale (the paper's ``1/sqrt 2``), or 1 (octaves).
"""

from __future__ import annotations

import cv2
import numpy as np

from ..errors import InputError, Remedy


def level_scale(level: int, per_octave: int = 2) -> float:
    """Scale factor of 1-based pyramid ``level``, ``per_octave`` levels per halving."""
    step = 1 / np.sqrt(2) if per_octave == 2 else 0.5 ** (1 / per_octave)
    return step ** (level - 1)


def level_shape(shape: tuple[int, int], level: int, per_octave: int = 2) -> tuple[int, int]:
    """``(rows, cols)`` of 1-based pyramid ``level`` for a frame of ``shape``.

    Level 1 is the frame itself; level ``l > 1`` has ``int(n*s) + 1`` samples
    along each axis, as the reference implementation sizes them.
    """
    h, w = shape
    if level == 1:
        return (h, w)
    s = level_scale(level, per_octave)
    return (int(h * s) + 1, int(w * s) + 1)


def max_levels(shape: tuple[int, int], per_octave: int = 2) -> int:
    """The most pyramid levels a frame of ``shape`` has that are at least
    2 x 2 pixels (coarser ones would be a single row or column)."""
    level = 1
    while min(level_shape(shape, level + 1, per_octave)) >= 2:
        level += 1
    return level


def check_levels(shape: tuple[int, int], levels: int, source="<frame>", per_octave: int = 2) -> None:
    """Refuse more pyramid levels than a frame of ``shape`` can have."""
    most = max_levels(shape, per_octave)
    if levels > most:
        raise InputError(
            source,
            f"a {shape[1]} x {shape[0]} frame (width x height) has at most {most} pyramid levels of at least "
            f"2 x 2 pixels, and {levels} were asked for",
            remedy=Remedy(f"levels={most} or fewer", f"--levels {most} or fewer"),
        )


def resize(img: np.ndarray, shape: tuple[int, int], interpolation: str = "cubic") -> np.ndarray:
    """Resize a 2-D (or H x W x C) float64 array to ``shape`` (rows, cols).

    ``cubic`` is OpenCV's bicubic (a = -0.75, half-pixel centres); ``linear``
    is bilinear. Returns the input unchanged if the shape already matches.
    """
    if img.shape[:2] == tuple(shape):
        return img
    flag = {"cubic": cv2.INTER_CUBIC, "linear": cv2.INTER_LINEAR}[interpolation]
    # OpenCV handles at most 512 channels per call.
    if img.ndim == 3 and img.shape[2] > 512:
        return np.concatenate(
            [resize(img[..., i : i + 512], shape, interpolation) for i in range(0, img.shape[2], 512)], axis=2
        )
    out = cv2.resize(img, (shape[1], shape[0]), interpolation=flag)
    if img.ndim == 3 and out.ndim == 2:
        out = out[..., None]
    return out


def pyramid(img: np.ndarray, levels: int, per_octave: int = 2) -> list[np.ndarray]:
    """Bicubic pyramid of ``img`` (float64), one array per level."""
    img = np.asarray(img, dtype=np.float64)
    return [resize(img, level_shape(img.shape[:2], level, per_octave)) for level in range(1, levels + 1)]
