"""``snn-fg events``: summarise a recording (or simulate an image) and write frames.

Wire it in with :func:`add_events_command`; the handler raises
:class:`~snn_fg.errors.InputError` for bad input (the main CLI prints it).
``--write-spikes`` (input spikes for an exported network) is :mod:`.spikes`.
"""

from __future__ import annotations

import argparse
import textwrap
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..events import (
    PixelOptions,
    events_to_frame,
    image_to_events,
    iter_recording,
    iter_windows,
    open_recording,
    save_events,
)
from ..events.activity import activity, saturated_lines, timeline_text
from ..events.aps import frame_summary, open_frames
from ..events.cutter import WINDOW_MS
from ..events.esim import AMPLITUDE_PX, MOTION, MOTIONS, THRESHOLD
from ..events.formats import SUFFIXES_TEXT
from ..events.images import IMAGE_SUFFIXES, read_image
from ..frames.still import image_scale_refusal, simulator_cost, sized_image
from ..results.activity import activity_figure
from ..results.atomic import save_figure, save_npz
from ..results.outputs import check_output_file
from .options import (
    DEMO,
    add_camera_options,
    add_image_scale_option,
    camera_options,
    number,
    recording_or_demo,
    sensor_size,
    subcommand,
)
from .spikes import add_spike_options, write_spikes

#: the simulated camera's options (an image's) and their defaults: the parser's, and what a recording
#: must leave them at (each set otherwise is refused: it would be ignored)
CAMERA = {"threshold": THRESHOLD, "motion": MOTION, "amplitude_px": AMPLITUDE_PX, "seed": 0, "threshold_sigma": 0.0}


def add_events_command(subparsers) -> argparse.ArgumentParser:
    """Register ``events`` on an ``argparse`` subparsers object; returns the parser."""
    p = subcommand(
        subparsers,
        "events",
        description="Print format, sensor size, event count, time span and rate of an event recording "
        f"({SUFFIXES_TEXT}). For an image (png/jpg/...) simulate "
        "an event camera (ESIM) under a small motion instead. Optionally write the event frame "
        "of one window (.npz with pos, neg, t_start_us, t_end_us) and/or the events.",
    )
    p.add_argument("input", metavar="INPUT", help="recording or image file, or demo (the built-in demo recording)")
    g = p.add_argument_group("recordings")
    g.add_argument(
        "--window-ms",
        type=float,
        default=WINDOW_MS,
        help=f"window length of the activity timeline and --write-frame (default {WINDOW_MS:g}, as snn-fg run)",
    )
    g.add_argument(
        "--start-ms",
        type=float,
        default=0.0,
        help="start of the activity table's first window and of --write-frame's, ms after the first event (default 0)",
    )
    g.add_argument(
        "--sensor-size",
        type=sensor_size,
        default=None,
        metavar="WxH",
        help="sensor size, needed for RAW files without geometry (e.g. 640x480); .txt events and arrays without it "
        "take their extent, with a warning",
    )
    add_camera_options(g)
    g = p.add_argument_group("images (event-camera simulation)")
    g.add_argument(
        "--threshold",
        type=float,
        default=CAMERA["threshold"],
        metavar="C",
        help=f"contrast threshold (default {THRESHOLD:g})",
    )
    g.add_argument(
        "--motion",
        choices=MOTIONS,
        default=CAMERA["motion"],
        help="shift4: 1-px shift up, right, down, left; circle: iCub microsaccade; paper: the authors' "
        f"BSDS conversion (2-px copies down and right, through JPEG) (default {MOTION})",
    )
    g.add_argument(
        "--amplitude-px",
        type=float,
        default=CAMERA["amplitude_px"],
        metavar="A",
        help=f"motion amplitude (default {AMPLITUDE_PX:g})",
    )
    g.add_argument(
        "--seed", type=number(int, 0, strict=False), default=CAMERA["seed"], help="seed for threshold noise (default 0)"
    )
    g.add_argument(
        "--threshold-sigma",
        type=float,
        default=CAMERA["threshold_sigma"],
        help="per-pixel threshold noise (std, default 0)",
    )
    add_image_scale_option(g, "the simulated camera")
    g = p.add_argument_group("outputs")
    g.add_argument(
        "--write-frame",
        metavar="OUT.npz",
        default=None,
        help="write the event frame (pos, neg uint8, t_start_us, t_end_us)",
    )
    g.add_argument(
        "--write-events", metavar="OUT.npy", default=None, help="write the events (.npy, .npz, .raw EVT2 or .es)"
    )
    g.add_argument(
        "--plot",
        metavar="FILE.png",
        default=None,
        help="recordings: draw the events and the share of pixels they cover, window by window",
    )
    g.add_argument(
        "--force",
        action="store_true",
        help="replace the files --write-frame, --write-events, --write-spikes, --plot name if they are earlier ones of "
        "that kind (a user's other file is refused)",
    )
    g.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_spike_options(p)
    p.set_defaults(func=run_events, handler=run_events)
    return p


