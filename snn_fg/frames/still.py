"""What ``snn-fg run INPUT`` accepts, checked before any model runs.

* ``demo`` - the built-in synthetic scene (:func:`snn_fg.frames.scenes.demo`);
* an event frame ``.npz`` holding ``pos`` and ``neg`` (uint8 or bool, H x W, 0/1);
* an image file (png, jpg, bmp, tif);
* an event recording in any format :mod:`snn_fg.events` reads.

Every problem raises :class:`~snn_fg.errors.InputError` naming the file;
what a model runs on is a :class:`Still`.
"""

from __future__ import annotations

import warnings
import zipfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from .. import validate as check
from ..errors import InputError, InputWarning, Remedy
from ..events import events_to_frame, image_to_events
from ..events.esim import MOTION, THRESHOLD
from ..events.formats import SUFFIX_FORMAT
from ..events.images import IMAGE_SUFFIXES, read_image
from . import check as check_input
from .scenes import demo

#: an image whose longer side has more pixels than this gets a note (:func:`large_image_note`)
LARGE_IMAGE_SIDE = 1024
#: the size the model's pixel sizes (kernels, the grouping radius R0) were chosen and scored at: the BSDS
#: images' (481 x 321), whose longer side an image's note proposes to scale to
MODEL_IMAGE_SIDE = 481
#: the rate model's peak memory a pixel of an image, measured on photos of 0.75, 3 and 12 MP
#: (0.88, 4.6 and 18.1 GB; docs/performance.md, "Memory") ...
RATE_BYTES_PER_PIXEL = 1.5e3
#: ... and the default spiking network's, on BSDS image 12003 turned into events (6.7 GB for its
#: 481 x 321 pixels, the same table)
SPIKING_BYTES_PER_PIXEL = 43e3
#: the simulated event camera's peak memory a pixel of an image, by motion (amplitude 1 px), rounded up
#: from its measurement on BSDS images tiled to 1.4 and 5.6 MP (docs/performance.md, "Memory")
SIMULATOR_BYTES_PER_PIXEL = {"shift4": 0.3e3, "circle": 1.75e3, "paper": 0.2e3}
#: what an input of each kind (:func:`input_kind`) is, as the refusal of an option for another says it
KIND_NAMES = {
    "demo": "the demo is one image",
    "frame": "INPUT is one event frame",
    "image": "INPUT is one image",
    "recording": "INPUT is an event recording",
}


def image_scale_refusal(kind: str) -> str:
    """Why ``--image-scale`` does not apply to an input of ``kind`` (not an image), as every command says it."""
    return f"applies to images only; {KIND_NAMES[kind]}"


def simulator_cost(motion: str) -> tuple[str, float]:
    """``(what, bytes a pixel)`` of the simulated event camera under ``motion``, for :func:`check_fits`."""
    return f"event-camera simulator ({motion} motion)", SIMULATOR_BYTES_PER_PIXEL[motion]


def scaled_image(image: np.ndarray, scale: float, spec) -> np.ndarray:
    """``image`` (H x W [x 3], float in [0, 1]) resized by ``scale``: OpenCV's area
    average where it shrinks, bilinear where it grows; at least one pixel a side."""
    scale = check.number("image_scale", "image_scale", scale, lo=0, lo_open=True)
    h, w = image.shape[:2]
    size = (max(1, round(w * scale)), max(1, round(h * scale)))
    if size == (w, h):
        return image
    method = cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR
    out = cv2.resize(image, size, interpolation=method)
    if min(out.shape[:2]) < 2:
        raise InputError(spec, f"image_scale {scale:g} leaves {size[0]} x {size[1]} pixels of {w} x {h}")
    return np.clip(out, 0.0, 1.0)


