"""Built-in synthetic scenes with analytic figure-ground ground truth.

A :class:`Scene` is a grey image (float in [0, 1]) made of shapes painted back
to front, plus, at every boundary pixel, the unit vector (x right, y up)
pointing into the shape that owns that boundary: the front-most shape among
the regions that meet there. Shapes are rendered with 4x4 supersampling so
their edges are anti-aliased like a camera image.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import validate as check
from ..events import Recording, image_to_events
from ..events.cutter import WINDOW_MS
from ..events.esim import CIRCLE_STEPS

_SUPERSAMPLE = 4


def _unit(x, y):
    norm = np.hypot(x, y)
    norm = np.where(norm == 0, 1, norm)
    return x / norm, y / norm


@dataclass(frozen=True)
class _Shape:
    """A shape centred at (``row``, ``col``) of one ``size`` (radius or half
    side) and grey level ``intensity``."""

    row: float
    col: float
    size: float
    intensity: float

    def __post_init__(self):
        check.number(type(self).__name__, "size", self.size, lo=0, lo_open=True)

    @property
    def centre(self):
        return self.row, self.col


class Disc(_Shape):
    def contains(self, r, c):
        return (r - self.row) ** 2 + (c - self.col) ** 2 <= self.size**2

    def inward(self, r, c):
        """Unit vector (x, y-up) from (r, c) towards the centre."""
        return _unit(self.col - c, r - self.row)

    @property
    def radius(self) -> float:
        return self.size


class Square(_Shape):
    def contains(self, r, c):
        return (np.abs(r - self.row) <= self.size) & (np.abs(c - self.col) <= self.size)

    def inward(self, r, c):
        """Inward normal of the nearest side (diagonal exactly at corners)."""
        dr, dc = r - self.row, c - self.col
        ar, ac = np.abs(dr), np.abs(dc)
        return _unit(
            np.where(ac >= ar, -np.sign(dc), 0.0), np.where(ar >= ac, np.sign(dr), 0.0)
        )  # row below centre -> point up

    @property
    def half(self) -> float:
        return self.size


@dataclass
class Scene:
    """A synthetic image and its figure-ground ground truth."""

    name: str
    image: np.ndarray  # float64 (H, W) in [0, 1]
    shapes: tuple  # back to front
    background: float
    labels: np.ndarray = field(repr=False)  # 0 background, i+1 for shapes[i] (visible)
    boundary: np.ndarray = field(repr=False)  # bool, pixels where labels change (3x3)
    owner: np.ndarray = field(repr=False)  # label of the owning shape at boundary pixels, else 0
    truth_x: np.ndarray = field(repr=False)
    truth_y: np.ndarray = field(repr=False)

    @property
    def shape(self):
        return self.image.shape


def _neighbours(labels: np.ndarray) -> np.ndarray:
    """The 3 x 3 neighbourhood of every pixel, stacked: shape (9, H, W)."""
    h, w = labels.shape
    pad = np.pad(labels, 1, mode="edge")
    return np.stack([pad[1 + dr : h + 1 + dr, 1 + dc : w + 1 + dc] for dr in (-1, 0, 1) for dc in (-1, 0, 1)])


def render(shapes, size, background, name="scene") -> Scene:
    """Paint ``shapes`` (back to front) on a ``size`` = (H, W) background."""
    h, w = size
    s = _SUPERSAMPLE
    rr = (np.arange(h * s) + 0.5) / s - 0.5
    cc = (np.arange(w * s) + 0.5) / s - 0.5
    R, C = np.meshgrid(rr, cc, indexing="ij")
    fine = np.full((h * s, w * s), float(background))
    for sh in shapes:
        fine[sh.contains(R, C)] = sh.intensity
    image = fine.reshape(h, s, w, s).mean(axis=(1, 3))

    r, c = np.meshgrid(np.arange(h, dtype=float), np.arange(w, dtype=float), indexing="ij")
    labels = np.zeros((h, w), dtype=np.int32)
    for i, sh in enumerate(shapes):
        labels[sh.contains(r, c)] = i + 1
    neigh = _neighbours(labels)
    boundary = (neigh != labels[None]).any(axis=0)
    # Owner: the front-most (highest label) region meeting at the pixel.
    owner = np.where(boundary, neigh.max(axis=0), 0)
    tx = np.zeros((h, w))
    ty = np.zeros((h, w))
    for i, sh in enumerate(shapes):
        m = owner == i + 1
        x, y = sh.inward(r[m], c[m])
        tx[m], ty[m] = x, y
    return Scene(name, image, tuple(shapes), float(background), labels, boundary, owner, tx, ty)


def _centred(shape_type, size, light_on_dark, margin, name) -> Scene:
    """One shape centred in a square frame of side ``2*margin*size`` (at least 64)."""
    side = max(64, int(round(2 * margin * size)))
    fg, bg = (0.8, 0.2) if light_on_dark else (0.2, 0.8)
    c = (side - 1) / 2
    kind = "light" if light_on_dark else "dark"
    return render([shape_type(c, c, size, fg)], (side, side), bg, name=f"{name}{size:g}-{kind}")


def disc(radius: float = 24, light_on_dark: bool = True, margin: float = 1.5) -> Scene:
    """One disc centred in a square frame of side ``2*margin*radius`` (at least 64)."""
    return _centred(Disc, radius, light_on_dark, margin, "disc-r")


def square(half: float = 24, light_on_dark: bool = True, margin: float = 1.5) -> Scene:
    """One square (half side ``half``) centred in a frame of side ``2*margin*half`` (at least 64)."""
    return _centred(Square, half, light_on_dark, margin, "square-h")


def occlusion(size=(96, 128)) -> Scene:
    """A dark square partly hidden behind a light disc on a mid-grey background.

    The disc is in front: it owns the border the two shapes share.
    """
    h, w = size
    back = Square(h * 0.45, w * 0.36, min(h, w) * 0.22, 0.15)
    front = Disc(h * 0.52, w * 0.58, min(h, w) * 0.22, 0.9)
    return render([back, front], size, 0.5, name="occlusion")


def demo(size=(120, 160)) -> Scene:
    """The built-in default input: two discs and a square of several sizes,
    light-on-dark and dark-on-light, one disc occluding the square."""
    h, w = size
    shapes = [
        Square(h * 0.62, w * 0.30, h * 0.17, 0.85),
        Disc(h * 0.42, w * 0.42, h * 0.13, 0.15),
        Disc(h * 0.40, w * 0.76, h * 0.16, 0.9),
    ]
    return render(shapes, size, 0.45, name="demo")


def shared_border_ownership(scene: Scene, fg_x, fg_y, front: int, back: int, tol_deg: float = 90.0):
    """Fraction of the border shared by shapes ``front`` and ``back`` (0-based)
    that the model assigns to ``front``: pixels of that border where the model
    vector lies within ``tol_deg`` of the front shape's inward direction.
    Only pixels where the model vector is non-zero count.
    """
    neigh = _neighbours(scene.labels)
    shared = (neigh == front + 1).any(0) & (neigh == back + 1).any(0)
    mag = np.hypot(fg_x, fg_y)
    m = shared & (mag > 0)
    if not m.any():
        return float("nan"), 0
    r, c = np.nonzero(m)
    tx, ty = scene.shapes[front].inward(r.astype(float), c.astype(float))
    cos = (fg_x[m] * tx + fg_y[m] * ty) / mag[m]
    return float(np.mean(cos > np.cos(np.radians(tol_deg)))), int(m.sum())


def flipping_disc_recording(radius: float = 16, windows: int = 4, window_ms: float = WINDOW_MS):
    """A synthetic recording whose figure changes polarity every window: a
    disc seen through the iCub's circular microsaccade (the built-in event
    simulator), light on dark in even windows and dark on light in odd ones.

    Each window must be grouped by the other family than the one before, so
    a network that carries its decision from one window into the next can
    get the flipped windows wrong (the spiking network without its window
    clock does: ``experiments.validation.window_clock``). Returns ``(scenes,
    recording)``: one :class:`Scene` per window (its ``labels`` give the
    disc) and the :class:`~snn_fg.events.Recording`, whose events of window
    ``k`` start at ``k * window_ms`` ms and end before ``(k + 1) * window_ms``
    (so ``iter_windows(recording, window_ms=window_ms)`` cuts it at the flips).
    """
    check.integer("flipping_disc_recording", "windows", windows, lo=1)
    window_ms = check.number("flipping_disc_recording", "window_ms", window_ms, lo=0, lo_open=True)
    scenes = [disc(radius, light_on_dark=k % 2 == 0) for k in range(windows)]
    return scenes, _seen_in_turn(scenes, window_ms)


#: the windows of the demo recording (:func:`demo_recording`): 2 s of events at 85 ms a window
DEMO_WINDOWS = 24


def demo_recording(windows: int = DEMO_WINDOWS, window_ms: float = WINDOW_MS) -> Recording:
    """The demo scene (:func:`demo`, the one ``snn-fg run demo`` shows) as an event
    camera sees it through the iCub's circular microsaccade, one turn a window (as
    the iCub's), for ``windows`` windows of ``window_ms`` ms on a 160 x 120 sensor.
    It is ``demo`` where a command takes a recording (``snn-fg stream demo``,
    ``snn-fg events demo``), so that a live run can be tried with no camera and no
    data. (A whole turn, every border moved across: the first 85 ms of the
    simulator's 360 ms turn, :func:`flipping_disc_recording`'s, left the compact
    spiking network without a figure-ground vector.)"""
    check.integer("demo_recording", "windows", windows, lo=1)
    window_ms = check.number("demo_recording", "window_ms", window_ms, lo=0, lo_open=True)
    return _seen_in_turn([demo()] * windows, window_ms, step_us=int(window_ms * 1000 // CIRCLE_STEPS))


def _seen_in_turn(scenes, window_ms: float, step_us: int = 5000) -> Recording:
    """One window of events a scene, each the first ``window_ms`` of the microsaccade's turn over it
    (a position every ``step_us``), window ``k``'s from ``k * window_ms`` on."""
    parts, seen = [], {}  # (a scene given again is simulated once)
    for k, scene in enumerate(scenes):
        if id(scene) not in seen:
            ev = image_to_events(scene.image, motion="circle", frame_interval_us=step_us).events
            seen[id(scene)] = ev[ev["t"] - ev["t"].min() < window_ms * 1000]
        ev = seen[id(scene)].copy()
        ev["t"] += int(round(k * window_ms * 1000)) - ev["t"].min()
        parts.append(ev)
    h, w = scenes[0].shape
    return Recording(events=np.concatenate(parts), sensor_size=(w, h, 2), format="synthetic", path=None)


