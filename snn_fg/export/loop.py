"""Both ends of a board run: input spikes for an export, and maps from its counts.

* ``snn-fg events INPUT --write-spikes input.npz --export DIR``
  (:func:`write_spikes`): a recording window (the ``--start-ms`` /
  ``--window-ms`` of ``snn-fg events``; its events at their own times,
  repeated as ``snn-fg run`` presents one window), an image (its simulated
  camera's event frame) or an event frame (regular trains, as ``snn-fg
  run``), cut to the export's frame (``--crop-at``; by default the crop
  with the most event pixels), on the export's time
  step: the file ``DIR/run.py --input`` reads;
* ``snn-fg decode counts.npz --export DIR --out OUT`` (:func:`cmd_decode`):
  ``run.py``'s counts decoded as ``snn-fg run`` decodes a spiking run, into
  ``OUT/maps.npz`` and ``OUT/maps.png``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import InputError

#: regular trains of an event frame: the rate ``snn-fg run`` uses (Hz)
FRAME_RATE_HZ = 200.0
#: an input whose rate differs from the one the export's gains are set for by more than this factor
#: is driven noticeably differently from how ``snn-fg run`` (which calibrates to its input) drives it
RATE_MISMATCH = 1.2


def add_spike_options(parser):
    """``--write-spikes`` and its options on ``snn-fg events``'s parser."""
    g = parser.add_argument_group("input spikes for an exported network (snn-fg export --format pynn)")
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
        "(--network compact: 3 x 3 blocks; default: the crop with the most event pixels or blocks)",
    )
    g.add_argument(
        "--duration-ms",
        type=float,
        default=400.0,
        help="frames and images: length of the regular trains (400, as snn-fg run)",
    )


def export_network(folder):
    """The snn-fg description a PyNN export was made from (its board network)."""
    from ..network.graph import Network

    path = Path(folder) / "network.json"
    try:
        meta = json.loads(path.read_text())
        return Network.from_dict(meta["snn_fg_network"]), meta
    except FileNotFoundError:
        raise InputError(path, "no such file: --export needs a folder written by snn-fg export --format pynn") from None
    except (ValueError, KeyError, TypeError) as e:
        raise InputError(path, f"not a PyNN export's network.json ({type(e).__name__}: {e})") from None


def busiest_crop(active: np.ndarray, want) -> tuple:
    """Top-left ``(row, col)`` of the ``want``-sized crop with the most
    active pixels; of several such, the one nearest the input's centre."""
    eh, ew = want
    s = np.pad(np.cumsum(np.cumsum(active.astype(np.int64), 0), 1), ((1, 0), (1, 0)))
    inside = s[eh:, ew:] - s[:-eh, ew:] - s[eh:, :-ew] + s[:-eh, :-ew]
    rows, cols = np.nonzero(inside == inside.max())
    centre = ((active.shape[0] - eh) / 2, (active.shape[1] - ew) / 2)
    best = int(np.argmin(np.hypot(rows - centre[0], cols - centre[1])))
    return int(rows[best]), int(cols[best])


def centroid_crop(events, want, sensor_shape) -> tuple:
    """Top-left ``(row, col)`` of the ``want``-sized (rows, cols) crop
    centred on the mean event position of ``events``, moved inside a sensor
    of ``sensor_shape`` (rows, cols): a moving object stays in view however
    the events are spread, with no look at what the network makes of them."""
    (eh, ew), (h, w) = want, sensor_shape
    r0 = int(np.floor(np.mean(events["y"]) - (eh - 1) / 2 + 0.5))
    c0 = int(np.floor(np.mean(events["x"]) - (ew - 1) / 2 + 0.5))
    return min(max(r0, 0), h - eh), min(max(c0, 0), w - ew)


def crop_events(events, top_left, shape):
    """The events inside the ``shape`` (rows, cols) box at ``top_left`` (row, col), in its coordinates."""
    (r0, c0), (h, w) = top_left, shape
    ev = events[(events["y"] >= r0) & (events["y"] < r0 + h) & (events["x"] >= c0) & (events["x"] < c0 + w)].copy()
    ev["x"] -= c0
    ev["y"] -= r0
    return ev