def large_image_note(spec, shape) -> str:
    """The note for an image larger than :data:`LARGE_IMAGE_SIDE`: its size, that the model's pixel
    sizes were chosen for BSDS-sized images, the rate model's memory for it, and the scale that
    brings its longer side to :data:`MODEL_IMAGE_SIDE`."""
    h, w = shape[:2]
    scale = float(f"{MODEL_IMAGE_SIDE / max(h, w):.2g}")  # (as the note writes it: the size it gives is that one's)
    rate, spiking = (h * w * b / 1e9 for b in (RATE_BYTES_PER_PIXEL, SPIKING_BYTES_PER_PIXEL))
    return (
        f"{spec}: a {w} x {h} image ({w * h / 1e6:.1f} MP): the model's sizes in pixels (kernels, the grouping "
        f"radius) were chosen for images of about {MODEL_IMAGE_SIDE} x 321 (BSDS), and its time and memory grow "
        f"with the pixels (here about {rate:.1f} GB for the rate model, {spiking:.0f} GB for the default spiking "
        f"network); --image-scale {scale:g} makes it {round(w * scale)} x {round(h * scale)}"
    )


def check_fits(spec, shape, model: str, bytes_per_pixel: float, available: float | None = None) -> None:
    """An :class:`~snn_fg.errors.InputError` before an image of ``shape`` is run, if ``model``'s
    memory for it (``bytes_per_pixel``, as measured: :data:`RATE_BYTES_PER_PIXEL`, ...) is more than
    the machine has available (``available`` bytes; Linux's ``MemAvailable`` if None, no check
    where that is not known): a run that would be ended by the system, or swap for hours, is
    refused with the scale that fits."""
    from ..pynn.memory import short_of  # (the standard library only)

    h, w = shape[:2]
    need = h * w * bytes_per_pixel
    have = short_of(need, available)
    if have is None:
        return
    scale = float(f"{(have / need) ** 0.5 * 0.8:.2g}")  # (a fifth to spare: the cost a pixel is a measurement)
    model_scale = float(f"{MODEL_IMAGE_SIDE / max(h, w):.2g}")
    if max(h, w) > LARGE_IMAGE_SIDE and model_scale < scale:  # (the large-image note's scale fits too: one said, not
        scale = model_scale  # two: a new user was told 0.3 by the note and 0.43 by this line, 30 Nov)
    raise InputError(
        spec,
        f"a {w} x {h} image: the {model} needs about {need / 1e9:.1f} GB for it, more than the "
        f"{have / 1e9:.1f} GB this machine has available",
        remedy=Remedy(f"image_scale={scale:g}", f"--image-scale {scale:g}"),
        note=f" to make it {round(w * scale)} x {round(h * scale)} (about {need * scale**2 / 1e9:.1f} GB)",
    )


def sized_image(image: np.ndarray, spec, image_scale=None, cost=None) -> np.ndarray:
    """An image as a model or the simulated camera takes it: resized by ``image_scale``
    (:func:`scaled_image`), or without one as it is, with an :class:`~snn_fg.errors.InputWarning`
    (:func:`large_image_note`) when its longer side has more than :data:`LARGE_IMAGE_SIDE` pixels;
    refused (:func:`check_fits`) when what it goes to (``cost``: ``(what, bytes a pixel)``, e.g.
    :func:`simulator_cost`) needs more memory than the machine has available."""
    if image_scale is not None:
        image = scaled_image(image, image_scale, spec)
    elif max(image.shape[:2]) > LARGE_IMAGE_SIDE:
        warnings.warn(InputWarning(large_image_note(spec, image.shape)), stacklevel=3)
    if cost is not None:
        check_fits(spec, image.shape, *cost)
    return image


