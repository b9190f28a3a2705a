"""Windows per second over a folder of recordings, on 1 and 2 local workers side by side.

``snn-fg run FOLDER --out DIR --workers N --no-figures`` on a folder of
``--recordings`` copies of ``dvs.es`` (each written as its own ``.npy``
recording), for the rate model and the compact spiking network, the two
worker counts alternating over ``--rounds`` rounds, each run a fresh process
with a fresh output folder. Windows per second: the windows the summary
lists, over the command's wall time (start-up, reading and writing
included). The machine's load is recorded with every run.

    python -m experiments.bench.dataset_throughput [--recordings 4] [--rounds 2] [--models rate spiking:compact]

Writes experiments/results/dataset_throughput.{json,md}.
"""

from __future__ import annotations

import argparse
import csv
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from experiments.common import ROOT, Run, dataset, describe, fail, load, markdown_table, save_results

NAME = "dataset_throughput"


def _folder(path: Path, n: int) -> None:
    """``n`` copies of ``dvs.es`` as ``.npy`` recordings in ``path``."""
    from snn_fg.events import open_recording, save_events

    rec = open_recording(dataset("events", "dvs.es"))
    path.mkdir()
    for k in range(n):
        save_events(path / f"dvs_{k}.npy", rec.events, rec.sensor_size)


def _run(folder: Path, out: Path, workers: int, model: str) -> dict:
    name, _, network = model.partition(":")
    argv = [
        sys.executable,
        "-m",
        "snn_fg.cli",
        "run",
        str(folder),
        "--out",
        str(out),
        "--workers",
        str(workers),
        "--model",
        name,
        "--no-figures",
        "--no-progress",
    ] + (["--network", network] if network else [])
    before = load()[0]
    t = time.perf_counter()
    p = subprocess.run(argv, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t
    if p.returncode:
        fail(f"{model} on {workers} worker(s): {(p.stderr.strip().splitlines() or ['?'])[-1]}")
    with open(out / "summary.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    windows = sum(int(r["windows"]) for r in rows)
    if any(r["status"] != "done" for r in rows):
        fail(f"{model} on {workers} worker(s): not every recording is done ({[r['status'] for r in rows]})")
    return {
        "model": model,
        "workers": workers,
        "recordings": len(rows),
        "windows": windows,
        "wall_s": round(wall, 2),
        "windows_per_s": round(windows / wall, 3),
        "load": before,
    }


def _markdown(rec) -> list[str]:
    rows = []
    for model in rec["models"]:
        med = {
            w: statistics.median(r["windows_per_s"] for r in rec["runs"] if r["model"] == model and r["workers"] == w)
            for w in (1, 2)
        }
        loads = [r["load"] for r in rec["runs"] if r["model"] == model]
        rows.append(
            [model, f"{med[1]:.2f}", f"{med[2]:.2f}", f"{med[2] / med[1]:.2f}", f"{min(loads):.1f}-{max(loads):.1f}"]
        )
    runs = [
        [
            r["model"],
            r["workers"],
            r["round"],
            r["windows"],
            f"{r['wall_s']:.1f}",
            f"{r['windows_per_s']:.2f}",
            f"{r['load']:.1f}",
        ]
        for r in rec["runs"]
    ]
    per = rec["runs"][0]["windows"] // rec["recordings"]
    return (
        [
            "# Windows per second over a folder of recordings, 1 and 2 local workers",
            "",
            describe(rec["run"]),
            "",
            f"{rec['recordings']} copies of `dvs.es` (320 x 240, 1 s: {per} windows of 85 ms each) as `.npy` "
            "recordings; `snn-fg run FOLDER --workers N --no-figures`, a fresh process and output folder per run, "
            "the worker counts alternating. Windows per second: the summary's windows over the command's wall "
            "time. Medians over the rounds:",
            "",
        ]
        + markdown_table(["model", "1 worker (windows/s)", "2 workers (windows/s)", "2 / 1", "load"], rows)
        + ["", "Every run:", ""]
        + markdown_table(["model", "workers", "round", "windows", "wall (s)", "windows/s", "load before"], runs)
        + [""]
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--recordings", type=int, default=4)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument(
        "--models",
        nargs="+",
        default=["rate", "spiking:compact"],
        help="model[:network] to run (rate, spiking:compact, ...)",
    )
    a = ap.parse_args()
    if a.recordings < 2 or a.rounds < 1:
        fail("--recordings must be at least 2 and --rounds at least 1")
    run, runs = Run(), []
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d) / "recordings"
        _folder(folder, a.recordings)
        for model in a.models:
            for r in range(a.rounds):
                for workers in (1, 2) if r % 2 == 0 else (2, 1):
                    out = Path(d) / f"out_{len(runs)}"
                    row = {**_run(folder, out, workers, model), "round": r + 1}
                    runs.append(row)
                    print(
                        f"{model:<16} {workers} worker(s)  round {r + 1}  {row['windows']} windows  "
                        f"{row['wall_s']:6.1f} s  {row['windows_per_s']:.2f} windows/s  (load {row['load']:.2f})",
                        flush=True,
                    )
    record = {"recordings": a.recordings, "models": a.models, "runs": runs, "run": run.record()}
    lines = _markdown(record)
    save_results(NAME, record, lines)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
