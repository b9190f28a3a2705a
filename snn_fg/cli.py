"""The ``snn-fg`` command line: ``run``, ``compare``, ``events``, ``export`` and ``data``.

Bad input ends with one line ``snn-fg: error: <file>: <problem>`` and exit
status 2; an interrupted run (Ctrl-C, SIGTERM) exits 130 or 143 and leaves
the output folder as it was (a frame), or with the windows completed so far
(a recording, which ``--resume`` continues).
"""

from __future__ import annotations

import argparse
import os
import sys

from . import __version__, cancel
from .backends import DEFAULT_BACKEND, backend_names
from .compare_cli import add_compare_command
from .datasets.cli import add_data_command
from .errors import InputError, SnnFgError, warnings_as_lines
from .events.esim import MOTIONS
from .events_cli import add_events_command, sensor_size_arg
from .export.cli import add_export_command
from .export.loop import add_decode_command
from .models import MODELS
from .params import EDGE_OPERATORS, ModelParams

EXIT_INPUT = 2
MODEL_PARAMS = ("levels", "n_ori", "r0", "iterations", "alpha", "w_inh", "side_cue")
#: how a recording is cut into windows (snn_fg.events.iter_windows)
WINDOW_OPTIONS = ("window_ms", "start_ms", "stride_ms", "max_windows", "denoise_us", "refractory_us")
#: options that only a recording uses
RECORDING_OPTIONS = WINDOW_OPTIONS + ("readout_lag_ms", "carry_state", "window_clock", "save_spikes", "resume")
#: spiking options for one frame that a recording (one continuous run) does not use
FRAME_ONLY_OPTIONS = ("duration_ms", "settle_ms", "seed", "spike_input")


class _Parser(argparse.ArgumentParser):
    """A usage error is one line naming the command, the problem and where help is (no usage block)."""

    def error(self, message):
        self.exit(EXIT_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _number(kind, lo, strict=True):
    def parse(text):
        try:
            v = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected {'an integer' if kind is int else 'a number'}, got {text!r}"
            ) from None
        finite = v - v == 0  # False for inf and nan
        if not finite or not (v > lo if strict else v >= lo):
            raise argparse.ArgumentTypeError(
                f"must be {'' if finite else 'a finite number '}{'>' if strict else '>='} {lo}, got {text}"
            )
        return v

    return parse


def _crop_arg(text):
    try:
        crop = tuple(int(v) for v in text.split(","))
    except ValueError:
        crop = ()
    if len(crop) != 4:
        raise argparse.ArgumentTypeError(f"expected four integers X0,Y0,X1,Y1, got {text!r}")
    return crop


