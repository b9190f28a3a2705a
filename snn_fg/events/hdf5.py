"""Event recordings stored in HDF5 (``.h5``, ``.hdf5``), read with h5py one slice at a time.

Three layouts are read; the file's datasets say which it is:

=====================  ======================================  ============================  ====================
layout                 datasets                                times, polarity               camera (sensor)
=====================  ======================================  ============================  ====================
DSEC ``events.h5``     ``events/x``, ``/y`` (uint16), ``/t``   uint32 us plus ``t_offset``;  640 x 480 (Prophesee
                       (uint32), ``/p`` (uint8); ``t_offset``  p 0/1                         Gen3.1)
MVSEC ``*_data.hdf5``  ``davis/left/events``: N x 4 float64    float seconds; p -1/+1        346 x 260 (DAVIS346)
                       (x, y, t, p)
Prophesee ``.hdf5``    ``CD/events``: compound x, y, p, t      int64 us; p 0/1               the file's camera
=====================  ======================================  ============================  ====================

DSEC's and MVSEC's files state no sensor size: give it (``--sensor-size 640x480`` for DSEC,
``346x260`` for MVSEC), else it is taken from the events' extent, with a warning
(:func:`~snn_fg.events.core.infer_sensor_size`). A Metavision file states its camera's in
the root attribute ``geometry`` (``"1280x720"``, the metadata of its RAW header), which is
taken, as a RAW file's header is (:func:`~snn_fg.events.core.file_sensor_size`); without
it, the events' extent, with the same warning.

MVSEC holds two cameras (``davis/left/events``, ``davis/right/events``): the format option
``channel`` picks one (0 left, the default; 1 right), the other's events are counted and left
out, as are Prophesee's trigger events. A DSEC or Prophesee file holds one camera's events
(DSEC keeps each camera in its own ``events.h5``) and takes no ``channel``.

DSEC's ``ms_to_idx`` says where each millisecond of ``events/t`` begins: a reading that starts
later than the first event (``start_ms`` of :func:`~snn_fg.events.iter_windows`) begins
there instead of reading the events before it (:meth:`~snn_fg.events.RecordingStream.skip_to`);
a table that disagrees with the events is warned about and the file read from its start.

DSEC compresses its datasets with Blosc (HDF5 filter 32001), which h5py reads once the
``hdf5plugin`` package is installed (the ``h5`` extra). Prophesee compresses ``CD/events``
with its ECF codec (filter ``0x8ECF``), which neither carries: such a file is refused in
one line saying how to get its events out (Metavision's ``metavision_file_to_dat``, or
the ECF plugin from Prophesee's ``hdf5_ecf`` repository on ``HDF5_PLUGIN_PATH``); an
uncompressed one is read. Any other HDF5 file is refused with the datasets it holds.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from snn_fg.errors import InputError, InputWarning, SnnFgError, install_hint
from snn_fg.events.core import as_events, file_sensor_size, first_fault, infer_sensor_size
from snn_fg.events.prophesee import header_geometry
from snn_fg.events.source import DecodeTally, Skip, Source

#: HDF5 filter ids whose absence is explained by name (the HDF Group's registry of filters)
BLOSC_FILTER, ECF_FILTER = 32001, 0x8ECF
#: float64 seconds below this hold every microsecond (to within 0.49 us): time to 2106
MAX_FLOAT_SECONDS = 2.0**32
#: datasets named in the message for an HDF5 file of no layout read here
LISTED_DATASETS = 6
#: MVSEC's cameras by channel (the ``channel`` format option): davis/<side>/events
MVSEC_CAMERAS = {0: "left", 1: "right"}
_READ = "DSEC's events/x, y, t, p, MVSEC's davis/left/events and Prophesee's CD/events are read"
_ECF_WAY_OUT = (
    "Prophesee's ECF codec (HDF5 filter 0x8ECF), which h5py does not carry: convert it with Metavision's "
    "metavision_file_to_dat -i {file} (a .dat is read here), or install the ECF filter plugin "
    "(github.com/prophesee-ai/hdf5_ecf) and point HDF5_PLUGIN_PATH at it"
)


@dataclass(frozen=True)
class Layout:
    """One layout found in a file: what :func:`open_h5` reads and how."""

    name: str  # the decoder name (Source.format)
    label: str  # whose layout, for messages
    where: dict  # field (x, y, t, p) -> where it is read: a dataset's path, then its column or field if any
    count: int  # events
    read: Callable  # (file, i, j) -> events i..j-1 as a structured array (t in microseconds)
    skipped: dict  # what is left out: {"events of the right camera": n}
    sensor: tuple | None = None  # the sensor size (W, H) the file states, if it does
    seek: Callable | None = None  # (file, time after the first event in us) -> (index, first event's t) or None


def _h5py():
    try:
        import h5py
    except ImportError:
        return None
    try:  # registers Blosc and other filters with HDF5 (DSEC's files need it)
        import hdf5plugin  # noqa: F401
    except ImportError:
        pass
    return h5py


def _open_file(h5py, path):
    try:
        return h5py.File(path, "r")
    except Exception as exc:  # h5py raises OSError, RuntimeError... on damaged files
        text = str(exc)
        cut = re.search(r"eof = (\d+).*stored_eof = (\d+)", text)
        if cut:
            raise InputError(
                path,
                f"HDF5 file is cut short: it ends at byte {cut.group(1)} of the {cut.group(2)} it announces",
                f"byte offset {cut.group(1)}",
            ) from None
        raise InputError(path, f"not a readable HDF5 file ({text})") from None


def _dataset(f, name):
    obj = f.get(name)
    return obj if obj is not None and hasattr(obj, "shape") and hasattr(obj, "dtype") else None


def _dsec(f, path) -> Layout | None:
    cols = {k: _dataset(f, f"events/{k}") for k in "xytp"}
    if any(c is None for c in cols.values()):
        return None
    for k, c in cols.items():
        if c.ndim != 1 or c.dtype.kind not in "iu":
            raise InputError(
                path,
                f"DSEC dataset events/{k} must be 1-D integers (found {c.dtype}, shape {c.shape})",
                f"dataset events/{k}",
            )
    lengths = {k: c.shape[0] for k, c in cols.items()}
    if len(set(lengths.values())) > 1:
        odd = min(lengths, key=lambda k: sum(v == lengths[k] for v in lengths.values()))
        raise InputError(
            path,
            "DSEC datasets of unequal length (" + ", ".join(f"events/{k} {n:,}" for k, n in lengths.items()) + ")",
            f"dataset events/{odd}",
        )
    offset = 0
    if "t_offset" in f:
        off = _dataset(f, "t_offset")
        if off is None or off.size != 1 or off.dtype.kind not in "iu":
            raise InputError(path, "t_offset must be one integer (microseconds)", "dataset t_offset")
        offset = int(np.asarray(off[()]).reshape(-1)[0])
    dtype = [("x", cols["x"].dtype), ("y", cols["y"].dtype), ("t", "<i8"), ("p", cols["p"].dtype)]

    def read(f, i, j):
        out = np.empty(j - i, dtype=dtype)
        for k in "xyp":
            out[k] = _slice(f, path, f"events/{k}", i, j)
        out["t"] = _slice(f, path, "events/t", i, j).astype(np.int64) + offset
        return out

    def seek(f, after_us):
        found = dsec_seek(f, path, lengths["t"], after_us)
        return None if found is None else (found[0], found[1] + offset)

    where = {k: f"events/{k}" for k in "xytp"}
    return Layout("dsec", "DSEC", where, lengths["t"], read, {}, seek=seek if "ms_to_idx" in f else None)


def dsec_seek(f, path, count: int, after_us: int) -> tuple[int, int] | None:
    """``(index, t)``: where DSEC's ``ms_to_idx`` says the events from ``after_us`` after the first
    one begin (at or before the first of them; every event before it is earlier), and the first
    event's ``events/t``; None where the table cannot say (beyond its end, no event after) or
    disagrees with the events (an :class:`~snn_fg.errors.InputWarning`: the caller reads from the
    start). The table is defined on ``events/t`` before ``t_offset``: ``t[ms_to_idx[ms]] >= ms * 1000``
    and ``t[ms_to_idx[ms] - 1] < ms * 1000`` (uzh-rpg/DSEC README, "Events"; dsec.ifi.uzh.ch/data-format)."""
    table = _dataset(f, "ms_to_idx")
    if table is None or table.ndim != 1 or table.dtype.kind not in "iu" or count == 0:
        return _bad_table(path, " is not a 1-D table of integers" if table is not None and count else None)
    t = f["events/t"]
    t_first = int(t[0])
    ms = (t_first + after_us) // 1000
    if ms >= table.shape[0]:
        return None
    i = int(table[ms])
    if not 0 <= i <= count:
        return _bad_table(path, f"[{ms}] is {i}, outside the {count:,} events")
    if (i > 0 and int(t[i - 1]) >= ms * 1000) or (i < count and int(t[i]) < ms * 1000):
        return _bad_table(path, f"[{ms}] is {i}, not the first event at or after {ms} ms (events/t)")
    return None if i == count else (i, t_first)


def _bad_table(path, problem: str | None):
    if problem is not None:
        warnings.warn(InputWarning(f"{path}: ms_to_idx{problem}; read from the start instead"), stacklevel=2)
    return None


def _mvsec(f, path, channel=None) -> Layout | None:
    held = {c: _dataset(f, f"davis/{side}/events") for c, side in MVSEC_CAMERAS.items()}
    if all(ds is None for ds in held.values()):
        return None
    channel = 0 if channel is None else channel
    if channel not in held or held[channel] is None:
        raise InputError(path, camera_line(held, channel))
    ds, name = held[channel], f"davis/{MVSEC_CAMERAS[channel]}/events"
    if ds.ndim != 2 or ds.shape[1] != 4 or ds.dtype.kind not in "fiu":
        raise InputError(path, f"MVSEC {name} must be N x 4 numbers (found {ds.dtype}, shape {ds.shape})", name)
    other = held[1 - channel]
    skipped = {f"events of the {MVSEC_CAMERAS[1 - channel]} camera": other.shape[0]} if other is not None else {}
    dtype = [("x", "<f8"), ("y", "<f8"), ("t", "<i8"), ("p", "<f8")]

    def read(f, i, j):
        a = np.asarray(_slice(f, path, name, i, j), dtype=np.float64)
        out = np.empty(j - i, dtype=dtype)
        out["x"], out["y"], out["p"] = a[:, 0], a[:, 1], a[:, 3]
        out["t"] = seconds_to_us(a[:, 2], path, f"{name} column 2 (t)", i)
        return out

    where = {"x": "column 0 (x)", "y": "column 1 (y)", "t": "column 2 (t)", "p": "column 3 (p)"}
    return Layout("mvsec", "MVSEC", {k: f"{name} {w}" for k, w in where.items()}, ds.shape[0], read, skipped)


def camera_line(held: dict, channel) -> str:
    """The problem of an MVSEC file whose cameras (``held``: channel -> dataset, None where absent)
    do not include the ``channel`` asked for, naming those it has."""
    sides = [(c, MVSEC_CAMERAS[c]) for c, ds in held.items() if ds is not None]
    has = " and ".join(f"the {side} (channel {c}, davis/{side}/events)" for c, side in sides)
    if channel == "both":
        return f"MVSEC's cameras are read one at a time, not 'both': this file has {has}"
    return f"this MVSEC file has no {MVSEC_CAMERAS[channel]} camera (channel {channel}): it has {has}"


def _prophesee(f, path) -> Layout | None:
    ds = _dataset(f, "CD/events")
    if ds is None or ds.dtype.names is None or not set("xytp") <= set(ds.dtype.names):
        return None
    name = "CD/events"
    if ds.ndim != 1:
        raise InputError(path, f"{name} must be 1-D (found shape {ds.shape})", name)
    trig = _dataset(f, "EXT_TRIGGER/events")
    skipped = {"external trigger events": trig.shape[0]} if trig is not None and trig.ndim == 1 else {}

    def read(f, i, j):
        return _slice(f, path, name, i, j)

    # (Metavision writes its camera's metadata, a RAW header's keys, as the root's string attributes:
    # openeb sdk/modules/stream/cpp/src/hdf5_event_file_writer.cpp, add_metadata_map_from_camera)
    stated = header_geometry({str(k).lower(): _text(v) for k, v in f.attrs.items()})
    where = {k: f"{name} field {k}" for k in "xytp"}
    return Layout("prophesee-hdf5", "Prophesee", where, ds.shape[0], read, skipped, sensor=stated)


def _text(value) -> str:
    """An HDF5 attribute's value as text (h5py gives a variable-length string as str, a fixed one as bytes)."""
    return value.decode("utf-8", "replace") if isinstance(value, bytes) else str(value)