def _pixel(net) -> str:
    """What one of the network's input sources sees: a pixel, or a block of pixels."""
    return "block" if net.params.input_pool > 1 else "pixel"


def _at(net, r0, c0) -> str:
    return f"{'block ' if net.params.input_pool > 1 else ''}x={c0}, y={r0}"


#: share of a crop's pixels (or blocks) with events above which --write-spikes notes it may lie inside an object
CROP_FILLED = 0.5


def _crop_box(active, net, crop_at, source):
    """Top-left (row, col) of the crop of the network's frame from the (pooled) input's ``active`` sources."""
    from .pynn import frame_size

    (h, w), want = active.shape, tuple(net.frame_shape)
    (eh, ew), size = want, frame_size(net, active.shape)
    if h < eh or w < ew:
        raise InputError(source, f"an input of {size} is smaller than the export's frame of {frame_size(net)}")
    if crop_at is None:
        return busiest_crop(active, want)
    try:
        x, y = (int(v) for v in crop_at.split(","))
    except ValueError:
        raise InputError(source, f"--crop-at {crop_at!r}: expected X,Y") from None
    if not (0 <= x <= w - ew and 0 <= y <= h - eh):
        raise InputError(source, f"--crop-at {x},{y}: a crop of {frame_size(net)} must lie inside the input's {size}")
    return y, x


def _input_spikes(args, net, dt_ms):
    """InputSpikes of the input cut to the network's frame, and a description. A
    network that pools its input (``params.input_pool``) sees the input's blocks,
    and its input adapter's refractory period applies to a recording's events."""
    from ..events import iter_recording, iter_windows
    from ..frames.pool import pool_events, pool_frame
    from ..frames.still import input_kind, load_frame
    from ..lowering.input_spikes import event_spikes, frame_spikes

    shape, pool = tuple(net.frame_shape), net.params.input_pool
    kind = input_kind(args.input)
    if kind == "recording":
        stream = iter_recording(args.input, sensor_size=args.sensor_size)
        win = next(iter(iter_windows(stream, window_ms=args.window_ms, start_ms=args.start_ms, max_windows=1)))
        on, off = pool_frame(win.pos, win.neg, pool)
        r0, c0 = _crop_box((on > 0) | (off > 0), net, args.crop_at, args.input)
        ev = crop_events(pool_events(win.events, pool), (r0, c0), shape)
        if ev.size == 0:
            raise InputError(
                args.input, f"no event in the crop at {_at(net, r0, c0)} of window {win.t_start_us}..{win.t_end_us} us"
            )
        inp = event_spikes(
            ev,
            (shape[1], shape[0]),
            dt_ms,
            replay=True,
            source=str(args.input),
            t0_us=win.t_start_us,
            refractory_ms=net.input_refractory_ms,
        )
        what = f"window {win.t_start_us}..{win.t_end_us} us, {ev.size:,} events"
    else:
        frame, _ = load_frame(args.input, "events", args.threshold, args.motion)
        on, off = pool_frame(frame.pos, frame.neg, pool)
        r0, c0 = _crop_box((on > 0) | (off > 0), net, args.crop_at, args.input)
        cut = (slice(r0, r0 + shape[0]), slice(c0, c0 + shape[1]))
        pos, neg = on[cut], off[cut]
        if not (pos.any() or neg.any()):
            raise InputError(args.input, f"no event {_pixel(net)} in the crop at {_at(net, r0, c0)}")
        inp = frame_spikes(pos, neg, FRAME_RATE_HZ, dt_ms, args.duration_ms)
        what = f"{kind}, regular trains at {FRAME_RATE_HZ:g} Hz for {args.duration_ms:g} ms"
    share = float(((on > 0) | (off > 0))[r0 : r0 + shape[0], c0 : c0 + shape[1]].mean())
    origin = {
        "input": str(args.input),
        "made_from": what,
        "pool": pool,
        "crop_x_px": int(c0 * pool),
        "crop_y_px": int(r0 * pool),
        "event_share": round(share, 4),
    }
    return inp, f"{what}; crop at {_at(net, r0, c0)}", origin


