"""The spiking network against the rate model on real recordings, window by window.

    python -m experiments.validation.recording_fidelity [--windows 6] [--only dvs_biplane ...]
    python -m experiments.validation.recording_fidelity --diagnose

For each shared recording (dataset ``events``) and each network (the
default, and the compact one against the rate model on its own recipe),
the spiking network with each input coding (``events``: every event a
spike at its time; ``window``: the window's event frame held as it is
built; ``sliding``: each pixel's last polarity held for a window's length,
not cleared at window edges) against the rate model, on the pixels where both have a vector:
the share within 45 degrees (pooled over the windows, and its range per
window), the mean absolute angle difference, the grouping r, and the share
of the rate model's vectors the spiking map has (coverage). Beside them the
rate model against itself at twice its iterations, and on ``dvs.es`` the
share of the plane's outline vectors that point inwards (the truth there).
Writes ``recording_fidelity.{json,md,png}`` (the figure: one window of each
recording, each model side by side).

``--diagnose`` (``dvs.es`` only) measures why the two part: the network
handed each window's event frame as a still input for 60 to 400 ms
(how long it needs to settle on a frame), and the rate model at 1 to 5
iterations against its 10th (how many of its iterations that is). Writes
``recording_diagnosis.{json,md}``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from experiments.common import Run, dataset, describe, markdown_table, save_figure, save_results

#: name -> (file, window ms, start ms, sensor size or None); after each recording's start-up burst
RECORDINGS = {
    "dvs_biplane": ("dvs.es", 85.0, 100.0, None),
    "person": ("tonic_sample_person.aedat4", 85.0, 0.0, None),
    "spinner": ("expelliarmus_evt2_spinner.raw", 25.0, 0.0, (640, 480)),  # (5 ms windows: no spiking vector)
}
NETWORKS = ("default", "compact")
CODINGS = ("events", "window", "sliding")


def windows_of(name: str, n: int):
    from snn_fg.events import iter_windows

    file, window_ms, start_ms, size = RECORDINGS[name]
    options = {"sensor_size": size} if size else {}
    return list(iter_windows(dataset("events", file), window_ms=window_ms, start_ms=start_ms, max_windows=n, **options))


def rate_maps(wins, network: str, iterations: int | None = None):
    from snn_fg.models import get_model
    from snn_fg.network.recipes import RECIPES

    params = RECIPES[network].params
    if iterations is not None:
        params = params.replace(iterations=iterations)
    model = get_model("rate", params)
    return [model.run_window(w) for w in wins]


def spiking_maps(wins, network: str, coding: str):
    from snn_fg.models.spiking import run_spiking_windows

    t = time.perf_counter()
    maps = run_spiking_windows(wins, network=network, input_coding=coding, progress=False)
    return maps, (time.perf_counter() - t) / len(wins)


def scores(maps, ref) -> dict:
    """Pooled and per-window agreement of ``maps`` with ``ref``, on the pixels where both have a vector."""
    from snn_fg.scoring.metrics import angle_difference_deg, pearson

    within, shared, absdiff, cover_num, cover_den, per_window, rs = 0, 0, 0.0, 0, 0, [], []
    for m, r in zip(maps, ref):
        has_m, has_r = np.hypot(m.fg_x, m.fg_y) > 0, np.hypot(r.fg_x, r.fg_y) > 0
        both = has_m & has_r
        d = angle_difference_deg(m.fg_x, m.fg_y, r.fg_x, r.fg_y)[both]
        within += int((d <= 45).sum())
        shared += d.size
        absdiff += float(d.sum())
        cover_num += int(both.sum())
        cover_den += int(has_r.sum())
        per_window.append(float(np.mean(d <= 45)) if d.size else float("nan"))
        rs.append(pearson(m.grouping, r.grouping))
    return {
        "within_45": within / max(shared, 1),
        "within_45_per_window": per_window,
        "mean_abs_deg": absdiff / max(shared, 1),
        "grouping_r_mean": float(np.nanmean(rs)) if np.isfinite(rs).any() else float("nan"),
        "grouping_r_min": float(np.nanmin(rs)) if np.isfinite(rs).any() else float("nan"),
        "coverage": cover_num / max(cover_den, 1),
        "pixels": shared,
    }


def inward(maps, wins) -> list[float]:
    """The share of the outline vectors pointing into the window's filled event region (dvs.es: the plane)."""
    from snn_fg.scoring.outline import filled_outline, outline_scores

    return [outline_scores(m.fg_x, m.fg_y, filled_outline(w.pos | w.neg))["inward"] for m, w in zip(maps, wins)]