#: the file line of ``snn-fg events demo``
DEMO_SAID = (
    "demo (built in: the demo scene, as snn-fg run demo shows it, seen through the iCub's microsaccade, "
    "a turn every 85 ms; snn-fg stream demo sends it)"
)


def _summary(lines):
    width = max(len(k) for k, _ in lines)
    return "\n".join(f"{k + ':':<{width + 1}} {v}" for k, v in lines)


def _span_lines(n, n_on, t_first, t_last):
    span = (t_last - t_first) if n else 0
    rate = f"{n / (span / 1e6):,.0f} events/s" if span > 0 else "n/a"
    on = f" (ON {100 * n_on / n:.1f} %)" if n else ""
    return [
        ("events", f"{n:,}{on}"),
        ("time span", f"{span / 1e6:.6f} s (file clock {t_first} .. {t_last} us)" if n else "n/a"),
        ("event rate", rate),
    ]


def _written_note(out):
    if Path(out).suffix.lower() == ".npy":
        return f"{out} (.npy keeps no sensor size: give it when reading, or write .npz)"
    return str(out)


def run_events(args) -> int:
    """Handler of ``snn-fg events``; prints a summary, returns 0."""
    path, demo = Path(args.input), args.input == DEMO
    if not (demo or path.exists()):
        raise InputError(path, "no such file")
    _check_outputs(args, path)
    is_image = path.suffix.lower() in IMAGE_SUFFIXES
    if args.image_scale is not None and not is_image:
        raise InputError(path, f"--image-scale: {image_scale_refusal('recording')}")
    # (set away from its default on a recording, an option of the simulated camera was ignored without a word)
    for name, default in CAMERA.items():
        if not is_image and getattr(args, name) != default:
            flag = "--" + name.replace("_", "-")
            raise InputError(path, f"{flag}: applies to images turned into events only; INPUT is an event recording")
    if args.write_spikes is not None:
        return write_spikes(args)
    _check_plot(args, path)
    if is_image:
        print(_summary(_image_lines(path, args)))
        return 0
    stream, lines, spans_time, damage = _recording_lines(path, args)
    print(_summary(lines))
    if damage is not None:  # (the events before the damage summarised, then the error's one line)
        raise damage
    if spans_time:  # (a stream that spans no time has been warned about)
        _print_activity(stream, args)
    return 0


def _image_lines(path, args) -> list:
    """The summary of an image's simulated events, writing the frame and
    events asked for."""
    image = read_image(path, grey=args.motion != "paper")  # (paper: the authors' JPEG encoder makes the grey)
    shown = sized_image(image, path, args.image_scale, simulator_cost(args.motion))
    rec = image_to_events(
        shown,
        threshold=args.threshold,
        motion=args.motion,
        amplitude_px=args.amplitude_px,
        seed=args.seed,
        pixels=PixelOptions(threshold_sigma=args.threshold_sigma),
    )
    ev = rec.events
    n = len(ev)
    motion = args.motion if args.motion == "paper" else f"{args.motion}, amplitude {args.amplitude_px:g} px"
    lines = [
        ("file", str(path)),
        ("format", f"image, simulated (ESIM, {motion}, threshold {args.threshold:g})"),
        *_scaled_line(image, shown, args.image_scale),
        ("sensor", f"{rec.sensor_size[0]} x {rec.sensor_size[1]}"),
    ]
    t_first, t_last = (int(ev["t"][0]), int(ev["t"][-1])) if n else (0, 0)
    lines += _span_lines(n, int((ev["p"] > 0).sum()), t_first, t_last)
    if args.write_frame:
        pos, neg = events_to_frame(ev, rec.sensor_size)
        t_end = t_last + 1 if n else 0
        save_npz(args.write_frame, pos=pos, neg=neg, t_start_us=np.int64(0), t_end_us=np.int64(t_end))
        lines.append(
            ("frame written", f"{args.write_frame} (whole motion, {int(pos.sum())} ON, {int(neg.sum())} OFF pixels)")
        )
    if args.write_events:
        save_events(args.write_events, ev, rec.sensor_size)
        lines.append(("events written", _written_note(args.write_events)))
    return lines


def _scaled_line(image, shown, scale) -> list:
    """The summary's line saying how an image was resized (none when it was not)."""
    if scale is None:
        return []
    (h, w), (sh, sw) = image.shape[:2], shown.shape[:2]
    return [("image", f"{w} x {h}, resized by --image-scale {scale:g} to {sw} x {sh}")]