def _slice(f, path, name, i, j):
    try:
        return f[name][i:j]
    except Exception as exc:  # h5py raises OSError, ValueError, KeyError... on damaged data
        raise InputError(path, f"cannot read {name} ({exc})", f"dataset {name}, events {i}-{j - 1}") from None


def seconds_to_us(t, source, name: str, offset: int = 0) -> np.ndarray:
    """Float seconds as int64 microseconds, rounded to the nearest (truncating would turn
    0.000249 s into 248 us). Exact for stamps of whole microseconds below
    :data:`MAX_FLOAT_SECONDS`: an absolute stamp such as 1504645177.4 s is stored within
    0.12 us and its product with 1e6 rounds by at most 0.125 us, well inside half a
    microsecond."""
    bad = ~np.isfinite(t) | (np.abs(t) >= MAX_FLOAT_SECONDS)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(
            source,
            f"{name} holds {float(t[i])!r}, not a time in seconds (float64 seconds hold microseconds below 2**32 s)",
            f"event {offset + i}",
        )
    return np.rint(t * 1e6).astype(np.int64)


def filters_missing(ds, h5py) -> list[int]:
    """Ids of the HDF5 filters ``ds`` is written with that this HDF5 library cannot apply."""
    plist = ds.id.get_create_plist()
    codes = [plist.get_filter(k)[0] for k in range(plist.get_nfilters())]
    return [c for c in codes if not h5py.h5z.filter_avail(c)]