def measure(name: str, n: int) -> tuple[dict, dict]:
    wins = windows_of(name, n)
    out, shown = {"windows": len(wins), "rows": []}, {}
    for network in NETWORKS:
        ref = rate_maps(wins, network)
        row = {"network": network, "map": "rate, 10 against 20 iterations"}
        row.update(scores(ref, rate_maps(wins, network, 20)))
        if name == "dvs_biplane":
            row["inward"] = inward(ref, wins)
        out["rows"].append(row)
        shown[(network, "rate")] = ref
        for coding in CODINGS:
            maps, per_window_s = spiking_maps(wins, network, coding)
            row = {"network": network, "map": f"spiking, {coding} coding", "s_per_window": per_window_s}
            row.update(scores(maps, ref))
            if name == "dvs_biplane":
                row["inward"] = inward(maps, wins)
            out["rows"].append(row)
            shown[(network, coding)] = maps
            print(f"{name} {network} {coding}: {row['within_45']:.3f} within 45 deg", flush=True)
    return out, {"wins": wins, "maps": shown}


def score_cells(r: dict) -> list[str]:
    """A table row's scores (:func:`scores`, ``inward``, ``s_per_window``) as text."""
    per = r["within_45_per_window"]
    return [
        f"{r['within_45']:.1%} ({np.nanmin(per):.0%}-{np.nanmax(per):.0%})",
        f"{r['mean_abs_deg']:.1f}",
        f"{r['grouping_r_mean']:.3f} (min {r['grouping_r_min']:.3f})",
        f"{r['coverage']:.1%}",
        f"{np.median(r['inward']):.2f}" if "inward" in r else "",
        f"{r['s_per_window']:.2f}" if "s_per_window" in r else "",
    ]


def table_lines(results: dict) -> list[str]:
    lines = []
    for name, res in results.items():
        rows = []
        for r in res["rows"]:
            inw = f"{np.median(r['inward']):.2f}" if "inward" in r else ""
            if not r["pixels"]:  # (no window has a vector: the windows are shorter than the network's answer)
                timing = f"{r['s_per_window']:.2f}" if "s_per_window" in r else ""
                rows.append([r["network"], r["map"], "no vector in any window", "", "", "0 %", inw, timing])
                continue
            rows.append([r["network"], r["map"], *score_cells(r)])
        file, window_ms, start_ms, _ = RECORDINGS[name]
        lines += [
            f"## {name} (`{file}`, {res['windows']} windows of {window_ms:g} ms from {start_ms:g} ms)",
            "",
            *markdown_table(
                [
                    "network",
                    "map, against the rate model on the same recipe",
                    "within 45° (pooled; per window)",
                    "mean abs °",
                    "grouping r",
                    "coverage",
                    "plane outline inward (median)",
                    "s per window",
                ],
                rows,
            ),
            "",
        ]
    return lines


def figure(shown: dict):
    import matplotlib

    matplotlib.use("Agg")  # (an experiment script, never imported by the package)
    import matplotlib.pyplot as plt

    from snn_fg.results.figures import event_frame_rgb, fg_rgb

    names = list(shown)
    cols = ("events", "rate model", *(f"spiking, {c} coding" for c in CODINGS))
    fig, axes = plt.subplots(len(names), len(cols), figsize=(4 * len(cols), 3.4 * len(names)), squeeze=False)
    for row, name in zip(axes, names):
        wins, maps = shown[name]["wins"], shown[name]["maps"]
        k = min(3, len(wins) - 1)
        w = wins[k]
        panels = [
            event_frame_rgb(w.pos, w.neg),
            *(
                fg_rgb(m[k].fg_x, m[k].fg_y)
                for m in (maps[("default", "rate")], *(maps[("default", c)] for c in CODINGS))
            ),
        ]
        show_row(row, f"{name} window {k}", zip(cols, panels))
    fig.tight_layout()
    return fig


def show_row(axes, label: str, panels) -> None:
    """One figure row: each ``(title, image)`` of ``panels`` on its axes, titled ``label: title``."""
    for ax, (title, img) in zip(axes, panels):
        ax.imshow(img)
        ax.set_title(f"{label}: {title}", fontsize=9)
        ax.set_xlabel("x (px)")
        ax.set_ylabel("y (px)")


def frame_events(w, t_us) -> np.ndarray:
    """Window ``w``'s event frame as events: one per pixel of the frame, with its polarity, at ``t_us``."""
    ys, xs = np.nonzero(w.pos | w.neg)
    ev = np.zeros(xs.size, dtype=w.events.dtype)
    ev["x"], ev["y"], ev["t"], ev["p"] = xs, ys, t_us, w.pos[ys, xs] != 0
    return ev


