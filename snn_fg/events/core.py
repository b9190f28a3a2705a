"""Event dtype, the :class:`Recording` container and array validation."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from snn_fg import validate
from snn_fg.errors import InputError, InputWarning, Remedy

#: Structured dtype of every event array this package returns (tonic-style
#: field names; ``t`` in microseconds; ``p`` is 1 for ON, 0 for OFF).
EVENT_DTYPE = np.dtype([("x", "<i2"), ("y", "<i2"), ("t", "<i8"), ("p", "i1")])

_COORD_MAX = np.iinfo(np.int16).max
#: the largest sensor side, in pixels, that event coordinates can address
MAX_SENSOR_SIDE = _COORD_MAX + 1
#: how a user gives a recording's sensor size where the file does not say it
SENSOR_SIZE = Remedy("sensor_size=(W, H)", "--sensor-size WxH")


@dataclass(frozen=True)
class Recording:
    """Events of one recording.

    ``events`` has dtype :data:`EVENT_DTYPE`, ``sensor_size`` is ``(W, H, 2)``
    as in tonic, ``format`` names the decoder used and ``path`` is the source
    file (``None`` for an in-memory array).  ``exposure_events`` counts the
    ATIS exposure-measurement events the file held: they are not polarity
    events, so they are not in ``events`` (0 for every other format).
    """

    events: np.ndarray
    sensor_size: tuple[int, int, int]
    format: str
    path: Path | None = None
    exposure_events: int = 0

    @property
    def width(self) -> int:
        return self.sensor_size[0]

    @property
    def height(self) -> int:
        return self.sensor_size[1]

    def __len__(self) -> int:
        return len(self.events)

    @property
    def duration_us(self) -> int:
        """Last minus first timestamp (0 for fewer than two events)."""
        if len(self.events) < 2:
            return 0
        return int(self.events["t"][-1]) - int(self.events["t"][0])


def empty_events(n: int = 0) -> np.ndarray:
    return np.zeros(n, dtype=EVENT_DTYPE)


def pack_events(x, y, t, p) -> np.ndarray:
    """One :data:`EVENT_DTYPE` array from equal-length columns (a decoder's output)."""
    out = np.empty(len(t), dtype=EVENT_DTYPE)
    out["x"] = x
    out["y"] = y
    out["t"] = t
    out["p"] = p
    return out


def _parse_sensor_size(sensor_size):
    """``((W, H, 2), None)`` from ``(W, H)`` or ``(W, H, 2)``, or ``(None, what is wrong)``."""
    try:
        vals = tuple(int(v) for v in sensor_size)
        if any(float(a) != b for a, b in zip(sensor_size, vals)):
            raise ValueError
    except (TypeError, ValueError):
        return None, "must be (width, height[, 2]) integers"
    if len(vals) == 2:
        vals = vals + (2,)
    if len(vals) != 3 or vals[2] != 2 or vals[0] < 1 or vals[1] < 1:
        return None, "must be (width, height[, 2]) with positive sizes"
    if vals[0] > _COORD_MAX + 1 or vals[1] > _COORD_MAX + 1:
        return None, f"exceeds the supported {_COORD_MAX + 1} pixels a side"
    return vals, None


def check_sensor_size(sensor_size, source="<sensor_size>") -> tuple[int, int, int]:
    """``(W, H, 2)`` from a file's (or an array's) sensor size; :class:`InputError` if it is nonsense."""
    size, problem = _parse_sensor_size(sensor_size)
    if problem:
        raise InputError(source, f"sensor size {sensor_size!r} {problem}")
    return size


def file_sensor_size(path, given, header) -> tuple[int, int, int]:
    """``(W, H, 2)`` a file is read with: its own (``header``), or the size ``given`` where
    the file states none. A size given that differs from the file's own is refused, naming
    both: the file says which sensor its events come from, and another size maps them onto a
    sensor they were not recorded on (a larger one was taken silently until 30 Nov, a smaller
    one refused). ``header`` may be ``None`` or hold ``None`` where the file says no size, or
    none that makes sense (the opener then needs one given)."""
    stated = header is not None and None not in tuple(header)[:2] and not _parse_sensor_size(header)[1]
    if not stated:
        return check_sensor_size(header if given is None else given, path)
    size = check_sensor_size(header, path)
    wanted = size if given is None else check_sensor_size(given, path)
    if wanted[:2] != size[:2]:
        raise InputError(
            path,
            f"the sensor size given, {wanted[0]} x {wanted[1]}, disagrees with the file's own "
            f"{size[0]} x {size[1]}: leave the size out for this file",
        )
    return size


def sensor_size_parameter(owner: str, sensor_size) -> tuple[int, int, int]:
    """``(W, H, 2)`` from a sensor size a caller passed to ``owner``; ParameterError if it is nonsense."""
    size, problem = _parse_sensor_size(sensor_size)
    if problem:
        validate.fail(owner, "sensor_size", sensor_size, problem)
    return size


#: Events that may lie outside the bulk's extent before an inferred sensor size is refused (a share of all).
FAR_SHARE = 1e-4


def _size_hint(source) -> str:
    """How to give ``source``'s sensor size: ``--sensor-size``, and for an array file an .npz's ``sensor_size``."""
    in_npz = Path(str(source)).suffix.lower() in (".npz", ".npy")
    return "--sensor-size WxH" + (", or sensor_size in an .npz" if in_npz else "")


def infer_sensor_size(source, arrays, *, camera: str | None = None) -> tuple[int, int, int]:
    """Sensor size ``(max x + 1, max y + 1, 2)`` over event arrays, for inputs that give none.

    Says so in an :class:`~snn_fg.errors.InputWarning`: a sensor larger than
    the events' extent gives other maps (``camera``: the name of a camera a file's
    header gives that snn-fg does not know, said there too). Refused when a few far-out events set
    it: more than twice (plus 64 px) the extent that holds all events but
    :data:`FAR_SHARE` of them (a stray x = 30000 among a 320 x 240 sensor's
    events would make a frame of 30001 columns)."""
    counts = {"x": np.zeros(1, np.int64), "y": np.zeros(1, np.int64)}
    far = {"x": (-1, -1), "y": (-1, -1)}  # (largest value, its event index)
    n = 0
    for a in arrays:
        if not len(a):
            continue
        for axis in "xy":
            col = np.asarray(a[axis], np.int64)
            i = int(np.argmax(col))
            if col[i] > far[axis][0]:
                far[axis] = (int(col[i]), n + i)
            c = np.bincount(np.maximum(col, 0), minlength=len(counts[axis]))
            c[: len(counts[axis])] += counts[axis]
            counts[axis] = c
        n += len(a)
    (mx, _), (my, _) = far["x"], far["y"]
    if mx < 0 or my < 0:
        raise InputError(
            source, "cannot infer the sensor size (no events, or negative coordinates)", remedy=SENSOR_SIZE
        )
    keep = n - int(FAR_SHARE * n)
    bulk = {axis: int(np.searchsorted(np.cumsum(counts[axis]), keep)) + 1 for axis in "xy"}
    unknown = f", and the header's camera {camera!r} is not one snn-fg knows" if camera else ""
    for axis in "xy":
        value, index = far[axis]
        if value + 1 > 2 * bulk[axis] + 64:
            outside = n - int(counts[axis][: bulk[axis]].sum())
            raise InputError(
                source,
                f"no sensor size given{unknown}, and a few events lie far beyond the others "
                f"({axis} = {value} at event {index}; {outside} of {n} events outside the "
                f"{bulk['x']} x {bulk['y']} the others fill): give the sensor size "
                f"({_size_hint(source)}) and remove those events",
            )
    size = check_sensor_size((mx + 1, my + 1), source)
    warnings.warn(
        f"{source}: no sensor size given{unknown}; {size[0]} x {size[1]} from the events' extent (a larger "
        f"sensor gives other maps: {_size_hint(source)})",
        InputWarning,
        stacklevel=2,
    )
    return size


def as_events(arr, source="<array>", offset: int = 0, what: str = "the array") -> np.ndarray:
    """Convert a structured array with fields x, y, t, p to :data:`EVENT_DTYPE`.

    ``p`` of 1 becomes ON (1), 0 or -1 OFF (0); a boolean ``p`` is kept; any other value is refused.
    Timestamps must be integers (or integral floats) in microseconds.
    ``offset`` is added to event indices in error messages; ``what`` names ``arr`` in the one
    for something that is not a structured array (a live stream's ``"chunk 3"``).
    """
    if not isinstance(arr, np.ndarray) or arr.dtype.names is None:
        kind = f"{arr.dtype} array of shape {arr.shape}" if isinstance(arr, np.ndarray) else type(arr)
        raise InputError(source, f"{what} is a {kind}, not events (fields x, y, t, p)")
    missing = [f for f in "xytp" if f not in arr.dtype.names]
    if missing:
        raise InputError(
            source, f"structured array lacks field(s) {', '.join(missing)} (has {', '.join(arr.dtype.names)})"
        )
    if arr.ndim != 1:
        arr = arr.reshape(-1)
    if arr.dtype == EVENT_DTYPE:
        return arr
    out = np.empty(len(arr), dtype=EVENT_DTYPE)
    for name in "xyt":
        col = arr[name]
        if col.dtype.kind not in "iub":
            if col.dtype.kind != "f":
                raise InputError(source, f"field {name} has non-numeric dtype {col.dtype}")
            bad = ~np.isfinite(col) | (col != np.round(col))
            if bad.any():
                i = int(np.argmax(bad))
                unit = " microseconds (times in seconds: multiply by 1e6 and round to int64)" if name == "t" else ""
                raise InputError(
                    source, f"field {name} must hold integer{unit or 's'}, got {col[i].item()!r}", f"event {i + offset}"
                )
        lim = (-_COORD_MAX - 1, _COORD_MAX) if name in "xy" else (np.iinfo(np.int64).min, np.iinfo(np.int64).max)
        if len(col) and col.dtype.kind != "b":
            bad = (col < lim[0]) | (col > lim[1])
            if bad.any():
                i = int(np.argmax(bad))
                raise InputError(source, f"field {name} value {col[i].item()!r} is out of range", f"event {i + offset}")
        out[name] = col
    pcol = arr["p"]
    if pcol.dtype.kind not in "iubf":
        raise InputError(source, f"field p has non-numeric dtype {pcol.dtype}")
    if pcol.dtype.kind != "b" and len(pcol):
        bad = (pcol != 0) & (pcol != 1) & (pcol != -1)
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(
                source, f"field p must be 1 (ON) and 0 or -1 (OFF), or boolean, got {pcol[i]}", f"event {i + offset}"
            )
    out["p"] = pcol > 0
    return out


def check_in_sensor(events: np.ndarray, sensor_size, source="<array>", offset: int = 0) -> None:
    """Raise :class:`InputError` naming the first event outside the sensor."""
    w, h = sensor_size[0], sensor_size[1]
    if not len(events):
        return
    x = events["x"]
    y = events["y"]
    bad = (x < 0) | (x >= w) | (y < 0) | (y >= h)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(source, outside_problem(x[i], y[i], w, h), f"event {i + offset}")


def outside_problem(x, y, w: int, h: int) -> str:
    """What is wrong with an event at ``(x, y)`` on a ``w`` x ``h`` sensor it lies outside."""
    return f"event at (x={int(x)}, y={int(y)}) lies outside the {w} x {h} sensor"


def backwards_problem(t, before) -> str:
    """What is wrong with an event at time ``t`` after one at ``before`` (us)."""
    return f"timestamp goes backwards ({int(t)} us after {int(before)} us)"


def first_fault(x, y, t, sensor_size, prev_t) -> tuple[int, str]:
    """The index of a decoder's first event that lies outside ``sensor_size`` (``None``: not
    checked) or is earlier than the event before it (``prev_t`` before the first; ``None``:
    none), and what is wrong with it; ``(len(t), "")`` when none is. A decoder yields the
    events before it and raises the problem with where in the file that event lies."""
    n = len(t)
    if not n:
        return 0, ""
    outside = np.zeros(n, bool)
    if sensor_size is not None:
        outside = (x < 0) | (x >= sensor_size[0]) | (y < 0) | (y >= sensor_size[1])
    back = np.empty(n, bool)
    back[0] = prev_t is not None and t[0] < prev_t
    back[1:] = t[1:] < t[:-1]
    bad = outside | back
    if not bad.any():
        return n, ""
    i = int(np.argmax(bad))
    if outside[i]:
        return i, outside_problem(x[i], y[i], sensor_size[0], sensor_size[1])
    return i, backwards_problem(t[i], t[i - 1] if i else prev_t)


def check_monotonic(events: np.ndarray, source="<array>", offset: int = 0, prev_t: int | None = None) -> None:
    """Raise :class:`InputError` naming the first event whose timestamp goes backwards."""
    t = events["t"]
    if not len(t):
        return
    if prev_t is not None and t[0] < prev_t:
        raise InputError(source, backwards_problem(t[0], prev_t), f"event {offset}")
    if len(t) > 1:
        d = np.diff(t)
        bad = d < 0
        if bad.any():
            i = int(np.argmax(bad)) + 1
            raise InputError(source, backwards_problem(t[i], t[i - 1]), f"event {i + offset}")
