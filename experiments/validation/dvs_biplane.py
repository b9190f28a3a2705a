"""A model on the real DVS recording of a toy biplane (dvs.es of the dataset ``events``).

The rate model runs window by window; the spiking model runs one continuous
network over the whole recording (one build, each event a spike in its
0.5 ms step, the default network's ``events`` input coding:
docs/spiking-network.md, "How events become input spikes"; each window read
from its own spikes plus the read-out lag). For every 85 ms window (from
--start-ms, default 1 ms: the first 1 ms is a reset burst) it reports whether
the grouping maximum lies on the plane (inside the filled outline of
that window's events) and the fraction of figure-ground vectors along the
outline that point inwards. Writes experiments/results/dvs_biplane[_spiking].json and .png (input,
figure-ground map, grouping map with the outline and the grouping maximum,
one row per window).

    python -m experiments.validation.dvs_biplane [--model spiking --start-ms 100 --backend fast]

With --model spiking it also measures the latency (experiments.validation.dvs_latency)
and writes dvs_biplane_spiking[_BACKEND].md and _latency.png.
"""

from __future__ import annotations

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from experiments.common import (
    Run,
    dataset,
    describe,
    markdown_table,
    save_figure,
    save_json,  # noqa: E402
    save_markdown,
)
from experiments.validation.dvs_latency import R_WITHIN, plane_latency, window_latencies  # noqa: E402
from snn_fg.backends import DEFAULT_BACKEND, backend_names  # noqa: E402
from snn_fg.events import iter_windows  # noqa: E402
from snn_fg.models.rate.edfg import run_edfg  # noqa: E402
from snn_fg.results.figures import event_frame_rgb, plot_maps_row  # noqa: E402
from snn_fg.scoring.metrics import grouping_peak  # noqa: E402
from snn_fg.scoring.outline import filled_outline, outline_scores  # noqa: E402


def _maps(model: str, windows, backend: str, instantiate=None):
    """Each window's maps, what to record about the run, and the run (spiking)."""
    if model == "rate":
        return [run_edfg(w.pos, w.neg) for w in windows], {}, None
    from snn_fg.models.spiking.continuous import simulate_windows, window_maps

    run = simulate_windows(windows, backend=backend, instantiate=instantiate)
    maps = window_maps(run)
    sim = maps[0].params["simulation"]
    return (
        maps,
        {
            "simulated_ms": run.simulation["simulated_ms"],  # (a window's own: up to its read-out)
            "network_builds": sim["network_builds"],
            "readout_lag_ms": sim["readout_lag_ms"],
            "backend": maps[0].params["backend"],
            "instantiate": sim["instantiate"],
            "cells": maps[0].params["counts"]["total_cells"],
            "synapses": maps[0].params["counts"]["total_synapses"],
            "backend_stats": maps[0].params.get("backend_stats", {}),
            "timings_s": maps[-1].params["timings_s"],
        },
        run,
    )


