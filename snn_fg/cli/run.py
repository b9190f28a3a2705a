"""``snn-fg run``: a model on a frame, an image, the demo or a recording,
into an output folder; several recordings with :mod:`.batch`.

:func:`cmd_run` chooses the model (:func:`~.run_options.chosen_model`),
then runs a still input all or nothing (:func:`_run_still`) or a recording
window by window into a folder that a run cut short keeps for ``--resume``
(:func:`_run_recording`, with :func:`_finished_already` and
:func:`_settled`).
"""

from __future__ import annotations

import math
from pathlib import Path

from ..errors import InputError
from ..events.aps import FramedWindows, pairing_note, require_frames
from ..events.cutter import WINDOW_MS
from ..events.esim import MOTION, MOTIONS, THRESHOLD
from ..events.formats import SUFFIXES_TEXT
from ..events.identity import input_keys
from ..frames.pool import pooled_shape
from ..frames.pyramid import check_levels
from ..frames.still import RATE_BYTES_PER_PIXEL, SPIKING_BYTES_PER_PIXEL, input_kind, load_frame
from ..models import MODELS
from ..network.recipes import is_recipe, load_description
from ..results.atomic import OutputFolder, growing_folder, settle_folder
from ..results.store import STORE_NAME, read_attrs, run_finished, store_arrays, stored_run, windows_complete
from ..results.timeline import MAPS_FIGURE
from ..validate import check_crop
from .batch import is_dataset, run_dataset
from .options import (
    FORCE_FOLDER_HELP,
    add_camera_options,
    add_image_scale_option,
    camera_options,
    crop,
    number,
    sensor_size,
    subcommand,
)
from .run_options import WINDOW_LIMITS, WINDOW_OPTIONS, add_option_groups, chosen_model, run_key
from .runner import goes_on, nothing_written, recording_windows, run_recording, run_still


def add_run_command(sub):
    """Register ``run`` on an ``argparse`` subparsers object; returns the parser."""
    p = subcommand(
        sub,
        "run",
        description="Run a model on INPUT: an .npz event frame (pos, neg), an image (png/jpg/...), "
        f"an event recording ({SUFFIXES_TEXT}) or 'demo' "
        "(a built-in synthetic scene). Writes DIR/maps.npz (fg_x, fg_y, grouping, "
        "params; a recording: DIR/maps.zarr, window by window) and figures.",
    )
    p.add_argument(
        "input",
        metavar="INPUT",
        help="a frame, an image, a recording or demo; several recordings: a "
        "folder, a glob (quoted) or a .txt list of paths, each into "
        "DIR/NAME with DIR/summary.csv",
    )
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (must be new or empty)")
    p.add_argument("--force", action="store_true", help=FORCE_FOLDER_HELP)
    p.add_argument(
        "--resume",
        action="store_const",
        const=True,
        help="recordings: continue the run in --out from its last complete window (same INPUT and options)",
    )
    p.add_argument(
        "--workers",
        type=number(int, 1, strict=False),
        metavar="N",
        help="several recordings (INPUT a folder, a glob or a .txt list): local processes (one per core)",
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="several recordings: run them on the Dask cluster at ADDRESS (pip install -e '.[sweep]')",
    )
    p.add_argument(
        "--model",
        choices=tuple(MODELS),
        default="rate",
        help="rate: the rate reference model (EDFG); fbfg: frame-based model on an image or on a "
        "DAVIS recording's APS frames (each window: the last frame before its end); "
        "spiking: the spiking network; natural, natural-spiking: the variant for natural "
        "scenes (contrast-invariant grouping, docs/model.md), rate and spiking (default: rate)",
    )
    g = p.add_argument_group("input")
    g.add_argument(
        "--threshold",
        type=number(float, 0),
        default=THRESHOLD,
        metavar="C",
        help=f"images turned into events: contrast threshold of the simulated event camera ({THRESHOLD:g})",
    )
    g.add_argument(
        "--motion",
        choices=MOTIONS,
        default=None,
        help="images turned into events: motion of the simulated event camera; paper: the authors' "
        "BSDS conversion (default shift4)",
    )
    add_image_scale_option(g, "the model")
    g.add_argument(
        "--sensor-size",
        type=sensor_size,
        metavar="WxH",
        help="recordings: sensor size for RAW files without geometry, .txt events and .npy/.npz arrays (without "
        "it, a text file's or an array's sensor is its events' extent, with a warning); a file that states its own "
        "takes that one only",
    )
    add_camera_options(g)
    g = p.add_argument_group("output")
    g.add_argument(
        "--crop",
        type=crop,
        metavar="X0,Y0,X1,Y1",
        help="figures: draw only pixels X0 <= x < X1, Y0 <= y < Y1 (the maps keep the whole frame)",
    )
    g.add_argument("--no-progress", action="store_true", help="no progress messages or bars")
    g.add_argument("--no-figures", action="store_true", help="write the maps only (no figures)")
    add_option_groups(p)
    p.set_defaults(handler=cmd_run)
    return p


