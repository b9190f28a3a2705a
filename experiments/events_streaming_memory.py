"""Peak memory and time of streaming a large recording window by window.

Builds a synthetic recording of ``--events`` events (default 10 million) as a
``.npy`` file on disk (written chunk by chunk, never held in memory), then, in
a fresh child process, streams it through ``iter_windows`` + ``events_to_frame``
and reports the child's peak resident memory (``VmHWM`` from /proc on Linux;
``ru_maxrss`` as well, which Linux carries over from the parent across
fork/exec, hence the file is built in a separate process too), the peak of
Python/numpy allocations (``tracemalloc``, optional) and the wall time.

    python experiments/events_streaming_memory.py [--events N] [--duration-s S]
           [--window-ms W] [--chunk-events C] [--keep FILE.npy] [--report OUT.json]

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

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from snn_fg.atomic import atomic_path, save_text  # noqa: E402
from snn_fg.events import EVENT_DTYPE  # noqa: E402

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
            mm[i:i + m] = c
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--events", type=int, default=10_000_000)
    ap.add_argument("--duration-s", type=float, default=60.0)
    ap.add_argument("--window-ms", type=float, default=85.0)
    ap.add_argument("--chunk-events", type=int, default=1_000_000)
    ap.add_argument("--tracemalloc", action="store_true", help="also trace numpy allocations (slower)")
    ap.add_argument("--keep", type=Path, default=None, help="build/keep the recording here instead of a temp dir")
    ap.add_argument("--report", type=Path, default=None, help="write the result as JSON")
    ap.add_argument("--child", type=Path, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--build-only", type=Path, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)

    if args.build_only is not None:  # a separate process, so its memory never counts below
        build(args.build_only, args.events, args.duration_s)
        return 0
    if args.child is not None:  # the measured process: only streams
        print(json.dumps(stream(args.child, args.window_ms, args.chunk_events, args.tracemalloc)))
        return 0

    with tempfile.TemporaryDirectory() as d:
        path = args.keep or Path(d) / "synthetic_10M.npy"
        t0 = time.perf_counter()
        if not path.exists():
            subprocess.run([sys.executable, __file__, "--build-only", str(path), "--events", str(args.events),
                            "--duration-s", str(args.duration_s)], check=True)
        build_s = time.perf_counter() - t0
        cmd = [sys.executable, __file__, "--child", str(path), "--window-ms", str(args.window_ms),
               "--chunk-events", str(args.chunk_events)] + (["--tracemalloc"] if args.tracemalloc else [])
        res = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if res.returncode != 0:
            print(res.stderr, file=sys.stderr)
            return res.returncode
        result = json.loads(res.stdout.strip().splitlines()[-1])
        result.update({
            "events": args.events, "duration_s": args.duration_s, "window_ms": args.window_ms,
            "chunk_events": args.chunk_events, "file_mb": round(path.stat().st_size / 2**20, 1),
            "build_s": round(build_s, 1), "target_peak_mb": 1024,
        })
        result["within_target"] = result["peak_rss_mb"] < 1024
    text = json.dumps(result, indent=2)
    print(text)
    if args.report:
        save_text(args.report, text + "\n")
    return 0 if result["within_target"] else 1


if __name__ == "__main__":
    sys.exit(main())
