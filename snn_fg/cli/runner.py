"""Running a model on an input into an output folder, as ``snn-fg run`` does:
a frame all or nothing (an :class:`~snn_fg.results.atomic.OutputFolder`), a
recording window by window into a store that a run can continue
(:mod:`snn_fg.results.store`).
"""

from __future__ import annotations

import contextlib
import itertools
import sys
import warnings
from pathlib import Path

import numpy as np

from ..backends import cancel
from ..errors import InputError
from ..events import EmptyWindowWarning, RecordingWindows, iter_recording
from ..events.activity import pixel_share, saturated_lines
from ..events.clock import clock_keys
from ..events.cutter import WINDOW_MS
from ..frames.pool import signed_frame
from ..frames.still import Still
from ..models import Model
from ..results.activity import Activity
from ..results.maps import Maps, maps_scale
from ..results.overview import input_images, overview_options, write_run_tables
from ..results.progress import bar
from ..results.store import STORE_NAME, MapsStore, read_maps, store_arrays

#: events read at a time from a recording a model runs on (1.6 MB): the
#: spiking model reads the recording while the network runs, and the copies
#: a chunk goes through on its way to a window add to the run's peak; a tenth
#: of the reader's default keeps that addition small (measured in
#: docs/performance.md, "Long recordings")
RUN_CHUNK_EVENTS = 100_000


def recording_windows(path, *, sensor_size=None, window_options: dict, progress: bool = True, **camera):
    """The windows of the recording ``path`` as ``snn-fg run`` reads them
    (85 ms unless ``window_options`` say otherwise; read again on every
    iteration, with a progress bar on each reading), and its sensor size;
    ``camera``: the format options ``chip`` and ``channel``."""
    stream = iter_recording(path, sensor_size=sensor_size, chunk_events=RUN_CHUNK_EVENTS, **camera)
    windows = RecordingWindows(stream, **{"window_ms": WINDOW_MS, **window_options}, chunk_events=RUN_CHUNK_EVENTS)
    if progress:
        windows = _Counted(windows, window_options.get("max_windows"))
    return windows, stream.sensor_size


class _Counted:
    """``windows`` (read again on every iteration) with a progress bar on each reading. A model
    that takes the events as they come (:meth:`cut`: the spiking network, whose windows are read
    well before they are done) gets a bar of the windows done instead, which :meth:`done` moves."""

    def __init__(self, windows, total):
        self.windows, self.total, self.bar = windows, total, None

    def __iter__(self):
        return _counted(self.windows, self.total)

    def cut(self):
        self.bar = bar("windows done", "win", self.total)
        return self.windows.cut()

    def done(self) -> None:
        """A window's maps are written."""
        if self.bar is not None:
            self.bar.update()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _counted(windows, total):
    """``windows`` with a progress bar that appears once the first window is read
    (a file refused on reading shows no empty bar before its error line)."""
    it = iter(windows)
    first = next(it, None)
    if first is None:
        return
    with bar("windows read", "win", total) as read:
        for w in itertools.chain([first], it):
            yield w
            read.update()


def run_still(
    model: Model, still: Still, out: Path, source: dict, crop=None, figures: bool = True, run_key: dict | None = None
) -> Maps:
    """One still input through ``model``; ``maps.npz`` and (with ``figures``) its
    figures into ``out`` (``crop``: see :meth:`Model.write_figures`). ``run_key``: the
    command's (:func:`~.run_options.run_key`), kept in ``params`` as a recording's store keeps
    it, so that a batch run again knows the run for its own."""
    maps = model.run_still(still)
    maps.params = {**maps.params, "source": source, **({"run_key": run_key} if run_key is not None else {})}
    maps.save(out / "maps.npz")
    if figures:
        model.write_figures(out, maps, model.figure_input(still), crop=crop)
    return maps


def last_window_note(lag_ms: float, n: int, source: dict) -> str:
    """The line for a run whose last window's read-out lag ran ``lag_ms`` past the end of its input,
    a run of ``n`` windows from ``source``; a recording's names the ``--max-windows`` that leaves
    the window out (a live stream takes none)."""
    live = source.get("kind") == "live"
    cut = n > 1 and not live
    return (
        f"snn-fg: note: the last window's read-out lag ran {lag_ms:g} ms past the "
        f"{'stream' if live else 'recording'}'s end, without input: "
        "its maps can differ from the windows before it"
        + (
            f" (--max-windows {n - 1} leaves it out and reads the window before it with the events after it)"
            if cut
            else ""
        )
    )