def diagnose() -> tuple[dict, list[str]]:
    from snn_fg.models.spiking import run_spiking
    from snn_fg.scoring.metrics import agreement

    wins = windows_of("dvs_biplane", 6)
    ref = rate_maps(wins, "default")
    settle = []
    for duration, count_from in ((60, 20), (105, 20), (200, 100), (400, 200)):
        rows = [
            agreement(run_spiking(pos=w.pos, neg=w.neg, duration_ms=duration, settle_ms=count_from, progress=False), r)
            for w, r in zip(wins, ref)
        ]
        settle.append(
            {
                "duration_ms": duration,
                "count_from_ms": count_from,
                "within_45": [r["within_45"] for r in rows],
                "grouping_r": [r["grouping_r"] for r in rows],
            }
        )
        print(f"frame for {duration} ms: {np.mean(settle[-1]['within_45']):.3f}", flush=True)
    # the window's whole frame from the window's start on: what a held input could at best give in the
    # recording's own time (it knows each pixel's last event before it happens, so no causal input can)
    from dataclasses import replace

    from snn_fg.models.spiking import run_spiking_windows

    ahead = [replace(w, events=frame_events(w, w.t_start_us)) for w in wins]
    foresight = {}
    for name, runs in (("held as it is built (causal)", wins), ("whole from the window's start (not causal)", ahead)):
        maps = run_spiking_windows(runs, input_coding="window", progress=False)
        foresight[name] = [agreement(m, r)["within_45"] for m, r in zip(maps, ref)]
    iterations = []
    for its in (1, 2, 3, 5):
        rows = [agreement(m, r) for m, r in zip(rate_maps(wins, "default", its), ref)]
        iterations.append({"iterations": its, "within_45": [r["within_45"] for r in rows]})
    lines = [
        "## The network on each window's event frame, presented as a still input",
        "",
        *markdown_table(
            ["presented for", "counted over", "within 45° of the rate model, per window", "mean", "grouping r (mean)"],
            [
                [
                    f"{s['duration_ms']} ms",
                    f"{s['count_from_ms']}-{s['duration_ms']} ms",
                    " ".join(f"{x:.2f}" for x in s["within_45"]),
                    f"{np.mean(s['within_45']):.3f}",
                    f"{np.mean(s['grouping_r']):.3f}",
                ]
                for s in settle
            ],
        ),
        "",
        "## The window coding with the whole frame known at the window's start",
        "",
        *markdown_table(
            ["the window's event frame", "within 45° of the rate model, per window", "mean"],
            [[k, " ".join(f"{x:.2f}" for x in v), f"{np.mean(v):.3f}"] for k, v in foresight.items()],
        ),
        "",
        "## The rate model at fewer iterations, against its 10th",
        "",
        *markdown_table(
            ["iterations", "within 45° of the 10th, per window", "mean"],
            [
                [i["iterations"], " ".join(f"{x:.2f}" for x in i["within_45"]), f"{np.mean(i['within_45']):.3f}"]
                for i in iterations
            ],
        ),
        "",
    ]
    return {"settle": settle, "foresight": foresight, "iterations": iterations}, lines


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--windows", type=int, default=6, help="windows per recording (6)")
    ap.add_argument("--only", nargs="+", choices=sorted(RECORDINGS), default=None)
    ap.add_argument("--diagnose", action="store_true", help="why the two part on dvs.es (see the module docstring)")
    a = ap.parse_args()
    run = Run()
    if a.diagnose:
        record, lines = diagnose()
        head = ["# Why the spiking network and the rate model part on dvs.es", "", describe(run.record()), ""]
        save_results("recording_diagnosis", {"run": run.record(), **record}, head + lines)
        return
    results, shown = {}, {}
    for name in a.only or RECORDINGS:
        results[name], shown[name] = measure(name, a.windows)
    head = [
        "# The spiking network against the rate model on recordings",
        "",
        describe(run.record()),
        "",
        "Pixels where both maps have a vector; coverage: the share of the rate model's vectors that the",
        "map has. The rate row is the rate model against itself at 20 iterations (its own stability).",
        "Plane outline inward: the share of the outline vectors of the window's filled event region",
        "that point into it (dvs.es, where the region is the plane: the truth).",
        "",
    ]
    save_results("recording_fidelity", {"run": run.record(), "recordings": results}, head + table_lines(results))
    save_figure(figure(shown), "recording_fidelity")


if __name__ == "__main__":
    main()