#: (group title, ((flag, type, lower bound, strictly above it, help), ...)); defaults in brackets
_RUN_OPTIONS = (
    (
        "model parameters (defaults: the paper's)",
        (
            (
                "--network",
                None,
                None,
                None,
                "a network by name (default, compact: the deployment form, "
                "docs/model.md) or a stored description (FILE.json, see networks/); "
                "its model parameters replace the options below, for the rate and "
                "the spiking model (default)",
            ),
            ("--levels", int, 1, False, "pyramid levels (10)"),
            ("--n-ori", int, 2, False, "orientations per half-turn (8)"),
            ("--r0", float, 0, True, "grouping radius in px: sets the object size grouped (8)"),
            ("--iterations", int, 0, False, "grouping/feedback iterations (10)"),
            ("--alpha", float, 0, False, "feedback gain (2)"),
            ("--w-inh", float, 0, False, "opposite border-ownership inhibition (1)"),
            ("--side-cue", float, 0, False, "gain of the side cue, the busier side within 160 px (0; natural: 3000)"),
        ),
    ),
    (
        "recordings (not for frames or images)",
        (
            ("--window-ms", float, 0, True, "window length (85, the iCub microsaccade period)"),
            ("--start-ms", float, 0, False, "start of the first window, ms after the first event (0)"),
            ("--stride-ms", float, 0, True, "window stride (the window length)"),
            ("--max-windows", int, 1, False, "stop after this many windows (all)"),
            ("--denoise-us", int, 0, True, "tonic Denoise filter time in us (off)"),
            ("--refractory-us", int, 0, True, "tonic RefractoryPeriod in us (off)"),
        ),
    ),
    (
        "spiking model",
        (
            (
                "--backend",
                None,
                None,
                None,
                f"simulator: {', '.join(backend_names())} ({DEFAULT_BACKEND}; "
                "the one used is recorded in the maps' params)",
            ),
            ("--duration-ms", float, 0, True, "simulated time per frame or window (400)"),
            ("--settle-ms", float, 0, False, "spikes before this time are not counted (half of --duration-ms)"),
            (
                "--dt-ms",
                float,
                0,
                True,
                "simulation time step (the network's: 0.5 ms, the compact network 1 ms; 1 "
                "ms on the default network takes about 3/4 of the time and moves the maps "
                "of natural images by 5-14 deg: experiments/results/spiking_dt.md)",
            ),
            ("--seed", int, -(2**63), False, "seed of the input spike phases (0)"),
            (
                "--spike-input",
                ("regular", "events"),
                None,
                None,
                "images: regular trains at every event pixel, or the "
                "simulated camera's events with their timing (regular)",
            ),
            (
                "--feedback",
                ("on", "off"),
                None,
                None,
                "off: remove the feedback onto border-ownership cells, the model's ablation (on)",
            ),
            ("--readout-lag-ms", float, 0, False, "recordings: read each window from the spikes this much later (20)"),
            (
                "--window-clock",
                ("on", "off"),
                None,
                None,
                "recordings: fire the network's window clock as each window "
                "starts, so that its grouping cells compete afresh (off: "
                "the network carries its state into the next window) (on)",
            ),
            (
                "--instantiate",
                ("input", "all"),
                None,
                None,
                "cells to create: those this input can use, or every "
                "cell of the network (the backend's choice: brian2 input, "
                "fast all)",
            ),
            (
                "--save-spikes",
                True,
                None,
                None,
                "recordings: also keep each window's spike count of every cell that "
                "fired (about 2 MB a dvs.es window; a frame always keeps them)",
            ),
        ),
    ),
    (
        "rate model",
        (
            (
                "--carry-state",
                ("on", "off"),
                None,
                None,
                "recordings: start each window's grouping and feedback where "
                "the previous window's stopped, as a network that is never "
                "reset would (off: each window afresh, the paper's model)",
            ),
        ),
    ),
    (
        "frame-based model",
        (
            (
                "--edge-operator",
                EDGE_OPERATORS,
                None,
                None,
                "simple cells' edge operator: gaussian (a "
                "Gaussian-derivative stand-in) or corf (Hu et al.'s "
                "CORF push-pull, slower) (gaussian)",
            ),
        ),
    ),
)


