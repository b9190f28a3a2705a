"""Table 1 of the paper: angle error of the figure-ground maps against human labels, per
event-simulator contrast threshold, for every model.

    python experiments/table1.py [--quick | --images N] [--scheduler ADDRESS] [--workers N]
                                 [--spiking-images N --spiking-threshold C]

Events come from ``--motion paper`` at thresholds 0.10-0.40 (and from the
built-in ``shift4`` at 0.10, for comparison); the frame-based model (both edge
operators) sees the image. Every map is scored at the figure pixels of both
labellers (pooled), with the paper's mean *signed* error beside the mean
absolute error, the median and the fraction within 45 degrees. The spiking
network runs on its own small subset (``--spiking-images``), one image at a time,
beside the rate model on the same images (table1_extra.json); this shares its
cache with spiking_groundtruth.py.

Writes experiments/results/table1.json / .csv (rows: model, threshold,
mean_signed_deg, mean_abs_deg, median_abs_deg, within45, n_images, n_pixels),
table1_extra.json (shift4 rows, the human ceiling, the authors' stored outputs
scored the same way) and table1.png.
"""
from __future__ import annotations

import json
import time

import numpy as np
from bsds_sweep import BSDS_EDFG, BSDS_FG, RESULTS, evaluate, parser, save_figure, write_table

#: The paper's best Table 1 number (mean signed error at threshold 0.10), degrees.
PAPER_BEST_DEG = 5.29
ROW_KEYS = ("mean_signed_deg", "mean_abs_deg", "median_abs_deg", "within45", "n_pixels")


def _row(model, threshold, units, n_images):
    from snn_fg.evaluation import pool_stats

    stats = pool_stats(units)
    return {"model": model, "threshold": threshold, **{k: stats[k] for k in ROW_KEYS[:4]},
            "n_images": n_images, "n_pixels": stats["n_pixels"]}


def rows_of(results: dict, motion: str = "paper") -> list[dict]:
    """Pooled rows per (model, threshold) of the per-image results."""
    groups: dict = {}
    for res in results.values():
        for u in res["units"]:
            if u["motion"] in (motion, "image"):
                groups.setdefault((u["model"], u["threshold"]), []).append(u)
    return [_row(m, t, units, len(units)) for (m, t), units in sorted(groups.items(), key=lambda kv: (
        kv[0][0], -1 if kv[0][1] is None else kv[0][1]))]


def authors_outputs() -> list[dict]:
    """The authors' stored rate-model maps (bsds-edfg) scored against the labels of the same images."""
    from snn_fg.evaluation import error_stats, pool_stats
    from snn_fg.groundtruth import angle_errors, boundary_directions, load_bsds_fg

    rows, parts = [], []
    for path in sorted(BSDS_EDFG.glob("*.npz")):
        if not (BSDS_FG / "labels" / path.name).exists():
            continue                      # two of the six are among the labels kept back
        ref = np.load(path)
        gt = load_bsds_fg(BSDS_FG, path.stem)
        signed = np.concatenate([angle_errors(ref["fg_x"], ref["fg_y"], *boundary_directions(m)) for m in gt.fg])
        parts.append(error_stats(signed))
        rows.append({"image_id": path.stem, **pool_stats([parts[-1]])})
    return rows + [{"image_id": "pooled", **pool_stats(parts)}] if rows else []