def write_spikes(args) -> int:
    """``snn-fg events INPUT --write-spikes OUT --export DIR``; prints what it wrote (and how to
    re-export calibrated to the input's rate when that is far from the export's), returns 0."""
    from ..results.atomic import atomic_path
    from .pynn import frame_text, save_input

    if args.export is None:
        raise InputError(args.write_spikes, "--write-spikes needs --export DIR (the export's frame and time step)")
    if args.write_frame or args.write_events:
        raise InputError(args.write_spikes, "--write-spikes goes alone: not with --write-frame or --write-events")
    if Path(args.write_spikes).suffix.lower() != ".npz":
        raise InputError(args.write_spikes, "--write-spikes needs an .npz file name")
    net, meta = export_network(args.export)
    inp, what, origin = _input_spikes(args, net, float(meta["dt_ms"]))
    with atomic_path(args.write_spikes, suffix=".npz") as part:
        save_input(inp, part, float(meta["dt_ms"]), origin)
    print(
        f"snn-fg: wrote {args.write_spikes}: {inp.indices.size:,} spikes ({inp.rate_hz:.0f} Hz per active "
        f"{_pixel(net)}; the export's gains are set for {net.input_rate_hz:g} Hz) for the export {args.export} "
        f"({frame_text(net, meta.get('sensor_shape'))}) at dt {meta['dt_ms']} ms; {what}"
    )
    if origin["event_share"] > CROP_FILLED:
        print(
            f"snn-fg: note: events cover {origin['event_share']:.0%} of the crop's {_pixel(net)}s: a crop that "
            f"lies inside a filled object holds its texture, not its outline, and its maps show little of the "
            f"object's figure-ground; --crop-at X,Y places the crop elsewhere"
        )
    hint = recalibration_hint(inp.rate_hz, net.input_rate_hz, meta.get("export_command"), _pixel(net))
    if hint:
        print(hint)
    return 0


def recalibration_hint(input_hz: float, export_hz: float, command: str | None, pixel: str = "pixel") -> str | None:
    """What to do when an input's rate is far from the one the export's gains
    are set for (``snn-fg run`` calibrates its network to its input's rate):
    the command to re-export with (``command``: the export's own, if known)."""
    if max(input_hz, export_hz) <= RATE_MISMATCH * min(input_hz, export_hz):
        return None
    redo = (
        f"{command} --input-rate-hz {input_hz:.3g} --force"
        if command
        else f"the export's snn-fg export command with --input-rate-hz {input_hz:.3g}"
    )
    return (
        f"snn-fg: note: this input is {input_hz:.3g} Hz per active {pixel}, {input_hz / export_hz:.2g} times the "
        f"{export_hz:g} Hz the export's gains are set for; snn-fg run calibrates its network to its input's "
        f"rate. To drive the export as snn-fg run drives the network, re-export: {redo} (it keeps the "
        "folder's input.npz, whose spikes do not depend on the gains)"
    )


def add_decode_command(sub):
    """Register ``decode`` on an ``argparse`` subparsers object; returns the parser."""
    p = sub.add_parser(
        "decode",
        allow_abbrev=False,
        help="decode an exported network's spike counts into maps",
        description="Turn the counts an exported network's run.py wrote (counts.npz) into the maps "
        "snn-fg run writes for a spiking run: OUT/maps.npz and OUT/maps.png.",
    )
    p.add_argument("counts", metavar="COUNTS", help="run.py's output (counts.npz)")
    p.add_argument("--export", required=True, metavar="DIR", help="the export folder run.py ran")
    p.add_argument("--out", required=True, metavar="OUT", help="output folder")
    p.add_argument(
        "--input",
        metavar="SPIKES.npz",
        default=None,
        help="the input spike file, for the figure's input panel (default: input.npz beside COUNTS)",
    )
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")
    p.set_defaults(handler=cmd_decode)
    return p