def _add_run(sub):
    p = sub.add_parser(
        "run",
        allow_abbrev=False,
        help="run a figure-ground model on an input and write its maps",
        description="Run a model on INPUT: an .npz event frame (pos, neg), an image (png/jpg/...), "
        "an event recording (.es .raw .dat .aedat4 .bin data.log .npy .npz) or 'demo' "
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
    p.add_argument("--force", action="store_true", help="replace the output folder if it holds an earlier run")
    p.add_argument(
        "--resume",
        action="store_const",
        const=True,
        help="recordings: continue the run in --out from its last complete window (same INPUT and options)",
    )
    p.add_argument(
        "--workers",
        type=_number(int, 1, strict=False),
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
        help="rate: the rate reference model (EDFG); fbfg: frame-based model on an image; "
        "spiking: the spiking network; natural, natural-spiking: the variant for natural "
        "scenes (contrast-invariant grouping, docs/model.md), rate and spiking (default: rate)",
    )
    g = p.add_argument_group("input")
    g.add_argument(
        "--threshold",
        type=_number(float, 0),
        default=0.10,
        metavar="C",
        help="images turned into events: contrast threshold of the simulated event camera (0.10)",
    )
    g.add_argument(
        "--motion",
        choices=MOTIONS,
        default=None,
        help="images turned into events: motion of the simulated event camera; paper: the authors' "
        "BSDS conversion (default shift4)",
    )
    g.add_argument(
        "--sensor-size",
        type=sensor_size_arg,
        metavar="WxH",
        help="recordings: sensor size for RAW files without geometry and for .npy/.npz arrays (without it an "
        "array's sensor is its events' extent, with a warning), or a larger one than a file's",
    )
    g = p.add_argument_group("output")
    g.add_argument(
        "--crop",
        type=_crop_arg,
        metavar="X0,Y0,X1,Y1",
        help="figures: draw only pixels X0 <= x < X1, Y0 <= y < Y1 (the maps keep the whole frame)",
    )
    g.add_argument("--no-progress", action="store_true", help="no progress messages or bars")
    g.add_argument("--no-figures", action="store_true", help="write the maps only (no figures)")
    for title, options in _RUN_OPTIONS:
        g = p.add_argument_group(title)
        for flag, kind, lo, strict, text in options:
            if kind is True:
                g.add_argument(flag, action="store_const", const=True, help=text)
            elif isinstance(kind, tuple):
                g.add_argument(flag, choices=kind, help=text)
            else:
                g.add_argument(flag, type=_number(kind, lo, strict) if kind else None, help=text)
    p.set_defaults(handler=cmd_run)
    return p


def build_parser() -> tuple[argparse.ArgumentParser, dict]:
    """The parser and its subcommand parsers by name."""
    parser = _Parser(
        prog="snn-fg",
        allow_abbrev=False,
        description="Event-driven figure-ground organisation as a spiking neural network: run the "
        "model on events or images, compare maps, inspect event recordings, export the "
        "network.",
    )
    parser.add_argument("--version", action="version", version=f"snn-fg {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    subs = {
        "run": _add_run(sub),
        "compare": add_compare_command(sub, _number),
        "events": add_events_command(sub),
        "export": add_export_command(sub, sensor_size_arg, _number),
        "decode": add_decode_command(sub),
        "data": add_data_command(sub),
    }
    return parser, subs


# --------------------------------------------------------------------------
# run
# --------------------------------------------------------------------------
#: what each kind of INPUT is called when an option does not apply to it
_KIND_NAMES = {
    "demo": "the demo is one image",
    "frame": "INPUT is one event frame",
    "image": "INPUT is one image",
    "recording": "INPUT is an event recording",
}


def _refused_options(args, kind) -> list[tuple[str, str]]:
    """``(flag, why it does not apply)`` for every given option the run would ignore."""
    model = MODELS[args.model]
    given = lambda k: getattr(args, k) is not None  # noqa: E731
    refused = []
    takers: dict[str, list[str]] = {}  # an option the chosen model does not take -> the models that do
    for other in MODELS.values():
        for k in other.options:
            if k not in model.options and k != "network" and given(k):
                takers.setdefault(k, []).append(other.name)
    for k, names in takers.items():
        which = f"the {names[0]} model" if len(names) == 1 else f"the {', '.join(names[:-1])} and {names[-1]} models"
        refused.append((k, f"applies to {which} only (--model {names[0]})"))
    named = {k for k, _ in refused}
    if kind != "recording":
        refused += [
            (k, f"applies to event recordings only; {_KIND_NAMES[kind]}")
            for k in RECORDING_OPTIONS + ("sensor_size",)
            if given(k) and k not in named
        ]
    else:
        refused += [
            (k, f"applies to a single frame or image only; {_KIND_NAMES[kind]}, run as one continuous network")
            for k in FRAME_ONLY_OPTIONS
            if given(k) and k not in named
        ]
    if args.motion is not None and kind in ("recording", "frame") and model.needs != "image":  # images only
        refused.append(("motion", f"applies to images turned into events only; {_KIND_NAMES[kind]}"))
    if model.needs == "image":  # the frame-based model: no events, no network
        refused += [
            (k, f"the {model.name} model {why}")
            for k, why in (
                ("motion", "reads the image itself, not events made from it"),
                ("network", "has no network (the event models take one)"),
                ("side_cue", "reads the image itself; the side cue counts events"),
            )
            if given(k)
        ]
    if args.network is not None:
        refused += [
            (k, "a named or stored network (--network) carries its own model parameters")
            for k in MODEL_PARAMS
            if given(k)
        ]
        if model.needs != "image" and model.base_params != ModelParams():  # the natural models
            refused.append(
                (
                    "network",
                    f"the {model.name} model has its own parameters, and a network carries "
                    "others (--model spiking --network runs a network as it is)",
                )
            )
    return refused


def _verb(why: str, n: int) -> str:
    return why if n == 1 else why.replace("applies", "apply", 1)


def _model(args, kind):
    """The model the arguments ask for, refusing options that would be ignored."""
    from .network.recipes import model_params_of

    refused = _refused_options(args, kind)
    if refused:
        reasons: dict[str, list[str]] = {}
        for k, why in refused:
            reasons.setdefault(why, []).append("--" + k.replace("_", "-"))
        raise InputError(
            args.input, "; ".join(f"{', '.join(flags)}: {_verb(why, len(flags))}" for why, flags in reasons.items())
        )
    given = {k: getattr(args, k) for k in MODEL_PARAMS if getattr(args, k) is not None}
    takes = MODELS[args.model].options
    progress = None if args.no_progress else _progress_factory()
    options = {k: getattr(args, k) for k in takes if getattr(args, k) is not None}
    for k in ("feedback", "carry_state", "window_clock"):
        if k in options:
            options[k] = options[k] == "on"
    params = MODELS[args.model].base_params.replace(**given) if args.network is None else model_params_of(args.network)
    return MODELS[args.model](params, progress, **options)


def _progress_factory():
    from tqdm import tqdm

    return lambda it: tqdm(it, desc="iterations", leave=False, file=sys.stderr)


def _windows(args):
    from .runner import recording_windows

    opts = {k: getattr(args, k) for k in WINDOW_OPTIONS if getattr(args, k) is not None}
    windows, sensor_size = recording_windows(
        args.input, sensor_size=args.sensor_size, window_options=opts, progress=not args.no_progress
    )
    source = {"input": args.input, "kind": "recording", "window_ms": 85.0, "start_ms": 0.0, **opts}
    source.setdefault("stride_ms", source["window_ms"])
    return windows, source, tuple(sensor_size[1::-1])


def cmd_run(args) -> int:
    from .batch import is_dataset, run_dataset
    from .frames.pool import pooled_shape
    from .frames.pyramid import check_levels
    from .frames.still import input_kind, load_frame
    from .results.atomic import OutputFolder, growing_folder, settle_folder
    from .results.store import STORE_NAME, finished_run, windows_complete
    from .runner import run_recording, run_still
    from .validate import check_crop

    if is_dataset(args.input):
        return run_dataset(args, cmd_run)
    if args.workers is not None or args.scheduler is not None:
        given = "--workers" if args.workers is not None else "--scheduler"
        raise InputError(
            args.input, f"{given}: applies to several recordings only (INPUT a folder, a glob or a .txt list)"
        )
    kind = input_kind(args.input)
    model = _model(args, kind)
    if kind == "recording":
        if model.needs == "image":
            raise InputError(args.input, f"the {model.name} model needs an image, not an event recording")
        windows, source, shape = _windows(args)
    else:
        frame, source = load_frame(args.input, model.needs, args.threshold, args.motion or "shift4")
        shape = frame.shape
    check_levels(
        pooled_shape(shape, model.params.input_pool), model.params.levels, args.input, model.params.levels_per_octave
    )
    if args.crop is not None:
        check_crop(args.crop, shape, owner=f"{args.input}: --crop")
    if kind == "recording":
        out, previous = growing_folder(args.out, force=args.force, resume=bool(args.resume))
        finished = finished_run(out / STORE_NAME, _run_key(args)) if args.resume else None
        if finished is not None:
            print(
                f"snn-fg: the run in {args.out}/ is finished already ({finished} windows): nothing to resume, "
                "nothing written"
            )
            return 0
        args.interrupt_note = (
            f"the windows completed so far are in {args.out}/; the same command with --resume "
            "continues from the last one"
        )
        try:
            n = run_recording(
                model,
                windows,
                out,
                source,
                crop=args.crop,
                figures=not args.no_figures,
                resume=bool(args.resume),
                run_key=_run_key(args),
            )
        except InputError as exc:
            # bad input part way through (a file cut short, say): no half-written output
            # (an interrupted run, below, keeps its windows for --resume; a resumed one keeps the earlier run's)
            if args.resume:
                raise
            done = windows_complete(out)
            settle_folder(out, previous, keep_new=False)
            if not done and previous is None:
                raise
            said = f"; the earlier run in {args.out}/ is kept" if previous is not None else ""
            if done:
                said = (
                    f"; nothing written{said} (--max-windows {done} runs the {done} "
                    f"window{'s' if done > 1 else ''} before it)"
                )
            raise InputError(exc.source, exc.problem + said, exc.where) from None
        except BaseException:  # (refused before its first window: nothing to keep)
            settle_folder(out, previous, keep_new=bool(windows_complete(out)))
            raise
        settle_folder(out, previous, keep_new=True)
        written = f"{n} window{'s' if n != 1 else ''}, " + ", ".join(sorted(p.name for p in out.iterdir()))
    else:
        with OutputFolder(args.out, force=args.force, cancelled=getattr(args, "interrupted", None)) as folder:
            run_still(model, frame, folder.dir, source, crop=args.crop, figures=not args.no_figures)
            written = ", ".join(sorted(p.name for p in folder.dir.iterdir()))
    print(f"snn-fg: {model.name} model on {args.input}: wrote {args.out}/ ({written})")
    return 0


#: run options that do not change a recording's maps (a run may be continued with others)
_NOT_IN_RUN_KEY = (
    "out",
    "force",
    "resume",
    "no_progress",
    "no_figures",
    "crop",
    "handler",
    "command",
    "interrupted",
    "interrupt_note",
    "workers",
    "scheduler",
)


def _run_key(args) -> dict:
    """What a continued run (--resume) must share with the run it continues."""
    return {k: v for k, v in sorted(vars(args).items()) if k not in _NOT_IN_RUN_KEY}


def main(argv=None, *, exit_on_interrupt: bool = False) -> int:
    """Run one ``snn-fg`` command; returns the exit status.

    ``exit_on_interrupt``: after Ctrl-C or SIGTERM (and the one-line message)
    end the process at once with 130 or 143, without unwinding: what an
    interrupt cut short in library code (a half-loaded compiled module, say)
    can crash the interpreter while it is torn down, or make it end itself by
    the signal. The output folder has been restored by then."""
    parser, subs = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:  # report an unknown option under the subcommand's own usage
        subs[args.command].error(f"unrecognized arguments: {' '.join(extra)}")
    with cancel.Signals() as signals, warnings_as_lines():
        args.interrupted = lambda: bool(signals.received)
        try:
            try:
                return args.handler(args)
            except Exception as exc:
                # after an interrupt that a library swallowed, whatever fails
                # next is its consequence: report the interrupt, not the error
                if signals.received:
                    raise KeyboardInterrupt(signals.received[-1]) from None
                if not isinstance(exc, SnnFgError):
                    raise
                print(f"snn-fg: error: {exc}", file=sys.stderr)
                return EXIT_INPUT
        except KeyboardInterrupt:
            term = "SIGTERM" in signals.received
            note = getattr(args, "interrupt_note", "the output was left as it was before the run")
            print(f"snn-fg: interrupted ({'SIGTERM' if term else 'Ctrl-C'}); {note}", file=sys.stderr)
            code = 143 if term else 130
            if exit_on_interrupt:
                sys.stdout.flush()
                sys.stderr.flush()
                os._exit(code)
            return code


def console():
    """The ``snn-fg`` entry point: :func:`main`, exiting with its status (at
    once after an interrupt). Output piped into a reader that stops early
    (``snn-fg events REC | head``) ends the command quietly."""
    try:
        sys.exit(main(exit_on_interrupt=True))
    except BrokenPipeError:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # (no error when Python flushes it)
        sys.exit(1)


if __name__ == "__main__":
    console()
