"""The ``snn-fg`` command line: ``run``, ``compare``, ``events`` and ``export``.

Bad input ends with one line ``snn-fg: error: <file>: <problem>`` and exit
status 2; an interrupted run (Ctrl-C, SIGTERM) exits 130 or 143 and leaves
the output folder as it was.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import sys
from pathlib import Path

from . import __version__, cancel
from .backends import DEFAULT_BACKEND, backend_names
from .errors import InputError, SnnFgError
from .events.cli import add_events_command, sensor_size_arg
from .events.esim import MOTIONS
from .export.cli import add_export_command
from .models import MODELS
from .rate.fbfg import EDGE_OPERATORS

EXIT_INPUT = 2
MODEL_PARAMS = ("levels", "n_ori", "r0", "iterations", "alpha", "w_inh")
#: how a recording is cut into windows (snn_fg.events.iter_windows)
WINDOW_OPTIONS = ("window_ms", "start_ms", "stride_ms", "max_windows", "denoise_us", "refractory_us")
#: options that only a recording uses
RECORDING_OPTIONS = WINDOW_OPTIONS + ("readout_lag_ms", "carry_state", "window_clock")
#: spiking options for one frame that a recording (one continuous run) does not use
FRAME_ONLY_OPTIONS = ("duration_ms", "settle_ms", "seed", "spike_input")


def _number(kind, lo, strict=True):
    def parse(text):
        try:
            v = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {'an integer' if kind is int else 'a number'}, "
                                             f"got {text!r}") from None
        if not (v > lo if strict else v >= lo) or v != v or v in (float("inf"), float("-inf")):
            raise argparse.ArgumentTypeError(f"must be {'>' if strict else '>='} {lo}, got {text}")
        return v
    return parse


#: (group title, ((flag, type, lower bound, strictly above it, help), ...)); defaults in brackets
_RUN_OPTIONS = (
    ("model parameters (defaults: the paper's)", (
        ("--levels", int, 1, False, "pyramid levels (10)"),
        ("--n-ori", int, 2, False, "orientations per half-turn (8)"),
        ("--r0", float, 0, True, "grouping radius in px: sets the object size grouped (8)"),
        ("--iterations", int, 0, False, "grouping/feedback iterations (10)"),
        ("--alpha", float, 0, False, "feedback gain (2)"),
        ("--w-inh", float, 0, False, "opposite border-ownership inhibition (1)"))),
    ("recordings (not for frames or images)", (
        ("--window-ms", float, 0, True, "window length (85, the iCub microsaccade period)"),
        ("--start-ms", float, 0, False, "start of the first window, ms after the first event (0)"),
        ("--stride-ms", float, 0, True, "window stride (the window length)"),
        ("--max-windows", int, 1, False, "stop after this many windows (all)"),
        ("--denoise-us", int, 0, True, "tonic Denoise filter time in us (off)"),
        ("--refractory-us", int, 0, True, "tonic RefractoryPeriod in us (off)"))),
    ("spiking model", (
        ("--network", None, None, None, "run a stored network description (FILE.json, see networks/) instead "
                                        "of building one from the model parameters"),
        ("--backend", None, None, None, f"simulator: {', '.join(backend_names())} ({DEFAULT_BACKEND}; "
                                        "the one used is recorded in the maps' params)"),
        ("--duration-ms", float, 0, True, "simulated time per frame or window (400)"),
        ("--settle-ms", float, 0, False, "spikes before this time are not counted (half of --duration-ms)"),
        ("--dt-ms", float, 0, True, "simulation time step (0.5; 1 takes about 3/4 of the time, and moves the "
                                    "maps of natural images by 5-14 deg: experiments/results/spiking_dt.md)"),
        ("--seed", int, -2**63, False, "seed of the input spike phases (0)"),
        ("--spike-input", ("regular", "events"), None, None, "images: regular trains at every event pixel, or the "
                                                            "simulated camera's events with their timing (regular)"),
        ("--feedback", ("on", "off"), None, None, "off: remove the feedback onto border-ownership cells, the "
                                                  "model's ablation (on)"),
        ("--readout-lag-ms", float, 0, False, "recordings: read each window from the spikes this much later "
                                              "(20)"),
        ("--window-clock", ("on", "off"), None, None, "recordings: fire the network's window clock as each window "
                                                      "starts, so that its grouping cells compete afresh (off: "
                                                      "the network carries its state into the next window) (on)"),
        ("--instantiate", ("input", "all"), None, None, "cells to create: those this input can use, or every "
                                                        "cell of the network (the backend's choice: brian2 input, "
                                                        "fast all)"))),
    ("rate model", (
        ("--carry-state", ("on", "off"), None, None, "recordings: start each window's grouping and feedback where "
                                                     "the previous window's stopped, as a network that is never "
                                                     "reset would (off: each window afresh, the paper's model)"),)),
    ("frame-based model", (
        ("--edge-operator", EDGE_OPERATORS, None, None, "simple cells' edge operator: gaussian (a "
                                                               "Gaussian-derivative stand-in) or corf (Hu et al.'s "
                                                               "CORF push-pull, slower) (gaussian)"),)),
)


def _add_run(sub):
    p = sub.add_parser("run", allow_abbrev=False, help="run a figure-ground model on an input and write its maps",
                       description="Run a model on INPUT: an .npz event frame (pos, neg), an image (png/jpg/...), "
                                   "an event recording (.es .raw .dat .aedat4 .bin data.log .npy .npz) or 'demo' "
                                   "(a built-in synthetic scene). Writes DIR/maps.npz (fg_x, fg_y, grouping, "
                                   "params) and figures.")
    p.add_argument("input", metavar="INPUT")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (must be new or empty)")
    p.add_argument("--force", action="store_true", help="replace the output folder if it holds an earlier run")
    p.add_argument("--model", choices=tuple(MODELS), default="rate",
                   help="rate: the rate reference model (EDFG); fbfg: frame-based model on an image; "
                        "spiking: the spiking network; natural, natural-spiking: the variant for natural "
                        "scenes (contrast-invariant grouping, docs/model.md), rate and spiking (default: rate)")
    for title, options in _RUN_OPTIONS:
        g = p.add_argument_group(title)
        for flag, kind, lo, strict, text in options:
            if isinstance(kind, tuple):
                g.add_argument(flag, choices=kind, help=text)
            else:
                g.add_argument(flag, type=_number(kind, lo, strict) if kind else None, help=text)
    p.add_argument("--threshold", type=_number(float, 0), default=0.10, metavar="C",
                   help="images turned into events: contrast threshold of the simulated event camera (0.10)")
    p.add_argument("--motion", choices=MOTIONS, default=None,
                   help="images turned into events: motion of the simulated event camera; paper: the authors' "
                        "BSDS conversion (default shift4)")
    p.add_argument("--sensor-size", type=sensor_size_arg, metavar="WxH",
                   help="recordings: sensor size for RAW files without geometry, or .npy arrays (from the file)")
    p.add_argument("--no-progress", action="store_true", help="no progress messages or bars")
    p.set_defaults(handler=cmd_run)
    return p


def _add_compare(sub):
    p = sub.add_parser("compare", allow_abbrev=False, help="compare two maps.npz files (e.g. spiking vs rate)",
                       description="Print, window by window, how two maps files agree: grouping Pearson r and "
                                   "SSIM, and on the pixels where both have a figure-ground vector the angle "
                                   "difference (mean, median, fraction within 45 degrees) and angle-map MSE "
                                   "and SSIM.")
    p.add_argument("a", metavar="A.npz")
    p.add_argument("b", metavar="B.npz")
    p.add_argument("--window", type=_number(int, 0, strict=False), metavar="I",
                   help="compare window I of each recording (a single frame is used as it is); by default "
                        "recordings are paired window by window, by start time when both store it")
    p.add_argument("--json", metavar="OUT.json", default=None,
                   help="where to save the metrics (compare.json next to A)")
    p.set_defaults(handler=cmd_compare)
    return p


def build_parser() -> tuple[argparse.ArgumentParser, dict]:
    """The parser and its subcommand parsers by name."""
    parser = argparse.ArgumentParser(prog="snn-fg", allow_abbrev=False,
                                     description="Event-driven figure-ground organisation as a spiking neural "
                                                 "network: run the model on events or images, compare maps, "
                                                 "inspect event recordings, export the network.")
    parser.add_argument("--version", action="version", version=f"snn-fg {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    subs = {"run": _add_run(sub), "compare": _add_compare(sub), "events": add_events_command(sub),
            "export": add_export_command(sub, sensor_size_arg, _number)}
    return parser, subs


# --------------------------------------------------------------------------
# run
# --------------------------------------------------------------------------
def _model(args, kind):
    """The model the arguments ask for, refusing options that would be ignored."""
    given = {k: getattr(args, k) for k in MODEL_PARAMS if getattr(args, k) is not None}
    takes = MODELS[args.model].options
    unused = [k for m in MODELS.values() for k in m.options if k not in takes and getattr(args, k) is not None]
    if kind != "recording":
        unused += [k for k in RECORDING_OPTIONS + ("sensor_size",) if getattr(args, k) is not None]
    else:
        unused += [k for k in FRAME_ONLY_OPTIONS if getattr(args, k) is not None]
    if args.motion is not None and (kind in ("recording", "frame") or MODELS[args.model].needs == "image"):
        unused.append("motion")      # only images turned into events have a motion
    if args.network is not None and given:
        unused += list(given)
    if unused:
        flags = ", ".join("--" + k.replace("_", "-") for k in unused)
        why = "a stored network (--network) carries its own model parameters" if args.network and given else \
            f"they do not apply to the {args.model} model on this input"
        raise InputError(args.input, f"{flags}: {why}")
    progress = None if args.no_progress else _progress_factory()
    options = {k: getattr(args, k) for k in takes if getattr(args, k) is not None}
    for k in ("feedback", "carry_state", "window_clock"):
        if k in options:
            options[k] = options[k] == "on"
    return MODELS[args.model](MODELS[args.model].base_params.replace(**given), progress, **options)


def _progress_factory():
    from tqdm import tqdm

    return lambda it: tqdm(it, desc="iterations", leave=False, file=sys.stderr)


def _windows(args):
    from .events import iter_recording, iter_windows

    stream = iter_recording(args.input, sensor_size=args.sensor_size)
    opts = {k: getattr(args, k) for k in WINDOW_OPTIONS if getattr(args, k) is not None}
    windows = iter_windows(stream, **{"window_ms": 85.0, **opts})
    if not args.no_progress:
        from tqdm import tqdm

        windows = tqdm(windows, desc="windows", unit="win", file=sys.stderr, total=args.max_windows)
    source = {"input": args.input, "kind": "recording", "window_ms": 85.0, "start_ms": 0.0, **opts}
    source.setdefault("stride_ms", source["window_ms"])
    return windows, source, tuple(stream.sensor_size[1::-1])


def cmd_run(args) -> int:
    from .frames.pyramid import check_levels
    from .inputs import input_kind, load_frame
    from .runner import OutputFolder, run_frame, run_recording

    kind = input_kind(args.input)
    model = _model(args, kind)
    if kind == "recording":
        if model.needs == "image":
            raise InputError(args.input, f"the {model.name} model needs an image, not an event recording")
        windows, source, shape = _windows(args)
    else:
        frame, source = load_frame(args.input, model.needs, args.threshold, args.motion or "shift4")
        shape = frame.shape
    check_levels(shape, model.params.levels, args.input)
    with OutputFolder(args.out, force=args.force, cancelled=getattr(args, "interrupted", None)) as out:
        if kind == "recording":
            run_recording(model, windows, out.dir, source, args.input)
        else:
            run_frame(model, frame, out.dir, source)
        written = ", ".join(sorted(p.name for p in out.dir.iterdir()))
    print(f"snn-fg: {model.name} model on {args.input}: wrote {args.out}/ ({written})")
    return 0


# --------------------------------------------------------------------------
# compare
# --------------------------------------------------------------------------
#: compare's table: (header, row key, width, format spec); at most 100 characters wide
_COMPARE_COLUMNS = (("A", "window_a", 3, "d"), ("B", "window_b", 3, "d"), ("t (ms)", "t_start_ms", 8, ".1f"),
                    ("pixels", "pixels_compared", 7, "d"), ("mean°", "angle_diff_mean_deg", 6, ".1f"),
                    ("median°", "angle_diff_median_deg", 7, ".1f"), ("<=45°", "angle_within_45_frac", 6, ".3f"),
                    ("MSE", "angle_mse", 6, ".3f"), ("SSIM", "angle_ssim", 6, ".3f"),
                    ("grp r", "grouping_pearson_r", 6, ".3f"), ("grp SSIM", "grouping_ssim", 8, ".3f"))


def compare_table(rows) -> str:
    """The rows of :func:`~snn_fg.metrics.compare_maps` as a text table."""
    lines = ["  ".join(f"{h:>{w}}" for h, _, w, _ in _COMPARE_COLUMNS)]
    lines += ["  ".join("-".rjust(w) if r[k] is None else f"{r[k]:>{w}{spec}}" for _, k, w, spec in _COMPARE_COLUMNS)
              for r in rows]
    lines += ["A, B: compared windows; angle columns on pixels where both maps have a figure-ground vector",
              "(SSIM: where either has one); grouping r and SSIM on the whole map, SSIM with each map scaled to 1"]
    return "\n".join(lines)


def cmd_compare(args) -> int:
    from .atomic import save_text
    from .maps import Maps
    from .metrics import compare_maps

    a, b = Maps.load(args.a), Maps.load(args.b)
    try:
        rows = compare_maps(a, b, window=args.window)
    except SnnFgError as exc:
        raise InputError(args.b, str(exc).removeprefix("compare_maps: ")) from None
    print(compare_table(rows))
    out = Path(args.json) if args.json else Path(args.a).with_name("compare.json")
    save_text(out, json.dumps({"a": str(args.a), "b": str(args.b), "windows": rows}, indent=2))
    print(f"snn-fg: metrics saved to {out}")
    return 0


class _Signals:
    """Ctrl-C (SIGINT) and SIGTERM while a command runs: each is remembered
    (:mod:`snn_fg.cancel`, so a run whose KeyboardInterrupt a library
    swallowed still stops at its next check and never commits its output)
    and raised as KeyboardInterrupt. A swallowed one is not printed ("Exception
    ignored..."): the one-line message follows."""

    def __init__(self):
        self.received: list[str] = []
        self.previous = {}
        self.previous_hook = None

    def __call__(self, signum, frame):      # noqa: ARG002 - signal handler signature
        self.received.append(signal.Signals(signum).name)
        cancel.request(self.received[-1])
        raise KeyboardInterrupt(self.received[-1])

    def _unraisable(self, info):
        if not (issubclass(info.exc_type, KeyboardInterrupt) and self.received):
            self.previous_hook(info)

    def __enter__(self):
        cancel.clear()
        for sig in (signal.SIGINT, signal.SIGTERM):
            self.previous[sig] = signal.signal(sig, self)
        self.previous_hook, sys.unraisablehook = sys.unraisablehook, self._unraisable
        return self

    def __exit__(self, *exc):
        for sig, handler in self.previous.items():
            signal.signal(sig, handler)
        sys.unraisablehook = self.previous_hook
        cancel.clear()


def main(argv=None, *, exit_on_interrupt: bool = False) -> int:
    """Run one ``snn-fg`` command; returns the exit status.

    ``exit_on_interrupt``: after Ctrl-C or SIGTERM (and the one-line message)
    end the process at once with 130 or 143, without unwinding: what an
    interrupt cut short in library code (a half-loaded compiled module, say)
    can crash the interpreter while it is torn down, or make it end itself by
    the signal. The output folder has been restored by then."""
    parser, subs = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:       # report an unknown option under the subcommand's own usage
        subs[args.command].error(f"unrecognized arguments: {' '.join(extra)}")
    with _Signals() as signals:
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
            print(f"snn-fg: interrupted ({'SIGTERM' if term else 'Ctrl-C'}); the output was left as it was before "
                  "the run", file=sys.stderr)
            code = 143 if term else 130
            if exit_on_interrupt:
                sys.stdout.flush()
                sys.stderr.flush()
                os._exit(code)
            return code


def console():
    """The ``snn-fg`` entry point: :func:`main`, exiting with its status (at
    once after an interrupt)."""
    sys.exit(main(exit_on_interrupt=True))


if __name__ == "__main__":
    console()
