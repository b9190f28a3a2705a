"""The window clock's strength against what a continuous run remembers.

The continuous spiking network carries its state from one window of a
recording into the next: the feedback's inhibition of the border-ownership
cells that lost (``feedback_inh_bo`` thresholds of current per 100 Hz of the
feedback half against them, about 120 from a pair at 600 Hz, decaying with
tau_inh = 10 ms) outlasts the window, and the grouping family
that won one window keeps winning the next. The window clock fires as each
window starts and inhibits every grouping cell by ``clock_inh_group``
thresholds; this sweeps that strength on two inputs:

* a synthetic recording made here (no dataset needed): a disc seen through the
  iCub's circular microsaccade, light on dark and dark on light in
  alternate 85 ms windows (radius 16 and 24 px), scored against the disc;
* ``dvs.es`` from 100 ms, 85 ms windows, scored as ``dvs_biplane`` does
  (outline of the plane's events).

Per window: the fraction of outline vectors pointing inwards (within 90
degrees of the inward normal), the fraction within 45 degrees and the mean
absolute angle to it, and how many vectors there are (the clock's cost: the grouping is silent for part of the
window), whether the grouping peak is on the figure, the light family's
share of grouping spikes, and the grouping onset: how long after a window
starts its grouping cells have fired 5 % of that window's grouping spikes.
Writes ``experiments/results/window_clock.{json,md,png}``; with ``--no-dvs``
``window_clock_synthetic.*`` instead, leaving the full run's files alone.

    python -m experiments.validation.window_clock [--gains 0,100,300,1000] [--no-dvs]
"""

from __future__ import annotations

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from experiments.common import (
    DVS_FROM_MS,
    Run,
    dataset,
    describe,
    markdown_table,
    save_figure,
    save_json,  # noqa: E402
    save_markdown,
)
from experiments.validation.dvs_history import spiking_light_share as light_share  # noqa: E402
from snn_fg.events import iter_windows  # noqa: E402
from snn_fg.frames.scenes import flipping_disc_recording  # noqa: E402
from snn_fg.models.spiking.continuous import simulate_windows, window_maps  # noqa: E402
from snn_fg.network import Gains, SpikingParams  # noqa: E402
from snn_fg.params import ModelParams  # noqa: E402
from snn_fg.scoring.metrics import grouping_peak  # noqa: E402
from snn_fg.scoring.outline import filled_outline, outline_scores  # noqa: E402

WINDOW_MS = 85.0


def flip_recording(radius: float, windows: int = 4):
    """Alternately light and dark discs, one per window; returns (figure masks, windows)."""
    scenes, rec = flipping_disc_recording(radius, windows, WINDOW_MS)
    return [s.labels > 0 for s in scenes], list(iter_windows(rec, window_ms=WINDOW_MS))


def _onset_ms(run, share: float = 0.05) -> list:
    """Per window after the first: ms from its start (plus the clock's
    delay) until its grouping cells have fired ``share`` of the spikes they
    fire before the next window starts: how long they stay (nearly) silent."""
    spikes = run.result.spikes
    t = np.sort(np.concatenate([spikes[n][1] for n in spikes if n.startswith("group_")] + [np.zeros(0)]))
    clock = run.network.by_role("clock")
    delay = run.network.outgoing(clock[0].name)[0].delay_ms if clock else 0.0
    lag = run.simulation["readout_lag_ms"]
    bounds = [a - lag + delay for a, _ in run.spans] + [run.simulation["simulated_ms"]]
    out = []
    for a, b in zip(bounds[1:-1], bounds[2:]):
        inside = t[(t > a) & (t <= b)]
        out.append(float(inside[int(share * inside.size)] - a) if inside.size else None)
    return out


def sweep_one(windows, regions, gain: float, params=None) -> dict:
    run = simulate_windows(
        windows, params=params, spiking=SpikingParams(gains=Gains(clock_inh_group=gain)), backend="fast", progress=False
    )
    rows = []
    for m, region in zip(window_maps(run), regions):
        r, c = grouping_peak(m.grouping)
        o = outline_scores(m.fg_x, m.fg_y, region)
        rows.append(
            {
                "inward_fraction": o["inward"],
                "outline_vectors": o["vectors"],
                "mean_abs_deg": o["mean_deg"],
                "within_45": o["within45"],
                "peak_on_figure": bool(region[r, c]),
                "light_share": light_share(m),
            }
        )
    return {
        "gain": gain,
        "windows": rows,
        "onset_ms": _onset_ms(run),
        "min_inward": float(np.nanmin([r["inward_fraction"] for r in rows])),
        "min_within_45": float(np.nanmin([r["within_45"] for r in rows])),
        "max_mean_abs_deg": float(np.nanmax([r["mean_abs_deg"] for r in rows])),
        "peak_on_figure": sum(r["peak_on_figure"] for r in rows),
        "vectors": int(sum(r["outline_vectors"] for r in rows)),
    }


