"""ESIM-style event-camera simulator for still images moved by a small motion.

Model (after Rebecq et al. 2018, "ESIM: an open event camera simulator"):

* Intensities are scaled to [0, 1] (uint8 / 255, uint16 / 65535; floats
  must already lie in [0, 1]; RGB is converted to grey with the BT.601
  weights 0.299, 0.587, 0.114) and the simulator works on
  ``L = log(I + eps)`` with ``eps = 1e-3`` (:data:`LOG_EPS`), so that black
  pixels have a finite log intensity.
* Each pixel keeps a reference level, initialised to ``L`` of the first
  frame.  Between two frames ``L`` is interpolated linearly in time; every
  time it crosses ``ref + C_on`` (ON) or ``ref - C_off`` (OFF) an event is
  emitted at the interpolated crossing time and the reference moves by one
  threshold, so one interval can produce several events per pixel.
* Thresholds default to 0.10 for both polarities; ``threshold_sigma``
  (:class:`PixelOptions`, as are the next options) adds
  per-pixel Gaussian noise to them (drawn once, from ``seed``; clipped below
  at 0.01).
* ``refractory_us``: an event closer than this to the previous *emitted*
  event of the same pixel is dropped (the reference still moves, as in ESIM).
* Timestamps are integer microseconds: a crossing at fraction ``f`` of an
  interval ``(t0, t1]`` is stamped ``t0 + ceil(f * (t1 - t0))``.  Events are
  sorted by time, then by pixel (row-major), so output is deterministic.

Motions (see :func:`motion_frames`): ``shift4`` moves the image content by one
pixel up, right, down and left, back to the start (5 frames); ``circle`` is the
iCub's circular microsaccade, 72 positions on a circle of radius
``amplitude_px`` (default 1 px) around the original position, visited in
order and returning to the first (73 frames); ``paper`` is the authors' own
BSDS conversion (two copies moved 2 px down and 2 px right, each through a
JPEG round trip; :mod:`snn_fg.events.paper_motion`), 2 frames.  Frames are
``frame_interval_us`` apart (default 5000 us for both).  Shifted frames
replicate the edge pixels instead of wrapping around (so image borders
do not produce spurious events); integer shifts are exact, sub-pixel
positions use bilinear interpolation (``cv2.warpAffine``, ``INTER_LINEAR``,
``BORDER_REPLICATE``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from snn_fg import validate
from snn_fg.events.core import EVENT_DTYPE, Recording
from snn_fg.events.frame import events_to_frame
from snn_fg.events.images import to_grey
from snn_fg.events.paper_motion import PAPER_SHIFT_PX, paper_frames

#: eps in ``log(I + eps)``, intensities in [0, 1].
LOG_EPS = 1e-3
#: Smallest contrast threshold kept after adding threshold noise.
MIN_THRESHOLD = 0.01
MOTIONS = ("shift4", "circle", "paper")
#: the simulated camera's defaults wherever an image is turned into events: its contrast threshold and motion
THRESHOLD = 0.10
MOTION = "shift4"
#: how far (px) a motion moves the image unless told otherwise
AMPLITUDE_PX = 1.0
#: Positions per turn of the ``circle`` motion (every 5 degrees).
CIRCLE_STEPS = 72


def shift_image(img: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """Move image content by ``(dx, dy)`` pixels (right, down), replicating edges."""
    if dx == int(dx) and dy == int(dy):
        dx, dy = int(dx), int(dy)
        h, w = img.shape
        ys = np.clip(np.arange(h) - dy, 0, h - 1)
        xs = np.clip(np.arange(w) - dx, 0, w - 1)
        return img[np.ix_(ys, xs)]

    m = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]])
    return cv2.warpAffine(img, m, (img.shape[1], img.shape[0]), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def motion_offsets(motion: str = MOTION, amplitude_px: float = AMPLITUDE_PX) -> np.ndarray:
    """Image offsets ``(dx, dy)`` (pixels; +x right, +y down) of each frame."""
    validate.choice("motion_offsets", "motion", motion, MOTIONS)
    if motion == "paper":
        return np.array([(0, PAPER_SHIFT_PX), (PAPER_SHIFT_PX, 0)], dtype=np.float64)
    a = validate.number("motion_offsets", "amplitude_px", amplitude_px, lo=0, lo_open=True)
    if motion == "shift4":
        if a != int(a):
            validate.fail("motion_offsets", "amplitude_px", amplitude_px, "must be a whole number of pixels for shift4")
        return np.array([(0, 0), (0, -a), (a, -a), (a, 0), (0, 0)], dtype=np.float64)
    k = np.arange(CIRCLE_STEPS + 1) % CIRCLE_STEPS
    ang = 2 * np.pi * k / CIRCLE_STEPS
    off = np.stack([a * np.cos(ang), a * np.sin(ang)], axis=1)
    return np.round(off, 12)  # exact integers where the circle meets the axes


def motion_frames(image, motion: str = MOTION, amplitude_px: float = AMPLITUDE_PX, frame_interval_us: int = 5000):
    """Return ``(frames, times_us)``: grey frames (N x H x W float64) and their times.

    ``paper`` ignores ``amplitude_px`` (its shift is the authors' 2 px) and
    reads colour images in colour (the JPEG encoder makes the grey).
    """
    interval = validate.number("motion_frames", "frame_interval_us", frame_interval_us, lo=1)
    if interval != int(interval):
        validate.fail("motion_frames", "frame_interval_us", frame_interval_us, "must be a whole number")
    offs = motion_offsets(motion, amplitude_px)
    if motion == "paper":
        frames = paper_frames(image)
    else:
        img = to_grey(image)
        frames = np.stack([shift_image(img, dx, dy) for dx, dy in offs])
    times = np.arange(len(offs), dtype=np.int64) * int(interval)
    return frames, times


def _thresholds(value, sigma, shape, rng, name):
    value = validate.number("simulate_frames", name, value, lo=0, lo_open=True)
    if sigma == 0:
        return np.full(shape, float(value))
    return np.maximum(value + sigma * rng.standard_normal(shape), MIN_THRESHOLD)


@dataclass(frozen=True, kw_only=True)
class PixelOptions:
    """How the simulated pixels differ from ideal ones (checked once, here).

    ``threshold_off``: the OFF threshold (default: the ON one);
    ``threshold_sigma``: per-pixel Gaussian noise on both thresholds;
    ``refractory_us``: least time between two emitted events of a pixel;
    ``eps``: the offset in ``log(I + eps)``.
    """

    threshold_off: float | None = None
    threshold_sigma: float = 0.0
    refractory_us: int = 0
    eps: float = LOG_EPS

    def __post_init__(self):
        if self.threshold_off is not None:
            validate.number("PixelOptions", "threshold_off", self.threshold_off, lo=0, lo_open=True)
        validate.number("PixelOptions", "threshold_sigma", self.threshold_sigma, lo=0)
        validate.number("PixelOptions", "refractory_us", self.refractory_us, lo=0)
        validate.number("PixelOptions", "eps", self.eps, lo=0, lo_open=True)


def simulate_frames(
    frames, times_us, threshold_on=THRESHOLD, *, pixels: PixelOptions | None = None, seed=0
) -> np.ndarray:
    """Simulate events from grey frames in [0, 1] (N x H x W) at ``times_us``."""
    px_opts = pixels or PixelOptions()
    frames = np.asarray(frames, dtype=np.float64)
    times = np.asarray(times_us, dtype=np.int64)
    if frames.ndim != 3 or len(frames) != len(times) or len(frames) < 1:
        validate.fail("simulate_frames", None, None, "frames must be N x H x W with one time per frame")
    if len(times) > 1 and (np.diff(times) <= 0).any():
        validate.fail("simulate_frames", None, None, "frame times must increase strictly")
    threshold_off = threshold_on if px_opts.threshold_off is None else px_opts.threshold_off
    threshold_sigma, refractory_us, eps = px_opts.threshold_sigma, px_opts.refractory_us, px_opts.eps
    _, h, w = frames.shape
    rng = np.random.default_rng(validate.seed("simulate_frames", seed))
    c_on = _thresholds(threshold_on, threshold_sigma, h * w, rng, "threshold_on")
    c_off = _thresholds(threshold_off, threshold_sigma, h * w, rng, "threshold_off")

    logs = np.log(frames.reshape(len(frames), -1) + eps)
    ref = logs[0].copy()
    last_t = np.full(h * w, np.iinfo(np.int64).min // 2)
    chunks_idx, chunks_t, chunks_p = [], [], []
    for i in range(1, len(frames)):
        l0, l1 = logs[i - 1], logs[i]
        t0, dt = int(times[i - 1]), int(times[i] - times[i - 1])
        for sign, c in ((1, c_on), (-1, c_off)):
            n = np.floor(sign * (l1 - ref) / c).astype(np.int64)
            # a crossing needs L to move that way in this interval; this also
            # drops float round-off "crossings" where L stands still
            pix = np.flatnonzero((n > 0) & (sign * (l1 - l0) > 0))
            if not len(pix):
                continue
            n_p, c_p, ref_p = n[pix], c[pix], ref[pix]
            d_p = l1[pix] - l0[pix]
            for k in range(1, int(n_p.max()) + 1):
                sel = n_p >= k
                px = pix[sel]
                level = ref_p[sel] + sign * k * c_p[sel]
                frac = np.clip((level - l0[px]) / d_p[sel], 0.0, 1.0)
                t = t0 + np.clip(np.ceil(frac * dt).astype(np.int64), 1, dt)
                if refractory_us:
                    keep = t - last_t[px] >= refractory_us
                    px, t = px[keep], t[keep]
                last_t[px] = t
                chunks_idx.append(px)
                chunks_t.append(t)
                chunks_p.append(np.full(len(px), sign > 0, dtype=np.int8))
            ref[pix] = ref_p + sign * n_p * c_p
    if not chunks_idx:
        return np.zeros(0, dtype=EVENT_DTYPE)
    idx = np.concatenate(chunks_idx)
    t = np.concatenate(chunks_t)
    p = np.concatenate(chunks_p)
    order = np.lexsort((np.arange(len(t)), idx, t))
    ev = np.empty(len(t), dtype=EVENT_DTYPE)
    ev["x"] = idx[order] % w
    ev["y"] = idx[order] // w
    ev["t"] = t[order]
    ev["p"] = p[order]
    return ev


def image_to_events(
    image,
    threshold: float = THRESHOLD,
    motion: str = MOTION,
    *,
    amplitude_px: float = AMPLITUDE_PX,
    frame_interval_us: int = 5000,
    seed: int = 0,
    pixels: PixelOptions | None = None,
) -> Recording:
    """Simulate an event camera looking at ``image`` under ``motion``.

    ``image`` is an array (see :func:`to_grey`) or an image file path.
    ``threshold`` is the ON threshold (and the OFF one unless
    ``pixels.threshold_off`` is given; :class:`PixelOptions` holds the
    pixels' noise, refractory period and log offset).  Returns a :class:`Recording` with
    ``format="esim"``: ``.events`` (tonic-style structured array) and
    ``.sensor_size`` ``(W, H, 2)``.  Deterministic for a given ``seed``.
    """
    src = Path(image) if isinstance(image, (str, Path)) else None
    frames, times = motion_frames(image, motion, amplitude_px, frame_interval_us)
    ev = simulate_frames(frames, times, threshold, pixels=pixels, seed=seed)
    h, w = frames.shape[1:]
    return Recording(events=ev, sensor_size=(int(w), int(h), 2), format="esim", path=src)


def image_to_frame(image, threshold: float = THRESHOLD, motion: str = MOTION, **kwargs):
    """``(pos, neg)`` event frame of the simulated events (whole motion = one window)."""
    rec = image_to_events(image, threshold=threshold, motion=motion, **kwargs)
    return events_to_frame(rec.events, rec.sensor_size)
