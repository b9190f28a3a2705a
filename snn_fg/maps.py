"""Decoded model output: the figure-ground vector field and the grouping map."""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .atomic import RawArrayFile, save_npz
from . import validate as check
from .errors import InputError


@dataclass
class Maps:
    """Figure-ground field (``fg_x``, ``fg_y``; x right, y up) and grouping map.

    Arrays are float32, ``(H, W)`` for one frame or ``(n_windows, H, W)`` for a
    recording. ``params`` records every parameter used (saved as JSON).
    ``extra`` holds further arrays saved beside them (spike counts, times...).
    """

    fg_x: np.ndarray
    fg_y: np.ndarray
    grouping: np.ndarray
    params: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        shapes = {self.fg_x.shape, self.fg_y.shape, self.grouping.shape}
        if len(shapes) != 1:
            check.fail("Maps", None, None, f"fg_x, fg_y and grouping differ in shape: {sorted(shapes)}")

    @property
    def angle(self) -> np.ndarray:
        """Direction towards the owning object, radians (``atan2(fg_y, fg_x)``)."""
        return np.arctan2(self.fg_y, self.fg_x)

    @property
    def magnitude(self) -> np.ndarray:
        return np.hypot(self.fg_x, self.fg_y)

    def save(self, path) -> Path:
        return save_npz(path, fg_x=self.fg_x, fg_y=self.fg_y, grouping=self.grouping,
                        params=np.array(json.dumps(self.params, sort_keys=True)), **self.extra)

    @classmethod
    def load(cls, path) -> "Maps":
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as d:
                missing = [k for k in ("fg_x", "fg_y", "grouping") if k not in d.files]
                if missing:
                    raise InputError(path, f"not a maps file: missing {', '.join(missing)}")
                params = json.loads(str(d["params"])) if "params" in d.files else {}
                extra = {k: d[k] for k in d.files if k not in ("fg_x", "fg_y", "grouping", "params")}
                return cls(d["fg_x"], d["fg_y"], d["grouping"], params, extra)
        except InputError:
            raise
        except FileNotFoundError:
            raise InputError(path, "file not found") from None
        except Exception as exc:  # zip/pickle/format errors from numpy
            raise InputError(path, f"cannot read maps file ({type(exc).__name__}: {exc})") from None


class MapsSeriesWriter:
    """Collect per-window Maps on disk, then write one ``maps.npz`` atomically.

    Each window's arrays are appended to temporary raw files next to the
    destination, so memory stays bounded by one window however long the
    recording; :meth:`finish` copies them block by block into the result.
    Temporary files are removed whatever happens.

    An array with the same shape in every window is stored stacked,
    ``(n_windows, ...)``; a window that lacks it (an empty window has no spike
    counts) gets zeros. An array whose length varies between windows (spike
    counts per instantiated cell: each window instantiates its own cells) is
    stored *ragged*: ``key`` is the windows' arrays concatenated along their
    first axis and ``key_offsets`` (int64, ``n_windows + 1``) says where each
    window's part starts; see :func:`window_part`. A window's ``params`` that
    differ from the first window's are kept under ``params["windows"]``.
    """

    def __init__(self, path):
        import tempfile

        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._dir = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.", suffix=".parts", dir=self.path.parent))
        self._dtype: dict[str, np.dtype] = {}
        self._shapes: dict[str, list] = {}     # key -> per window: its shape, or None where absent
        self._window_params: list[dict] = []
        self.n = 0
        self.params: dict = {}

    def append(self, maps: Maps, **more):
        """Add one window's maps (and any ``more`` per-window arrays)."""
        arrays = {"fg_x": maps.fg_x, "fg_y": maps.fg_y, "grouping": maps.grouping, **maps.extra, **more}
        if self.n == 0:
            self.params = dict(maps.params)
        self._window_params.append({k: v for k, v in maps.params.items() if self.params.get(k) != v})
        for key, v in arrays.items():
            v = np.asarray(v)
            if key not in self._dtype:
                self._dtype[key] = v.dtype
                self._shapes[key] = [None] * self.n
            elif v.dtype != self._dtype[key]:
                v = v.astype(self._dtype[key])
            with open(self._dir / key, "ab") as fh:
                np.ascontiguousarray(v).tofile(fh)
            self._shapes[key].append(v.shape)
        for key, shapes in self._shapes.items():
            if len(shapes) == self.n:      # absent from this window
                shapes.append(None)
        self.n += 1

    def stacked(self, lazy: bool = False) -> dict:
        """The windows so far, ``(n, ...)`` per key (read-only memory maps where
        every window has the key), plus ``key`` / ``key_offsets`` for ragged
        keys. ``lazy``: arrays that are a whole part file come as
        :class:`~snn_fg.atomic.RawArrayFile` instead of memory maps."""
        if self.n == 0:
            check.fail("MapsSeriesWriter", None, None, "no window was appended")
        out = {}
        for key, shapes in self._shapes.items():
            present = [s for s in shapes if s is not None]
            count = sum(int(np.prod(s)) for s in present)

            def whole(shape):
                if count == 0:
                    return np.zeros(shape, self._dtype[key])
                if lazy:
                    return RawArrayFile(self._dir / key, self._dtype[key], shape)
                return np.memmap(self._dir / key, dtype=self._dtype[key], mode="r", shape=shape)

            if len(set(present)) == 1 and len(present) == self.n:
                out[key] = whole((self.n,) + present[0])
            elif len(set(present)) == 1 and len(present[0]) != 1:
                # a fixed-shape array (a map, a scalar) missing from some windows: zeros there
                full = np.zeros((self.n,) + present[0], self._dtype[key])
                raw = np.fromfile(self._dir / key, dtype=self._dtype[key]).reshape((-1,) + present[0])
                full[[i for i, s in enumerate(shapes) if s is not None]] = raw
                out[key] = full
            else:
                tails = {s[1:] for s in present}
                if len(tails) != 1 or any(len(s) == 0 for s in present):
                    check.fail("MapsSeriesWriter", None, None, f"array {key!r} changes its trailing shape between windows "
                               f"({sorted(set(present))}); cannot store it")
                tail = tails.pop()
                lengths = [0 if s is None else s[0] for s in shapes]
                out[key] = whole((sum(lengths),) + tail)
                out[f"{key}_offsets"] = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
        return out

    def finish(self, params: dict | None = None, **extra) -> Path:
        """Write ``path``: the stacked windows, ``extra`` arrays and ``params``.

        The windows' arrays are copied from their part files in blocks (never
        loaded or mapped). The temporary parts stay until :meth:`close` (or
        the end of the ``with`` block), so :meth:`stacked` can still be read
        afterwards.
        """
        stacked = self.stacked(lazy=True)
        stacked.update(extra)
        params = dict(params if params is not None else self.params)
        if any(self._window_params):
            params["windows"] = self._window_params
        stacked["params"] = np.array(json.dumps(params, sort_keys=True))
        return save_npz(self.path, **stacked)

    def close(self):
        import shutil

        shutil.rmtree(self._dir, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def window_part(extra: dict, key: str, window: int) -> np.ndarray:
    """Window ``window``'s part of a per-window array of a recording's Maps:
    a slice of a ragged array (see :class:`MapsSeriesWriter`) or one row of a
    stacked one."""
    if f"{key}_offsets" in extra:
        off = np.asarray(extra[f"{key}_offsets"])
        return np.asarray(extra[key])[off[window]:off[window + 1]]
    return np.asarray(extra[key])[window]