@dataclass
class Still:
    """A still input, what a model runs on once (a recording is run window by
    window): an event frame (``pos``, ``neg``) and/or an image, and for an
    image turned into events, the simulated camera's timed events
    (``recording``, a :class:`~snn_fg.events.Recording`) the event frame was made of.

    * ``pos``, ``neg``: the event frame, two ``H x W`` arrays of one shape
      (row 0 at the top of the image), uint8 or bool: 1 where the pixel's
      last event was ON (``pos``) or OFF (``neg``), 0 elsewhere, as
      :func:`~snn_fg.events.events_to_frame` and
      :func:`~snn_fg.events.image_to_frame` make them. The event models
      (rate, spiking, natural) run on it.
    * ``image``: grey ``H x W`` or RGB ``H x W x 3``, floats in [0, 1] (an
      8-bit image divided by 255), what the frame-based model (fbfg) runs on.

    Anything else (one array of the frame missing, shapes that differ, RGB
    frames, values outside [0, 1]) is refused here with an
    :class:`~snn_fg.errors.InputError` (:mod:`snn_fg.frames.check`).
    """

    pos: np.ndarray | None = None
    neg: np.ndarray | None = None
    image: np.ndarray | None = None
    recording: object | None = None

    def __post_init__(self):
        if self.pos is None and self.neg is None and self.image is None:
            raise InputError("Still", "give an event frame (pos, neg) or an image")
        if self.pos is not None or self.neg is not None:
            check_input.event_frame("Still", self.pos, self.neg)
        if self.image is not None:
            check_input.image("Still", self.image)

    @property
    def shape(self) -> tuple[int, int]:
        return (self.pos if self.pos is not None else self.image).shape[:2]


def input_kind(spec: str) -> str:
    """One of ``demo``, ``frame``, ``image``, ``recording``."""
    if spec == "demo":
        return "demo"
    path = Path(spec)
    if not path.exists():
        raise InputError(path, "no such file (INPUT is an .npz event frame, an image, a recording or 'demo')")
    if path.is_dir():
        raise InputError(path, "is a folder, not a file")
    suffix = path.suffix.lower()
    if suffix in IMAGE_SUFFIXES:
        return "image"
    if suffix not in SUFFIX_FORMAT:  # (.npz is one: a recording's arrays or an event frame)
        raise InputError(
            path,
            f"unknown extension '{suffix or '(none)'}': INPUT is an image "
            f"({', '.join(sorted(IMAGE_SUFFIXES))}), an .npz event frame, a recording "
            f"({', '.join(sorted(SUFFIX_FORMAT))}) or 'demo'",
        )
    if suffix == ".npz":
        try:
            with check.load_npz(path, "an event frame (pos, neg) or a recording (x, y, t, p)") as d:
                if "pos" in d.files or "neg" in d.files:
                    return "frame"
                if "events" not in d.files and not {"x", "y", "t", "p"} <= set(d.files):
                    raise InputError(
                        path,
                        "lacks keys pos, neg (an event frame) and x, y, t, p or "
                        f"'events' (a recording); found keys {', '.join(d.files) or 'none'}",
                    )
        except InputError:
            raise
        except (zipfile.BadZipFile, ValueError, OSError, EOFError) as exc:
            raise InputError(path, f"not a readable .npz archive ({exc})") from None
    return "recording"


def _check_binary(path, key, a) -> np.ndarray:
    if a.ndim != 2:
        raise InputError(path, f"'{key}' must be a 2-D H x W array, got shape {a.shape}")
    if a.dtype.kind == "f":
        bad = ~np.isfinite(a)
        if bad.any():
            r, c = np.argwhere(bad)[0]
            raise InputError(path, f"'{key}' contains NaN or infinite values", f"pixel row {r}, column {c}")
    if a.dtype != np.uint8 and a.dtype != np.bool_:
        raise InputError(path, f"'{key}' has dtype {a.dtype}; an event frame needs uint8 (or bool) 0/1 values")
    if a.dtype == np.uint8 and a.max(initial=0) > 1:
        r, c = np.argwhere(a > 1)[0]
        raise InputError(path, f"'{key}' holds values other than 0 and 1 (max {a.max()})", f"pixel row {r}, column {c}")
    return a.astype(np.uint8)


