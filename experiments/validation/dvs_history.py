"""How much a window's spiking maps depend on what the network saw before it.

The continuous spiking network (one build, each event a spike in its 0.5 ms
step: the default network's ``events`` input coding, docs/spiking-network.md,
"How events become input spikes") carries its state from one window into the
next; the rate model starts each window afresh. This runs one window of ``dvs.es`` (default: window 8 from
100 ms, the one where the continuous run of ``dvs_biplane`` misses the
inward-vector goal) as the last window of continuous runs that start
0, 1, 3, ... windows earlier, and the rate model on the same window. For
each it reports the fraction of outline vectors pointing inwards, whether
the grouping peak is on the plane, and how far the peak is from the
centroid of this window's plane and of the previous window's plane (a peak
that stays near the previous position is the network's memory), and the
share of the grouping activity in the light family (L) rather than the dark
one (D), over all levels: the families compete winner-take-all.

The rate model is also run over every window both ways: afresh (the paper's
model) and continued from the previous window's state
(``run_edfg_state(..., previous=..., carry=c)``, all of its grouping maps or
the fraction ``c`` of them), which is what a network that is never reset, or
one that forgets part of its state between windows, does with the model's
dynamics.

The spiking runs leave the network's window clock silent by default
(``--window-clock off``): this studies what the network itself remembers,
which the clock is there to wipe (``experiments.validation.window_clock``).

Writes ``experiments/results/dvs_history.{json,md,png}``.

    python -m experiments.validation.dvs_history [--window 8] [--before 0,1,3,8] [--backend fast] [--carry 1,0.1]
                                                 [--each-alone] [--window-clock off]
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
    fail,
    markdown_table,
    save_figure,  # noqa: E402
    save_results,
)
from snn_fg.backends import DEFAULT_BACKEND, backend_names  # noqa: E402
from snn_fg.events import iter_windows  # noqa: E402
from snn_fg.models.rate.edfg import run_edfg_state  # noqa: E402
from snn_fg.results.figures import event_frame_rgb, plot_maps_row  # noqa: E402
from snn_fg.scoring.metrics import grouping_peak  # noqa: E402
from snn_fg.scoring.outline import filled_outline, inward_score  # noqa: E402


def _centroid(region) -> np.ndarray:
    return np.argwhere(region).mean(axis=0)


def _row(label, maps, region, previous, light_share) -> dict:
    r, c = grouping_peak(maps.grouping)
    frac, n = inward_score(maps.fg_x, maps.fg_y, region)
    peak = np.array([r, c], float)
    return {
        "run": label,
        "peak": [r, c],
        "peak_on_plane": bool(region[r, c]),
        "outline_vectors": n,
        "inward_fraction": frac,
        "peak_to_plane_px": float(np.hypot(*(peak - _centroid(region)))),
        "peak_to_previous_plane_px": None if previous is None else float(np.hypot(*(peak - _centroid(previous)))),
        "light_share": light_share,
    }


def _rate_light_share(state) -> float:
    """GL / (GL + GD), summed over the levels' grouping maps."""
    gl = sum(float(lv.interior(lv.g_l).sum()) for lv in state.engine.levels)
    gd = sum(float(lv.interior(lv.g_d).sum()) for lv in state.engine.levels)
    return gl / (gl + gd) if gl + gd > 0 else float("nan")


def spiking_light_share(maps) -> float:
    """Spikes of the light family's grouping cells over both families', all
    levels, in the window's read-out span (the counts stored with its maps)."""
    counts = {f: sum(int(c.sum()) for k, c in maps.extra.items() if k.startswith(f"spikes_group_{f}_")) for f in "LD"}
    total = counts["L"] + counts["D"]
    return counts["L"] / total if total else float("nan")


