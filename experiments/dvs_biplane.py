"""A model on the real DVS recording of a toy biplane (../shared/data/events/dvs.es).

The rate model runs window by window; the spiking model runs one continuous
network over the whole recording (one build, every event at its own time,
each window read from its own spikes plus the read-out lag). For every
85 ms window (from --start-ms, default 1 ms: the first 1 ms is a reset burst) it reports
whether the grouping maximum lies on the plane (inside the filled outline of
that window's events) and the fraction of figure-ground vectors along the
outline that point inwards. Writes experiments/results/dvs_biplane[_spiking].json and .png (input,
figure-ground map, grouping map with the outline and the grouping maximum,
one row per window).

    python experiments/dvs_biplane.py [--model spiking --start-ms 100 --backend brian2]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from snn_fg.atomic import save_figure, save_text  # noqa: E402
from snn_fg.events import iter_windows  # noqa: E402
from snn_fg.figures import event_frame_rgb, plot_maps_row  # noqa: E402
from snn_fg.metrics import grouping_peak  # noqa: E402
from snn_fg.outline import filled_outline, inward_score  # noqa: E402
from snn_fg.rate.edfg import run_edfg  # noqa: E402

REC = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "events" / "dvs.es"
OUT = Path(__file__).with_name("results")


def _maps(model: str, windows, backend: str):
    """Each window's maps, and what to record about the run."""
    if model == "rate":
        return [run_edfg(w.pos, w.neg) for w in windows], {}
    from snn_fg.spiking.continuous import run_spiking_windows

    maps = run_spiking_windows(windows, backend=backend)
    sim = maps[0].params["simulation"]
    return maps, {"simulated_ms": sim["simulated_ms"], "network_builds": sim["network_builds"],
                  "readout_lag_ms": sim["readout_lag_ms"], "backend": maps[0].params["backend"],
                  "cells": maps[0].params["counts"]["total_cells"],
                  "synapses": maps[0].params["counts"]["total_synapses"],
                  "timings_s": maps[-1].params["timings_s"]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", choices=("rate", "spiking"), default="rate")
    ap.add_argument("--start-ms", type=float, default=1.0)
    ap.add_argument("--backend", default="brian2")
    a = ap.parse_args()
    if not REC.exists():
        sys.exit(f"needs {REC} (../shared is absent)")
    t0 = time.perf_counter()
    windows = list(iter_windows(REC, window_ms=85, start_ms=a.start_ms))
    all_maps, run = _maps(a.model, windows, a.backend)
    rows, panels = [], []
    for w, m in zip(windows, all_maps):
        region = filled_outline(w.pos | w.neg)
        r, c = grouping_peak(m.grouping)
        frac, n = inward_score(m.fg_x, m.fg_y, region)
        row = {"window": w.index, "t_start_ms": w.t_start_us / 1000, "t_end_ms": w.t_end_us / 1000,
               "events": int(len(w.events)), "plane_pixels": int(region.sum()),
               "grouping_peak": [r, c], "peak_on_plane": bool(region[r, c]),
               "outline_vectors": n, "outline_inward_fraction": frac}
        rows.append(row)
        panels.append((w, m, region, (r, c)))
        print(f"window {w.index:2d} {row['t_start_ms']:6.0f}-{row['t_end_ms']:4.0f} ms  events {row['events']:6d}  "
              f"peak on plane: {row['peak_on_plane']}  inward {frac:.2f} of {n}", flush=True)
    fig, axes = plt.subplots(len(panels), 3, figsize=(11, 3.0 * len(panels)), squeeze=False)
    for ax, (w, m, region, (r, c)) in zip(axes, panels):
        plot_maps_row(ax, event_frame_rgb(w.pos, w.neg), m.fg_x, m.fg_y, m.grouping,
                      f"{w.t_start_us / 1000:.0f}-{w.t_end_us / 1000:.0f} ms")
        ax[2].contour(region, levels=[0.5], colors="white", linewidths=0.8)
        ax[2].plot(c, r, "w+", ms=12, mew=2)
    fig.tight_layout()
    stem = "dvs_biplane" + ("" if a.model == "rate" else f"_{a.model}")
    save_figure(fig, OUT / f"{stem}.png", dpi=80)
    plt.close(fig)
    summary = {"recording": str(REC.name), "model": a.model, "window_ms": 85, "start_ms": a.start_ms, **run,
               "seconds": time.perf_counter() - t0, "load": os.getloadavg(), "windows": rows,
               "peak_on_plane": sum(r["peak_on_plane"] for r in rows),
               "median_inward_fraction": float(np.nanmedian([r["outline_inward_fraction"] for r in rows]))}
    save_text(OUT / f"{stem}.json", json.dumps(summary, indent=2))
    print(f"grouping peak on the plane in {summary['peak_on_plane']} of {len(rows)} windows; "
          f"median inward fraction {summary['median_inward_fraction']:.2f}")


if __name__ == "__main__":
    main()