def cmd_run(args) -> int:
    """Handler of ``snn-fg run``; prints what it wrote, returns 0 (a batch: 1 when a recording failed)."""
    if is_dataset(args.input):
        return run_dataset(args, cmd_run)
    if args.workers is not None or args.scheduler is not None:
        given = "--workers" if args.workers is not None else "--scheduler"
        raise InputError(
            args.input, f"{given}: applies to several recordings only (INPUT a folder, a glob or a .txt list)"
        )
    kind = input_kind(args.input)
    model = chosen_model(args, kind)
    written = _run_recording(args, model) if kind == "recording" else _run_still(args, model)
    if written is not None:
        print(f"snn-fg: {model.name} model on {args.input}: wrote {args.out}/ ({written})")
    return 0


def _check_frame(args, model, shape) -> None:
    """The input's frame of ``shape`` (rows, cols) holds the model's levels and ``--crop``; a
    stored network made for another frame is said to run resized to it (its kernels are weight
    shared: only its populations' sizes change; ``params["network"]["resized_from"]`` records it)."""
    stored = getattr(args, "network", None)
    if "network" in model.options and stored is not None and not is_recipe(stored) and Path(stored).is_file():
        made = load_description(stored).frame_shape
        runs = pooled_shape(shape, model.params.input_pool)
        if tuple(made) != tuple(runs):
            print(
                f"snn-fg: note: {stored} was made for a {made[1]} x {made[0]} frame and runs resized to this "
                f"input's {runs[1]} x {runs[0]} (the same kernels: only its populations' sizes change)"
            )
    try:
        check_levels(
            pooled_shape(shape, model.params.input_pool),
            model.params.levels,
            args.input,
            model.params.levels_per_octave,
        )
    except InputError as e:
        if getattr(args, "sensor_size", None) is None:
            raise
        # (a sensor given by hand too small for the recording is its real problem: it showed only at fewer levels)
        size = f"{args.sensor_size[0]}x{args.sensor_size[1]}"
        raise e.but(source=args.input, problem=f"{e.problem} (is --sensor-size {size} right?)") from None
    if args.crop is not None:
        check_crop(args.crop, shape, owner=f"{args.input}: --crop")


def _run_still(args, model) -> str:
    """A frame, an image or the demo into ``--out``, all or nothing; what was written."""
    frame, source = load_frame(
        args.input, model.needs, args.threshold, args.motion or MOTION, args.image_scale, image_cost(args, model)
    )
    _check_frame(args, model, frame.shape)
    with OutputFolder(args.out, force=args.force, cancelled=getattr(args, "interrupted", None)) as folder:
        key = run_key(args)
        run_still(model, frame, folder.dir, source, crop=args.crop, figures=not args.no_figures, run_key=key)
        return ", ".join(sorted(p.name for p in folder.dir.iterdir()))


def image_cost(args, model):
    """``(what, bytes a pixel)`` of the memory ``model`` needs for an image, where measured: the frame
    models' (rate, fbfg, natural) and the default spiking network's (:mod:`snn_fg.frames.still`);
    None for another network (not measured on images)."""
    if model.name in ("rate", "fbfg", "natural"):
        return f"{model.name} model", RATE_BYTES_PER_PIXEL
    if args.network in (None, "default"):
        return f"{model.name} model on the default network", SPIKING_BYTES_PER_PIXEL
    return None


