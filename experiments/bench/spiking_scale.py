"""Wall time and peak memory of the spiking network on full 321 x 481 frames.

Each frame runs in its own child process so that its peak resident memory
(``ru_maxrss`` of the child) is its own. Prints and stores, per frame: cells,
synapses (an unrolling backend) or synaptic events (the fast engine, which
never unrolls), spikes, the backend's timings, total wall time including
start-up, peak memory and the machine's load before and after. Targets
(issue 11): no frame above 7 GB, and no slower than the 20-160 s a frame
took when that issue was filed.

Usage: python -m experiments.bench.spiking_scale [--backend NAME] [--instantiate input|all] [FRAME_ID ...]
(default: all six frames of the dataset ``bsds-edfg``).
Writes experiments/results/spiking_scale.json and .md.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

from experiments.common import Run, dataset, describe, load, markdown_table, save_json, save_markdown

CHILD = r"""
import json, sys, time, resource
import numpy as np
from snn_fg.models.spiking import run_spiking_result
t0 = time.perf_counter()
d = np.load({path!r})
res = run_spiking_result(d["pos"], d["neg"], backend={backend!r}, instantiate={instantiate!r}, progress=False,
                         record_spikes=True)
wall = time.perf_counter() - t0
m = res.maps
out = {{"wall_s": wall, "timings_s": m.params["timings_s"], "counts": m.params["counts"],
        "backend": m.params["backend"], "backend_stats": m.params["backend_stats"],
        "instantiate": m.params["simulation"]["instantiate"],
        "populations": m.params["populations"],
        "peak_rss_mb_self": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}}
print("@@RESULT@@" + json.dumps(out, default=float))
"""


def _load() -> str:
    """The 1-minute load average, as text."""
    return f"{load()[0]:.2f}"


def run_still(path: Path, backend: str, instantiate: str | None = None) -> dict:
    code = CHILD.format(path=str(path), backend=backend, instantiate=instantiate)
    load_before = _load()
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{path.name}: child failed\n{proc.stderr[-3000:]}")
    line = next(ln for ln in proc.stdout.splitlines() if ln.startswith("@@RESULT@@"))
    res = json.loads(line[len("@@RESULT@@") :])
    res.update(frame=path.stem, load_before=load_before, load_after=_load())
    res["process_wall_s"] = wall  # includes Python start-up and imports
    res["peak_rss_mb"] = res["peak_rss_mb_self"]  # the child's own maximum resident memory
    return res


def main(argv=None):
    from snn_fg.backends import DEFAULT_BACKEND, backend_names

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("frames", nargs="*", help="BSDS frame ids (default: all six)")
    ap.add_argument(
        "--backend", default=DEFAULT_BACKEND, choices=backend_names(), help=f"simulator (default {DEFAULT_BACKEND})"
    )
    ap.add_argument(
        "--instantiate",
        choices=("input", "all"),
        default=None,
        help="cells to create (default: the backend's own default, as snn-fg run does)",
    )
    args = ap.parse_args(argv)
    paths = sorted(dataset("bsds-edfg").glob("*.npz"))
    run = Run()
    if args.frames:
        paths = [p for p in paths if p.stem in args.frames]
    rows = []
    for p in paths:
        r = run_still(p, args.backend, args.instantiate)
        rows.append(r)
        t = ", ".join(f"{k} {v:.1f}" for k, v in r["timings_s"].items())
        print(
            f"{r['frame']}: {r['counts']['total_cells']:,} cells, wall {r['process_wall_s']:.1f} s ({t}), "
            f"peak {r['peak_rss_mb']:.0f} MB (load {r['load_before']})",
            flush=True,
        )
    record = {"rows": rows, "run": run.record()}
    lines = markdown(rows, record["run"])  # (before either file is written: never one without the other)
    save_json("spiking_scale", record)
    save_markdown("spiking_scale", lines)
    print("wrote experiments/results/spiking_scale.json and .md")


def _population_table(pops: dict) -> str:
    lines = [
        f"{'population':16s} {'role':12s} {'level':>5s} {'cells':>10s} {'mean rate (Hz)':>15s} {'synapses in':>12s}"
    ]
    lines += [
        f"{name:16s} {p['role']:12s} {p['level']:5d} {p['cells']:10,d} {p['mean_rate_hz']:15.1f} "
        + (f"{p['synapses_in']:12,d}" if p["synapses_in"] is not None else f"{'-':>12s}")  # (None: fast engine)
        for name, p in pops.items()
    ]
    return "\n".join(lines)


def _row(r) -> list:
    st = r.get("backend_stats", {})
    return [
        r["frame"],
        r["backend"]["name"],
        f"{r['counts']['total_cells']:,} ({r['instantiate']})",
        f"{r['counts']['total_synapses']:,}" if r["counts"]["total_synapses"] else "-",
        f"{st['synaptic_events_total']:,}" if "synaptic_events_total" in st else "-",
        f"{st['spikes']:,}" if "spikes" in st else "-",
        ", ".join(f"{k} {v:.1f}" for k, v in r["timings_s"].items()),
        f"{r['process_wall_s']:.1f}",
        f"{r['peak_rss_mb']:.0f}",
        f"{r['load_before']} / {r['load_after']}",
    ]


def markdown(rows, run) -> list[str]:
    backends = sorted({r["backend"]["name"] for r in rows})
    lines = [
        "# Spiking network at full size (321 x 481, 10 levels)",
        "",
        f"{describe(run)} Backend: {', '.join(backends)}; one child process per frame, run one after another; "
        "default parameters (400 ms simulated, dt 0.5 ms, spikes recorded). Peak = the child's maximum "
        "resident memory; wall includes Python start-up and imports. Synapses are those an unrolling backend "
        "creates; the fast engine never unrolls the kernels and counts synaptic events (one per tap a spike "
        "is delivered through) instead.",
        "",
    ]
    lines += markdown_table(
        [
            "frame",
            "backend",
            "cells (instantiated)",
            "synapses",
            "synaptic events",
            "spikes",
            "timings (s)",
            "wall incl. start-up (s)",
            "peak memory (MB)",
            "load before / after (1 min)",
        ],
        map(_row, rows),
    )
    if rows:
        big = max(rows, key=lambda r: r["counts"]["total_cells"])
        lines += [
            "",
            f"## Cells per population ({big['frame']}, the most cells)",
            "",
            "```",
            _population_table(big["populations"]),
            "```",
        ]
    return lines


if __name__ == "__main__":
    main()
