"""Side-by-side speed benchmark of the figure-ground models (issue 13).

One command times, in one run and on the same inputs, the rate model and the
spiking model on every registered backend (``snn_fg.backends.backend_names()``;
a backend that is not installed is skipped with a note):

* ``frames``     - the six BSDS reference frames (dataset ``bsds-edfg``; rate: ratio to the
  authors' code, calibrated in the same process: their frame time is 955 x one
  ``scipy.ndimage.correlate`` of a 321 x 481 float64 array with a 49 x 49
  kernel, timed right before each repeat). Spiking backends on frames take
  minutes each with Brian2: only with ``--spiking-frames``;
* ``dvs``        - 85 ms windows of dvs.es (dataset ``events``; first ms dropped);
* ``synthetic``  - synthetic 85 ms windows of 1k to 100k events, and the
  scaling of time per window with event count (least-squares slope and fixed
  cost) per engine;
* ``throughput`` - ``snn-fg run dvs.es --window-ms 85`` end to end (reading,
  all windows, writing maps and figures): windows per second;
* ``stream``     - the real-time question: ``snn-fg run dvs.es --start-ms 100
  --no-figures --network N`` for every network of ``--networks`` (default,
  compact), both models, pinned to one core and to two (``--cores``), in
  ``--stream-rounds`` rounds alternating them: the
  median of each window's own time beyond the first (the maps' params:
  ``timings_s.window`` of a spiking run's stream, ``timings_s.run`` of the rate
  model), the whole run's wall time per window, and for the spiking network
  its synaptic events per window and CPU nanoseconds per event against the
  machine's floor measured in each round (:mod:`.stream`, :mod:`.floor`);
* ``profile``    - the rate model's time per stage.

Every measurement runs in its own process (median of repeats after a
warm-up; peak RSS of that process from ``wait4``); ``uptime``'s load average
is recorded before and after each (the synthetic section also plots
``bench_scaling.png`` beside the JSON). Results go to
``experiments/results/bench.json``: a run replaces only the entries (section,
engine) it measured, each stamped with its time and load.

    python -m experiments.bench                       # everything but spiking on frames
    python -m experiments.bench --quick --only rate   # a few minutes
    python -m experiments.bench --sections frames --spiking-frames --frames 105053
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from experiments.common import ROOT, git_commit, processor

from .inputs import DVS_START_MS, WINDOW_MS, bsds_names, dvs_path, dvs_windows
from .processes import measure, run_process, uptime
from .report import plot_scaling, print_summary
from .stream import section_stream  # noqa: F401 - (a section, found by name)

SECTIONS = ("calibrate", "frames", "dvs", "synthetic", "throughput", "stream", "profile")
#: sections that only run when named in --sections
ON_REQUEST = ("stream",)
SYNTH_SIZES = (1000, 2000, 5000, 10000, 20000, 50000, 100000)
QUICK_SIZES = (1000, 10000, 100000)
RESULTS = ROOT / "experiments" / "results" / "bench.json"


def engines(only) -> tuple[list[tuple[str, str | None]], list[str]]:
    """``[(model, backend)]`` to time and notes on what was skipped."""
    from snn_fg.backends import available_backends

    chosen, notes = [], []
    if only is None or "rate" in only:
        chosen.append(("rate", None))
    for name, (ok, why) in available_backends().items():
        if only is not None and "spiking" not in only and name not in only:
            continue
        if ok:
            chosen.append(("spiking", name))
        else:
            notes.append(f"backend {name} skipped: {why}")
    return chosen, notes


#: the cells spiking runs create (--instantiate; None: each backend's default)
INSTANTIATE = {"value": None}


def engine_name(model, backend) -> str:
    if backend is None:
        return model
    how = INSTANTIATE["value"]
    return f"{model}/{backend}" + (f"[{how}]" if how else "")


def _time(model, backend, inputs, args, *, repeats, calibrate=False, warmup=None):
    spec = {
        "task": "model",
        "model": model,
        "backend": backend,
        "inputs": inputs,
        "repeats": repeats,
        "calibrate": calibrate,
        "warmup": warmup,
        "instantiate": args.instantiate if backend else None,
    }
    print(f"[{engine_name(model, backend)}] {len(inputs)} input(s) x {repeats}", file=sys.stderr, flush=True)
    return measure(spec, args.timeout)


def section_frames(args, eng):
    out = {}
    frames = args.frames or bsds_names()
    if not frames:
        return {"note": "the dataset bsds-edfg is absent (snn-fg data fetch bsds-edfg)"}
    for model, backend in eng:
        if model == "spiking" and not args.spiking_frames:
            continue
        reps = args.repeats if model == "rate" else args.spiking_repeats
        # Spiking warms up on a small synthetic window (absorbs compilation only).
        warm = None if model == "rate" else "synth:1000"
        rows = [
            _time(model, backend, [f"bsds:{f}"], args, repeats=reps, calibrate=(model == "rate"), warmup=warm)
            for f in frames
        ]
        out[engine_name(model, backend)] = rows
    return out


def section_dvs(args, eng):
    n_all = len(dvs_windows())
    out = {"windows_in_recording": n_all}
    for model, backend in eng:
        n = min(n_all, args.dvs_windows if model == "rate" else args.spiking_windows)
        reps = args.repeats if model == "rate" else args.spiking_repeats
        warm = "dvs:0" if model == "rate" else "synth:1000"
        start = "" if model == "rate" or args.dvs_start_ms is None else f"@{args.dvs_start_ms:g}"
        out[engine_name(model, backend)] = _time(
            model, backend, [f"dvs:{k}{start}" for k in range(n)], args, repeats=reps, warmup=warm
        )
    return out


def fit_line(n_events, seconds) -> dict:
    """Least-squares ``t = fixed + slope * n``: fixed cost (ms), slope (us per
    event) and R^2 of the fit."""
    n = np.asarray(n_events, float)
    t = np.asarray(seconds, float)
    if len(n) < 2:
        return {}
    slope, fixed = np.polyfit(n, t, 1)
    pred = fixed + slope * n
    ss = float(((t - t.mean()) ** 2).sum())
    r2 = 1.0 - float(((t - pred) ** 2).sum()) / ss if ss > 0 else 1.0
    return {
        "fixed_ms": 1e3 * fixed,
        "slope_us_per_event": 1e6 * slope,
        "r2": r2,
        "per_1k_events_ms": 1e3 * (fixed + slope * 1000),
        "per_100k_events_ms": 1e3 * (fixed + slope * 1e5),
    }


def section_synthetic(args, eng):
    out = {}
    for model, backend in eng:
        sizes = args.sizes if model == "rate" else args.spiking_sizes
        reps = args.repeats if model == "rate" else args.spiking_repeats
        m = _time(model, backend, [f"synth:{n}" for n in sizes], args, repeats=reps, warmup=f"synth:{sizes[0]}")
        if "result" in m:
            rows = m["result"]
            m["scaling"] = fit_line([r["n_events"] for r in rows], [r["median_s"] for r in rows])
            m["scaling_cpu"] = fit_line([r["n_events"] for r in rows], [r["cpu_median_s"] for r in rows])
        out[engine_name(model, backend)] = m
    return out


def section_throughput(args, eng):
    """``snn-fg run dvs.es`` end to end, all windows (spiking: ``--spiking-windows``)."""
    out = {}
    n_all = len(dvs_windows())
    for model, backend in eng:
        with tempfile.TemporaryDirectory() as tmp:
            cmd = [
                sys.executable,
                "-c",
                "from snn_fg.cli import console; console()",
                "run",
                str(dvs_path()),
                "--model",
                model,
                "--window-ms",
                str(WINDOW_MS),
                "--start-ms",
                str(DVS_START_MS),
                "--out",
                str(Path(tmp) / "out"),
                "--no-progress",
            ]
            n = n_all
            if model == "spiking":
                n = min(n_all, args.spiking_windows)
                cmd += ["--backend", backend, "--max-windows", str(n)]
            print(f"[{engine_name(model, backend)}] snn-fg run dvs.es ({n} windows)", file=sys.stderr, flush=True)
            before = uptime()
            t = time.perf_counter()
            code, _, rss = run_process(cmd, args.timeout)
            wall = time.perf_counter() - t
        row = {
            "windows": n,
            "windows_in_recording": n_all,
            "wall_s": wall,
            "exit_status": code,
            "peak_rss_mb": rss,
            "load_before": before,
            "load_after": uptime(),
        }
        if code == 0:
            row.update(windows_per_s=n / wall, s_per_window=wall / n)
        out[engine_name(model, backend)] = row
    return out


def section_calibrate(args, eng):
    return measure({"task": "calibrate", "repeats": max(3, args.repeats)}, args.timeout)


def section_profile(args, eng):
    frames = args.frames or bsds_names()
    if not any(m == "rate" for m, _ in eng) or not frames:
        return None
    print("[profile] rate model stages", file=sys.stderr, flush=True)
    return measure({"task": "profile", "inputs": [f"bsds:{f}" for f in frames], "repeats": args.repeats}, args.timeout)


def parse_args(argv=None):
    ap = argparse.ArgumentParser(
        prog="python -m experiments.bench", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "--sections",
        default=",".join(s for s in SECTIONS if s not in ON_REQUEST),
        help=f"comma list of {', '.join(SECTIONS)} (all but {', '.join(ON_REQUEST)})",
    )
    ap.add_argument(
        "--networks", default="default,compact", help="stream: comma list of networks by name (default,compact)"
    )
    ap.add_argument("--cores", default="1,2", help="stream: comma list of how many cores a run may use (1,2)")
    ap.add_argument(
        "--stream-rounds",
        type=int,
        default=3,
        help="stream: rounds alternating every configuration; the median round is reported (3)",
    )
    ap.add_argument("--stream-copies", type=int, default=1, help="stream: dvs.es played this many times in a row (1)")
    ap.add_argument("--peer", default="", help="stream: comma list of peer backends on the compact network (nest)")
    ap.add_argument("--peer-windows", type=int, default=2, help="stream: windows the peer simulates (2)")
    ap.add_argument("--bsds-image", default="", help="stream: comma list of BSDS image ids run end to end")
    ap.add_argument("--only", help="comma list of engines: rate, spiking (every backend) or backend names")
    ap.add_argument(
        "--quick",
        action="store_true",
        help="3 repeats, 2 frames, 3 dvs windows, sizes 1k/10k/100k (minutes for the rate model)",
    )
    ap.add_argument("--repeats", type=int, default=5, help="timed repeats after the warm-up (5)")
    ap.add_argument("--frames", help="comma list of BSDS frame ids (all six)")
    ap.add_argument(
        "--spiking-frames",
        action="store_true",
        help="also time the spiking backends on the BSDS frames (minutes per frame with Brian2)",
    )
    ap.add_argument("--spiking-repeats", type=int, default=1, help="timed repeats for spiking runs (1)")
    ap.add_argument("--dvs-windows", type=int, default=None, help="dvs.es windows timed for the rate model (all)")
    ap.add_argument(
        "--spiking-windows",
        type=int,
        default=1,
        help="dvs.es windows for spiking runs, timed and in the throughput run (1)",
    )
    ap.add_argument(
        "--dvs-start-ms",
        type=float,
        default=None,
        help="spiking runs: dvs.es windows from this time (ms; default 1, as the rate model's)",
    )
    ap.add_argument(
        "--instantiate",
        choices=("input", "all"),
        default=None,
        help="cells spiking backends create (each backend's default: brian2 input, fast all)",
    )
    ap.add_argument("--sizes", help="synthetic event counts for the rate model (1k..100k)")
    ap.add_argument(
        "--spiking-sizes", default="1000,10000", help="synthetic event counts for spiking runs (1000,10000)"
    )
    ap.add_argument("--timeout", type=float, default=3600.0, help="seconds per measuring process (3600)")
    ap.add_argument("--out", type=Path, default=RESULTS, help=f"JSON file ({RESULTS.relative_to(ROOT)})")
    ap.add_argument("--report", action="store_true", help="print the tables of the JSON file; measure nothing")
    ap.add_argument(
        "--merge", type=Path, metavar="JSON", help="merge another run's JSON file into --out; measure nothing"
    )
    args = ap.parse_args(argv)
    args.sections = [s for s in args.sections.split(",") if s]
    bad = set(args.sections) - set(SECTIONS)
    if bad:
        ap.error(f"unknown section(s) {', '.join(sorted(bad))}")
    args.only = None if args.only is None else set(args.only.split(","))
    args.networks = args.networks.split(",")
    args.cores = [int(c) for c in args.cores.split(",")]
    args.peer = [p for p in args.peer.split(",") if p]
    args.bsds_image = [b for b in args.bsds_image.split(",") if b]
    args.frames = args.frames.split(",") if args.frames else None
    if args.quick:
        args.repeats = min(args.repeats, 3)
        args.frames = args.frames or bsds_names()[:2]
        args.dvs_windows = args.dvs_windows or 3
    args.dvs_windows = args.dvs_windows or 10**6
    sizes = [int(s) for s in args.sizes.split(",")] if args.sizes else list(QUICK_SIZES if args.quick else SYNTH_SIZES)
    args.sizes = sizes
    args.spiking_sizes = [int(s) for s in args.spiking_sizes.split(",")]
    INSTANTIATE["value"] = args.instantiate
    return args


def _merge(merged: dict, measured: dict, stamp) -> None:
    """Entries (one per engine, mostly) replace their earlier values; the
    others keep theirs, each with the time it was measured."""
    for name, sec in measured.items():
        old = merged.setdefault("sections", {}).setdefault(name, {"data": {}, "measured": {}})
        old["data"].update(sec["data"])
        when = sec["measured"]
        old["measured"].update({key: when if isinstance(when, str) else when.get(key, stamp) for key in sec["data"]})


def main(argv=None) -> int:
    args = parse_args(argv)
    if args.report or args.merge:
        merged = json.loads(args.out.read_text()) if args.out.exists() else {}
        if args.merge:
            other = json.loads(args.merge.read_text())
            _merge(merged, other.get("sections", {}), other.get("last_run", {}).get("started"))
            merged.setdefault("runs", []).extend(other.get("runs", []))
            if other.get("last_run", {}).get("started", "") > merged.get("last_run", {}).get("started", ""):
                merged["last_run"] = other["last_run"]
            from snn_fg.results.atomic import save_text

            save_text(args.out, json.dumps(merged, indent=1))
        print_summary(merged, merged.get("sections", {}))
        if args.merge and plot_scaling(merged, args.out.with_name("bench_scaling.png")):
            print(f"saved {args.out.with_name('bench_scaling.png')}")
        return 0
    eng, notes = engines(args.only)
    for n in notes:
        print(f"note: {n}", file=sys.stderr)
    run = {
        "started": datetime.datetime.now().isoformat(timespec="seconds"),
        "commit": git_commit(),
        "command": sys.argv,
        "cpus": os.cpu_count(),
        "processor": processor(),
        "load_at_start": uptime(),
        "engines": [engine_name(*e) for e in eng],
        "notes": notes,
    }
    measured = {}
    for name in args.sections:
        got = globals()[f"section_{name}"](args, eng)
        if got is not None:
            measured[name] = {"measured": run["started"], "data": got}
    run["load_at_end"] = uptime()
    merged = json.loads(args.out.read_text()) if args.out.exists() else {}
    _merge(merged, measured, run["started"])
    merged["last_run"] = run
    merged.setdefault("runs", []).append(run)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    from snn_fg.results.atomic import save_text

    save_text(args.out, json.dumps(merged, indent=1))
    print_summary(merged, measured)
    print(f"saved {args.out}")
    if "synthetic" in measured and plot_scaling(merged, args.out.with_name("bench_scaling.png")):
        print(f"saved {args.out.with_name('bench_scaling.png')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
