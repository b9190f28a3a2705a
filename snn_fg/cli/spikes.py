"""``snn-fg events INPUT --write-spikes OUT --export DIR``: the spike file an
exported network's ``run.py --input`` reads.

A recording window (the ``--start-ms`` / ``--window-ms`` of ``snn-fg
events``; its events made spikes by the network's input coding, as in
docs/spiking-network.md "How events become input spikes", and repeated
window after window, where ``snn-fg run`` feeds a window's events once), an
image (its simulated camera's event frame) or an event frame (regular
trains, as ``snn-fg run``), cut to the export's frame (``--crop-at``; by
default the crop with the most outline pixels,
:func:`~snn_fg.export.loop.outline_crop`),
on the export's time step.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from ..events import iter_recording, iter_windows
from ..export.edits import checked_export
from ..export.folder import frame_size, frame_text
from ..export.loop import crop_events, export_network, outline_crop, recalibration_hint
from ..export.pynn import save_input
from ..frames.pool import pool_events, pool_frame
from ..frames.still import input_kind, load_frame, simulator_cost
from ..lowering.held_input import held_window
from ..lowering.input_spikes import InputSpikes, event_spikes, frame_spikes
from ..models.spiking.options import FRAME_DURATION_MS
from ..network.graph import HELD_CODINGS, INPUT_RATE_HZ
from ..network.recipes import POOL
from ..results.atomic import atomic_path
from .options import camera_options


def add_spike_options(parser):
    """``--write-spikes`` and its options on ``snn-fg events``'s parser."""
    g = parser.add_argument_group(
        "input spikes for an exported network (snn-fg export --format pynn or lava, or nir into a folder)"
    )
    g.add_argument(
        "--write-spikes",
        metavar="OUT.npz",
        default=None,
        help="write the spike file the export's run.py --input reads (needs --export)",
    )
    g.add_argument("--export", metavar="DIR", default=None, help="the export folder: its frame size and time step")
    g.add_argument(
        "--crop-at",
        metavar="X,Y",
        default=None,
        help="top-left pixel of the export-sized crop, or block for an export that pools its input "
        f"(--network compact: {POOL} x {POOL} blocks; default: the crop with the most event pixels (or blocks) "
        "beside one without: the most outline)",
    )
    g.add_argument(
        "--duration-ms",
        type=float,
        default=FRAME_DURATION_MS,
        help=f"frames and images: length of the regular trains ({FRAME_DURATION_MS:g}, as snn-fg run)",
    )


def _pixel(net) -> str:
    """What one of the network's input sources sees: a pixel, or a block of pixels."""
    return "block" if net.params.input_pool > 1 else "pixel"


def _at(net, r0, c0) -> str:
    return f"{'block ' if net.params.input_pool > 1 else ''}x={c0}, y={r0}"


#: share of a crop's pixels (or blocks) with events above which --write-spikes notes it may lie inside an object
CROP_FILLED = 0.5


def _crop_box(active, net, crop_at, source):
    """Top-left (row, col) of the crop of the network's frame from the (pooled) input's ``active`` sources."""
    (h, w), want = active.shape, tuple(net.frame_shape)
    (eh, ew), size = want, frame_size(net, active.shape)
    if h < eh or w < ew:
        raise InputError(source, f"an input of {size} is smaller than the export's frame of {frame_size(net)}")
    if crop_at is None:
        return outline_crop(active, want)
    try:
        x, y = (int(v) for v in crop_at.split(","))
    except ValueError:
        raise InputError(source, f"--crop-at {crop_at!r}: expected X,Y") from None
    if not (0 <= x <= w - ew and 0 <= y <= h - eh):
        raise InputError(source, f"--crop-at {x},{y}: a crop of {frame_size(net)} must lie inside the input's {size}")
    return y, x


def _times_ms(win) -> tuple[float, float]:
    """A window's start and end in ms after the recording's first event (a camera's own clock may start anywhere)."""
    t0 = win.t_start_us if win.t_first_event_us is None else win.t_first_event_us
    return (win.t_start_us - t0) / 1000, (win.t_end_us - t0) / 1000