def _recording_lines(path, args):
    """The recording's stream, its summary (writing the frame and events
    asked for), whether its events span any time, and the error of a damaged
    file (None): its events before the damage are summarised (no file is written
    from them), as ``snn-fg run`` keeps its whole windows."""
    source = recording_or_demo(args.input)
    stream = iter_recording(source, sensor_size=args.sensor_size, progress=not args.no_progress, **camera_options(args))
    n = n_on = 0
    t_first = t_last = damage = None
    try:
        for chunk in stream:
            n += len(chunk)
            n_on += int((chunk["p"] > 0).sum())
            if t_first is None:
                t_first = int(chunk["t"][0])
            t_last = int(chunk["t"][-1])
    except InputError as exc:
        if not n or args.write_frame or args.write_events:
            raise
        damage = exc
    lines = [
        ("file", str(path) if source is args.input else DEMO_SAID),
        ("format", f"{stream.format}" + ("" if stream.streams else " (read into memory whole, not streamed)")),
        ("sensor", f"{stream.sensor_size[0]} x {stream.sensor_size[1]}"),
    ]
    lines += _span_lines(n, n_on, t_first or 0, t_last or 0)
    if damage is not None:
        lines.append(("damaged", f"the events above are those before it ({damage.where or 'see below'})"))
    if stream.skipped:
        lines.append(
            (
                "skipped",
                ", ".join(f"{n:,} {what}" for what, n in stream.skipped.items()) + " (read, not used by the model)",
            )
        )
    lines += _frame_lines(path, stream, t_first)
    if args.write_frame:
        w = next(iter(iter_windows(stream, window_ms=args.window_ms, start_ms=args.start_ms, max_windows=1)))
        save_npz(
            args.write_frame, pos=w.pos, neg=w.neg, t_start_us=np.int64(w.t_start_us), t_end_us=np.int64(w.t_end_us)
        )
        lines.append(
            (
                "frame written",
                f"{args.write_frame} (window {w.span_ms[0]:g}-{w.span_ms[1]:g} ms, "
                f"{len(w.events):,} events, {int(w.pos.sum())} ON, "
                f"{int(w.neg.sum())} OFF pixels)",
            )
        )
    if args.write_events:
        rec = open_recording(stream)
        save_events(args.write_events, rec.events, rec.sensor_size)
        lines.append(("events written", _written_note(args.write_events)))
    if damage is not None:
        return stream, lines, False, damage
    return stream, lines, bool(n and t_last > t_first), None


def _frame_lines(path, stream, t_first) -> list:
    """The APS frames line of a DAVIS recording (an AEDAT 4 file; other formats carry none):
    how many and how often, or why the fbfg model cannot run on them."""
    if stream.format != "aedat4":
        return []
    frames = open_frames(path)
    if frames is None:
        return [("APS frames", "none (the file holds no frame stream: the fbfg model cannot run on it)")]
    try:
        line = frame_summary(frames).text(t_first)
    except InputError as exc:  # (frames out of time order: the events are still summarised)
        return [("APS frames", f"unusable: {exc.problem}" + (f" ({exc.where})" if exc.where else ""))]
    if frames.size != tuple(stream.sensor_size[:2]):
        line += " (another size than the event sensor: the fbfg model cannot run on them)"
    return [("APS frames", line)]


#: the options of ``snn-fg events`` that name a file to write, and the file names each writes
OUTPUT_FLAGS = {
    "--write-frame": (".npz",),
    "--write-events": (".npy", ".npz", ".raw", ".es"),
    "--write-spikes": (".npz",),
    "--plot": (".png",),
}


def _check_outputs(args, path):
    """Each file to write: not the input, replaced only with ``--force``, writable (before the work)."""
    for flag, suffixes in OUTPUT_FLAGS.items():
        out = getattr(args, flag.lstrip("-").replace("-", "_"))
        if out is None:
            continue
        if Path(out).resolve() == path.resolve():
            raise InputError(out, "output would overwrite the input")
        check_output_file(out, args.force, flag, suffixes)


def _check_plot(args, path):
    if args.plot is None:
        return
    if path.suffix.lower() in IMAGE_SUFFIXES:
        raise InputError(path, "--plot draws a recording's activity over time; an image has none")


def _print_activity(stream, args):
    """The recording's activity window by window (a second pass over the
    file), its saturated windows, and the ``--plot`` figure."""
    act = activity(stream, window_ms=args.window_ms, start_ms=args.start_ms)
    print("activity:\n" + timeline_text(act))
    for line in saturated_lines(act):
        print(textwrap.fill(f"saturated: {line}", width=100, subsequent_indent="  ", break_on_hyphens=False))
    if args.plot:
        save_figure(activity_figure(act, f"{Path(args.input).name}: activity over time"), args.plot, dpi=110)
        print(f"snn-fg: figure saved to {args.plot}")