#: the synthetic DAVIS recording (:func:`davis_disc_recording`): a DAVIS346's sensor (rows, columns)
DAVIS346_SHAPE = (260, 346)
#: its clock's start: DAVIS cameras stamp Unix time in microseconds (14 Nov 2023)
DAVIS_T0_US = 1_700_000_000_000_000
#: the microsaccade's radius (px) and period (us): one turn per 85 ms window, as the iCub's
MICROSACCADE_PX, MICROSACCADE_US = 1.0, int(WINDOW_MS * 1000)
#: time step of the simulated event camera (us): 34 positions per turn
DAVIS_STEP_US = 2_500
#: APS frames: one every 40 ms (25 per second), the first 20 ms in, each exposed 4 ms (sampled 5 times)
APS_INTERVAL_US, APS_FIRST_US, APS_EXPOSURE_US, APS_EXPOSURE_SAMPLES = 40_000, 20_000, 4_000, 5


@dataclass(frozen=True, kw_only=True)
class DavisRecording:
    """A synthetic DAVIS recording: the scene (its truth at rest), the
    events (a :class:`~snn_fg.events.Recording`) and the APS frames
    (:class:`~snn_fg.events.aps.ApsFrame` s), on one clock."""

    scene: Scene
    recording: Recording
    frames: tuple


