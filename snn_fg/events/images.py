"""Still images in: reading files and arrays as float images in [0, 1].

Shared by the event-camera simulator (grey) and the frame-based model (RGB).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from snn_fg.errors import InputError

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".webp"}
#: ITU-R BT.601 luma weights for RGB -> grey.
GREY_WEIGHTS = np.array([0.299, 0.587, 0.114])


def read_image(path, grey: bool = True) -> np.ndarray:
    """Read an image file as float64 in [0, 1]: grey (H, W), or RGB (H, W, 3) if ``grey=False``;
    upright as its EXIF orientation says (a photo as a viewer shows it)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "no such file")
    data = np.fromfile(path, dtype=np.uint8)
    if not len(data):
        raise InputError(path, "file is empty", "byte offset 0")
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)  # a damaged file: one line, ours
    try:
        # (its bit depth and channels as stored, alpha left out, turned upright by its EXIF orientation
        # as a photo viewer shows it: IMREAD_UNCHANGED ignored the orientation, so a phone's portrait
        # photo was run on its side)
        img = cv2.imdecode(data, cv2.IMREAD_ANYDEPTH | cv2.IMREAD_ANYCOLOR)
    finally:
        cv2.utils.logging.setLogLevel(level)
    if img is None:
        kind = image_format(data[:16].tobytes())
        if kind is None:
            from .formats import looks_like  # (a recording given an image's suffix: said what it is, as a list is)

            seen, suffixes = looks_like(data[:4096].tobytes())
            hint = f": it looks like {seen}; give it the suffix {' or '.join(suffixes)}" if suffixes else ""
            raise InputError(path, f"not an image: its first bytes are no image format's{hint}", "byte offset 0")
        raise InputError(path, f"a {kind} file that OpenCV cannot decode: damaged or cut short ({len(data):,} bytes)")
    if img.ndim == 3:
        if img.shape[2] == 4:
            img = img[:, :, :3]
        img = img[:, :, ::-1]  # OpenCV decodes to BGR
    return as_float_image(img, path, grey)


#: First bytes of each image format OpenCV reads here.
_MAGIC = (
    (b"\x89PNG\r\n\x1a\n", "PNG"),
    (b"\xff\xd8\xff", "JPEG"),
    (b"BM", "BMP"),
    (b"II*\x00", "TIFF"),
    (b"MM\x00*", "TIFF"),
    (b"P5", "PGM"),
    (b"P6", "PPM"),
)


def image_format(head: bytes) -> str | None:
    """The image format a file's first bytes announce (``"PNG"``, ``"JPEG"``, ...), or None."""
    if head[:4] == b"RIFF" and head[8:12] == b"WEBP":
        return "WebP"
    return next((name for magic, name in _MAGIC if head.startswith(magic)), None)


def as_float_image(image, source="<image>", grey: bool = True) -> np.ndarray:
    """Return a float64 copy of ``image`` scaled to [0, 1], grey unless ``grey=False``.

    ``image`` is H x W, H x W x 1, H x W x 3 (RGB) or H x W x 4 (RGBA, alpha
    ignored); uint8 is divided by 255, uint16 by 65535, other integer
    types must hold 0..255, floats must lie in [0, 1], bool maps to 0/1.
    """
    if isinstance(image, (str, Path)):
        return read_image(image, grey)
    try:
        img = np.asarray(image)
    except Exception as exc:  # ragged lists and the like
        raise InputError(source, f"not an image array ({exc})") from exc
    if img.ndim == 3 and img.shape[2] in (1, 3, 4):
        pass
    elif img.ndim != 2:
        raise InputError(source, f"image must be H x W or H x W x 3, got shape {img.shape}")
    if img.shape[0] < 1 or img.shape[1] < 1:
        raise InputError(source, f"image is empty (shape {img.shape})")
    if img.shape[0] > 32767 or img.shape[1] > 32767:
        raise InputError(source, f"image {img.shape[:2]} is larger than the 32767-pixel event coordinates allow")
    kind = img.dtype.kind
    if kind == "b":
        f = img.astype(np.float64)
    elif img.dtype == np.uint8:
        f = img.astype(np.float64) / 255.0
    elif img.dtype == np.uint16:
        f = img.astype(np.float64) / 65535.0
    elif kind in "iu":
        if img.size and (img.min() < 0 or img.max() > 255):
            raise InputError(
                source, f"integer image of dtype {img.dtype} must hold values 0..255 (found {img.min()}..{img.max()})"
            )
        f = img.astype(np.float64) / 255.0
    elif kind == "f":
        f = img.astype(np.float64)
        if not np.isfinite(f).all():
            raise InputError(source, "image contains NaN or infinite values")
        if f.size and (f.min() < -1e-6 or f.max() > 1.0 + 1e-6):
            raise InputError(source, f"float image must lie in [0, 1] (found {f.min():g}..{f.max():g})")
        f = np.clip(f, 0.0, 1.0)  # round-off of a weighted grey conversion may overshoot 1 slightly
    else:
        raise InputError(source, f"unsupported image dtype {img.dtype}")
    if f.ndim == 3:
        if f.shape[2] == 1:
            f = f[:, :, 0]
        elif grey:
            f = np.clip(f[:, :, :3] @ GREY_WEIGHTS, 0.0, 1.0)
        else:
            f = f[:, :, :3]
    return np.ascontiguousarray(f)


def to_grey(image, source="<image>") -> np.ndarray:
    """Grey float64 image in [0, 1] from an array or an image file path."""
    return as_float_image(image, source, grey=True)
