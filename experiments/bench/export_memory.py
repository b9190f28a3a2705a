"""Memory of the exports: writing the NIR file, and the PyNN export's run on NEST.

* ``nir``: peak memory of writing the default 304 x 240 network's NIR file,
  above the process's memory once the network is built: ``nir.write`` of
  the whole graph (how the export wrote it before) against
  ``snn_fg.export.nir.export_nir`` (node by node). Each in a fresh process.
* ``nest``: ``run.py`` of PyNN exports of several sizes on NEST (one thread,
  a disc as input), peak resident memory and wall times, each in a fresh
  process. The model of ``snn_fg/pynn/memory.py`` (a fixed part, a
  part per cell and one per synapse) is fitted on the sizes given by
  ``--fit`` and judged on the others: predicted against measured. The
  sizes run replace their rows; the others' rows are kept. The times of
  the sizes run give ``run.py``'s time figures (``snn_fg/pynn/memory.py``):
  synapses built per second, and seconds per simulated ms per synapse (a
  run's spike deliveries grow with its synapses at the rates the export's
  gains are set for; the disc's trains run at 200 Hz, the rate the
  gains are set for).

Writes experiments/results/export_memory.{json,md}.
Usage: python -m experiments.bench.export_memory [nir] [nest] [--sizes 24x24:1 32x24:2 ...] [--fit 3]
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from experiments.common import RESULTS, Run, describe, load, load_change, markdown_table, save_json, save_markdown

NIR_CHILD = """
import resource, sys, time
from pathlib import Path
import nir
from snn_fg.export.artefacts import default_icub_network
from snn_fg.export.nir import export_nir, to_nir
net = default_icub_network()
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
t0 = time.perf_counter()
if sys.argv[1] == "whole":
    nir.write(sys.argv[2], to_nir(net))
else:
    export_nir(net, Path(sys.argv[2]), force=True)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(base, peak, time.perf_counter() - t0, Path(sys.argv[2]).stat().st_size)
