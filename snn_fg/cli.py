"""The ``snn-fg`` command line.

``snn-fg run INPUT --out DIR --model rate|fbfg|spiking``   maps.npz + maps.png
``snn-fg compare A.npz B.npz [--json OUT]``                 metrics between maps
``snn-fg events INPUT``                                      recording summary / event frames

Bad input ends with one line ``snn-fg: error: <file>: <problem>`` and a
non-zero exit status; outputs are written atomically.
"""
from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np

from .errors import SnnFgError
from .events.cli import sensor_size_arg

MODELS = ("rate", "fbfg", "spiking")
EXIT_INPUT = 2


def _positive_int(text):
    v = int(text)
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {v}")
    return v


def _add_run(sub):
    p = sub.add_parser("run", help="run the figure-ground model on an input and write maps",
                       description="Run the model on INPUT: an .npz event frame (pos, neg), an image "
                                   "(png/jpg), an event recording (.es .raw .dat .aedat4 .bin data.log "
                                   ".npy .npz), or 'demo' (built-in synthetic scene). Writes DIR/maps.npz "
                                   "(fg_x, fg_y, grouping float32, params JSON) and DIR/maps.png.")
    p.add_argument("input", metavar="INPUT")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--model", choices=MODELS, default="rate",
                   help="rate: event-driven rate model (EDFG); fbfg: frame-based model on an image; "
                        "spiking: the Brian2 spiking network")
    g = p.add_argument_group("model parameters (defaults: the paper's Table T1)")
    g.add_argument("--levels", type=_positive_int)
    g.add_argument("--n-ori", type=_positive_int, help="orientations per half-turn (8)")
    g.add_argument("--r0", type=float, help="von Mises radius in px (8)")
    g.add_argument("--iterations", type=int)
    g.add_argument("--alpha", type=float, help="feedback gain (2)")
    g.add_argument("--w-inh", type=float, help="opposite border-ownership inhibition (1)")
    g = p.add_argument_group("images -> events (rate and spiking models)")
    g.add_argument("--threshold", type=float, default=0.10, metavar="C",
                   help="contrast threshold of the simulated event camera (0.10)")
    g = p.add_argument_group("recordings")
    g.add_argument("--window-ms", type=float, default=85.0, help="window length (85, the iCub microsaccade period)")
    g.add_argument("--start-ms", type=float, default=0.0, help="first window start, ms after the first event")
    g.add_argument("--stride-ms", type=float, default=None, help="window stride (default: the window length)")
    g.add_argument("--max-windows", type=_positive_int, default=None)
    g.add_argument("--denoise-us", type=int, default=None, help="tonic Denoise filter time (us)")
    g.add_argument("--refractory-us", type=int, default=None, help="tonic RefractoryPeriod (us)")
    g.add_argument("--sensor-size", type=sensor_size_arg, default=None, metavar="WxH",
                   help="for RAW files without geometry, or .npy arrays")
    g = p.add_argument_group("spiking model")
    g.add_argument("--duration-ms", type=float, default=None, help="simulated time per frame or window (400)")
    g.add_argument("--settle-ms", type=float, default=None,
                   help="spikes before this time are not counted (default: half of --duration-ms)")
    g.add_argument("--dt-ms", type=float, default=None, help="simulation time step")
    g.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(handler=cmd_run)


def _add_compare(sub):
    p = sub.add_parser("compare", help="compare two maps.npz files (e.g. spiking vs rate)",
                       description="Print the comparison metrics of two maps files, window by window: "
                                   "grouping Pearson r and SSIM (11x11), angle-map MSE and SSIM, median and "
                                   "mean absolute angle difference on pixels where both maps have a vector.")
    p.add_argument("a", metavar="A.npz")
    p.add_argument("b", metavar="B.npz")
    p.add_argument("--json", metavar="OUT.json", default=None,
                   help="where to save the metrics (default: compare.json next to A)")
    p.set_defaults(handler=cmd_compare)