def _latency(run, maps, regions, rows, step_ms, stem):
    """Window and plane latencies (:mod:`experiments.validation.dvs_latency`) into ``rows``, a figure, and
    their summary."""
    per_window = window_latencies(run, maps, step_ms)
    plane = plane_latency(run, regions, step_ms, until_ms=run.spans[0][1] + 85.0)
    for row, lat in zip(rows, per_window):
        row["latency_ms"] = lat["latency_ms"]
        row["latency_curve"] = {"t_ms": lat["t_ms"], "r": lat["r"]}
    fig, ax = plt.subplots(1, 2, figsize=(11, 3.6))
    for k, lat in enumerate(per_window):
        ax[0].plot(lat["t_ms"], lat["r"], lw=1, label=f"window {k}")
    ax[0].axhline(R_WITHIN, color="k", ls=":", lw=1)
    ax[0].axvline(85.0, color="grey", ls="--", lw=0.8)
    ax[0].set(
        xlabel="ms since the window's start",
        ylabel="r (running vs final grouping map)",
        title=f"window latency (step {step_ms:g} ms)",
        ylim=(-0.2, 1.02),
    )
    ax[0].legend(fontsize=6, ncol=2)
    ax[1].step(plane["t_ms"], np.asarray(plane["peak_on_plane"], float), where="post")
    ax[1].set(
        xlabel="ms since the first events",
        ylabel="grouping peak on the plane",
        title="plane latency (all spikes so far)",
        yticks=(0, 1),
        yticklabels=("no", "yes"),
    )
    fig.tight_layout()
    save_figure(fig, f"{stem}_latency", dpi=90, bbox_inches=None)
    plt.close(fig)
    found = [r["latency_ms"] for r in rows if r["latency_ms"] is not None]
    return {
        "step_ms": step_ms,
        "r_within": R_WITHIN,
        "plane_latency_ms": plane["latency_ms"],
        "plane": plane,
        "window_latency_median_ms": float(np.median(found)) if found else None,
        "windows_never_within": len(rows) - len(found),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", choices=("rate", "spiking"), default="rate")
    ap.add_argument("--start-ms", type=float, default=1.0)
    ap.add_argument("--backend", default=DEFAULT_BACKEND, choices=backend_names())
    ap.add_argument(
        "--instantiate",
        choices=("input", "all"),
        default=None,
        help="spiking: cells to create (the backend's default: brian2 input, fast all)",
    )
    ap.add_argument(
        "--latency-step-ms", type=float, default=2.5, help="spiking: count step of the latency measures (2.5)"
    )
    a = ap.parse_args()
    recording = dataset("events", "dvs.es")
    run_record = Run()
    windows = list(iter_windows(recording, window_ms=85, start_ms=a.start_ms))
    all_maps, run, sim_run = _maps(a.model, windows, a.backend, a.instantiate)
    rows, panels = [], []
    for w, m in zip(windows, all_maps):
        region = filled_outline(w.pos | w.neg)
        r, c = grouping_peak(m.grouping)
        o = outline_scores(m.fg_x, m.fg_y, region)
        frac, n, mean_deg, within45 = o["inward"], o["vectors"], o["mean_deg"], o["within45"]
        row = {
            "window": w.index,
            "t_start_ms": w.t_start_us / 1000,
            "t_end_ms": w.t_end_us / 1000,
            "events": int(len(w.events)),
            "plane_pixels": int(region.sum()),
            "grouping_peak": [r, c],
            "peak_on_plane": bool(region[r, c]),
            "outline_vectors": n,
            "outline_inward_fraction": frac,
            "outline_within_45": within45,
            "outline_mean_abs_deg": mean_deg,
        }
        rows.append(row)
        panels.append((w, m, region, (r, c)))
        print(
            f"window {w.index:2d} {row['t_start_ms']:6.0f}-{row['t_end_ms']:4.0f} ms  events {row['events']:6d}  "
            f"peak on plane: {row['peak_on_plane']}  inward {frac:.2f} of {n}",
            flush=True,
        )
    fig, axes = plt.subplots(len(panels), 3, figsize=(11, 3.0 * len(panels)), squeeze=False)
    for ax, (w, m, region, (r, c)) in zip(axes, panels):
        plot_maps_row(
            ax,
            event_frame_rgb(w.pos, w.neg),
            (m.fg_x, m.fg_y, m.grouping),
            f"{w.t_start_us / 1000:.0f}-{w.t_end_us / 1000:.0f} ms",
        )
        ax[2].contour(region, levels=[0.5], colors="white", linewidths=0.8)
        ax[2].plot(c, r, "w+", ms=12, mew=2)
    fig.tight_layout()
    stem = (
        "dvs_biplane"
        + ("" if a.model == "rate" else f"_{a.model}")
        + ("" if a.model == "rate" or a.backend == "brian2" else f"_{a.backend}")
    )
    save_figure(fig, stem, dpi=80, bbox_inches=None)
    plt.close(fig)
    latency = None
    if sim_run is not None and sim_run.result.spikes is not None:
        latency = _latency(sim_run, all_maps, [p[2] for p in panels], rows, a.latency_step_ms, stem)
    summary = {
        "recording": recording.name,
        "model": a.model,
        "window_ms": 85,
        "start_ms": a.start_ms,
        **run,
        "latency": latency,
        "windows": rows,
        "peak_on_plane": sum(r["peak_on_plane"] for r in rows),
        "median_inward_fraction": float(np.nanmedian([r["outline_inward_fraction"] for r in rows])),
        "run": run_record.record(),
    }
    save_json(stem, summary)
    save_markdown(stem, _markdown(summary, stem))
    print(
        f"grouping peak on the plane in {summary['peak_on_plane']} of {len(rows)} windows; "
        f"median inward fraction {summary['median_inward_fraction']:.2f}"
    )
    if latency:
        print(
            f"window latency (r >= {latency['r_within']}) median {latency['window_latency_median_ms']} ms; "
            f"plane latency {latency['plane_latency_ms']} ms"
        )


def _window_row(r, lat) -> list:
    row = [
        r["window"],
        f"{r['t_start_ms']:.0f}-{r['t_end_ms']:.0f}",
        f"{r['events']:,}",
        "yes" if r["peak_on_plane"] else "no",
        f"{r['outline_inward_fraction']:.2f} ({r['outline_vectors']})",
        f"{r['outline_within_45']:.2f}",
        f"{r['outline_mean_abs_deg']:.0f}°",
    ]
    return row + ([("never" if r["latency_ms"] is None else format(r["latency_ms"], "g"))] if lat else [])


def _markdown(s: dict, stem: str) -> list[str]:
    lat = s.get("latency")
    lines = [
        f"# {s['recording']}: {s['model']} model, {s['window_ms']} ms windows from {s['start_ms']:g} ms",
        "",
        f"{describe(s['run'])} Figures: `{stem}.png`" + (f", `{stem}_latency.png`" if lat else "") + ".",
    ]
    if "backend" in s:
        t = s["timings_s"]
        lines += [
            "",
            f"Backend {s['backend'].get('name')} ({s['instantiate']} cells: {s['cells']:,}), one network "
            f"build, {s['simulated_ms']:g} ms simulated (read-out lag {s['readout_lag_ms']:g} ms); "
            f"build {t.get('build', 0):.1f} s, run {t.get('run', 0):.1f} s "
            f"({t.get('run', 0) / len(s['windows']):.2f} s per window), total {t.get('total', 0):.1f} s.",
        ]
        st = s.get("backend_stats", {})
        if st.get("synaptic_events_total"):
            lines.append(
                f"Synaptic events {st['synaptic_events_total']:,} "
                f"({st['synaptic_events_total'] / len(s['windows']):,.0f} per window, "
                f"{1e9 * t.get('run', 0) / st['synaptic_events_total']:.1f} ns each), "
                f"spikes {st.get('spikes', 0):,}."
            )
    lines += [
        "",
        "Outline vectors (within 3 px of the filled event region's outline) are scored against the "
        "region's inward normal: inward = within 90°, and, stricter, within 45° and the mean absolute angle.",
        "",
    ]
    lines += markdown_table(
        ["window", "ms", "events", "peak on plane", "inward fraction (vectors)", "within 45°", "mean angle"]
        + (["latency r>=0.9 (ms)"] if lat else []),
        [_window_row(r, lat) for r in s["windows"]],
    )
    lines += [
        "",
        f"Grouping peak on the plane in {s['peak_on_plane']} of {len(s['windows'])} windows; median "
        f"inward fraction {s['median_inward_fraction']:.2f}.",
    ]
    if lat:
        lines += [
            "",
            f"Latency (counts in steps of {lat['step_ms']:g} ms): window latency = from a window's "
            f"start until the grouping map of the spikes since that start is within r >= {lat['r_within']} "
            f"of the window's final map: median {lat['window_latency_median_ms']} ms "
            f"({lat['windows_never_within']} windows never); plane latency = from the first events until "
            f"the grouping peak of all spikes so far sits on the plane: {lat['plane_latency_ms']} ms.",
        ]
    return lines


if __name__ == "__main__":
    main()