def unreadable_line(layout: str, dataset: str, missing: list[int], file: str = "FILE") -> str:
    """The problem of ``file`` (its name), whose ``dataset`` is compressed with filters this h5py lacks."""
    if ECF_FILTER in missing:
        return f"a Prophesee Metavision HDF5 file: {dataset} is compressed with {_ECF_WAY_OUT.format(file=file)}"
    if BLOSC_FILTER in missing:
        return f"{layout} dataset {dataset} is compressed with Blosc (HDF5 filter 32001): {install_hint('h5')}"
    ids = ", ".join(str(c) for c in missing)
    return f"{layout} dataset {dataset} is compressed with HDF5 filter {ids}, which this HDF5 library does not have"


def unknown_layout_line(f) -> str:
    """The problem of an HDF5 file of no layout read here: the datasets it holds."""
    found = []
    f.visititems(lambda name, obj: found.append((name, obj.shape)) if hasattr(obj, "shape") else None)
    shown = ", ".join(f"{name} {shape}" for name, shape in found[:LISTED_DATASETS])
    more = f", ... ({len(found)} in all)" if len(found) > LISTED_DATASETS else ""
    held = f"datasets {shown}{more}" if found else "no datasets"
    return f"an HDF5 file of no event layout read here ({held}); {_READ}"


