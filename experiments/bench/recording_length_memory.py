"""Peak memory and output size of ``snn-fg run`` over recordings of two lengths, both models.

A recording's run keeps one window in memory and writes each window to
``maps.zarr`` as it completes, so peak memory should not grow with the
recording. This runs a synthetic recording (the demo scene seen by a camera
moving in a circle, played again and again with shifted timestamps, written
as ``.npy``) cut to ``--windows`` 85 ms windows (10 and 40), through the rate
and the spiking model, each run in a fresh process (peak resident memory: the
child's ``VmHWM`` from /proc, Linux), side by side, with the load.

    python -m experiments.bench.recording_length_memory [--windows 10 40] [--models rate spiking]

Writes experiments/results/recording_length_memory.{json,md}.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from experiments.common import (ROOT, Run, describe, fail, load, markdown_table, peak_rss_mb, save_json,
                                save_markdown)

#: each copy of the scene's events starts this long after the one before (us)
COPY_SPAN_US = 400_000


def _recording(path: Path, windows: int) -> str:
    """The synthetic recording, long enough for ``windows`` 85 ms windows; returns its sensor size (WxH)."""
    from snn_fg.events import image_to_events, save_events
    from snn_fg.scenes import demo

    rec = image_to_events(demo().image, motion="circle")
    copies = -(-windows * 85_000 // COPY_SPAN_US) + 1
    ev = np.concatenate([rec.events] * copies)
    ev["t"] += np.repeat(np.arange(copies) * COPY_SPAN_US, len(rec.events)).astype(ev["t"].dtype)
    save_events(path, ev, rec.sensor_size)
    return f"{rec.sensor_size[0]}x{rec.sensor_size[1]}"


def _child(argv: list[str]) -> dict:
    """``snn-fg run`` with ``argv`` in this process: windows, time, peak memory, output size."""
    from snn_fg.cli import main as cli
    from snn_fg.store import windows_complete

    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        rc = cli(["run", *argv, "--out", out, "--no-progress"])
        wall = time.perf_counter() - t0
        n = windows_complete(out)
        store_kb = sum(p.stat().st_size for p in (Path(out) / "maps.zarr").rglob("*") if p.is_file()) / 1024
    return {"exit_code": rc, "windows": n, "wall_s": round(wall, 1), "store_kb_per_window": round(store_kb / n, 1),
            "peak_rss_mb": peak_rss_mb()}


def _markdown(rec) -> list[str]:
    lines = ["# Peak memory and output size over recordings of two lengths", "", describe(rec["run"]), "",
             "A synthetic recording (the demo scene, camera moving in a circle, repeated), 85 ms windows, "
             "each run a fresh process with figures; `maps.zarr` per window.", ""]
    lines += markdown_table(["model", "windows", "peak memory (MB)", "time (s)", "maps.zarr per window (kB)",
                             "load before"],
                            [[c["model"], c["windows"], f"{c['peak_rss_mb']:.0f}", f"{c['wall_s']:.1f}",
                              f"{c['store_kb_per_window']:.0f}", f"{c['load']:.1f}"] for c in rec["cases"]])
    lines += [""]
    for model, ratio in rec["ratios"].items():
        lines.append(f"- {model}: peak memory at the longest run / at the shortest = {ratio:.3f}")
    return lines + [""]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--windows", type=int, nargs="*", default=[10, 40])
    ap.add_argument("--models", nargs="*", default=["rate", "spiking"])
    ap.add_argument("--child", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child is not None:
        print(json.dumps(_child(a.child)))
        return
    run = Run()
    cases = []
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "synthetic.npy"
        size = _recording(path, max(a.windows))
        for model in a.models:
            for k in a.windows:
                argv = [str(path), "--model", model, "--sensor-size", size, "--max-windows", str(k)]
                before = load()[0]
                p = subprocess.run([sys.executable, "-m", __spec__.name, "--child", *argv], capture_output=True,
                                   text=True, cwd=ROOT)
                if p.returncode:
                    fail(f"{model}, {k} windows: {p.stderr.strip().splitlines()[-1] if p.stderr.strip() else '?'}")
                case = {"model": model, "load": before, **json.loads(p.stdout.strip().splitlines()[-1])}
                cases.append(case)
                print(f"{model:<8} {case['windows']:4d} windows  {case['peak_rss_mb']:7.0f} MB peak  "
                      f"{case['wall_s']:6.1f} s  {case['store_kb_per_window']:6.0f} kB/window  (load {before:.2f})",
                      flush=True)
    ratios = {}
    for model in a.models:
        peaks = [c["peak_rss_mb"] for c in cases if c["model"] == model]
        ratios[model] = peaks[-1] / peaks[0]
    record = {"cases": cases, "ratios": ratios, "run": run.record()}
    save_json("recording_length_memory", record)
    save_markdown("recording_length_memory", _markdown(record))
    print("\n".join(_markdown(record)))


if __name__ == "__main__":
    main()
