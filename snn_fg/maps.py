"""Decoded model output: the figure-ground vector field and the grouping map."""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .atomic import save_npz
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
            raise ValueError(f"Maps: fg_x, fg_y and grouping differ in shape: {sorted(shapes)}")

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
    recording; :meth:`finish` reads them back as memory maps while writing the
    stacked ``.npz``. Temporary files are removed whatever happens.
    """

    def __init__(self, path):
        import tempfile

        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._dir = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.", suffix=".parts", dir=self.path.parent))
        self._meta: dict[str, tuple] = {}   # key -> (dtype, shape of one window)
        self.n = 0
        self.params: dict = {}

    def append(self, maps: Maps, **more):
        """Add one window's maps (and any ``more`` per-window arrays)."""
        arrays = {"fg_x": maps.fg_x, "fg_y": maps.fg_y, "grouping": maps.grouping, **maps.extra, **more}
        if self.n == 0:
            self.params = dict(maps.params)
            self._meta = {k: (np.asarray(v).dtype, np.shape(v)) for k, v in arrays.items()}
        for key, (dtype, shape) in self._meta.items():
            v = np.asarray(arrays.get(key, np.zeros(shape, dtype)), dtype=dtype)
            if v.shape != shape:   # e.g. an empty window without spike counts
                v = np.zeros(shape, dtype)
            with open(self._dir / key, "ab") as fh:
                v.tofile(fh)
        self.n += 1

    def stacked(self) -> dict:
        """The windows so far as read-only memory maps, ``(n, ...)`` per key."""
        if self.n == 0:
            raise ValueError("MapsSeriesWriter: no window was appended")
        return {k: np.memmap(self._dir / k, dtype=dt, mode="r", shape=(self.n,) + shp)
                for k, (dt, shp) in self._meta.items()}

    def finish(self, params: dict | None = None, **extra) -> Path:
        """Write ``path``: the stacked windows, ``extra`` arrays and ``params``.

        The temporary parts stay until :meth:`close` (or the end of the
        ``with`` block), so :meth:`stacked` can still be read afterwards.
        """
        stacked = self.stacked()
        stacked.update(extra)
        stacked["params"] = np.array(json.dumps(params if params is not None else self.params, sort_keys=True))
        return save_npz(self.path, **stacked)

    def close(self):
        import shutil

        shutil.rmtree(self._dir, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