def build_parser() -> argparse.ArgumentParser:
    from .events.cli import add_events_command

    parser = argparse.ArgumentParser(prog="snn-fg", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    _add_run(sub)
    _add_compare(sub)
    add_events_command(sub)
    return parser


# --------------------------------------------------------------------------
# run
# --------------------------------------------------------------------------
def _params(args):
    from .params import ModelParams

    changes = {k: getattr(args, a) for k, a in (("levels", "levels"), ("n_ori", "n_ori"), ("r0", "r0"),
                                                ("iterations", "iterations"), ("alpha", "alpha"),
                                                ("w_inh", "w_inh")) if getattr(args, a) is not None}
    return ModelParams(**changes)


def _progress(args, desc):
    if args.no_progress:
        return None
    from tqdm import tqdm

    return lambda it: tqdm(it, desc=desc, leave=False, file=sys.stderr)


def _spiking():
    """The spiking simulator package, or a clear error if this build lacks it."""
    try:
        from . import spiking
    except ImportError as exc:
        raise SnnFgError(f"the spiking model is not available in this installation ({exc})") from None
    return spiking


def _spiking_kw(args):
    return {k: v for k, v in (("duration_ms", args.duration_ms), ("dt_ms", args.dt_ms), ("settle_ms", args.settle_ms))
            if v is not None}


def _run_frame(args, params, pos, neg, image, progress=True):
    """One frame through the chosen model -> Maps."""
    bar = _progress(args, "iterations") if progress else None
    if args.model == "rate":
        from .rate.edfg import run_edfg

        return run_edfg(pos, neg, params, progress=bar)
    if args.model == "fbfg":
        from .rate.fbfg import run_fbfg

        return run_fbfg(image, params, progress=bar)
    return _spiking().run_spiking(pos=pos, neg=neg, params=params, seed=args.seed,
                                  progress=progress and not args.no_progress, **_spiking_kw(args))


def cmd_run(args) -> int:
    from .errors import InputError
    from .figures import event_frame_rgb
    from .images import read_image
    from .inputs import input_kind, load_event_frame
    from .maps import Maps, MapsSeriesWriter

    params = _params(args)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InputError(out, "--out must be a folder, but a file of that name exists")
    kind = input_kind(args.input)
    source = {"input": args.input, "kind": kind}

    if kind == "recording":
        if args.model == "fbfg":
            raise InputError(args.input, "the fbfg model needs an image, not an event recording")
        from .events import EmptyWindowWarning, iter_windows

        windows = iter_windows(args.input, window_ms=args.window_ms, start_ms=args.start_ms,
                               stride_ms=args.stride_ms, max_windows=args.max_windows,
                               denoise_us=args.denoise_us, refractory_us=args.refractory_us,
                               sensor_size=args.sensor_size)
        if not args.no_progress:
            from tqdm import tqdm

            windows = tqdm(windows, desc="windows", unit="win", file=sys.stderr,
                           total=args.max_windows)
        out.mkdir(parents=True, exist_ok=True)
        t0, t1 = [], []
        n_empty = 0
        with MapsSeriesWriter(out / "maps.npz") as sink, warnings.catch_warnings():
            # Empty windows are counted and reported once below.
            warnings.simplefilter("ignore", EmptyWindowWarning)
            for w in windows:
                empty = not (w.pos.any() or w.neg.any())
                n_empty += empty
                if empty:
                    m = _empty_maps(w.pos.shape, params, args.model)
                elif args.model == "spiking":
                    m = _spiking().run_spiking(events=w.events, sensor_size=(w.pos.shape[1], w.pos.shape[0], 2),
                                               params=params, seed=args.seed, progress=False,
                                               **_spiking_kw(args))
                else:
                    m = _run_frame(args, params, w.pos, w.neg, None, progress=False)
                # The window's event frame (+1 ON, -1 OFF) is kept with its maps.
                sink.append(m, event_frame=w.pos.astype(np.int8) - w.neg.astype(np.int8))
                t0.append(w.t_start_us)
                t1.append(w.t_end_us)
            if sink.n == 0:
                raise InputError(args.input, "no window to process: the recording has no events after --start-ms")
            if n_empty:
                print(f"snn-fg: warning: {n_empty} of {sink.n} windows had no events; their maps are zero",
                      file=sys.stderr)
            source.update(window_ms=args.window_ms, start_ms=args.start_ms,
                          stride_ms=args.stride_ms or args.window_ms, max_windows=args.max_windows,
                          denoise_us=args.denoise_us, refractory_us=args.refractory_us)
            st = sink.stacked()
            maps = Maps(st["fg_x"], st["fg_y"], st["grouping"], {**sink.params, "source": source},
                        {k: v for k, v in st.items() if k not in ("fg_x", "fg_y", "grouping")})
            # Times relative to the first window (some formats stamp Unix time in us).
            titles = [f"{(a - t0[0]) / 1000:.0f}-{(b - t0[0]) / 1000:.0f} ms" for a, b in zip(t0, t1)]
            sink.finish(maps.params, t_start_us=np.array(t0, dtype=np.int64),
                        t_end_us=np.array(t1, dtype=np.int64))
            _write_figures(args, out, _LazyFrames(st["event_frame"]), maps, titles)
            del maps, st
        _report(args, out)
        return 0
    else:
        image = pos = neg = None
        if kind == "demo":
            from .scenes import demo

            image = demo().image
        elif kind == "image":
            image = read_image(args.input, grey=args.model != "fbfg")
        else:
            if args.model == "fbfg":
                raise InputError(args.input, "the fbfg model needs an image, not an event frame")
            pos, neg = load_event_frame(args.input)
        if pos is None and args.model != "fbfg":
            from .events import image_to_frame

            pos, neg = image_to_frame(image, threshold=args.threshold)
            source["threshold"] = args.threshold
            if not (pos.any() or neg.any()):
                raise InputError(args.input, f"the image gives no events at contrast threshold {args.threshold}")
        maps = _run_frame(args, params, pos, neg, image)
        inputs = image if args.model == "fbfg" else event_frame_rgb(pos, neg)
    maps.params = {**maps.params, "source": source}
    out.mkdir(parents=True, exist_ok=True)
    maps.save(out / "maps.npz")
    _write_figures(args, out, inputs, maps, None)
    _report(args, out)
    return 0


def _write_figures(args, out, inputs, maps, titles):
    from .figures import save_maps_figure

    save_maps_figure(out / "maps.png", inputs, maps.fg_x, maps.fg_y, maps.grouping, titles=titles)
    if args.model == "spiking":
        _spiking().save_spiking_figures(maps, out)


def _report(args, out):
    written = ", ".join(sorted(p.name for p in out.iterdir() if not p.name.startswith(".")))
    print(f"snn-fg: {args.model} model on {args.input}: wrote {out}/ ({written})")


class _LazyFrames:
    """Event frames (+1 ON, -1 OFF) shown as RGB only when a figure row needs them."""

    def __init__(self, frames):
        self.frames = frames

    def __len__(self):
        return len(self.frames)

    def __getitem__(self, i):
        from .figures import event_frame_rgb

        f = self.frames[i]
        return event_frame_rgb(f > 0, f < 0)


def _empty_maps(shape, params, model):
    from .maps import Maps

    z = np.zeros(shape, np.float32)
    return Maps(z, z.copy(), z.copy(), {"model": model, **params.to_dict()})


# --------------------------------------------------------------------------
# compare
# --------------------------------------------------------------------------
def cmd_compare(args) -> int:
    from .atomic import save_text
    from .maps import Maps
    from .metrics import compare_maps

    a, b = Maps.load(args.a), Maps.load(args.b)
    if a.fg_x.shape != b.fg_x.shape:
        from .errors import InputError

        raise InputError(args.b, f"maps shape {b.fg_x.shape} differs from {args.a}'s {a.fg_x.shape}")
    rows = compare_maps(a, b)
    keys = list(rows[0])
    print("window  " + "  ".join(f"{k:>22s}" for k in keys))
    for i, r in enumerate(rows):
        print(f"{i:6d}  " + "  ".join(f"{r[k]:22.4f}" if isinstance(r[k], float) else f"{r[k]:22d}" for k in keys))
    out = Path(args.json) if args.json else Path(args.a).with_name("compare.json")
    save_text(out, json.dumps({"a": str(args.a), "b": str(args.b), "windows": rows}, indent=2))
    print(f"snn-fg: metrics saved to {out}")
    return 0


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.handler(args)
    except SnnFgError as exc:
        print(f"snn-fg: error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt:
        print("snn-fg: interrupted; no partial output was written", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
