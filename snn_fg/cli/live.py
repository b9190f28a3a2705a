"""``snn-fg live``: a model on an event stream that arrives while it runs.

The stream (``udp://`` SPIF packets or a ``dv://`` DV stream,
:mod:`snn_fg.events.live_sources`) is received on a thread of its own and
cut into windows on its own clock (:class:`~snn_fg.events.live.LiveStream`);
the model runs on it as ``snn-fg run`` runs on a recording (the spiking
network continuously, reading the events as they come), writing
``DIR/maps.zarr`` window by window, publishing each window
(:mod:`snn_fg.results.publish`) and ending when the sender has gone, with
``DIR/live.json``. Ctrl-C ends it with the windows complete so far.
"""

from __future__ import annotations

from contextlib import ExitStack, closing

from ..errors import InputError
from ..events.clock import clock_keys
from ..events.cutter import WINDOW_MS
from ..events.live import MAX_BEHIND, SKIP_BEHIND
from ..events.live_dv import WAIT_S
from ..events.live_sources import IDLE_S
from ..models import MODELS
from ..models.live import live_stream, open_warmed
from ..results.atomic import growing_folder, settle_folder
from ..results.live_view import VIEW_HOST, LiveView
from ..results.outputs import check_output_folder
from ..results.publish import END_OF_STREAM, PEAKS, LiveModel, Publisher, ended_by
from ..results.store import STORE_NAME, store_arrays, windows_complete
from .options import FORCE_FOLDER_HELP, number, sensor_size, subcommand
from .run_options import add_option_groups, chosen_model
from .runner import nothing_written, run_recording

#: options of ``snn-fg run`` that a live run cannot use, and why: left out of ``snn-fg live --help``, refused in one
#: line (until 29 Nov --end-ms, --denoise-us and --refractory-us were offered and silently ignored)
_NOT_LIVE = {
    "max_windows": "a live run ends with its stream",
    "end_ms": "a live run ends with its stream",
    "stride_ms": "--hop-ms slides the read-out",
    "denoise_us": "a live stream is not filtered",
    "refractory_us": "a live stream is not filtered",
    "save_spikes": "a live run keeps the maps only",
    "duration_ms": "a single frame or image only",
    "settle_ms": "a single frame or image only",
    "spike_input": "a single frame or image only",
    "edge_operator": "the fbfg model's, which needs an image",
}
#: the models a live run offers: those that take events (the frame-based model needs an image)
LIVE_MODELS = tuple(name for name, model in MODELS.items() if model.needs != "image")


def add_live_command(sub):
    p = subcommand(
        sub,
        "live",
        description="Run a model on SOURCE as it arrives: udp://HOST:PORT (SpiNNaker interface board "
        "packets, as aestream sends them; needs --sensor-size), dv://HOST:PORT (a DV network stream, "
        "pip install -e '.[live]') or camera://[SERIAL] (an iniVation camera on USB, the same extra). "
        "Windows are cut on the stream's own clock; DIR/maps.zarr grows window by window as with snn-fg "
        "run, and DIR/live.json keeps each window's latency (from its last event's arrival to its maps) "
        "and what was dropped. Ends when the sender has gone (UDP: no packet for --idle-s).",
    )
    p.add_argument("source", metavar="SOURCE", help="udp://HOST:PORT, dv://HOST:PORT or camera://[SERIAL]")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (must be new or empty)")
    p.add_argument("--force", action="store_true", help=FORCE_FOLDER_HELP)
    p.add_argument("--model", choices=LIVE_MODELS, default="rate", help="as snn-fg run (default: rate)")
    p.add_argument("--sensor-size", type=sensor_size, metavar="WxH", help="the sensor (udp://: required)")
    p.add_argument(
        "--hop-ms",
        type=number(float, 0),
        metavar="H",
        help="a window's maps every H ms over the last --window-ms (a sliding read-out; default: one per window); "
        "a hop's read-out is skipped for a newer one when the model is --skip-behind hops behind",
    )
    p.add_argument(
        "--publish",
        metavar="URL",
        help="one JSON line per window (its span and peaks): udp://HOST:PORT, or tcp://HOST:PORT (connects there)",
    )
    p.add_argument(
        "--view",
        type=number(int, 0, strict=False, hi=65535),
        metavar="PORT",
        help="serve a page on http://127.0.0.1:PORT/ (--view-host) showing each window's event frame and maps, "
        "and the windows published, dropped and skipped, as they come",
    )
    p.add_argument(
        "--view-host",
        default=VIEW_HOST,
        metavar="HOST",
        help=f"the address --view serves on ({VIEW_HOST}: this machine only; 0.0.0.0: every network it is on, "
        "to anyone who can reach it)",
    )
    p.add_argument(
        "--peaks",
        type=number(int, 1, strict=False),
        default=PEAKS,
        metavar="K",
        help=f"grouping peaks published ({PEAKS})",
    )
    p.add_argument(
        "--max-behind",
        type=number(int, 0, strict=False),
        default=MAX_BEHIND,
        metavar="N",
        help="windows whose read-out is over waiting for their maps before whole windows are dropped "
        "(0: the least latency; more keeps more windows, each later; with --hop-ms, windows' worth of hops; "
        "the policy: docs/live.md, 'When the model falls behind')",
    )
    p.add_argument(
        "--skip-behind",
        type=number(int, 1, strict=False),
        default=SKIP_BEHIND,
        metavar="N",
        help=f"with --hop-ms: a hop's read-out is skipped for a newer one when the events that complete the read-out "
        f"N hops later have come already ({SKIP_BEHIND}; 1: the freshest maps, more: more hops made, each later)",
    )
    p.add_argument(
        "--wait-s",
        type=number(float, 0),
        default=WAIT_S,
        metavar="S",
        help=f"first packet within S s of 'ready' ({WAIT_S:g})",
    )
    p.add_argument(
        "--idle-s", type=number(float, 0), default=IDLE_S, metavar="S", help=f"udp://: end after S s idle ({IDLE_S:g})"
    )
    p.add_argument("--no-progress", action="store_true", help="no progress messages")
    p.add_argument("--no-figures", action="store_true", help="no figures at the end (the maps only)")
    add_option_groups(p, hidden=tuple(_NOT_LIVE))
    p.set_defaults(handler=cmd_live, input=None, motion=None, crop=None)
    return p