def find_layout(f, path, channel=None) -> Layout:
    """The layout of the open file ``f`` (``channel``: MVSEC's camera); :class:`InputError` when it
    has none read here, or one camera only and a ``channel`` is asked for."""
    layout = None
    for probe in (_dsec, lambda f, path: _mvsec(f, path, channel), _prophesee):
        layout = layout or probe(f, path)
    if layout is None:
        raise InputError(path, unknown_layout_line(f))
    if channel is not None and layout.name != "mvsec":
        raise InputError(
            path,
            f"a {layout.label} file holds one camera's events ({', '.join(dict.fromkeys(layout.where.values()))}), "
            f"so channel {channel!r} does not apply; MVSEC files hold two (davis/left, davis/right)",
        )
    return layout


def _check_readable(f, path, layout: Layout, h5py) -> None:
    for name in dict.fromkeys(where.split(" ")[0] for where in layout.where.values()):
        missing = filters_missing(f[name], h5py)
        if missing:
            raise InputError(path, unreadable_line(layout.label, name, missing, Path(path).name), f"dataset {name}")


def _named(error: InputError, layout: Layout, fields: str) -> InputError:
    """``error`` of a check on event fields, with the datasets they come from added to its place."""
    names = ", ".join(dict.fromkeys(layout.where[k] for k in fields))
    return error.but(where=f"{error.where}; {names}")


