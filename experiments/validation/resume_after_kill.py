"""A spiking run over a recording killed with SIGKILL halfway, then continued with --resume.

Runs ``snn-fg run REC --model spiking --no-figures`` once uncut, then again,
kills it (``kill -9``) as soon as ``--kill-at`` windows are complete in its
``maps.zarr``, reads the store as it was left (the complete windows, marked
incomplete), continues it with ``--resume`` and compares its maps with the
uncut run's.

    python -m experiments.validation.resume_after_kill [--recording FILE] [--max-windows 8] [--kill-at 4]
           [--start-ms 100]

Default recording: ``dvs.es`` of the dataset ``events``. Writes
experiments/results/resume_after_kill.{json,md}.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from experiments.common import DVS_FROM_MS, ROOT, Run, dataset, describe, fail, markdown_table, save_json, save_markdown


def _kill_and_resume(cmd: list[str], out: Path, kill_at: int) -> dict:
    from snn_fg.results.maps import Maps
    from snn_fg.results.store import read_attrs, windows_complete

    p = subprocess.Popen(cmd + ["--out", str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=ROOT)
    while windows_complete(out) < kill_at:
        if p.poll() is not None:
            fail(f"the run ended before {kill_at} windows were complete: {p.stderr.read().decode()[-300:]}")
        time.sleep(0.05)
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    row = {
        "killed_at_windows": windows_complete(out),
        "readable_windows": int(Maps.load(out).fg_x.shape[0]),
        "marked_complete": bool(read_attrs(out / "maps.zarr")["snn_fg"]["complete"]),
    }
    t = time.perf_counter()
    r = subprocess.run(cmd + ["--out", str(out), "--resume"], capture_output=True, text=True, cwd=ROOT)
    if r.returncode:
        fail(f"--resume failed: {r.stderr.strip()[-300:]}")
    return {**row, "resume_s": round(time.perf_counter() - t, 1), "windows_after_resume": windows_complete(out)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--recording", type=Path, default=None)
    ap.add_argument("--max-windows", type=int, default=8)
    ap.add_argument("--kill-at", type=int, default=4)
    ap.add_argument("--start-ms", type=float, default=DVS_FROM_MS)
    a = ap.parse_args()
    from snn_fg.results.maps import Maps

    rec = a.recording or dataset("events", "dvs.es")
    run = Run()
    cmd = [
        sys.executable,
        "-m",
        "snn_fg.cli",
        "run",
        str(rec),
        "--model",
        "spiking",
        "--no-figures",
        "--no-progress",
        "--max-windows",
        str(a.max_windows),
        "--start-ms",
        str(a.start_ms),
    ]
    with tempfile.TemporaryDirectory() as d:
        t = time.perf_counter()
        subprocess.run(cmd + ["--out", f"{d}/uncut"], check=True, capture_output=True, cwd=ROOT)
        uncut_s = round(time.perf_counter() - t, 1)
        row = _kill_and_resume(cmd, Path(d) / "cut", a.kill_at)
        x, y = Maps.load(f"{d}/cut"), Maps.load(f"{d}/uncut")
        equal = {k: bool(np.array_equal(getattr(x, k), getattr(y, k))) for k in ("fg_x", "fg_y", "grouping")}
        with_vectors = int((np.abs(y.fg_x).sum(axis=(1, 2)) > 0).sum())
    record = {
        "recording": str(rec),
        "uncut_s": uncut_s,
        **row,
        "equal": equal,
        "windows_with_vectors": with_vectors,
        "run": run.record(),
    }
    save_json("resume_after_kill", record)
    lines = [
        "# A spiking run killed with SIGKILL, then --resume",
        "",
        describe(record["run"]),
        "",
        f"Recording `{Path(rec).name}`, {a.max_windows} windows from {a.start_ms:g} ms, killed as soon as "
        f"{a.kill_at} were complete.",
        "",
    ]
    lines += markdown_table(
        [
            "uncut run (s)",
            "complete at the kill",
            "readable then",
            "marked complete",
            "resume (s)",
            "windows after",
            "maps equal bit for bit",
        ],
        [
            [
                uncut_s,
                row["killed_at_windows"],
                row["readable_windows"],
                row["marked_complete"],
                row["resume_s"],
                row["windows_after_resume"],
                all(equal.values()),
            ]
        ],
    )
    save_markdown("resume_after_kill", lines + [""])
    print("\n".join(lines))


if __name__ == "__main__":
    main()