def cmd_live(args) -> int:
    args.input = args.source
    refused: dict[str, list[str]] = {}
    for k, why in _NOT_LIVE.items():
        if getattr(args, k) is not None:
            refused.setdefault(why, []).append("--" + k.replace("_", "-"))
    if refused:
        said = "; ".join(f"{', '.join(flags)}: {why}" for why, flags in refused.items())
        raise InputError(args.source, f"not for a live stream: {said}")
    if args.view is None and args.view_host != VIEW_HOST:
        raise InputError(f"--view-host {args.view_host}", "serves the page of --view PORT, which is not given")
    model = chosen_model(args, "recording")
    check_output_folder(args.out, force=args.force)  # (before the warm-up: a folder refused at once, nothing touched)
    window_ms = args.window_ms if args.window_ms is not None else WINDOW_MS
    with ExitStack() as opened:  # (what is open so far is closed on an error)
        publisher = opened.enter_context(closing(Publisher(args.publish))) if args.publish else None
        view = None
        if args.view is not None:
            view = opened.enter_context(closing(LiveView(args.view, args.source, args.view_host)))
        source, warm = open_warmed(
            model, args.source, args.sensor_size, window_ms, args.peaks, wait_s=args.wait_s, idle_s=args.idle_s
        )
        opened.enter_context(closing(source))
        out, previous = growing_folder(args.out, force=args.force, resume=None)  # (a stream cannot be resumed)
        opened.pop_all()
    earlier = previous is not None and any(previous.iterdir())  # (an earlier run set aside, with --force)
    stream = record = None
    ended = ended_by(source)
    try:  # (from here on the folder is settled however the run ends: kept with its windows, or as it was)
        stream, record = _live_stream(model, source, publisher, view, window_ms, warm.seconds, args)
        described = {"input": args.source, "kind": "live", "window_ms": window_ms, "start_ms": args.start_ms or 0.0}
        described["stride_ms"] = args.hop_ms if args.hop_ms is not None else window_ms
        run_recording(
            LiveModel(model, stream, record),
            stream,
            out,
            described,
            figures=not args.no_figures,
            clock=lambda: clock_keys(source),
            template=(warm.window, warm.maps),
        )
    except KeyboardInterrupt:
        ended = "interrupted"
        raise
    except BaseException as exc:
        ended = f"error: {exc}"
        raise
    finally:
        for part in (stream if stream is not None else source, publisher, view):
            if part is not None:
                part.close()
        kept = windows_complete(out)
        if kept:  # (a window published as the run was cut, which its store did not take whole, left out)
            arrays = store_arrays(out / STORE_NAME, kept)
            record.keep_only(arrays["window"][:] if "window" in arrays else range(kept))
            summary = record.save(out / "live.json", ended)
        settle_folder(out, previous, keep_new=bool(kept))
        args.interrupt_note = _interrupted_note(args.out, kept, earlier, summary if kept else None)
    print(f"snn-fg: {model.name} model on {args.source}: {_summary_text(summary)}; wrote {args.out}/")
    return 0


