"""NEST (through PyNN) against Brian2 on full-size inputs, and NEST on 1 and 2 threads.

Inputs: BSDS frame 105053 (321 x 481, ../shared/data/bsds-edfg) and one
85 ms window of ../shared/data/events/dvs.es (320 x 240, from 100 ms).
Each (input, backend, threads) runs in its own process so that its wall
time and peak memory (ru_maxrss) are its own. Reported: grouping Pearson r,
fraction of edge pixels with a vector in both within 45 degrees, mean angle
difference, mean rate per role (NEST / Brian2), wall time, peak memory.

Writes experiments/results/nest_vs_brian2.json and .md.
Usage: python experiments/nest_vs_brian2.py [--only frame|dvs] [--no-threads]
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from snn_fg.atomic import save_text  # noqa: E402

SHARED = ROOT.parent / "shared" / "data"
OUT = ROOT / "experiments" / "results"
WINDOW = (100.0, 85.0)     # start, length (ms) of the dvs.es window


SYNTHETIC = ("disc16", "disc16dark", "occlusion", "demo", "disc32", "disc32dark", "disc48", "disc48dark")


def _inputs(name):
    if name in SYNTHETIC:
        from snn_fg import scenes
        from snn_fg.events import image_to_frame

        if name.startswith("disc"):
            sc = scenes.disc(int(name[4:6]), light_on_dark=not name.endswith("dark"))
        else:
            sc = getattr(scenes, name)()
        pos, neg = image_to_frame(sc.image)
        return {"pos": pos, "neg": neg}
    if name == "frame":
        d = np.load(SHARED / "bsds-edfg" / "105053.npz")
        return {"pos": d["pos"], "neg": d["neg"]}
    from snn_fg.events import iter_windows

    win = next(iter_windows(SHARED / "events" / "dvs.es", window_ms=WINDOW[1], start_ms=WINDOW[0]))
    return {"events": win.events, "sensor_size": (win.pos.shape[1], win.pos.shape[0], 2)}


def one(name, backend, threads, out):
    """Run one simulation in this process; save rates and maps."""
    from snn_fg.spiking import run_spiking_result

    t0 = time.perf_counter()
    opts = {"threads": threads} if backend == "nest" else {}
    res = run_spiking_result(**_inputs(name), backend=backend, backend_options=opts, progress=False)
    wall = time.perf_counter() - t0
    r = res.result
    roles = {}
    for p in r.populations:
        role = r.network.population(p).role
        n, c = roles.get(role, (0, 0))
        roles[role] = (n + r.counts[p].size, c + int(r.counts[p].sum()))
    np.savez(out, fg_x=res.maps.fg_x, fg_y=res.maps.fg_y, grouping=res.maps.grouping,
             meta=json.dumps({"wall_s": wall, "peak_rss_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6,
                              "timings_s": r.timings_s, "cells": r.total_cells,
                              "synapses": int(sum(r.stats["synapses_in"].values())),
                              "role_rates_hz": {k: c / max(n, 1) / (r.count_window_ms / 1000) for k, (n, c) in
                                                roles.items()}}))


def _run(name, backend, threads, tmp):
    out = Path(tmp) / f"{name}_{backend}_{threads}.npz"
    subprocess.run([sys.executable, __file__, "--one", name, backend, str(threads), str(out)], check=True,
                   env={**os.environ, "PYNEST_QUIET": "1"})
    d = np.load(out)
    return d, json.loads(str(d["meta"]))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--one", nargs=4, metavar=("INPUT", "BACKEND", "THREADS", "OUT"))
    ap.add_argument("--only", choices=("frame", "dvs", "synthetic"))
    ap.add_argument("--no-threads", action="store_true")
    args = ap.parse_args()
    if args.one:
        one(args.one[0], args.one[1], int(args.one[2]), args.one[3])
        return
    from snn_fg.metrics import compare_frame

    rows = []
    load = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        names = {"synthetic": list(SYNTHETIC), None: ["frame", "dvs"]}.get(args.only, [args.only])
        for name in names:
            b2, mb = _run(name, "brian2", 1, tmp)
            runs = [(1, _run(name, "nest", 1, tmp))]
            if not args.no_threads:
                runs.append((2, _run(name, "nest", 2, tmp)))
            for threads, (ne, mn) in runs:
                c = compare_frame(ne["fg_x"], ne["fg_y"], ne["grouping"], b2["fg_x"], b2["fg_y"], b2["grouping"])
                ratio = {k: (mn["role_rates_hz"][k] / v if v else None) for k, v in mb["role_rates_hz"].items()}
                rows.append({"input": name, "nest_threads": threads, "grouping_r": c["grouping_pearson_r"],
                             "within_45": c["angle_within_45_frac"], "mean_angle_deg": c["angle_diff_mean_deg"],
                             "pixels": c["pixels_compared"], "rate_ratio_nest_over_brian2": ratio,
                             "brian2": mb, "nest": mn})
                save_text(OUT / f"nest_vs_brian2{'_' + args.only if args.only else ''}.partial.json",
                          json.dumps(rows, indent=1))
                print(json.dumps({k: rows[-1][k] for k in ("input", "nest_threads", "grouping_r", "within_45")}),
                      f"brian2 {mb['wall_s']:.1f} s {mb['peak_rss_gb']:.2f} GB, nest {mn['wall_s']:.1f} s "
                      f"{mn['peak_rss_gb']:.2f} GB", flush=True)
    OUT.mkdir(parents=True, exist_ok=True)
    result = {"load_before": load, "load_after": os.getloadavg(), "window_ms": WINDOW, "rows": rows}
    stem = f"nest_vs_brian2{'_' + args.only if args.only else ''}"
    save_text(OUT / f"{stem}.json", json.dumps(result, indent=1))
    (OUT / f"{stem}.partial.json").unlink(missing_ok=True)
    lines = ["# NEST (PyNN) against Brian2", "", f"Load average before/after: {load} / {result['load_after']} "
             "(2 cores shared by five developers: timings are noisy).", "",
             "| input | NEST threads | grouping r | within 45° | mean angle ° | Brian2 s / GB | NEST s / GB | "
             "NEST run s | rate ratio range (NEST/Brian2, per role) |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        vals = [v for v in r["rate_ratio_nest_over_brian2"].values() if v]
        lines.append(f"| {r['input']} | {r['nest_threads']} | {r['grouping_r']:.3f} | {r['within_45']:.3f} | "
                     f"{r['mean_angle_deg']:.1f} | {r['brian2']['wall_s']:.0f} / {r['brian2']['peak_rss_gb']:.2f} | "
                     f"{r['nest']['wall_s']:.0f} / {r['nest']['peak_rss_gb']:.2f} | "
                     f"{r['nest']['timings_s'].get('run', 0):.1f} | {min(vals):.2f}-{max(vals):.2f} |")
    save_text(OUT / f"{stem}.md", "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