def _windows(args, model):
    """The recording's windows as the options cut it (for the frame-based model, each with its APS
    frame), its ``params["source"]`` and its frame shape (rows, cols)."""
    opts = {k: getattr(args, k) for k in WINDOW_OPTIONS if getattr(args, k) is not None}
    if args.end_ms is not None:
        opts["max_windows"] = min(opts.get("max_windows", math.inf), _windows_before_end(args))
    windows, sensor = recording_windows(
        args.input,
        sensor_size=args.sensor_size,
        window_options=opts,
        progress=not args.no_progress,
        **camera_options(args),
    )
    if model.needs == "image":  # (a recording without frames, or of frames of another size: one line)
        windows = FramedWindows(windows, require_frames(args.input, sensor), sensor)
    source = {"input": args.input, "kind": "recording", "window_ms": WINDOW_MS, "start_ms": 0.0, **opts}
    source.update(camera_options(args))  # (compare names another camera: scoring.inputs.other_inputs)
    if args.end_ms is not None:
        source["end_ms"] = args.end_ms
    source.setdefault("stride_ms", source["window_ms"])
    return windows, source, tuple(sensor[1::-1])


def _windows_before_end(args) -> int:
    """How many windows end by ``--end-ms`` (at least one, or refused)."""
    win = WINDOW_MS if args.window_ms is None else args.window_ms
    start = args.start_ms or 0.0
    stride = win if args.stride_ms is None else args.stride_ms
    n = math.floor((args.end_ms - start - win) / stride + 1e-9) + 1
    if n < 1:
        raise InputError(
            args.input,
            f"--end-ms {args.end_ms:g}: no window of {win:g} ms fits between --start-ms {start:g} and it",
        )
    return n


def _run_recording(args, model) -> str | None:
    """A recording window by window into ``--out`` (continued with ``--resume``); what was
    written, or None when a resumed run is finished already."""
    windows, source, shape = _windows(args, model)
    _check_frame(args, model, shape)
    # (compare tells inputs apart by these keys; read with the sensor the windows found, which a file that
    # states none took a whole pass over its events to infer: not a second one)
    source.update(input_keys(args.input, sensor_size=shape[::-1], **camera_options(args)))
    out, previous = growing_folder(args.out, force=args.force, resume=bool(args.resume))
    resumed = _resume_key(args, out, source)
    if _nothing_to_resume(args, out, source.get("max_windows"), resumed):
        return None
    args.interrupt_note = _interrupted(args.out, None)
    options = {"crop": args.crop, "figures": not args.no_figures, "resume": bool(args.resume)}
    key = {"run_key": resumed, "may_differ": WINDOW_LIMITS}
    # (an animation snn-fg plot drew of the windows before: a resumed run adds windows, and does not draw it again)
    stale = sorted(p.name for p in out.glob("maps.*") if p.suffix in (".gif", ".mp4")) if args.resume else []
    n = _settled(args, out, previous, lambda: run_recording(model, windows, out, source, **options, **key))
    if model.needs == "image":
        kept = store_arrays(out / STORE_NAME, n)
        print("snn-fg: " + pairing_note(kept["t_end_us"], kept["aps_index"], kept.get("aps_t_us")))
    for name in stale:
        print(
            f"snn-fg: {args.out}/{name} shows the windows before this run: snn-fg plot {args.out} --animate "
            f"{args.out}/{name} --force draws all {n}"
        )
    return f"{n} window{'s' if n != 1 else ''}, " + ", ".join(
        sorted(p.name for p in out.iterdir() if p.name not in stale)
    )


def _interrupted(folder: str, n: int | None, earlier: bool = False, finished: bool = False) -> str:
    """What an interrupted recording run left in ``folder``: its ``n`` windows (None: not known yet), or
    nothing (``earlier``: the earlier run that ``--force`` would have replaced is back), as a live run says it;
    ``finished``: every window was done, and the run was drawing its figures (there is nothing to resume)."""
    if n == 0:
        return nothing_written(folder, earlier)
    if finished:
        return (
            f"every window was done: the {n} window{'s' if n != 1 else ''} are in {folder}/ (maps.zarr), but not "
            f"every figure was drawn: snn-fg plot {folder} --force draws them (--resume has nothing left to run)"
        )
    kept = "the windows" if n is None else f"the {n} window{'s' if n != 1 else ''}"
    return (
        f"{kept} completed so far are in {folder}/ (maps.zarr: snn-fg plot {folder} draws them); "
        "the same command with --resume continues from the last one"
    )


