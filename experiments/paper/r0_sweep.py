"""Fig. S3 of the paper: grouping radius R0 against object size, on single dark discs on a white canvas.

    python -m experiments.paper.r0_sweep [--models rate fbfg spiking] [--scheduler ADDRESS] [--workers N]
                                         [--spiking-diameters D ...] [--diameters D ...]

For each model, R0 in {2, 4, 8, 10, 12} and disc diameter from 4 to 200 px:
whether the grouping map's peak hits the disc's centre (within a quarter of
the radius, at least 3 px), the angle error on the rim (fraction within 45
degrees, mean), and SSIM / MSE of the figure-ground map against the ideal map
(angle maps and colour-wheel renderings). The spiking network runs only on
``--spiking-diameters`` (8, 16, 32, 64 px by default: its frames grow with the disc).
Writes experiments/results/r0_sweep.json / .csv, r0_sweep_summary.json and r0_sweep.png.
"""

from __future__ import annotations

import numpy as np

from experiments.common import CACHE, Run, fail, save_figure, save_json
from experiments.paper.bsds import parser, write_table

R0S = (2, 4, 8, 10, 12)
DIAMETERS = (4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 160, 200)
SPIKING_DIAMETERS = (8, 16, 32, 64)
KEYS = (
    "model",
    "r0",
    "diameter",
    "hit",
    "peak_distance_px",
    "frac_within_45",
    "mean_err_deg",
    "coverage",
    "ssim_angle",
    "mse_angle",
    "ssim_render",
    "mse_render",
)


def summary(rows):
    """Per model and R0: the diameters whose centre the grouping peak hits, and mean SSIM / MSE."""
    out = []
    for model in dict.fromkeys(r["model"] for r in rows):
        for r0 in R0S:
            sel = [r for r in rows if r["model"] == model and r["r0"] == r0]
            if sel:
                out.append(
                    {
                        "model": model,
                        "r0": r0,
                        "hit_diameters": [r["diameter"] for r in sel if r["hit"]],
                        "hit_rate": float(np.mean([r["hit"] for r in sel])),
                        "mean_ssim_angle": float(np.mean([r["ssim_angle"] for r in sel])),
                        "mean_mse_angle": float(np.mean([r["mse_angle"] for r in sel])),
                        "mean_within45": float(np.nanmean([r["frac_within_45"] for r in sel])),
                    }
                )
    return out


def figure(rows):
    from matplotlib.figure import Figure

    models = list(dict.fromkeys(r["model"] for r in rows))
    fig = Figure(figsize=(13, 3.2 * len(models)))
    axes = np.atleast_2d(fig.subplots(len(models), 3))
    for ax_row, model in zip(axes, models):
        for r0 in R0S:
            sel = sorted((r for r in rows if r["model"] == model and r["r0"] == r0), key=lambda r: r["diameter"])
            if not sel:
                continue
            d = [r["diameter"] for r in sel]
            ax_row[0].plot(d, [r["peak_distance_px"] / (r["diameter"] / 2) for r in sel], "o-", label=f"R0={r0}")
            ax_row[1].plot(d, [r["frac_within_45"] for r in sel], "o-", label=f"R0={r0}")
            ax_row[2].plot(d, [r["ssim_angle"] for r in sel], "o-", label=f"R0={r0}")
        ax_row[0].axhline(0.25, color="k", lw=0.8)
        for ax, title in zip(
            ax_row,
            (
                "grouping peak distance / radius (line: r/4; a hit is within max(3 px, r/4))",
                "rim pixels within 45 deg",
                "SSIM vs ideal map (angle maps)",
            ),
        ):
            ax.set_xscale("log")
            ax.set_title(f"{model}: {title}", fontsize=9)
            ax.set_xlabel("disc diameter (px)")
        ax_row[0].set_yscale("symlog", linthresh=0.25)
        ax_row[0].legend(fontsize=7)
    fig.tight_layout()
    return fig


def main():
    p = parser(__doc__)
    p.add_argument("--models", nargs="+", default=["rate", "fbfg", "spiking"], choices=("rate", "fbfg", "spiking"))
    p.add_argument(
        "--spiking-diameters",
        type=float,
        nargs="+",
        default=SPIKING_DIAMETERS,
        metavar="D",
        help="diameters the spiking network runs on (8 16 32 64: its frames grow with the disc)",
    )
    p.add_argument(
        "--diameters",
        type=float,
        nargs="+",
        default=DIAMETERS,
        metavar="D",
        help="disc diameters in px (4 to 200 in 13 steps)",
    )
    args = p.parse_args()
    if args.images or args.quick or args.ids:
        p.error("--images, --quick and --ids do not apply: the sweep runs on synthetic discs, not BSDS images")
    from experiments.evaluation import evaluate_disc
    from experiments.sweep import SweepTask, run_sweep
    from snn_fg.errors import SnnFgError

    run = Run()
    tasks = [
        SweepTask(f"{m}-r{r0:g}-d{d:g}", {"model": m, "r0": r0, "diameter": d})
        for m in args.models
        for r0 in R0S
        for d in args.diameters
        if m != "spiking" or d in args.spiking_diameters
    ]
    try:
        res = run_sweep(
            evaluate_disc,
            tasks,
            CACHE / "r0_sweep",
            scheduler=args.scheduler,
            workers=args.workers,
            progress=not args.no_progress,
            desc="discs",
            preload=("brian2",) if "spiking" in args.models else (),
        )
    except SnnFgError as exc:
        fail(str(exc))
    rows = [{k: res[t.key][k] for k in KEYS} for t in tasks]
    summ = summary(rows)
    written = write_table("r0_sweep", rows, run=run.record())
    written.append(save_json("r0_sweep_summary", summ))
    written.append(save_figure(figure(rows), "r0_sweep"))
    for s in summ:
        print(
            f"{s['model']:8s} R0={s['r0']:<3d} hits {s['hit_rate']:.2f} diameters {s['hit_diameters']}  "
            f"SSIM {s['mean_ssim_angle']:.3f} MSE {s['mean_mse_angle']:.4f} within45 {s['mean_within45']:.3f}"
        )
    print(f"runtime {run.seconds:.0f} s; wrote " + ", ".join(str(w) for w in written))


if __name__ == "__main__":
    main()