def microsaccade_offset(t_us):
    """The image's offset ``(dx, dy)`` (px, right and down) at ``t_us`` after the recording's start."""
    a = 2 * np.pi * np.asarray(t_us, dtype=np.float64) / MICROSACCADE_US
    return MICROSACCADE_PX * np.cos(a), MICROSACCADE_PX * np.sin(a)


def davis_disc_recording(duration_ms: float = 400.0, threshold: float = 0.15, seed: int = 0) -> DavisRecording:
    """A light disc on a dark ground as a DAVIS346 would see it through the
    iCub's circular microsaccade (:data:`MICROSACCADE_PX`, one turn per
    85 ms): events from the built-in event-camera simulator (contrast
    ``threshold``, 0.03 threshold noise per pixel, seeded), and an APS frame
    every 40 ms, the image where the motion has it during the frame's
    exposure, in uint8 (no read noise: a noisy frame would not compress, and
    a test file must stay small). Times are Unix microseconds from
    :data:`DAVIS_T0_US`. The scene's truth is the disc at rest: the
    microsaccade moves it by at most one pixel."""
    from ..events import PixelOptions
    from ..events.aps import ApsFrame
    from ..events.esim import shift_image, simulate_frames

    duration_us = int(
        round(check.number("davis_disc_recording", "duration_ms", duration_ms, lo=0, lo_open=True) * 1000)
    )
    h, w = DAVIS346_SHAPE
    scene = render([Disc(h * 0.48, w * 0.52, 40.0, 0.7)], DAVIS346_SHAPE, 0.3, name="davis-disc")
    disc_ = scene.shapes[0]
    m = int(disc_.size + MICROSACCADE_PX + 4)  # (the ground is uniform: only the disc's square can change)
    r0, c0 = int(disc_.row) - m, int(disc_.col) - m
    part = scene.image[r0 : r0 + 2 * m + 1, c0 : c0 + 2 * m + 1]
    times = np.arange(0, duration_us + 1, DAVIS_STEP_US)
    seen = np.stack([shift_image(part, *microsaccade_offset(t)) for t in times])
    ev = simulate_frames(seen, times, threshold, pixels=PixelOptions(threshold_sigma=0.03), seed=seed)
    ev["x"] += c0
    ev["y"] += r0
    ev["t"] += DAVIS_T0_US
    frames = []
    for k, t in enumerate(range(APS_FIRST_US, duration_us, APS_INTERVAL_US)):
        during = t + np.linspace(-APS_EXPOSURE_US / 2, APS_EXPOSURE_US / 2, APS_EXPOSURE_SAMPLES)
        image = np.mean([shift_image(scene.image, *microsaccade_offset(s)) for s in during], axis=0)
        grey = np.round(255 * image).astype(np.uint8)
        t_abs = DAVIS_T0_US + t
        frames.append(ApsFrame(k, t_abs, grey, (t_abs - APS_EXPOSURE_US // 2, t_abs + APS_EXPOSURE_US // 2)))
    rec = Recording(events=ev, sensor_size=(w, h, 2), format="synthetic", path=None)
    return DavisRecording(scene=scene, recording=rec, frames=tuple(frames))