def figure(rows, shift4, same_images=()):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 3.6))
    axes = fig.subplots(1, 3)
    for ax, key, label in zip(axes, ("mean_signed_deg", "mean_abs_deg", "within45"),
                              ("mean signed error (deg)", "mean absolute error (deg)", "fraction within 45 deg")):
        for model, style in (("rate", "o-"), ("spiking", "s--")):
            sel = [r for r in rows if r["model"] == model]
            if sel:
                n = sorted({r["n_images"] for r in sel})
                ax.plot([r["threshold"] for r in sel], [r[key] for r in sel], style,
                        label=f"EDFG {model} (paper events, {'/'.join(map(str, n))} images)")
        if same_images:       # the rate model on the spiking subset: the like-for-like comparison
            ax.plot([r["threshold"] for r in same_images], [r[key] for r in same_images], "o", mfc="none",
                    color="tab:orange", ms=9, label=f"EDFG rate on the {same_images[0]['n_images']} spiking images")
        pts = [(r["threshold"], r[key]) for r in shift4]
        if pts:
            ax.plot(*zip(*pts), "x", ms=9, label="EDFG rate (shift4 events)")
        for model, color in (("fbfg", "tab:green"), ("fbfg-corf", "tab:red")):
            for r in rows:
                if r["model"] == model:
                    ax.axhline(r[key], color=color, ls=":", label=f"{model} (image)")
        if key == "mean_signed_deg":
            ax.axhline(PAPER_BEST_DEG, color="k", lw=0.8, label="paper: 5.29 deg")
        ax.set_xlabel("contrast threshold C")
        ax.set_title(label, fontsize=10)
    fig.legend(*axes[0].get_legend_handles_labels(), fontsize=8, loc="upper center", ncol=4,
               bbox_to_anchor=(0.5, 0.0))
    return fig


def main():
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--spiking-images", type=int, default=0, metavar="N",
                   help="also run the spiking network on N images (evenly spaced; default 0)")
    p.add_argument("--spiking-threshold", type=float, default=0.40, metavar="C",
                   help="contrast threshold of the spiking runs (0.40: the smallest event frames)")
    args = p.parse_args()
    t0 = time.perf_counter()
    results = evaluate(args)
    rows = rows_of(results)
    same_images = []        # the rate model on the spiking subset: like for like, in the extra file
    if args.spiking_images:
        from bsds_sweep import SETTINGS

        sub = p.parse_args([*(["--scheduler", args.scheduler] if args.scheduler else []), "--workers", "1",
                            "--images", str(args.spiking_images)] + (["--no-progress"] if args.no_progress else []))
        # the settings of spiking_groundtruth.py, so that the two share their cache
        spk = evaluate(sub, {**SETTINGS, "thresholds": (args.spiking_threshold,), "shift4_thresholds": (),
                             "event_models": ("rate", "spiking"), "fbfg_operators": (), "fig6": False})
        spk_rows = rows_of(spk)
        rows += [r for r in spk_rows if r["model"] == "spiking"]
        same_images = [r for r in spk_rows if r["model"] == "rate"]
    shift4 = [{**r, "motion": "shift4"} for r in rows_of(results, "shift4") if r["model"] == "rate"]
    from snn_fg.evaluation import pool_stats

    extra = {"images": sorted(results, key=int), "shift4": shift4,
             "human_ceiling": pool_stats([r["ceiling"] for r in results.values()]),
             "authors_outputs": authors_outputs(),
             "runtime_s": time.perf_counter() - t0}
    if args.spiking_images:
        extra["rate_on_the_spiking_images"] = same_images
    written = write_table("table1", rows)
    from snn_fg.atomic import save_text

    written.append(save_text(RESULTS / "table1_extra.json", json.dumps(extra, indent=1)))
    written.append(save_figure(figure(rows, shift4, same_images), "table1"))
    print(f"{'model':10s} {'C':>5s} {'signed':>8s} {'abs':>7s} {'median':>7s} {'<=45':>6s} {'imgs':>5s} {'pixels':>8s}")
    named = ([(r["model"], r) for r in rows] + [("rate/shift4", r) for r in shift4]
             + [("rate, the spiking images", r) for r in same_images])
    for name, r in named:
        c = "-" if r["threshold"] is None else f"{r['threshold']:.2f}"
        print(f"{name:10s} {c:>5s} {r['mean_signed_deg']:8.2f} {r['mean_abs_deg']:7.2f} {r['median_abs_deg']:7.2f} "
              f"{r['within45']:6.3f} {r['n_images']:5d} {r['n_pixels']:8d}")
    print(f"human ceiling: {extra['human_ceiling']}")
    print(f"paper (rate, C = 0.10, mean signed): {PAPER_BEST_DEG} deg; runtime {extra['runtime_s']:.0f} s")
    print("wrote " + ", ".join(str(w.relative_to(RESULTS.parent.parent)) for w in written))


if __name__ == "__main__":
    main()