def run_recording(
    model: Model,
    windows,
    out: Path,
    source: dict,
    *,
    crop=None,
    figures: bool = True,
    resume: bool = False,
    run_key: dict | None = None,
    may_differ=(),
    clock=clock_keys,
    template=None,
) -> int:
    """Every window of a recording through ``model`` into ``out/maps.zarr``
    (:mod:`snn_fg.results.store`: each window written as it completes) and, at the
    end, its table (``windows.csv``) and figures. Returns the number of windows (``crop``: see
    :meth:`Model.write_figures`). ``source`` describes the input (its
    ``"input"``, the name errors give, and the window options). Bad input part way
    through (a file cut short) ends the run at the windows complete before it, as
    ``max_windows`` of as many would, and is then raised.

    ``resume``: continue the store in ``out`` from its last complete window
    (it must have been made with the same ``run_key``: by default the
    ``source`` and the model's name and parameters; the keys ``may_differ``
    aside); a complete store is left as it is, unless its run ended at its
    window limit and ``source`` asks for more (:func:`goes_on`).

    The windows' times (``t_start_us``, ``t_end_us``, figure titles) count
    from the recording's first event; ``params["source"]["first_event_us"]``
    keeps that event's time in the file's own clock, and the keys that ``clock()``
    gives at the run's end say which clock that is (:mod:`snn_fg.events.clock`; by
    default a recording's own; a live source's is known once it has ended, so that
    ``snn-fg compare`` pairs windows on it). Each window's share of pixels with an
    event is recorded (``pixel_share``), and a window above
    :data:`~snn_fg.results.activity.SATURATED_SHARE` is warned about and
    listed (``saturated_windows``).

    ``template``: ``(window, maps)`` like the windows to come (a live run's warm-up's last), from
    which a new store's arrays are made before the first window (:meth:`MapsStore.prepare`)."""
    path = out / STORE_NAME
    run_key = {"source": source, "model": model.name, **model.params.to_dict()} if run_key is None else run_key
    store = MapsStore.reopen(path, run_key, may_differ) if resume and path.is_dir() else MapsStore.create(path, run_key)
    if template is not None and store.n == 0:
        _append_window(store, *template, prepare=True)
    if store.complete:
        if not goes_on(store.attrs, source.get("max_windows")):
            return store.n
        store.go_on()
    n_empty = n_blank = 0
    blank_spans_ms: list = []  # how long the events of each window without a vector last ...
    blank_events: list = []  # ... and how many they are

    def emit(w, maps):
        nonlocal n_empty, n_blank
        cancel.check()  # (an interrupt swallowed inside the window stops the run here)
        has_events = bool(w.pos.any() or w.neg.any())
        n_empty += not has_events
        if has_events and not (maps.fg_x.any() or maps.fg_y.any()):
            n_blank += 1
            t = w.events["t"]
            blank_spans_ms.append((int(t.max()) - int(t.min())) / 1000 if len(t) else 0.0)
            blank_events.append(len(t))
        _append_window(store, w, maps)
        if isinstance(windows, _Counted):
            windows.done()

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EmptyWindowWarning)  # counted and reported once below
        damage = None
        try:
            whole = model.run_windows_into(windows, emit, start=store.n)
        except InputError as exc:  # (bad input part way through: the windows before it make the run)
            if not _part_way(store, source, windows, clock):
                raise
            damage, whole = exc, {}
            source = {**source, "max_windows": store.n}  # (the run it is: --max-windows N's)
        except BaseException:  # (an interrupt: the windows completed so far, for --resume)
            _part_way(store, source, windows, clock)
            raise
        finally:
            if isinstance(windows, _Counted):
                windows.close()
    store.flush()  # (every window made visible: what follows reads them back from the store)
    if store.n == 0:
        raise InputError(
            source.get("input", "the recording"), "no window to process: the recording has no events after --start-ms"
        )
    if n_empty:
        print(f"snn-fg: warning: {n_empty} of {store.n} windows had no events; their maps are zero", file=sys.stderr)
    if n_blank:
        lo, hi = min(blank_spans_ms), max(blank_spans_ms)
        span = f"{lo:.0f} ms" if round(lo) == round(hi) else f"{lo:.0f}-{hi:.0f} ms"
        why = model.blank_window_hint
        hint = f"; {why.why(blank_spans_ms, blank_events)}" if why is not None else ""
        print(
            f"snn-fg: warning: {n_blank} of {store.n - n_empty} windows with events have no figure-ground "
            f"vector (their events last {span}{hint})",
            file=sys.stderr,
        )
    lag = float((whole or {}).get("readout_without_input_ms") or 0.0)
    if lag > 0 and damage is None:
        print(last_window_note(lag, store.n, source), file=sys.stderr)
    store.finish(_run_params(store, source, windows, clock, whole))
    maps = Maps(*read_maps(path, lazy=True))
    write_run_tables(out, maps, figures=figures, coverage=not model.vector_at_every_event)
    if figures:
        model.write_figures(out, maps, input_images(maps), crop=crop, **overview_options(maps, out))
    if damage is not None:
        raise damage
    return store.n


