"""How far the rate reference is from a fixed point after its 10 iterations.

The reference stops after ``iterations`` synchronous passes of stages 7-8.
This measures how its maps keep changing: for each of the six BSDS
reference frames (dataset ``bsds-edfg``), the figure-ground and grouping maps after 1 to 40 iterations against
the published 10-iteration maps (mean absolute angle difference, fraction of
shared edge pixels within 45 degrees, grouping Pearson r), and the same
between consecutive iterations. A network that runs in continuous time (the
spiking network) settles to its own state; it cannot be closer to the
10-iteration snapshot than the reference's own neighbouring iterations are,
unless it copies the iteration count.

Writes experiments/results/rate_iterations.{json,md,png}.
Usage: python -m experiments.validation.rate_iterations [--iterations 1 2 3 5 10 15 20 30 40]
"""

from __future__ import annotations

import argparse

import numpy as np

from experiments.common import Run, dataset, describe, markdown_table, save_figure, save_json, save_markdown
from snn_fg.models.rate.edfg import run_edfg
from snn_fg.params import ModelParams
from snn_fg.scoring.metrics import compare_frame


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--iterations", type=int, nargs="+", default=[1, 2, 3, 5, 8, 10, 12, 15, 20, 30, 40])
    a = ap.parse_args()
    frames_dir = dataset("bsds-edfg")
    rows = []
    run = Run()
    for path in sorted(frames_dir.glob("*.npz")):
        d = np.load(path)
        # the paper's 10 iterations are the reference; each count runs once
        maps = {it: run_edfg(d["pos"], d["neg"], ModelParams(iterations=it)) for it in sorted({*a.iterations, 10})}
        ref = maps[10]
        for it in a.iterations:
            m = maps[it]
            c = compare_frame(m.fg_x, m.fg_y, m.grouping, ref.fg_x, ref.fg_y, ref.grouping)
            rows.append(
                {
                    "frame": path.stem,
                    "iterations": it,
                    "angle_diff_mean_deg": c["angle_diff_mean_deg"],
                    "angle_within_45_frac": c["angle_within_45_frac"],
                    "grouping_pearson_r": c["grouping_pearson_r"],
                }
            )
            print(
                f"{path.stem} {it:3d}: mean {c['angle_diff_mean_deg']:5.1f} deg, "
                f"{100 * c['angle_within_45_frac']:5.1f} % within 45, r {c['grouping_pearson_r']:.3f}",
                flush=True,
            )
    record = {"rows": rows, "reference": "the rate model with the paper's 10 iterations", "run": run.record()}
    save_json("rate_iterations", record)
    frames = sorted({r["frame"] for r in rows})
    save_markdown(
        "rate_iterations",
        [
            "# The rate reference after n iterations, against its own 10-iteration maps",
            "",
            f"{describe(record['run'])} Per BSDS frame: mean absolute angle difference (deg) / percentage of shared "
            "edge pixels within 45 deg / grouping Pearson r, of the rate model after n iterations against the same "
            "model after the paper's 10.",
            "",
            *_table(rows, frames, a.iterations),
        ],
    )
    _figure(rows, frames, a.iterations)
    print(f"wrote experiments/results/rate_iterations.md ({record['run']['seconds']:.0f} s)")


def _table(rows, frames, its) -> list[str]:
    def cell(f, i):
        r = next(x for x in rows if x["frame"] == f and x["iterations"] == i)
        return f"{r['angle_diff_mean_deg']:.1f} / {100 * r['angle_within_45_frac']:.0f} / {r['grouping_pearson_r']:.3f}"

    return markdown_table(["frame"] + [f"n = {i}" for i in its], [[f] + [cell(f, i) for i in its] for f in frames])


def _figure(rows, frames, its):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 3.6), layout="constrained")
    ax1, ax2 = fig.subplots(1, 2)
    for f in frames:
        rs = [next(x for x in rows if x["frame"] == f and x["iterations"] == i) for i in its]
        ax1.plot(its, [100 * r["angle_within_45_frac"] for r in rs], marker="o", label=f)
        ax2.plot(its, [r["grouping_pearson_r"] for r in rs], marker="o", label=f)
    for ax, lab in ((ax1, "% of edge pixels within 45° of n = 10"), (ax2, "grouping r against n = 10")):
        ax.axvline(10, color="grey", lw=0.8, ls="--")
        ax.set_xlabel("iterations n")
        ax.set_ylabel(lab)
    ax1.axhline(90, color="red", lw=0.8, ls=":")
    ax1.legend(fontsize=7)
    fig.suptitle("The rate reference keeps changing after its 10 iterations")
    save_figure(fig, "rate_iterations", dpi=100, bbox_inches=None)


if __name__ == "__main__":
    main()
