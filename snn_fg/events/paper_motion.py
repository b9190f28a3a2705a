"""The paper's conversion of a still image into the two frames ESIM was played.

D'Angelo et al. made their BSDS event frames with a small script of their own
(``shaking-dynamic.py`` in the authors' public repository) and the ESIM
simulator. What that script does, and what :func:`paper_frames` reproduces:

1. read the colour image (8-bit RGB) and make **two copies**, the content
   moved by :data:`PAPER_SHIFT_PX` (2) pixels **down** in the first and
   **right** in the second. The rows (columns) uncovered at the top (left)
   keep the original first rows (columns); the last row (column) of each copy
   is left **black** (the script fills a zero array up to index ``-1``), which
   is why the authors' frames have events all along the bottom row and right
   column;
2. write each copy as a **JPEG** through imageio: a float array is stretched
   to 0..255 by its own minimum and maximum (the black line makes the minimum
   0), then encoded at quality 75 (the Pillow default);
3. ESIM's folder reader loads each JPEG as **grey** (``cv::imread(path, 0)``:
   the JPEG's luma channel) and divides by 255.

The event simulation itself is :func:`snn_fg.events.esim.simulate_frames`:
log intensity ``log(I + 1e-3)``, the first frame sets the reference, one
linear interval to the second frame. With one interval a pixel's events all
share one polarity, so the last event per pixel is the sign of the change
wherever ``|delta log I| >= C``: exactly ESIM's rule for two frames.

What is *not* published (the timestamps in ESIM's ``images.csv``, any time
window applied to the ROS bag of events) cannot be reproduced; see
``experiments/README.md`` for how close the result comes to the authors'
stored frames.
"""

from __future__ import annotations

import io

import cv2
import numpy as np
from PIL import Image

from snn_fg.events.images import as_float_image

#: How far the content moves in each copy (the script's ``shift = 1`` slices ``shift + 1`` rows).
PAPER_SHIFT_PX = 2
#: JPEG quality of the copies (Pillow's default, which imageio uses).
PAPER_JPEG_QUALITY = 75
#: Full scale of 8-bit images.
_FULL_SCALE = 255.0


def _rgb8(image) -> np.ndarray:
    """8-bit RGB (H, W, 3) of an image file, an array or a grey image."""
    f = as_float_image(image, grey=False)
    if f.ndim == 2:
        f = np.repeat(f[:, :, None], 3, axis=2)
    return np.round(f * _FULL_SCALE).astype(np.uint8)


def shifted_copy(rgb: np.ndarray, axis: int, shift: int = PAPER_SHIFT_PX) -> np.ndarray:
    """The script's copy of ``rgb`` moved by ``shift`` px along ``axis`` (0 down, 1 right), float64.

    The first ``shift`` rows (columns) repeat the original ones and the last
    row (column) is zero, as in the authors' slicing.
    """
    src = np.moveaxis(np.asarray(rgb, dtype=np.float64), axis, 0)
    out = np.zeros_like(src)
    out[:shift] = src[:shift]
    out[shift:-1] = src[: -(shift + 1)]
    return np.moveaxis(out, 0, axis)


def imageio_uint8(values: np.ndarray) -> np.ndarray:
    """imageio's conversion of a float array outside [0, 1] to uint8: stretch min..max to 0..255."""
    lo, hi = float(values.min()), float(values.max())
    if hi == lo:
        return values.astype(np.uint8)
    return ((values - lo) / (hi - lo) * _FULL_SCALE + 0.499999999).astype(np.uint8)


def jpeg_luma(rgb8: np.ndarray, quality: int = PAPER_JPEG_QUALITY) -> np.ndarray:
    """Encode ``rgb8`` as JPEG (Pillow) and decode its grey (luma) channel as OpenCV does; float in [0, 1]."""
    buf = io.BytesIO()
    Image.fromarray(rgb8).save(buf, format="JPEG", quality=quality)
    grey = cv2.imdecode(np.frombuffer(buf.getvalue(), np.uint8), cv2.IMREAD_GRAYSCALE)
    return grey.astype(np.float64) / _FULL_SCALE


def paper_frames(image) -> np.ndarray:
    """The two grey frames (2, H, W; float64 in [0, 1]) the authors played to ESIM.

    Parameters
    ----------
    image : array or path
        Colour or grey image (see :func:`snn_fg.events.images.as_float_image`).

    Returns
    -------
    numpy.ndarray
        Frame 0: content moved 2 px down; frame 1: moved 2 px right; each
        after the JPEG round trip of the authors' script.

    Examples
    --------
    >>> import numpy as np
    >>> img = np.zeros((32, 32)); img[8:24, 8:24] = 0.8
    >>> paper_frames(img).shape
    (2, 32, 32)
    """
    rgb = _rgb8(image)
    return np.stack([jpeg_luma(imageio_uint8(shifted_copy(rgb, axis))) for axis in (0, 1)])
