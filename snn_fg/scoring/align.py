"""Holding a board's maps against the reference (``snn-fg compare``).

A PyNN export's maps (``snn-fg decode``) cover the export's crop of the sensor and one window of
the recording; where its input came from is in ``params["source"]`` (``snn-fg events
--write-spikes`` records the crop and the window). A reference run (``snn-fg run`` on the same
recording) covers the whole sensor, window by window. :func:`align_to_export` cuts the reference
to the export's crop and picks its window, and says which model parameters differ, with the
option that makes a like-for-like reference.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..results.maps import Maps

#: what ``params["source"]`` of an export's decoded maps holds: where its crop lies on the sensor
EXPORT_KEYS = ("crop_x_px", "crop_y_px", "pool")
#: model parameters a like-for-like reference shares with the export, and the option of ``snn-fg run`` that sets each
MATCHED = {"levels": "--levels", "n_ori": "--n-ori", "r0": "--r0"}


def export_origin(maps: Maps) -> dict | None:
    """Where the input of an export's decoded ``maps`` came from (None: they are not an export's)."""
    src = maps.params.get("source")
    return src if isinstance(src, dict) and all(k in src for k in EXPORT_KEYS) else None


def _window(ref: Maps, origin: dict, window: int | None, name: str) -> int | None:
    """The reference's window the export's input was made from (None: the reference is one frame)."""
    if ref.fg_x.ndim == 2:
        return None
    if window is not None:
        return window
    starts = np.asarray(ref.extra.get("t_start_us", []), np.int64)
    if "t_start_ms" not in origin or not len(starts):
        raise InputError(name, "give --window I: which of its windows the export's input was made from")
    at = np.flatnonzero(starts == round(1000 * origin["t_start_ms"]))
    if not len(at):
        shown = ", ".join(f"{t / 1000:g}" for t in starts[:4]) + (", ..." if len(starts) > 4 else "")
        raise InputError(
            name,
            f"has no window starting {origin['t_start_ms']:g} ms after the first event, where the export's input "
            f"window does (its windows start at {shown} ms): run it with --start-ms {origin['t_start_ms']:g} "
            f"--window-ms {origin['t_end_ms'] - origin['t_start_ms']:g}, or give --window I",
        )
    return int(at[0])


def align_to_export(a: Maps, b: Maps, window: int | None = None, names=("A", "B")) -> tuple[Maps, Maps, list[str]]:
    """``a`` and ``b`` with the one that is not an export's decoded maps cut to the other's crop
    and window (``window``: that window of it, instead of the one the export's input was made
    from; its ``params["export_crop"]`` says where), and notes in words; both unchanged unless
    exactly one is an export's."""
    oa, ob = export_origin(a), export_origin(b)
    if (oa is None) == (ob is None):
        return a, b, []
    board, ref, name = (a, b, names[1]) if oa is not None else (b, a, names[0])
    origin = oa or ob
    h, w = board.fg_x.shape[-2:]
    if ref.fg_x.shape[-2:] == (h, w):
        return a, b, []
    if origin["pool"] != 1:
        raise InputError(
            name,
            f"the export pools its input {origin['pool']} x {origin['pool']}: its maps are on blocks, the "
            "reference's on pixels; decode its counts with --reference fast (snn-fg decode COUNTS --export DIR "
            "--out OUT --reference fast): OUT/reference/ holds the same network's maps on the same input",
        )
    x0, y0 = origin["crop_x_px"], origin["crop_y_px"]
    rows, cols = ref.fg_x.shape[-2:]
    if y0 + h > rows or x0 + w > cols:
        raise InputError(
            name, f"a frame of {cols} x {rows} holds no crop of {w} x {h} at x={x0}, y={y0}, where the export's lies"
        )
    i = _window(ref, origin, window, name)
    cut = (slice(y0, y0 + h), slice(x0, x0 + w))

    def part(v):
        return np.asarray(v if i is None else v[i])[cut]

    extra = {"event_frame": part(ref.extra["event_frame"])} if "event_frame" in ref.extra else {}
    params = {**ref.params, "export_crop": {"window": i, "x0": x0, "y0": y0, "width": w, "height": h}}
    cut_ref = Maps(part(ref.fg_x), part(ref.fg_y), part(ref.grouping), params, extra)
    when = "" if i is None else f", window {i}"
    notes = [f"{name} cut to the export's crop: x {x0}-{x0 + w - 1}, y {y0}-{y0 + h - 1}{when}"]
    differ = [k for k in MATCHED if k in board.params and k in ref.params and board.params[k] != ref.params[k]]
    if differ:
        said = ", ".join(f"{k} {board.params[k]:g} (the reference {ref.params[k]:g})" for k in differ)
        flags = " ".join(f"{MATCHED[k]} {board.params[k]:g}" for k in differ)
        notes.append(f"the export's network has {said}: a like-for-like reference runs with {flags}")
    return (a, cut_ref, notes) if board is a else (cut_ref, b, notes)