def _rate_over_recording(windows, carries) -> list[dict]:
    """Every window's inward fraction and light share, afresh and continued
    with each fraction of the previous window's grouping maps in ``carries``."""
    rows, previous = [], {c: None for c in carries}
    for k, w in enumerate(windows):
        region = filled_outline(w.pos | w.neg)
        runs = {"fresh": run_edfg_state(w.pos, w.neg)}
        for c in carries:
            previous[c] = run_edfg_state(w.pos, w.neg, previous=previous[c], carry=c)
            runs[f"carry {c:g}"] = previous[c]
        row = {
            "window": k,
            "t_ms": [w.t_start_us / 1000, w.t_end_us / 1000],
            "inward_fraction": {name: inward_score(st.fg_x, st.fg_y, region)[0] for name, st in runs.items()},
            "light_share": {name: _rate_light_share(st) for name, st in runs.items()},
        }
        rows.append(row)
        print(
            f"rate, window {k}: inward " + ", ".join(f"{v:.2f} {n}" for n, v in row["inward_fraction"].items()),
            flush=True,
        )
    return rows


def _spiking_each_alone(windows, backend, run_windows) -> list[dict]:
    """Every window simulated on its own, from rest: what a network that
    forgot everything between windows would give."""
    rows = []
    for k, w in enumerate(windows):
        m = run_windows([w], backend=backend, progress=False)[-1]
        rows.append(
            {"window": k, **_row(f"window {k} alone", m, filled_outline(w.pos | w.neg), None, spiking_light_share(m))}
        )
        print(f"spiking, window {k} alone: inward {rows[-1]['inward_fraction']:.2f}", flush=True)
    return rows


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--window", type=int, default=8, help="the window studied, counted from --start-ms (8)")
    ap.add_argument("--start-ms", type=float, default=DVS_FROM_MS)
    ap.add_argument(
        "--before",
        default="0,1,3,8",
        help="how many windows each continuous run simulates before the studied one (0,1,3,8)",
    )
    ap.add_argument("--backend", default=DEFAULT_BACKEND, choices=backend_names())
    ap.add_argument(
        "--each-alone",
        action="store_true",
        help="also simulate every window of the recording on its own, from rest (about 7 s each)",
    )
    ap.add_argument(
        "--carry",
        default="1,0.1",
        help="rate model over the recording: fractions of the previous window's grouping maps each "
        "window starts from (1,0.1; afresh is always run)",
    )
    ap.add_argument(
        "--window-clock",
        choices=("on", "off"),
        default="off",
        help="fire the network's window clock as each window starts (off: the network's own memory)",
    )
    return ap


def _figure(w, panels, rows, region, previous):
    """One row per map studied, the window's outline (white) and the previous window's (cyan) on the grouping."""
    fig, axes = plt.subplots(len(panels), 3, figsize=(11, 3.0 * len(panels)), squeeze=False)
    for ax, (label, m), row in zip(axes, panels, rows):
        plot_maps_row(
            ax,
            event_frame_rgb(w.pos, w.neg),
            (m.fg_x, m.fg_y, m.grouping),
            f"{w.t_start_us / 1000:.0f}-{w.t_end_us / 1000:.0f} ms; {label}",
        )
        ax[2].contour(region, levels=[0.5], colors="white", linewidths=0.8)
        if previous is not None:
            ax[2].contour(previous, levels=[0.5], colors="cyan", linewidths=0.6, linestyles="dashed")
        ax[2].plot(row["peak"][1], row["peak"][0], "w+", ms=12, mew=2)
        ax[1].set_xlabel(f"x (px); inward {row['inward_fraction']:.2f}", fontsize=7)
    fig.tight_layout()
    save_figure(fig, "dvs_history", dpi=80, bbox_inches=None)
    plt.close(fig)