def _sweep_row(r) -> list:
    onsets = [x for x in r["onset_ms"] if x is not None]
    return [
        f"{r['gain']:g}",
        f"{r['min_inward']:.2f}",
        f"{r['min_within_45']:.2f}",
        f"{r['max_mean_abs_deg']:.0f}°",
        ", ".join(f"{w['inward_fraction']:.2f} ({w['outline_vectors']})" for w in r["windows"]),
        ", ".join(f"{w['within_45']:.2f} / {w['mean_abs_deg']:.0f}°" for w in r["windows"]),
        ", ".join(f"{w['light_share']:.2f}" for w in r["windows"]),
        f"{r['peak_on_figure']}/{len(r['windows'])}",
        r["vectors"],
        np.median(onsets) if onsets else "-",
    ]


def _markdown(s: dict) -> list[str]:
    out = [
        "# Window clock: strength sweep",
        "",
        f"{describe(s['run'])} Default `clock_inh_group` = {s['default_gain']:g}.",
        "",
        "Per input and clock strength (thresholds of inhibitory current onto every grouping cell): the lowest "
        "fraction of outline vectors pointing inwards (within 90° of the inward normal) over the windows, the "
        "lowest fraction within 45° of it and the largest mean absolute angle to it, each window's values (and "
        "vector "
        "count), the windows whose grouping peak is on the figure, and the grouping onset: the median over "
        "windows 1.. of the time from a window's start until its grouping cells have fired 5 % of the "
        "spikes they fire before the next window starts.",
        "",
    ]
    for name, runs in s["inputs"].items():
        out += [f"## {name}", ""]
        out += markdown_table(
            [
                "clock",
                "lowest inward",
                "lowest within 45°",
                "largest mean angle",
                "per window: inward (vectors)",
                "per window: within 45° / mean angle",
                "light share",
                "peak on figure",
                "vectors",
                "grouping onset (median ms)",
            ],
            map(_sweep_row, runs),
        )
        out.append("")
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gains", default="0,100,300,1000", help="clock strengths (thresholds) to try")
    ap.add_argument("--no-dvs", action="store_true", help="only the synthetic recordings")
    a = ap.parse_args()
    gains = [float(g) for g in a.gains.split(",")]
    run = Run()
    inputs = {}
    for radius in (16, 24):
        regions, windows = flip_recording(radius)
        inputs[f"synthetic: disc r{radius}, polarity flipping every window"] = (windows, regions, ModelParams(levels=5))
    if not a.no_dvs:
        windows = list(iter_windows(dataset("events", "dvs.es"), window_ms=WINDOW_MS, start_ms=DVS_FROM_MS))
        inputs["dvs.es from 100 ms"] = (windows, [filled_outline(w.pos | w.neg) for w in windows], None)
    results = {}
    for name, (windows, regions, params) in inputs.items():
        results[name] = []
        for g in gains:
            r = sweep_one(windows, regions, g, params)
            results[name].append(r)
            print(
                f"{name}, clock {g:g}: inward "
                + " ".join(f"{w['inward_fraction']:.2f}" for w in r["windows"])
                + f"  vectors {r['vectors']}  onset {r['onset_ms']}",
                flush=True,
            )
    fig, axes = plt.subplots(2, len(results), figsize=(4.2 * len(results), 6.4), squeeze=False)
    for col, (name, runs) in enumerate(results.items()):
        for row, (key, label) in enumerate(
            (("inward_fraction", "inward fraction (< 90°)"), ("within_45", "fraction within 45° of inward"))
        ):
            ax = axes[row, col]
            for r in runs:
                ax.plot([w[key] for w in r["windows"]], "o-", ms=3, label=f"clock {r['gain']:g}")
            ax.axhline(0.6, color="k", ls=":", lw=0.8)
            ax.set(title=name, xlabel="window", ylabel=label, ylim=(0, 1.02))
            ax.title.set_fontsize(8)
            ax.legend(fontsize=7)
    fig.tight_layout()
    stem = "window_clock_synthetic" if a.no_dvs else "window_clock"  # (a partial run keeps off the full files)
    save_figure(fig, stem, dpi=90, bbox_inches=None)
    plt.close(fig)
    summary = {"default_gain": Gains().clock_inh_group, "inputs": results, "run": run.record()}
    save_json(stem, summary)
    save_markdown(stem, _markdown(summary))


if __name__ == "__main__":
    main()