def _settled(args, out, previous, run) -> int:
    """``run()`` into the growing folder ``out`` (``previous``: what it held, set aside, see
    :func:`~snn_fg.results.atomic.growing_folder`), then the folder settled by how it ended: kept
    when it completed, or finished at bad input part way through (the windows before it: never
    a half-written window); after an interrupt, the windows completed so far, for ``--resume``;
    after bad input before any window, nothing (the earlier run kept)."""
    try:
        n = run()
    except InputError as exc:
        # bad input: a run that met it part way through has finished with the windows before it
        # (run_recording, which says so); one that met it before any is dropped, the earlier run kept
        kept, earlier = run_finished(out), previous is not None and any(previous.iterdir())
        if not args.resume:  # (a run continued is kept as it is, as after an interrupt)
            settle_folder(out, previous, keep_new=kept)
        if kept:
            n = windows_complete(out)
            place, s = (f" (at {exc.where})" if exc.where else ""), ("s" if n > 1 else "")
            said = (
                f"{place}; stopped there: the {n} window{s} complete before it "
                f"{'are' if s else 'is'} written to {args.out}/, a finished run (what --max-windows {n} gives)"
            )
            raise exc.but(where=None, note=f"{exc.note}{said}") from None
        if not earlier:
            raise
        raise exc.but(note=f"{exc.note}; the earlier run in {args.out}/ is kept") from None
    except BaseException as exc:  # (refused before its first window: nothing to keep)
        n, earlier = windows_complete(out), previous is not None and any(previous.iterdir())
        settle_folder(out, previous, keep_new=bool(n))
        if isinstance(exc, KeyboardInterrupt):  # (the note says how many windows were kept)
            args.interrupt_note = _interrupted(args.out, n, earlier, finished=run_finished(out))
        raise
    settle_folder(out, previous, keep_new=True)
    return n


def _resume_key(args, out, source: dict) -> dict:
    """:func:`~.run_options.run_key` of the arguments; with ``--resume``, its input named as the run
    being continued names it where both read the same recording (the same sensor and first events,
    ``source``'s :func:`~snn_fg.events.identity.input_keys`): a path typed from another folder, or
    made absolute, is the same input (a job script that ran elsewhere was refused for the spelling)."""
    key = run_key(args)
    store = out / STORE_NAME
    if not args.resume or not store.is_dir():
        return key
    attrs = read_attrs(store)
    before = (attrs.get("params") or {}).get("source") or {}
    stored_input = (attrs["snn_fg"].get("run_key") or {}).get("input")
    same = before.get("events_head") is not None and all(
        before.get(k) == source.get(k) for k in ("events_head", "sensor_size")
    )
    if same and stored_input is not None:
        key["input"] = stored_input
    return key


def _nothing_to_resume(args, out, asked: int | None, key: dict) -> bool:
    """With ``--resume``, whether the run in ``out`` has nothing to add for the ``asked``
    windows (None: to the recording's end), said in one line (nothing is written): it is
    complete and does not go on (:func:`~.runner.goes_on`), or it holds more windows than asked
    (it is left as it is). A finished run cut by its window limit goes on to a larger one."""
    attrs = stored_run(out / STORE_NAME, key, WINDOW_LIMITS) if args.resume else None
    if attrs is None:
        return False
    n, complete = int(attrs["snn_fg"]["windows_complete"]), attrs["snn_fg"]["complete"]
    if asked is not None and asked < n:
        limit = "--end-ms" if args.max_windows is None else "--max-windows"
        print(
            f"snn-fg: the run in {args.out}/ holds {n} windows, more than the {asked} of {limit}: nothing to resume, "
            f"nothing written (its first {asked} windows are those a {asked}-window run gives; a shorter run of its "
            "own needs another --out)"
        )
        return True
    if complete and not goes_on(attrs, asked):
        drawn = (out / MAPS_FIGURE).exists() or args.no_figures
        figures = "" if drawn else f" ({MAPS_FIGURE} is not there: snn-fg plot {args.out} --force draws the figures)"
        print(
            f"snn-fg: the run in {args.out}/ is finished already ({n} windows): nothing to resume, nothing written"
            + figures
        )
        return True
    if n:  # (said before the work: a resumed run's progress counts the windows read again too)
        print(f"snn-fg: the run in {args.out}/ holds {n} complete windows: continuing from window {n}", flush=True)
    return False