def main():
    a = _parser().parse_args()
    rec = dataset("events", "dvs.es")
    from functools import partial

    from snn_fg.models.spiking import continuous

    run_windows = partial(continuous.run_spiking_windows, window_clock=a.window_clock == "on")

    run = Run()
    windows = list(iter_windows(rec, window_ms=85, start_ms=a.start_ms))
    if not 0 <= a.window < len(windows):
        fail(f"--window {a.window}: the recording has windows 0-{len(windows) - 1} from {a.start_ms:g} ms")
    befores = sorted({min(int(b), a.window) for b in a.before.split(",")})
    w = windows[a.window]
    region = filled_outline(w.pos | w.neg)
    previous = filled_outline(windows[a.window - 1].pos | windows[a.window - 1].neg) if a.window else None
    rows, panels = [], []
    rate = run_edfg_state(w.pos, w.neg)
    rows.append(_row("rate model, afresh (no history)", rate, region, previous, _rate_light_share(rate)))
    panels.append(("rate model", rate))
    for b in befores:
        first = a.window - b
        maps = run_windows(windows[first : a.window + 1], backend=a.backend, progress=False)[-1]
        label = f"spiking, from window {first} ({b} before)"
        rows.append(
            {
                **_row(label, maps, region, previous, spiking_light_share(maps)),
                "first_window": first,
                "simulated_ms": maps.params["simulation"]["simulated_ms"],
            }
        )
        panels.append((label, maps))
        print(
            f"{label}: inward {rows[-1]['inward_fraction']:.2f} of {rows[-1]['outline_vectors']}, light share "
            f"{rows[-1]['light_share']:.2f}",
            flush=True,
        )
    recording = _rate_over_recording(windows, [float(c) for c in a.carry.split(",")])
    alone = _spiking_each_alone(windows, a.backend, run_windows) if a.each_alone else None
    _figure(w, panels, rows, region, previous)
    summary = {
        "recording": rec.name,
        "window": a.window,
        "start_ms": a.start_ms,
        "window_ms": 85,
        "t_ms": [w.t_start_us / 1000, w.t_end_us / 1000],
        "backend": a.backend,
        "rows": rows,
        "rate_over_recording": recording,
        "spiking_each_window_alone": alone,
        "run": run.record(),
    }
    save_results("dvs_history", summary, _markdown(summary))


def _markdown(s) -> list[str]:
    rows, recording, alone = s["rows"], s["rate_over_recording"], s["spiking_each_window_alone"]
    lines = [
        f"# dvs.es window {s['window']} ({s['t_ms'][0]:.0f}-{s['t_ms'][1]:.0f} ms): "
        "what the continuous network carries in",
        "",
        f"{describe(s['run'])} Figure: `dvs_history.png` (white: this window's plane outline; dashed cyan: the "
        "previous window's).",
        "",
    ]
    lines += markdown_table(
        [
            "run",
            "inward fraction (vectors)",
            "light share of grouping",
            "peak on plane",
            "peak to this plane's centroid (px)",
            "peak to the previous plane's centroid (px)",
        ],
        [
            [
                r["run"],
                f"{r['inward_fraction']:.2f} ({r['outline_vectors']})",
                f"{r['light_share']:.2f}",
                "yes" if r["peak_on_plane"] else "no",
                f"{r['peak_to_plane_px']:.0f}",
                "" if r["peak_to_previous_plane_px"] is None else f"{r['peak_to_previous_plane_px']:.0f}",
            ]
            for r in rows
        ],
    )
    names = list(recording[0]["inward_fraction"])
    lines += [
        "",
        "The rate model over every window: afresh (each window from no feedback, the paper's model) and "
        "continued (each window from the previous window's grouping state, `run_edfg_state(..., "
        "previous=..., carry=c)`, with the fraction c of its grouping maps). Inward fraction / light share "
        "of the grouping.",
        "",
    ]
    lines += markdown_table(
        ["window", "ms", *names],
        [
            [
                r["window"],
                f"{r['t_ms'][0]:.0f}-{r['t_ms'][1]:.0f}",
                *(f"{r['inward_fraction'][n]:.2f} / {r['light_share'][n]:.2f}" for n in names),
            ]
            for r in recording
        ]
        + [["lowest inward", "", *(f"{min(r['inward_fraction'][n] for r in recording):.2f}" for n in names)]],
    )
    if alone:
        lines += [
            "",
            "The spiking network with every window simulated on its own, from rest (what a network "
            "reset between windows would give; `--each-alone`):",
            "",
        ]
        lines += markdown_table(
            ["window", "inward", "light share", "peak on plane"],
            [
                [
                    r["window"],
                    f"{r['inward_fraction']:.2f}",
                    f"{r['light_share']:.2f}",
                    "yes" if r["peak_on_plane"] else "no",
                ]
                for r in alone
            ]
            + [
                [
                    "lowest inward",
                    f"{min(r['inward_fraction'] for r in alone):.2f}",
                    "",
                    f"{sum(r['peak_on_plane'] for r in alone)} of {len(alone)}",
                ]
            ],
        )
    return lines


if __name__ == "__main__":
    main()
