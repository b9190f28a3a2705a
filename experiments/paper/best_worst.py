"""Figs. 4-5 of the paper: the images where the event-driven model agrees best and worst
with the human labels, shown as image, ground truth, frame-based and event-driven maps, and error.

    python -m experiments.paper.best_worst [--quick | --images N] [--scheduler ADDRESS] [--workers N] [--show K]

Ranks the images by the rate model's mean absolute angle error (``--motion
paper`` events, C = 0.10) against both labellers, among images with at least
MIN_PIXELS scored pixels; shows the K best and K worst, and the paper's own
picks (best 135069, 105019, 118035; worst 8143) when they are among the
evaluated images. Shares the per-image cache of table1.
Writes experiments/results/best_worst.json / .csv and best_worst.png (fewer than all
the images: best_worst_<N>images.*; --ids: best_worst_ids-<ids>.*).
"""

from __future__ import annotations

import numpy as np

from experiments.common import Run, dataset, save_figure
from experiments.paper.bsds import evaluate, parser, subset_name, write_table

MIN_PIXELS = 200
PAPER_BEST = ("135069", "105019", "118035")
PAPER_WORST = ("8143",)


def ranking(results: dict) -> list[dict]:
    from snn_fg.scoring.label_scores import pool_stats

    rows = []
    for image_id, res in results.items():
        by = {(u["model"], u["motion"], u["threshold"]): u for u in res["units"]}
        ed = pool_stats([by[("rate", "paper", 0.10)]])
        fb = pool_stats([by[("fbfg", "image", None)]])
        rows.append(
            {
                "image_id": image_id,
                "ed_mean_abs_deg": ed["mean_abs_deg"],
                "ed_within45": ed["within45"],
                "ed_pixels": ed["n_pixels"],
                "fb_mean_abs_deg": fb["mean_abs_deg"],
                "fb_within45": fb["within45"],
                "fb_pixels": fb["n_pixels"],
            }
        )
    rows = [r for r in rows if r["ed_pixels"] >= MIN_PIXELS]
    rows.sort(key=lambda r: r["ed_mean_abs_deg"])
    for rank, r in enumerate(rows, 1):
        r["rank"] = rank
    return rows


def _panels(image_id):
    """Image, GT field, FB field, ED field and ED's absolute error at the GT pixels."""
    from snn_fg.events import image_to_frame
    from snn_fg.events.images import read_image
    from snn_fg.models.rate.edfg import run_edfg
    from snn_fg.models.rate.fbfg import run_fbfg
    from snn_fg.scoring.groundtruth import boundary_directions, load_bsds_fg, signed_angle_deg

    gt = load_bsds_fg(dataset("bsds-fg"), image_id)
    tx, ty, valid = boundary_directions(gt.fg[0])
    image = read_image(gt.image_path, grey=False)
    fb = run_fbfg(image)
    ed = run_edfg(*image_to_frame(gt.image_path, threshold=0.10, motion="paper"))
    err = np.full(valid.shape, np.nan)
    has = valid & (ed.magnitude > 0)
    err[has] = np.abs(signed_angle_deg(ed.fg_x[has], ed.fg_y[has], tx[has], ty[has]))
    return image, (tx, ty), (fb.fg_x, fb.fg_y), (ed.fg_x, ed.fg_y), err


def _unit(field):
    """The vector field ``(x, y)`` scaled to unit length where it is not zero."""
    length = np.hypot(*field)
    return tuple(np.sign(length) * c / np.maximum(length, 1e-12) for c in field)


def figure(picks):
    from matplotlib.figure import Figure

    from snn_fg.results.figures import fg_rgb

    fig = Figure(figsize=(16, 2.6 * len(picks)))
    axes = np.atleast_2d(fig.subplots(len(picks), 5))
    for ax_row, (label, row) in zip(axes, picks):
        image, gt, fb, ed, err = _panels(row["image_id"])
        ax_row[0].imshow(image)
        for ax, field in zip(ax_row[1:4], (gt, fb, ed)):
            ax.imshow(fg_rgb(*_unit(field)))
        im = ax_row[4].imshow(err, cmap="inferno_r", vmin=0, vmax=180)
        fig.colorbar(im, ax=ax_row[4], fraction=0.035, label="|error| (deg)")
        ax_row[0].set_ylabel(f"{label}\n#{row['image_id']}", fontsize=9)
        for ax, title in zip(
            ax_row,
            (
                "image",
                "ground truth (labeller 1)",
                f"FB: mean |err| {row['fb_mean_abs_deg']:.0f} deg",
                f"ED: mean |err| {row['ed_mean_abs_deg']:.0f} deg, {100 * row['ed_within45']:.0f} % <= 45",
                "ED error at GT pixels",
            ),
        ):
            ax.set_title(title, fontsize=9)
            ax.set_xticks([])
            ax.set_yticks([])
    fig.tight_layout()
    return fig


def main():
    p = parser(__doc__)
    p.add_argument("--show", type=int, default=3, metavar="K", help="best and worst images to show (3)")
    args = p.parse_args()
    run = Run()
    results = evaluate(args)
    stem = subset_name("best_worst", args, len(results))  # a subset never overwrites the full-set files
    rows = ranking(results)
    k = min(args.show, len(rows) // 2 or 1)
    picks = [("best", r) for r in rows[:k]] + [("worst", r) for r in rows[-k:][::-1]]
    by_id = {r["image_id"]: r for r in rows}
    picks += [
        (f"paper's {kind}", by_id[i])
        for kind, ids in (("best", PAPER_BEST), ("worst", PAPER_WORST))
        for i in ids
        if i in by_id and all(i != r["image_id"] for _, r in picks)
    ]
    written = write_table(stem, rows, run=run.record()) + [save_figure(figure(picks), stem)]
    for label, r in picks:
        print(
            f"{label:14s} #{r['image_id']:>7s} rank {r['rank']:3d}/{len(rows)}  ED mean|err| "
            f"{r['ed_mean_abs_deg']:.1f} ({r['ed_within45']:.2f} <= 45)  FB {r['fb_mean_abs_deg']:.1f}"
        )
    print(f"runtime {run.seconds:.0f} s; wrote " + ", ".join(str(w) for w in written))


if __name__ == "__main__":
    main()
