"""Decoded model output: the figure-ground vector field and the grouping map."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import validate as check
from ..errors import InputError
from .atomic import save_npz
from .store import STORE_NAME, read_maps

#: what a spiking run's grouping map is (figure labels)
SPIKING_GROUPING_LABEL = "grouping rate (Hz, summed over levels)"


#: the name of a spiking run's per-pixel confidence (``Maps.extra``), beside ``fg_x`` and ``fg_y``:
#: how many standard errors of its spike counts each vector is long
#: (:func:`snn_fg.models.spiking.decode.vector_confidence`)
CONFIDENCE = "fg_confidence"


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

    def __repr__(self) -> str:
        """One line: what the maps cover and which model made them (the
        parameters and extra arrays by name only; they can run to megabytes)."""
        shape = self.fg_x.shape
        size = f"{shape[-1]} x {shape[-2]}"
        what = f"{shape[0]} windows of {size}" if len(shape) == 3 else size
        model = self.params.get("model")
        extra = ", ".join(sorted(self.extra)[:8]) + (", ..." if len(self.extra) > 8 else "")
        return (
            f"Maps({what}{f', model {model!r}' if model else ''}; fg_x, fg_y, grouping; "
            f"params: {len(self.params)} entries; extra: {extra or 'none'})"
        )

    @property
    def angle(self) -> np.ndarray:
        """Direction towards the owning object, radians (``atan2(fg_y, fg_x)``)."""
        return np.arctan2(self.fg_y, self.fg_x)

    @property
    def magnitude(self) -> np.ndarray:
        return np.hypot(self.fg_x, self.fg_y)

    def save(self, path) -> Path:
        """Write the maps to the ``.npz`` file ``path`` (whole, or not at: written aside and moved
        into place) and return its path: ``fg_x``, ``fg_y``, ``grouping``, ``params`` as a JSON
        string, and every ``extra`` array (:meth:`load` reads it back). Like every file snn-fg
        writes it carries the mark that lets a later ``--force`` replace it; a file of that name
        is replaced whatever it holds (the command line asks for ``--force`` first)."""
        return save_npz(
            path,
            fg_x=self.fg_x,
            fg_y=self.fg_y,
            grouping=self.grouping,
            params=np.array(json.dumps(self.params, sort_keys=True)),
            **self.extra,
        )

    @classmethod
    def load(cls, path) -> Maps:
        """Read maps saved by :meth:`save` (``maps.npz``), a recording's store
        (``maps.zarr``, :mod:`snn_fg.results.store`: its complete windows, also while
        a run still writes it) or a run's output folder holding either."""
        path = Path(path)
        if path.is_dir() and (path / "maps.npz").is_file():
            path = path / "maps.npz"
        elif path.is_dir():
            if not (path / STORE_NAME).is_dir() and not (path / ".zattrs").is_file():  # (neither a run nor a store)
                raise InputError(
                    path,
                    f"holds no maps.npz or {STORE_NAME}: not a finished run's folder (empty, or its maps "
                    "deleted or not written yet)",
                )
            return cls(*read_maps(path / STORE_NAME if (path / STORE_NAME).is_dir() else path))
        try:
            with check.load_npz(path, "maps.npz or a run's output folder") as d:
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


def made_by(params: dict) -> str:
    """Which model made maps of ``params``, in words for a figure or a line: ``the spiking model on
    the compact network (fast backend)`` (a spiking run's network: its recipe, its file, or the
    default built from parameters), ``the rate model, its input pooled in 3 x 3 blocks`` (a model
    whose input is pooled, as the compact recipe's; its maps are on the sensor's pixels unless
    they were kept on the blocks), and ``, maps on its blocks`` where they were kept there."""
    net, backend = params.get("network"), params.get("backend")
    said = f"the {params.get('model', 'unknown')} model"
    if isinstance(net, dict):  # (a spiking run's: snn_fg.models.spiking.record.run_provenance)
        origin = str(net.get("origin", "?"))
        name = net.get("recipe") if origin == "recipe" else "default" if origin == "built" else Path(origin).name
        said += f" on the {name} network"
    elif int(params.get("input_pool", 1) or 1) > 1:
        said += f", its input pooled in {params['input_pool']} x {params['input_pool']} blocks"
    if isinstance(backend, dict) and backend.get("name"):
        said += f" ({backend['name']} backend)"
    if maps_scale(params) > 1:
        said += ", maps on its blocks"
    return said


def input_name(params: dict, fallback: str | None = None) -> str | None:
    """The name of the input maps of ``params`` were made from (its file's name, ``demo``), else
    ``fallback``."""
    source = params.get("source") or {}
    given = source.get("input") if isinstance(source, dict) else None
    return Path(str(given)).name if given else fallback


def made_from(params: dict) -> str:
    """:func:`made_by` and the name of the input the maps were made from, for a figure's title:
    ``the rate model: dvs.es`` (a figure sent on its own said which model, not of what)."""
    name = input_name(params)
    return made_by(params) + (f": {name}" if name else "")


def window_part(extra: dict, key: str, window: int) -> np.ndarray:
    """Window ``window``'s part of a per-window array of a recording's Maps:
    a slice of a ragged array (``key`` with ``key_offsets``, see
    :mod:`snn_fg.results.store`) or one row of a stacked one."""
    if f"{key}_offsets" in extra:  # (only that part is read from a store's lazy arrays)
        off = extra[f"{key}_offsets"]
        return np.asarray(extra[key][int(off[window]) : int(off[window + 1])])
    return np.asarray(extra[key][window])


def maps_scale(params: dict) -> int:
    """How many sensor pixels wide one pixel of maps made with ``params`` (their
    ``Maps.params``) is: the input pool of maps kept on the blocks, else 1."""
    return int(params.get("input_pool", 1)) if params.get("maps_grid") == "blocks" else 1


def sensor_pixel(index: int, scale: int) -> int:
    """The sensor pixel (a column or a row) at the centre of map pixel ``index`` of maps
    ``scale`` sensor pixels wide (:func:`maps_scale`)."""
    return index * scale + scale // 2


def has_vector(fg_x, fg_y) -> np.ndarray:
    """Where a figure-ground map has a vector: its length is above zero (a NaN is none)."""
    return np.hypot(fg_x, fg_y) > 0