def _input_spikes(args, net, dt_ms):
    """InputSpikes of the input cut to the network's frame, and a description. A
    network that pools its input (``params.input_pool``) sees the input's blocks,
    and its input adapter's refractory period applies to a recording's events."""
    shape, pool = tuple(net.frame_shape), net.params.input_pool
    kind = input_kind(args.input)
    if kind == "recording":
        stream = iter_recording(args.input, sensor_size=args.sensor_size, **camera_options(args))
        win = next(iter(iter_windows(stream, window_ms=args.window_ms, start_ms=args.start_ms, max_windows=1)))
        on, off = pool_frame(win.pos, win.neg, pool)
        r0, c0 = _crop_box((on > 0) | (off > 0), net, args.crop_at, args.input)
        ev = crop_events(pool_events(win.events, pool), (r0, c0), shape)
        times = _times_ms(win)
        span = f"{times[0]:g}-{times[1]:g} ms after the first event"
        if ev.size == 0:
            raise InputError(args.input, f"no event in the crop at {_at(net, r0, c0)} of window {span}")
        what = f"window {span}, {ev.size:,} events"
        if net.input_coding in HELD_CODINGS:  # (each pixel holds its last polarity as the window's frame)
            inp = _held_input(ev, shape, dt_ms, win, net.input_rate_hz)
            what += f", held as the window's frame at {net.input_rate_hz:g} Hz"
        else:
            inp = event_spikes(
                ev,
                (shape[1], shape[0]),
                dt_ms,
                replay=True,
                source=str(args.input),
                t0_us=win.t_start_us,
                refractory_ms=net.input_refractory_ms,
            )
        window = {"t_start_ms": times[0], "t_end_ms": times[1]}
    else:
        cost = simulator_cost(args.motion)  # (the image is checked as snn-fg events checks it)
        frame, _ = load_frame(args.input, "events", args.threshold, args.motion, args.image_scale, cost)
        on, off = pool_frame(frame.pos, frame.neg, pool)
        r0, c0 = _crop_box((on > 0) | (off > 0), net, args.crop_at, args.input)
        cut = (slice(r0, r0 + shape[0]), slice(c0, c0 + shape[1]))
        pos, neg = on[cut], off[cut]
        if not (pos.any() or neg.any()):
            raise InputError(args.input, f"no event {_pixel(net)} in the crop at {_at(net, r0, c0)}")
        inp = frame_spikes(pos, neg, INPUT_RATE_HZ, dt_ms, args.duration_ms)
        what = f"{kind}, regular trains at {INPUT_RATE_HZ:g} Hz for {args.duration_ms:g} ms"
        window = {}
    share = float(((on > 0) | (off > 0))[r0 : r0 + shape[0], c0 : c0 + shape[1]].mean())
    origin = {
        "input": str(args.input),
        "made_from": what,
        "pool": pool,
        "crop_x_px": int(c0 * pool),
        "crop_y_px": int(r0 * pool),
        "event_share": round(share, 4),
        **window,
    }
    return inp, f"{what}; crop at {_at(net, r0, c0)}", origin


def _held_input(ev, shape, dt_ms, win, rate_hz) -> InputSpikes:
    """A window's events held as its frame (a held input coding), replayed every window."""
    idx, steps, period = held_window(ev, shape, dt_ms, win.t_start_us, win.t_end_us, rate_hz)
    fired = np.zeros(2 * shape[0] * shape[1], bool)
    fired[idx] = True
    on, off = fired[: shape[0] * shape[1]].reshape(shape), fired[shape[0] * shape[1] :].reshape(shape)
    return InputSpikes(shape, idx, steps, period, on, off, float(rate_hz), 0, "events-held")


def write_spikes(args) -> int:
    """``snn-fg events INPUT --write-spikes OUT --export DIR``; prints what it wrote (and how to
    re-export calibrated to the input's rate when that is far from the export's), returns 0."""
    if args.export is None:
        raise InputError(args.write_spikes, "--write-spikes needs --export DIR (the export's frame and time step)")
    if args.write_frame or args.write_events:
        raise InputError(args.write_spikes, "--write-spikes goes alone: not with --write-frame or --write-events")
    net, meta = export_network(args.export)
    # (an edited network.json: the spikes are for the description it embeds; refused where run.py's layout differs)
    edited = checked_export(Path(args.export) / "network.json", net, meta, None, "the spikes are written for")
    inp, what, origin = _input_spikes(args, net, float(meta["dt_ms"]))
    with atomic_path(args.write_spikes, suffix=".npz") as part:
        save_input(inp, part, float(meta["dt_ms"]), origin)
    print(
        f"snn-fg: wrote {args.write_spikes}: {inp.indices.size:,} spikes ({inp.rate_hz:.3g} Hz per active "
        f"{_pixel(net)}; the export's gains are set for {net.input_rate_hz:g} Hz) for the export {args.export} "
        f"({frame_text(net, meta.get('sensor_shape'))}) at dt {meta['dt_ms']} ms; {what}"
    )
    if origin["event_share"] > CROP_FILLED:
        print(
            f"snn-fg: note: events cover {origin['event_share']:.0%} of the crop's {_pixel(net)}s: a crop that "
            f"lies inside a filled object holds its texture, not its outline, and its maps show little of the "
            f"object's figure-ground; --crop-at X,Y places the crop elsewhere"
        )
    hint = recalibration_hint(inp.rate_hz, net.input_rate_hz, meta.get("export_command"), _pixel(net), args.export)
    if hint:
        print(hint)
    if edited:
        print(edited)
    return 0
