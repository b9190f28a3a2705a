"""Peak memory and time of the spiking model over recordings of growing length.

``snn-fg run RECORDING --model spiking`` runs a recording as one continuous
network, decoding each window as the run passes it (the fast engine then
forgets that window's spikes; until 25 Nov 2026 it kept them all to the
end). This measures what memory and time grow with the recording: ``dvs.es``
cut to its first ``--windows`` windows, and ``dvs.es`` played ``--repeats``
times in a row (each copy shifted by the recording's span plus 1 ms, written
as a ``.npy`` recording). Each case runs in a fresh process; its peak
resident memory is the child's ``VmHWM``, read from /proc (Linux).

    python -m experiments.bench.spiking_recording_memory [--windows 4 8 12] [--repeats 5]

Writes experiments/results/spiking_recording_memory.{json,md}, with the
least-squares line of peak memory against windows.
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

from experiments.common import ROOT, Run, dataset, describe, fail, load, markdown_table, save_results

SENSOR = "320x240"


def _repeated(rec: Path, path: Path, times: int) -> None:
    """The recording ``rec`` played ``times`` times in a row, as a ``.npy`` recording."""
    from snn_fg.events import open_recording

    ev = open_recording(rec).events
    span = int(ev["t"][-1] - ev["t"][0]) + 1000
    parts = []
    for k in range(times):
        part = ev.copy()
        part["t"] = ev["t"] - ev["t"][0] + k * span
        parts.append(part)
    np.save(path, np.concatenate(parts))


def _child(argv: list[str]) -> dict:
    """Run ``snn-fg run`` with ``argv`` in this process: time, windows, peak memory."""
    from snn_fg.cli import main as cli
    from snn_fg.results.store import windows_complete

    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        rc = cli(["run", *argv, "--out", out, "--model", "spiking", "--no-progress"])
        wall = time.perf_counter() - t0
        n_win = windows_complete(out)
        out_mb = sum(p.stat().st_size for p in Path(out).rglob("*") if p.is_file()) / 2**20
    status = Path("/proc/self/status").read_text()
    return {
        "exit_code": rc,
        "windows": n_win,
        "wall_s": round(wall, 1),
        "output_mb": round(out_mb, 1),
        "peak_rss_mb": round(int(status.split("VmHWM:")[1].split()[0]) / 1024, 1),
    }


def _markdown(rec) -> list[str]:
    fit = rec["fit"]
    lines = [
        "# The spiking model's peak memory over recordings of growing length",
        "",
        f"{describe(rec['run'])} Fast engine.",
        "",
    ]
    lines += markdown_table(
        ["recording", "windows", "peak memory (GB)", "time (s)", "output (MB)"],
        [
            [c["case"], c["windows"], f"{c['peak_rss_mb'] / 1024:.2f}", f"{c['wall_s']:.0f}", f"{c['output_mb']:.0f}"]
            for c in rec["cases"]
        ],
    )
    lines += [
        "",
        f"Peak memory = {fit['fixed_mb'] / 1024:.2f} GB + {fit['mb_per_window']:.0f} MB per window "
        f"(least squares over the {len(rec['cases'])} runs, largest residual {fit['max_residual_mb']:.0f} MB): "
        f"a 24 GB machine holds about {fit['windows_in_24gb']:.0f} windows "
        f"({fit['windows_in_24gb'] * 0.085:.0f} s of 85 ms windows).",
        "",
    ]
    return lines


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--windows", type=int, nargs="*", default=[4, 8, 12], help="runs on the first N windows of dvs.es (4 8 12)"
    )
    ap.add_argument("--repeats", type=int, nargs="*", default=[5], help="runs on dvs.es played N times in a row (5)")
    ap.add_argument("--child", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child is not None:
        print(json.dumps(_child(a.child)))
        return
    rec = dataset("events", "dvs.es")
    run = Run()
    cases = []
    with tempfile.TemporaryDirectory() as d:
        runs = [(f"dvs.es, first {k} windows", [str(rec), "--max-windows", str(k)]) for k in a.windows]
        for times in a.repeats:
            path = Path(d) / f"dvs_x{times}.npy"
            _repeated(rec, path, times)
            runs.append((f"dvs.es x {times}", [str(path), "--sensor-size", SENSOR]))
        for name, argv in runs:
            p = subprocess.run(
                [sys.executable, "-m", __spec__.name, "--child", *argv], capture_output=True, text=True, cwd=ROOT
            )
            if p.returncode:
                fail(f"{name}: snn-fg run failed: {p.stderr.strip().splitlines()[-1] if p.stderr.strip() else '?'}")
            case = {"case": name, **json.loads(p.stdout.strip().splitlines()[-1])}
            cases.append(case)
            print(
                f"{name:<26} {case['windows']:4d} windows  {case['peak_rss_mb'] / 1024:6.2f} GB peak  "
                f"{case['wall_s']:6.1f} s  (load {load()[0]:.2f})",
                flush=True,
            )
    x = np.array([c["windows"] for c in cases], float)
    y = np.array([c["peak_rss_mb"] for c in cases], float)
    slope, fixed = np.polyfit(x, y, 1)
    fit = {
        "fixed_mb": float(fixed),
        "mb_per_window": float(slope),
        "max_residual_mb": float(np.max(np.abs(fixed + slope * x - y))),
        "windows_in_24gb": float((24 * 1024 - fixed) / slope),
    }
    record = {"cases": cases, "fit": fit, "run": run.record()}
    save_results("spiking_recording_memory", record, _markdown(record))


if __name__ == "__main__":
    main()