def read_npz_arrays(path, required, optional=(), what: str = "file") -> dict:
    """The arrays ``required`` (and those of ``optional`` that are present) of an ``.npz`` file.

    A missing file, an unreadable archive or a missing key is an
    :class:`InputError` naming the file (``what`` says what it should be).
    """
    path = Path(path)
    try:
        with check.load_npz(path, what) as d:
            missing = [k for k in required if k not in d.files]
            if missing:
                raise InputError(
                    path, f"{what} lacks key(s) {', '.join(missing)} (found: {', '.join(d.files) or 'nothing'})"
                )
            return {k: d[k] for k in (*required, *optional) if k in d.files}
    except InputError:
        raise
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as exc:
        raise InputError(path, f"cannot read the .npz archive ({exc})") from None


def load_event_frame(path) -> tuple[np.ndarray, np.ndarray]:
    """``(pos, neg)`` from an ``.npz`` event frame, validated."""
    path = Path(path)
    arrays = read_npz_arrays(path, ("pos", "neg"), what="event frame")
    pos, neg = arrays["pos"], arrays["neg"]
    pos = _check_binary(path, "pos", pos)
    neg = _check_binary(path, "neg", neg)
    if pos.shape != neg.shape:
        raise InputError(path, f"'pos' and 'neg' differ in shape: {pos.shape} vs {neg.shape}")
    if min(pos.shape) < 2:
        raise InputError(path, f"frame of shape {pos.shape} is too small")
    if not (pos.any() or neg.any()):
        raise InputError(path, "the event frame is empty: no pixel has an event")
    both = (pos > 0) & (neg > 0)
    if both.any():
        r, c = np.argwhere(both)[0]
        raise InputError(
            path,
            "a pixel is both ON and OFF; stage 1 keeps only the last event's polarity",
            f"pixel row {r}, column {c}",
        )
    return pos, neg


def load_frame(spec: str, needs: str, threshold: float = THRESHOLD, motion: str = MOTION, image_scale=None, cost=None):
    """The frame a model needs from ``INPUT`` (``demo``, an image or an event
    frame), and what to record about where it came from.

    ``needs`` is ``"events"`` (an event frame; images are turned into events
    by the simulated event camera at contrast ``threshold`` under ``motion``,
    see :data:`snn_fg.events.esim.MOTIONS`) or ``"image"``. ``image_scale``:
    an image is resized by this factor first (:func:`scaled_image`); an image
    larger than :data:`LARGE_IMAGE_SIDE` without it gets an
    :class:`~snn_fg.errors.InputWarning` saying what it costs. ``cost``:
    ``(model, bytes a pixel)`` of the model to run, whose memory for an image
    (:func:`check_fits`) must fit what the machine has available.
    Returns ``(Still, source)``.
    """
    kind = input_kind(spec)
    source = {"input": str(spec), "kind": kind}
    if kind == "recording":
        raise InputError(spec, "is an event recording, not a frame")
    if image_scale is not None and kind == "frame":
        raise InputError(spec, f"image_scale {image_scale_refusal(kind)}")
    if kind == "frame":
        if needs == "image":
            raise InputError(spec, "the fbfg model needs an image, not an event frame")
        pos, neg = load_event_frame(spec)
        return Still(pos, neg), source
    if kind == "demo":
        image = demo().image
    else:
        image = read_image(spec, grey=needs != "image" and motion != "paper")
    if image_scale is not None:
        source.update(image_size=[int(image.shape[1]), int(image.shape[0])], image_scale=float(image_scale))
    image = sized_image(image, spec, image_scale, cost)
    if needs == "image":
        return Still(image=image), source
    recording = image_to_events(image, threshold=threshold, motion=motion)
    pos, neg = events_to_frame(recording.events, recording.sensor_size)
    if not (pos.any() or neg.any()):
        raise InputError(spec, f"the image gives no events at contrast threshold {threshold}")
    source.update(threshold=threshold, motion=motion)
    return Still(pos, neg, image, recording), source
