"""Fig. 6 of the paper: SSIM (11 x 11 window) and MSE, mean and SD over images, of
event-driven vs frame-based (EDvsFB), frame-based vs ground truth (FBvsGT) and
event-driven vs ground truth (EDvsGT), with the labeller-vs-labeller ceiling.

    python -m experiments.paper.fig6 [--quick | --images N] [--scheduler ADDRESS] [--workers N]

ED: the rate model on ``--motion paper`` events at C = 0.10; FB: the
frame-based model with the Gaussian-derivative operator and with CORF; GT:
labeller 1's directions (GT2: labeller 2's). Each comparison is computed two
ways: on **angle maps** (direction in turns where a map has a vector, 0
elsewhere) and on the **rendered colour-wheel images** (unit vectors, black
background), which is what the authors compared. Shares the per-image cache of
table1. Writes experiments/results/fig6.json / .csv and fig6.png (fewer than all the
images: fig6_<N>images.*; --ids: fig6_ids-<ids>.*).
"""

from __future__ import annotations

import numpy as np

from experiments.common import Run, save_figure
from experiments.paper.bsds import evaluate, parser, subset_name, write_table

#: (label, pair key of experiments.evaluation.evaluate_image)
COMPARISONS = (
    ("EDvsFB", "ED-rate|FB-fbfg"),
    ("EDvsFB-corf", "ED-rate|FB-fbfg-corf"),
    ("FBvsGT", "FB-fbfg|GT"),
    ("FB-corfvsGT", "FB-fbfg-corf|GT"),
    ("EDvsGT", "ED-rate|GT"),
    ("GTvsGT (ceiling)", "GT|GT2"),
)
METRICS = ("ssim_angle", "mse_angle", "ssim_render", "mse_render")


def rows_of(results: dict) -> list[dict]:
    rows = []
    for label, key in COMPARISONS:
        for metric in METRICS:
            v = np.array([r["fig6"][key][metric] for r in results.values() if key in r.get("fig6", {})])
            rows.append(
                {
                    "comparison": label,
                    "metric": metric,
                    "on": "angle maps" if "angle" in metric else "rendered images",
                    "mean": float(v.mean()) if v.size else float("nan"),
                    "sd": float(v.std(ddof=1)) if v.size > 1 else float("nan"),
                    "n_images": int(v.size),
                }
            )
    return rows


def figure(rows):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 6.5))
    axes = fig.subplots(2, 2)
    labels = [c for c, _ in COMPARISONS]
    for ax, metric in zip(axes.flat, ("ssim_angle", "mse_angle", "ssim_render", "mse_render")):
        sel = {r["comparison"]: r for r in rows if r["metric"] == metric}
        ax.bar(
            range(len(labels)),
            [sel[c]["mean"] for c in labels],
            yerr=[sel[c]["sd"] for c in labels],
            color=["tab:blue", "tab:cyan", "tab:green", "tab:olive", "tab:orange", "tab:gray"],
            capsize=4,
        )
        ax.set_xticks(range(len(labels)), labels, rotation=20, fontsize=8)
        kind = "angle maps" if "angle" in metric else "rendered colour-wheel images"
        ax.set_title(f"{metric.split('_')[0].upper()} on {kind}", fontsize=10)
    fig.tight_layout()
    return fig


def main():
    args = parser(__doc__).parse_args()
    run = Run()
    results = evaluate(args)
    rows = rows_of(results)
    stem = subset_name("fig6", args, len(results))  # a subset never overwrites the full-set fig6.*
    written = write_table(stem, rows, run=run.record()) + [save_figure(figure(rows), stem)]
    for r in rows:
        print(f"{r['comparison']:18s} {r['metric']:12s} {r['mean']:.4f} +- {r['sd']:.4f}  (n={r['n_images']})")
    print(f"runtime {run.seconds:.0f} s; wrote " + ", ".join(str(w) for w in written))


if __name__ == "__main__":
    main()