def _field_of(problem: str) -> str:
    m = re.match(r"field (\w)", problem)
    return m.group(1) if m else "xytp"


def open_h5(path, sensor_size, chunk_events, *, channel: int | str | None = None) -> Source:
    """Open an HDF5 event file of one of the layouts in the module table; ``channel``: MVSEC's
    camera, 0 (left, the default) or 1 (right)."""
    h5py = _h5py()
    if h5py is None:
        raise InputError(path, f"reading HDF5 files needs h5py (and hdf5plugin for DSEC): {install_hint('h5')}")
    with _open_file(h5py, path) as f:
        try:
            layout = find_layout(f, path, channel)
            _check_readable(f, path, layout, h5py)
        except SnnFgError:
            raise
        except Exception as exc:  # the file's structure is damaged: h5py raises RuntimeError, KeyError...
            raise InputError(path, f"damaged HDF5 file ({exc})") from None

    def chunks(n, tally, size=None, start=0):
        for what, count in layout.skipped.items():
            tally.skip(what, count)
        prev = None
        with _open_file(h5py, path) as f:
            for i in range(start, layout.count, n):
                raw = layout.read(f, i, min(i + n, layout.count))
                try:
                    ev = as_events(raw, path, offset=i)
                except InputError as exc:
                    raise _named(exc, layout, _field_of(exc.problem)) from None
                x, y = ev["x"], ev["y"]
                n, problem = first_fault(x, y, ev["t"], size, prev)
                if problem:  # (the events before the fault first, as every decoder gives them)
                    if n:
                        yield ev[:n]
                    outside = size is not None and not (0 <= x[n] < size[0] and 0 <= y[n] < size[1])
                    raise _named(InputError(path, problem, f"event {i + n}"), layout, "xy" if outside else "t")
                prev = int(ev["t"][-1]) if len(ev) else prev
                yield ev

    if sensor_size is not None or layout.sensor is not None:
        size = file_sensor_size(path, sensor_size, layout.sensor)
    else:
        size = infer_sensor_size(path, chunks(chunk_events, DecodeTally()))

    def skip(after_us):
        with _open_file(h5py, path) as f:
            found = layout.seek(f, after_us)
        if found is None:
            return None
        return Skip(t_first=found[1], index=found[0], chunks=lambda n, tally: chunks(n, tally, size, found[0]))

    seek = skip if layout.seek is not None else None
    return Source(path, layout.name, size, lambda n, tally: chunks(n, tally, size), skip=seek)
