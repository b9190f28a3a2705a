"""Peak memory and time of streaming a large recording window by window.

Builds a synthetic recording of ``--events`` events (default 10 million) as a
``.npy`` file on disk (written chunk by chunk, never held in memory), then, in
a fresh child process, streams it through ``iter_windows`` + ``events_to_frame``
and reports the child's peak resident memory (``VmHWM`` from /proc on Linux;
``ru_maxrss`` as well, which Linux carries over from the parent across
fork/exec, hence the file is built in a separate process too), the peak of
Python/numpy allocations (``tracemalloc``, optional) and the wall time.

    python -m experiments.bench.events_streaming_memory [--events N] [--duration-s S]
           [--window-ms W] [--chunk-events C] [--keep FILE.npy] [--report OUT.json]
           [--through-cli [--max-windows N]]

``--through-cli`` measures the whole product path instead: the child runs
``snn-fg run FILE --model rate`` (every window through the rate model, maps
streamed to ``maps.zarr``, figures), and reports its peak memory and the size
of what it wrote.

Target: peak memory under 1 GB for 10 million events.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from experiments.common import ROOT, Run
from snn_fg.events import EVENT_DTYPE
from snn_fg.results.atomic import atomic_path, save_text

SENSOR = (304, 240)


def build(path: Path, n: int, duration_s: float, seed: int = 0, chunk: int = 1_000_000) -> None:
    """Write ``n`` time-sorted random events spanning ``duration_s`` to ``path`` (.npy)."""
    rng = np.random.default_rng(seed)
    span = int(duration_s * 1e6)
    with atomic_path(path) as tmp:
        mm = np.lib.format.open_memmap(tmp, mode="w+", dtype=EVENT_DTYPE, shape=(n,))
        for i in range(0, n, chunk):
            m = min(chunk, n - i)
            # sorted timestamps: evenly spread blocks, sorted within each block
            lo = span * i // n
            hi = span * (i + m) // n
            c = np.empty(m, EVENT_DTYPE)
            c["t"] = np.sort(rng.integers(lo, max(hi, lo + 1), m))
            c["x"] = rng.integers(0, SENSOR[0], m)
            c["y"] = rng.integers(0, SENSOR[1], m)
            c["p"] = rng.integers(0, 2, m)
            mm[i : i + m] = c
        mm.flush()
        del mm


def stream(path: Path, window_ms: float, chunk_events: int, trace: bool) -> dict:
    """Stream ``path`` window by window; return counts, time and peak memory of this process."""
    import tracemalloc

    from snn_fg.events import iter_windows

    if trace:
        tracemalloc.start()
    t0 = time.perf_counter()
    n_win = n_ev = edge_px = 0
    for w in iter_windows(path, window_ms=window_ms, chunk_events=chunk_events, sensor_size=SENSOR):
        n_win += 1
        n_ev += len(w.events)
        edge_px += int((w.pos | w.neg).sum())
    wall = time.perf_counter() - t0
    out = {
        "windows": n_win,
        "events_streamed": n_ev,
        "mean_edge_pixels_per_window": edge_px / max(n_win, 1),
        "wall_s": round(wall, 2),
        "events_per_s": round(n_ev / wall),
        "ru_maxrss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
    }
    try:  # peak resident set of this process image only (Linux)
        status = Path("/proc/self/status").read_text()
        out["peak_rss_mb"] = round(int(status.split("VmHWM:")[1].split()[0]) / 1024, 1)
    except (OSError, IndexError, ValueError):
        out["peak_rss_mb"] = out["ru_maxrss_mb"]
    if trace:
        out["tracemalloc_peak_mb"] = round(tracemalloc.get_traced_memory()[1] / 2**20, 1)
    return out


def through_cli(path: Path, window_ms: float, max_windows: int | None) -> dict:
    """Run ``snn-fg run path --model rate`` in this process; time, peak memory, output size."""
    from snn_fg.cli import main as cli
    from snn_fg.results.store import windows_complete

    with tempfile.TemporaryDirectory() as out:
        argv = [
            "run",
            str(path),
            "--out",
            out,
            "--model",
            "rate",
            "--window-ms",
            str(window_ms),
            "--sensor-size",
            f"{SENSOR[0]}x{SENSOR[1]}",
            "--no-progress",
        ]
        if max_windows:
            argv += ["--max-windows", str(max_windows)]
        t0 = time.perf_counter()
        rc = cli(argv)
        wall = time.perf_counter() - t0
        n_win = windows_complete(out)
        out_mb = sum(p.stat().st_size for p in Path(out).rglob("*") if p.is_file()) / 2**20
    status = Path("/proc/self/status").read_text()
    return {
        "exit_code": rc,
        "windows": n_win,
        "wall_s": round(wall, 1),
        "s_per_window": round(wall / n_win, 3),
        "output_mb": round(out_mb, 1),
        "peak_rss_mb": round(int(status.split("VmHWM:")[1].split()[0]) / 1024, 1),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--events", type=int, default=10_000_000)
    ap.add_argument("--duration-s", type=float, default=60.0)
    ap.add_argument("--window-ms", type=float, default=85.0)
    ap.add_argument("--chunk-events", type=int, default=1_000_000)
    ap.add_argument("--tracemalloc", action="store_true", help="also trace numpy allocations (slower)")
    ap.add_argument("--keep", type=Path, default=None, help="build/keep the recording here instead of a temp dir")
    ap.add_argument("--report", type=Path, default=None, help="write the result as JSON")
    ap.add_argument("--through-cli", action="store_true", help="measure snn-fg run --model rate end to end")
    ap.add_argument("--max-windows", type=int, default=None, help="with --through-cli: stop after N windows")
    ap.add_argument("--child", type=Path, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--build-only", type=Path, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)

    if args.build_only is not None:  # a separate process, so its memory never counts below
        build(args.build_only, args.events, args.duration_s)
        return 0
    if args.child is not None:  # the measured process
        if args.through_cli:
            print(json.dumps(through_cli(args.child, args.window_ms, args.max_windows)))
        else:
            print(json.dumps(stream(args.child, args.window_ms, args.chunk_events, args.tracemalloc)))
        return 0

    run = Run()
    me = [sys.executable, "-m", __spec__.name]
    with tempfile.TemporaryDirectory() as d:
        path = args.keep or Path(d) / "synthetic_10M.npy"
        t0 = time.perf_counter()
        if not path.exists():
            subprocess.run(
                me + ["--build-only", str(path), "--events", str(args.events), "--duration-s", str(args.duration_s)],
                check=True,
                cwd=ROOT,
            )
        build_s = time.perf_counter() - t0
        cmd = (
            me
            + ["--child", str(path), "--window-ms", str(args.window_ms), "--chunk-events", str(args.chunk_events)]
            + (["--tracemalloc"] if args.tracemalloc else [])
            + (["--through-cli"] if args.through_cli else [])
            + (["--max-windows", str(args.max_windows)] if args.max_windows else [])
        )
        res = subprocess.run(cmd, capture_output=True, text=True, check=False, cwd=ROOT)
        if res.returncode != 0:
            print(res.stderr, file=sys.stderr)
            return res.returncode
        result = json.loads(res.stdout.strip().splitlines()[-1])
        result.update(
            {
                "events": args.events,
                "duration_s": args.duration_s,
                "window_ms": args.window_ms,
                "chunk_events": args.chunk_events,
                "file_mb": round(path.stat().st_size / 2**20, 1),
                "build_s": round(build_s, 1),
                "target_peak_mb": 1024,
                "measured": "snn-fg run --model rate (all stages, maps written)"
                if args.through_cli
                else "iter_windows + events_to_frame",
            }
        )
        result["within_target"] = result["peak_rss_mb"] < 1024
        result["run"] = run.record()
    text = json.dumps(result, indent=2)
    print(text)
    if args.report:
        save_text(args.report, text + "\n")
    return 0 if result["within_target"] else 1


if __name__ == "__main__":
    sys.exit(main())