def _part_way(store: MapsStore, source: dict, windows, clock) -> int:
    """The windows of a run stopped part way made visible (with the run's parameters so far: plot
    and compare read them as a finished run's); how many there are (0 when its disk failed)."""
    with contextlib.suppress(OSError):  # (a disk that failed: its error, not this one)
        store.flush()
        if store.n:
            store.describe(_run_params(store, source, windows, clock, warn=False))
            store.flush()
        return store.n
    return 0


def nothing_written(folder, earlier: bool) -> str:
    """What a run stopped before its first window left (``snn-fg run`` and ``snn-fg live`` after an
    interrupt): nothing, and, where ``--force`` had set an earlier run aside (``earlier``), that run back."""
    return "no window was complete: nothing written" + (f"; the earlier run in {folder}/ is kept" if earlier else "")


def goes_on(attrs: dict, asked: int | None) -> bool:
    """Whether the finished run whose store has the attributes ``attrs`` goes on to the
    ``asked`` windows (None: to the recording's end): it ended at its own window limit
    (``--max-windows``, ``--end-ms``), not at the recording's end, and fewer windows
    than asked."""
    n = int(attrs["snn_fg"]["windows_complete"])
    limit = attrs["params"].get("source", {}).get("max_windows")
    return limit is not None and n >= limit and (asked is None or asked > n)


def _append_window(store: MapsStore, w, maps: Maps, *, prepare: bool = False) -> None:
    """One window's maps into the store, with its number in the recording or stream (``window``:
    a live run that dropped windows keeps the others under their own), event frame (+1 ON, -1 OFF,
    on the maps' grid: :func:`~snn_fg.frames.pool.signed_frame`), times (from the recording's first
    event), event count and pixel share. ``prepare``: nothing appended, the store's arrays made for
    a window like ``w`` (:meth:`MapsStore.prepare`)."""
    origin = store.attrs["snn_fg"].get("first_event_us")
    if origin is None:
        origin = w.t_start_us if w.t_first_event_us is None else w.t_first_event_us
        if not prepare:
            store.attrs["snn_fg"]["first_event_us"] = int(origin)
    # (a store continued that was written without the numbers goes on without: its windows are numbered by place)
    numbered = store.n == 0 or "window" in store.arrays
    (store.prepare if prepare else store.append)(
        maps,
        **({"window": np.int64(w.index)} if numbered else {}),
        event_frame=signed_frame(w.pos, w.neg, maps_scale(maps.params)),
        t_start_us=np.int64(w.t_start_us - origin),
        t_end_us=np.int64(w.t_end_us - origin),
        event_count=np.int64(len(w.events)),
        pixel_share=np.float64(pixel_share(w)),
    )


def _run_params(store: MapsStore, source: dict, windows, clock, whole=None, *, warn: bool = True) -> dict:
    """The run's ``params`` as its store keeps them, up to its last complete window: the first
    window's parameters, ``params["source"]`` (:func:`_source_summary`; ``warn``: its saturated
    windows warned about; with ``clock()``'s keys), the whole run's (``whole``: known only at its end) and, of a live
    stream, the hops it skipped and the windows it dropped, every one until it stopped (a run cut short
    may have skipped or dropped some after its last window stored: its timeline draws them)."""
    arrays = store_arrays(store.path, store.n)
    params = {**store.attrs["params"], "source": {**_source_summary(store, arrays, source, warn), **clock()}}
    if whole:  # (kept apart: each window's own parameters are told against the first window's)
        params["whole_run"] = whole
    # (a live stream's hops passed over, and its windows dropped: kept by the stream as ranges [first, last]
    # of consecutive numbers, in order)
    for key, kept in (("skipped_windows", "skipped_windows"), ("dropped_windows", "dropped_ranges")):
        ranges = [[int(first), int(last)] for first, last in getattr(windows, kept, None) or ()]
        if ranges:
            params[key] = ranges
    return params


def _source_summary(store: MapsStore, arrays: dict, source: dict, warn: bool) -> dict:
    """``params["source"]`` of a recording's run from its stored ``arrays``: ``source``, the first
    event's time, every window's pixel share and the saturated windows (``warn``: each warned about)."""
    t0, t1 = (np.asarray(arrays[k]) for k in ("t_start_us", "t_end_us"))
    shares = np.asarray(arrays["pixel_share"])
    act = Activity(
        t_start_ms=t0 / 1000,
        t_end_ms=t1 / 1000,
        events=np.asarray(arrays["event_count"]),
        share=shares,
        window_ms=source.get("window_ms", 0),
    )
    for line in saturated_lines(act) if warn else ():
        print(f"snn-fg: warning: {line}", file=sys.stderr)
    return {
        **source,
        "first_event_us": store.attrs["snn_fg"]["first_event_us"],
        "pixel_share": [round(float(v), 4) for v in shares],
        "saturated_windows": act.saturated.tolist(),
    }