def last_spike_frame(inputs):
    """``(pos, neg)`` uint8 event frame of run.py input spikes
    (:class:`~snn_fg.lowering.input_spikes.InputSpikes`): each pixel the
    polarity of its last input spike (within the first period of a
    repeating pattern), as :func:`~snn_fg.events.window.events_to_frame`
    gives each pixel the polarity of its last event. A pixel whose ON and
    OFF sources last fire in the same step is OFF (an input file holds no
    order within a step; the figures draw OFF over ON too)."""
    h, w = inputs.shape
    n = h * w
    idx, steps = inputs.indices, inputs.steps
    last = np.full(2 * n, -1, np.int64)
    keep = idx < 2 * n  # (the clock source, if any, is no pixel)
    np.maximum.at(last, idx[keep], steps[keep])
    on, off = last[:n], last[n:]
    pos = (on > off).astype(np.uint8)
    neg = ((off >= on) & (off >= 0)).astype(np.uint8)
    return pos.reshape(h, w), neg.reshape(h, w)


def input_frame(path, shape):
    """The event frame (:func:`last_spike_frame`) of a run.py input file of ``shape`` (None: no such file)."""
    from .pynn import read_input

    if path is None or not Path(path).exists():
        return None
    try:
        inp = read_input(path)
    except InputError:
        raise
    except (OSError, ValueError, KeyError) as e:
        raise InputError(path, f"not a run.py input file ({type(e).__name__}: {e})") from None
    if inp.shape != tuple(shape):
        raise InputError(
            path,
            f"an input of {inp.shape[1]} x {inp.shape[0]}, the export's frame is "
            f"{shape[1]} x {shape[0]} (width x height)",
        )
    return last_spike_frame(inp)


def decode_counts(network, counts_path):
    """:class:`~snn_fg.results.maps.Maps` of ``run.py``'s counts for the export of ``network``."""
    from ..models.spiking.decode import decode
    from ..results.maps import Maps
    from .pynn import read_counts

    try:
        result = read_counts(network, counts_path)
    except InputError:
        raise
    except (OSError, ValueError, KeyError) as e:
        raise InputError(counts_path, f"not a run.py counts file of this export ({type(e).__name__}: {e})") from None
    fg_x, fg_y, grouping, _ = decode(result)
    params = {
        "model": "spiking",
        **network.params.to_dict(),
        "network": {
            "origin": "pynn-export",
            "frame_shape": list(network.frame_shape),
            "input_rate_hz": network.input_rate_hz,
        },
        "backend": {"name": "pynn-export", "counts": str(counts_path)},
        "simulation": {
            "dt_ms": result.dt_ms,
            "duration_ms": result.simulated_ms,
            "count_window_ms": result.count_window_ms,
        },
        "notes": list(network.notes),
    }
    return Maps(fg_x.astype(np.float32), fg_y.astype(np.float32), grouping.astype(np.float32), params)


def cmd_decode(args) -> int:
    from ..results.atomic import OutputFolder
    from ..results.figures import SPIKING_GROUPING_LABEL, event_frame_rgb, save_maps_figure

    net, _ = export_network(args.export)
    if not Path(args.counts).exists():
        raise InputError(args.counts, "no such file")
    from .pynn import input_origin

    maps = decode_counts(net, args.counts)
    spikes = args.input or Path(args.counts).with_name("input.npz")
    frame = input_frame(spikes, net.frame_shape)
    shown = event_frame_rgb(*frame) if frame is not None else np.zeros((*net.frame_shape, 3))
    origin = input_origin(spikes) if frame is not None else None
    if origin is not None:  # (maps on the export's frame: blocks of the sensor where it pools)
        maps.params["source"] = origin
    placed = None if origin is None else (origin["crop_x_px"], origin["crop_y_px"], origin["pool"])
    with OutputFolder(args.out, force=args.force) as out:
        maps.save(out.dir / "maps.npz")
        save_maps_figure(
            out.dir / "maps.png",
            shown,
            maps.fg_x,
            maps.fg_y,
            maps.grouping,
            grouping_label=SPIKING_GROUPING_LABEL,
            placed=placed,
        )
    print(f"snn-fg: decoded {args.counts} with the export {args.export}: wrote {args.out}/ (maps.npz, maps.png)")
    return 0