def _live_stream(model, source, publisher, view, window_ms: float, warm_s: float, args):
    """The stream cut from ``source`` for ``model`` and the record of its windows
    (:func:`~snn_fg.models.live.live_stream`), which says when the model is ready for it."""
    page = "" if view is None else f"; the live page is on http://{view.host}:{view.port}/"
    return live_stream(
        model, source, window_ms=window_ms, hop_ms=args.hop_ms, start_ms=args.start_ms or 0.0,
        max_behind=args.max_behind, skip_behind=args.skip_behind, publisher=publisher, view=view, peaks=args.peaks,
        warm_s=warm_s,
        on_ready=lambda: print(
            f"snn-fg: live: {model.name} model ready for {args.source} (warmed up in {warm_s:.1f} s){page}", flush=True
        ),
    )  # fmt: skip


def _interrupted_note(folder: str, kept: int, earlier: bool, summary: dict | None = None) -> str:
    """What an interrupted live run left in ``folder``: its ``kept`` windows, whose figures are drawn
    at the end of a run and so were not (``snn-fg plot`` draws them), and what it skipped and dropped
    besides and why (``live.json``'s ``summary``, worded as the closing line of a finished run words it:
    :func:`_behind_text`), or nothing (``earlier``: the earlier run that ``--force`` would have replaced
    is back)."""
    if kept:
        counts, why = _behind_text(summary) if summary is not None else ("", "")
        s, are, them = ("s", "are", "them") if kept != 1 else ("", "is", "it")
        return (
            f"the {kept} window{s} complete so far {are} in {folder}/ with live.json, without figures: "
            f"snn-fg plot {folder} draws {them}" + (f"; besides {them}, {counts}{why}" if counts else "")
        )
    return nothing_written(folder, earlier)


def _behind_text(summary: dict) -> tuple[str, str]:
    """What a live run left out, in words: its hops skipped for a newer one (with ``--hop-ms``, when any) and its
    windows dropped, and why it fell behind with where to read what to change ("" when nothing fell behind)."""
    skipped = summary.get("windows_skipped") or 0  # (hops: read-outs passed over for a newer hop's)
    counts = (f"{skipped} skipped for a newer hop, " if skipped else "") + f"{summary['windows_dropped']} dropped"
    why = summary.get("why_behind")
    return counts, f"; {why} (what to try: docs/live.md, 'If windows are dropped')" if why else ""


def _summary_text(summary: dict) -> str:
    """``live.json``'s summary in words: the windows (and those left out, :func:`_behind_text`), the events, and the
    latency of the windows the stream's own events completed, apart from those that waited for its end
    (``--idle-s``, or a server closing)."""
    n, lat = summary["windows"], summary["latency_ms_streaming"] or {}
    counts, why = _behind_text(summary)
    text = f"{n} window{'s' if n != 1 else ''} published, {counts}, {summary['events_received']:,} events received"
    lost = [  # (events the model never saw, said again here: the warning came once, long before)
        f"{summary[key]:,} {what}"
        for key, what in (("events_outside", "outside the sensor"), ("events_backwards", "back in time"))
        if summary.get(key)
    ]
    if lost:
        text += f" ({' and '.join(lost)}, dropped)"
    if summary.get("packets_lost"):  # (UDP says nothing to its sender: the kernel's count for the socket)
        text += (
            f" ({summary['packets_lost']:,} UDP packets lost before they were read: the socket's buffer was "
            "full; the receiver or the machine fell behind, or net.core.rmem_max keeps the buffer small)"
        )
    reach = summary.get("events_outside_reach")
    if reach:  # (a wrong --sensor-size: say what the events need)
        text += f" (they reach x={reach['x']}, y={reach['y']}: is --sensor-size right?)"
    text += (
        f"; latency median {lat.get('median', float('nan')):.1f} ms, "
        f"p95 {lat.get('p95', float('nan')):.1f} ms, max {lat.get('max', float('nan')):.1f} ms"
    )
    waited = [r["latency_ms"] for r in summary["per_window"] if r["completed_by"] == END_OF_STREAM]
    waited = [ms for ms in waited if ms is not None]
    if waited:  # (with --hop-ms, the last few hops)
        last = "the last window" if len(waited) == 1 else f"the last {len(waited)} windows"
        most = f"{waited[0]:.1f} ms" if len(waited) == 1 else f"up to {max(waited):.1f} ms"
        text += f" ({last}, completed by the end of the stream, not counted: {most})"
    return text + why