"""
#: an export's run.py in its own folder (which it imports its neighbours from), printing its peak resident
#: memory at the end (bytes)
RUN_CHILD = """
import resource, runpy, sys
sys.path.insert(0, ".")
sys.argv = ["run.py"] + sys.argv[1:]
runpy.run_path("run.py", run_name="__main__")
print("MAXRSS", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024)
"""


def nir_peaks(out: dict):
    with tempfile.TemporaryDirectory() as tmp:
        for mode in ("whole", "streaming"):
            load0 = load()
            done = subprocess.run(
                [sys.executable, "-c", NIR_CHILD, mode, str(Path(tmp) / f"{mode}.nir")],
                capture_output=True,
                text=True,
                check=True,
            )
            base, peak, secs, size = (float(v) for v in done.stdout.split())
            out[f"nir_{mode}"] = {
                "baseline_gb": base / 1e9,
                "peak_gb": peak / 1e9,
                "above_gb": (peak - base) / 1e9,
                "write_s": secs,
                "file_mb": size / 1e6,
                "load": load_change(load0),
            }
            print(mode, out[f"nir_{mode}"], flush=True)


def _export(tmp: Path, w: int, h: int, levels: int):
    from snn_fg.events import image_to_frame
    from snn_fg.export.pynn import export_pynn, save_input
    from snn_fg.frames.scenes import disc
    from snn_fg.lowering.input_spikes import frame_spikes
    from snn_fg.network import build_network
    from snn_fg.params import ModelParams

    folder = export_pynn(build_network(ModelParams(levels=levels), (h, w)), tmp / f"{w}x{h}_{levels}")
    pos, neg = image_to_frame(disc(min(w, h) / 3).image)
    r0, c0 = (pos.shape[0] - h) // 2, (pos.shape[1] - w) // 2
    cut = (slice(max(r0, 0), max(r0, 0) + h), slice(max(c0, 0), max(c0, 0) + w))
    frame = np.zeros((2, h, w), np.uint8)
    frame[:, : pos[cut].shape[0], : pos[cut].shape[1]] = pos[cut], neg[cut]
    save_input(frame_spikes(frame[0], frame[1], 200.0, 0.5, 100.0), folder / "input.npz", 0.5)
    meta = json.loads((folder / "network.json").read_text())
    return folder, sum(p["size"] for p in meta["populations"]), sum(pr["synapses"] for pr in meta["projections"])


def nest_runs(out: dict, sizes):
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for spec in sizes:
            wh, levels = spec.split(":")
            w, h = (int(v) for v in wh.split("x"))
            folder, cells, synapses = _export(Path(tmp), w, h, int(levels))
            load0, t0 = load(), time.perf_counter()
            done = subprocess.run(
                [
                    sys.executable,
                    "-c",
                    RUN_CHILD,
                    "--input",
                    "input.npz",
                    "--out",
                    "counts.npz",
                    "--duration-ms",
                    "100",
                    "--memory-gb",
                    "1000",
                ],
                cwd=folder,
                capture_output=True,
                text=True,
                check=True,
            )
            peak = float(done.stdout.split("MAXRSS")[1])
            built = [line for line in done.stdout.splitlines() if line.startswith("run.py: built")][0]
            build_s, ms, sim_s = (
                float(v)
                for v in re.search(
                    r"built in ([0-9.]+) s, simulated ([0-9.]+) ms in "
                    r"([0-9.]+) s",
                    built,
                ).groups()
            )
            rows.append(
                {
                    "size": spec,
                    "cells": cells,
                    "synapses": synapses,
                    "peak_gb": peak / 1e9,
                    "wall_s": time.perf_counter() - t0,
                    "build_s": build_s,
                    "simulate_s_per_ms": sim_s / ms,
                    "run_py": built,
                    "load": load_change(load0),
                    "load_before": load0,
                    "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
                }
            )
            print(rows[-1], flush=True)
    kept = {r["size"]: r for r in out.get("nest_runs", [])}
    out["nest_runs"] = list({**kept, **{r["size"]: r for r in rows}}.values())  # (in place, new sizes last)
    time_fit(out, rows)


def time_fit(out: dict, rows):
    """Synapses built per second and seconds per simulated ms per synapse (least squares through 0) of ``rows``."""
    syn = np.array([r["synapses"] for r in rows], float)
    build = np.array([r["build_s"] for r in rows])
    sim = np.array([r["simulate_s_per_ms"] for r in rows])
    out["nest_time_model"] = {
        "synapses_per_s": float(syn @ syn / (syn @ build)),
        "s_per_ms_per_synapse": float(syn @ sim / (syn @ syn)),
        "fitted_on": [r["size"] for r in rows],
        "date": rows[0]["date"],
        "load": " / ".join(r["load"] for r in rows),
    }


def fit(out: dict, n_fit: int):
    """Least squares of peak = base + per_cell * cells + per_synapse * synapses on the first n_fit runs."""
    rows = out["nest_runs"]
    a = np.array([[1.0, r["cells"], r["synapses"]] for r in rows[:n_fit]])
    y = np.array([r["peak_gb"] * 1e9 for r in rows[:n_fit]])
    coef = np.linalg.lstsq(a, y, rcond=None)[0]
    out["nest_model"] = {
        "base_bytes": coef[0],
        "bytes_per_cell": coef[1],
        "bytes_per_synapse": coef[2],
        "fitted_on": [r["size"] for r in rows[:n_fit]],
    }
    for r in rows:
        r["predicted_gb"] = float(coef @ [1.0, r["cells"], r["synapses"]]) / 1e9
        r["error_frac"] = r["predicted_gb"] / r["peak_gb"] - 1


def markdown(out: dict) -> list[str]:
    lines = [
        "# Memory of the exports",
        "",
        f"The latest part run: {describe(out['run'])} (2 shared cores.)"
        if "run" in out
        else "Machine: shared, 2 cores.",
        "",
    ]
    if "nir_whole" in out:
        lines += ["## Writing the NIR file of the default 304 x 240 network", ""]
        lines += markdown_table(
            ["writer", "baseline GB", "peak GB", "above baseline GB", "write s", "file MB", "load"],
            [
                [
                    mode,
                    f"{r['baseline_gb']:.2f}",
                    f"{r['peak_gb']:.2f}",
                    f"{r['above_gb']:.2f}",
                    f"{r['write_s']:.0f}",
                    f"{r['file_mb']:.1f}",
                    r["load"],
                ]
                for mode, r in ((m, out[f"nir_{m}"]) for m in ("whole", "streaming"))
            ],
        )
        lines.append("")
    if "nest_runs" in out:
        m = out.get("nest_model", {})
        lines += [
            "## run.py on NEST (one thread, 100 ms)",
            "",
            f"Model fitted on {', '.join(m.get('fitted_on', []))}: {m.get('base_bytes', 0) / 1e9:.2f} GB + "
            f"{m.get('bytes_per_cell', 0):.0f} B per cell or source + {m.get('bytes_per_synapse', 0):.1f} B per "
            "synapse.",
            "",
        ]
        nan = float("nan")
        lines += markdown_table(
            ["size (WxH:levels)", "cells+sources", "synapses", "peak GB", "predicted GB", "error", "wall s", "load"],
            [
                [
                    r["size"],
                    f"{r['cells']:,}",
                    f"{r['synapses']:,}",
                    f"{r['peak_gb']:.2f}",
                    f"{r.get('predicted_gb', nan):.2f}",
                    f"{100 * r.get('error_frac', nan):+.0f} %",
                    f"{r['wall_s']:.0f}",
                    r["load"],
                ]
                for r in out["nest_runs"]
            ],
        )
    if "nest_time_model" in out:
        t = out["nest_time_model"]
        lines += [
            "",
            f"## run.py's time on NEST (one thread; {t['date']}, load {t['load']})",
            "",
            f"Fitted on {', '.join(t['fitted_on'])}: {t['synapses_per_s']:.3g} synapses built per s, "
            f"{t['s_per_ms_per_synapse']:.3g} s per simulated ms per synapse.",
            "",
        ]
        rows = [r for r in out["nest_runs"] if r["size"] in t["fitted_on"]]
        lines += markdown_table(
            ["size (WxH:levels)", "synapses", "build s", "predicted", "s per simulated ms", "predicted", "load"],
            [
                [
                    r["size"],
                    f"{r['synapses']:,}",
                    f"{r['build_s']:.1f}",
                    f"{r['synapses'] / t['synapses_per_s']:.1f}",
                    f"{r['simulate_s_per_ms']:.3f}",
                    f"{r['synapses'] * t['s_per_ms_per_synapse']:.3f}",
                    r["load"],
                ]
                for r in rows
            ],
        )
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", nargs="*", default=["nir", "nest"])
    ap.add_argument("--sizes", nargs="+", default=["24x24:1", "32x24:2", "48x36:3", "64x48:3", "64x48:4"])
    ap.add_argument("--fit", type=int, default=3, help="fit the memory model on the first N sizes of the results")
    args = ap.parse_args(argv)
    run = Run()
    path = RESULTS / "export_memory.json"
    out = json.loads(path.read_text()) if path.exists() else {}
    if "nir" in args.what:
        nir_peaks(out)
    if "nest" in args.what:
        nest_runs(out, args.sizes)
        fit(out, args.fit)
    out["run"] = run.record()
    save_json("export_memory", out)
    save_markdown("export_memory", markdown(out))
    print("\n".join(markdown(out)))


if __name__ == "__main__":
    main()
