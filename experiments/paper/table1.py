"""Table 1 of the paper: angle error of the figure-ground maps against human labels, per
event-simulator contrast threshold, for every model.

    python -m experiments.paper.table1 [--quick | --images N] [--scheduler ADDRESS] [--workers N]
                                       [--spiking-images N --spiking-threshold C]

Events come from ``--motion paper`` at thresholds 0.10-0.40 (and from the
built-in ``shift4`` at 0.10, for comparison); the frame-based model (both edge
operators) sees the image. Every map is scored at the figure pixels of both
labellers (pooled): side accuracy and coverage, with the paper's mean *signed*
error beside the mean absolute error, the median and the fraction within 45
degrees. The spiking
network runs on its own small subset (``--spiking-images``), one image at a time,
beside the rate model on the same images (table1_extra.json); this shares its
cache with experiments.validation.spiking_groundtruth.

Every score is pooled over pixels, with a 95 % bootstrap interval over the
images; beside it the mean of the per-image scores. The field's own metric is
the binary side accuracy (within 90 degrees of the labelled direction); the
coverage is the share of labelled pixels that get a vector.

Writes experiments/results/table1.json / .csv (rows: model, threshold, each
score of snn_fg.scoring.label_scores.SCORES with its _low / _high interval, the per-image
means, median_abs_deg, n_images, n_pixels, n_truth), table1.md (the table),
table1_per_image.json / .csv (every image's scores per model and threshold),
table1_extra.json (shift4 rows, the human ceiling, the authors' stored outputs
scored the same way) and table1.png; a run on fewer than all the images writes
table1_<N>images*, one with --ids table1_ids-<ids>*: never the full set's files.
"""

from __future__ import annotations

import numpy as np

from experiments.common import Run, dataset, describe, markdown_table, save_figure, save_json, save_markdown
from experiments.paper.bsds import (
    SETTINGS,
    contrast_threshold,
    coverage_warnings,
    evaluate,
    parser,
    positive_int,
    subset_name,
    write_table,
)
from snn_fg.scoring.bootstrap import RESAMPLES

#: The paper's best Table 1 number (mean signed error at threshold 0.10), degrees.
PAPER_BEST_DEG = 5.29
#: resamples of the bootstrap over images behind every interval (the one count the package uses too)
BOOTSTRAP_RESAMPLES = RESAMPLES
#: the per-image scores kept in table1_per_image.csv
IMAGE_KEYS = ("side_accuracy", "coverage", "within45", "mean_abs_deg", "mean_signed_deg", "n_pixels", "n_truth")


def scored_row(per_image_parts: list, **label) -> dict:
    """One table row: every score pooled over pixels with its 95 % bootstrap
    interval over images, the mean of the per-image side accuracy and within-45
    share (with theirs), the median, and the image, pixel and labelled-pixel counts."""
    from experiments.pooled import bootstrap_scores
    from snn_fg.scoring.label_scores import SCORES, pool_stats

    pooled = pool_stats([u for ps in per_image_parts for u in ps])
    boot = bootstrap_scores(per_image_parts, n_resamples=BOOTSTRAP_RESAMPLES)
    row = dict(label)
    for key in SCORES:
        row.update({key: boot[key]["pooled"], f"{key}_low": boot[key]["low"], f"{key}_high": boot[key]["high"]})
    for key in ("side_accuracy", "within45"):
        b = boot[key]
        row.update(
            {
                f"{key}_image_mean": b["image_mean"],
                f"{key}_image_low": b["image_low"],
                f"{key}_image_high": b["image_high"],
            }
        )
    return {
        **row,
        "median_abs_deg": pooled["median_abs_deg"],
        "n_images": len(per_image_parts),
        "n_pixels": pooled["n_pixels"],
        "n_truth": pooled["n_truth"],
    }


def _groups(results: dict, motion: str) -> dict:
    """``{(model, threshold): {image_id: unit}}`` of the per-image results."""
    groups: dict = {}
    for image_id, res in results.items():
        for u in res["units"]:
            if u["motion"] in (motion, "image"):
                groups.setdefault((u["model"], u["threshold"]), {})[image_id] = u
    return dict(sorted(groups.items(), key=lambda kv: (kv[0][0], -1 if kv[0][1] is None else kv[0][1])))


def rows_of(results: dict, motion: str = "paper") -> list[dict]:
    """Pooled rows per (model, threshold) of the per-image results."""
    return [
        scored_row([[u] for u in units.values()], model=m, threshold=t)
        for (m, t), units in _groups(results, motion).items()
    ]


def per_image_rows(results: dict, motion: str = "paper") -> list[dict]:
    """Every image's own scores, per (model, threshold)."""
    from snn_fg.scoring.label_scores import pool_stats

    rows = []
    for (m, t), units in _groups(results, motion).items():
        for image_id in sorted(units, key=int):
            s = pool_stats([units[image_id]])
            rows.append({"image_id": image_id, "model": m, "threshold": t, **{k: s[k] for k in IMAGE_KEYS}})
    return rows


def authors_outputs() -> list[dict]:
    """The authors' stored rate-model maps (bsds-edfg) scored against the labels of the same images."""
    from snn_fg.scoring.groundtruth import boundary_directions, load_bsds_fg
    from snn_fg.scoring.label_scores import field_errors, pool_stats

    rows, parts = [], []
    labels = dataset("bsds-fg")
    for path in sorted(dataset("bsds-edfg").glob("*.npz")):
        if not (labels / "labels" / path.name).exists():
            continue  # two of the six are among the labels kept back
        ref = np.load(path)
        gt = load_bsds_fg(labels, path.stem)
        truths = [boundary_directions(m) for m in gt.fg]
        parts.append(field_errors(ref["fg_x"], ref["fg_y"], truths))
        rows.append({"image_id": path.stem, **pool_stats([parts[-1]])})
    return rows + [{"image_id": "pooled", **pool_stats(parts)}] if rows else []


#: the panels of table1.png: (score, title, chance level or None)
PANELS = (
    ("side_accuracy", "side accuracy (within 90 deg)", 0.5),
    ("coverage", "coverage", None),
    ("within45", "fraction within 45 deg", 0.25),
    ("mean_abs_deg", "mean absolute error (deg)", 90.0),
    ("mean_signed_deg", "mean signed error (deg)", None),
)


def figure(rows, shift4, same_images=()):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(17, 3.6))
    axes = fig.subplots(1, len(PANELS))
    for ax, (key, label, chance) in zip(axes, PANELS):
        for model, style in (("rate", "o-"), ("spiking", "s--")):
            sel = [r for r in rows if r["model"] == model]
            if sel:
                n = sorted({r["n_images"] for r in sel})
                t = [r["threshold"] for r in sel]
                ax.errorbar(
                    t,
                    [r[key] for r in sel],
                    yerr=_bars(sel, key),
                    fmt=style,
                    capsize=2,
                    label=f"EDFG {model} (paper events, {'/'.join(map(str, n))} images)",
                )
        if same_images:  # the rate model on the spiking subset: the like-for-like comparison
            ax.plot(
                [r["threshold"] for r in same_images],
                [r[key] for r in same_images],
                "o",
                mfc="none",
                color="tab:orange",
                ms=9,
                label=f"EDFG rate on the {same_images[0]['n_images']} spiking images",
            )
        pts = [(r["threshold"], r[key]) for r in shift4]
        if pts:
            ax.plot(*zip(*pts), "x", ms=9, label="EDFG rate (shift4 events)")
        for model, color in (("fbfg", "tab:green"), ("fbfg-corf", "tab:red")):
            for r in rows:
                if r["model"] == model:
                    ax.axhline(r[key], color=color, ls=":", label=f"{model} (image)")
                    ax.axhspan(r[f"{key}_low"], r[f"{key}_high"], color=color, alpha=0.12)
        if chance is not None:
            ax.axhline(chance, color="0.5", lw=0.8, ls="--", label="chance (random directions)")
        if key == "mean_signed_deg":
            ax.axhline(PAPER_BEST_DEG, color="k", lw=0.8, label="paper: 5.29 deg")
        ax.set_xlabel("contrast threshold C")
        ax.set_title(label, fontsize=10)
    handles = {}
    for ax in axes:
        handles.update(zip(*reversed(ax.get_legend_handles_labels())))
    fig.legend(list(handles.values()), list(handles), fontsize=8, loc="upper center", ncol=4, bbox_to_anchor=(0.5, 0.0))
    fig.suptitle(
        "Against the human labels: pooled over pixels, bars and bands the 95 % bootstrap interval over images",
        fontsize=10,
    )
    return fig


def _bars(rows, key):
    return np.array([[r[key] - r[f"{key}_low"] for r in rows], [r[f"{key}_high"] - r[key] for r in rows]])


def percent_with_interval(r, key) -> str:
    """A row's score in percent with its bootstrap interval: ``61.2 [58.0, 64.1]``."""
    return f"{100 * r[key]:.1f} [{100 * r[f'{key}_low']:.1f}, {100 * r[f'{key}_high']:.1f}]"


def markdown(named, ceiling, header: str) -> list[str]:
    """The table's lines: ``named`` is ``[(name, row)]`` of :func:`scored_row` rows."""

    def cells(name, r):
        c = "-" if r.get("threshold") is None else f"{r['threshold']:.2f}"
        return [
            name,
            c,
            percent_with_interval(r, "side_accuracy"),
            f"{100 * r['side_accuracy_image_mean']:.1f}",
            f"{100 * r['coverage']:.1f}",
            percent_with_interval(r, "within45"),
            f"{r['mean_abs_deg']:.1f} [{r['mean_abs_deg_low']:.1f}, {r['mean_abs_deg_high']:.1f}]",
            f"{r['mean_signed_deg']:.1f}",
            f"{r['median_abs_deg']:.1f}",
            r["n_images"],
            f"{r['n_pixels']:,}",
        ]

    ceiling_row = [
        "human ceiling (labeller 2 vs 1)",
        "",
        f"{100 * ceiling['side_accuracy']:.1f}",
        "",
        f"{100 * ceiling['coverage']:.1f}",
        f"{100 * ceiling['within45']:.1f}",
        f"{ceiling['mean_abs_deg']:.1f}",
        f"{ceiling['mean_signed_deg']:.1f}",
        f"{ceiling['median_abs_deg']:.1f}",
        "",
        f"{ceiling['n_pixels']:,}",
    ]
    return [header, ""] + markdown_table(
        [
            "model",
            "C",
            "side accuracy % [95 %]",
            "per-image mean %",
            "coverage %",
            "within 45 % [95 %]",
            "mean abs [95 %]",
            "mean signed",
            "median abs",
            "images",
            "pixels",
        ],
        [cells(name, r) for name, r in named] + [ceiling_row],
    )


def main():
    p = parser(__doc__)
    p.add_argument(
        "--spiking-images",
        type=positive_int,
        metavar="N",
        help="also run the spiking network on N images (evenly spaced; N >= 1); without it no spiking network runs",
    )
    p.add_argument(
        "--spiking-threshold",
        type=contrast_threshold,
        default=0.40,
        metavar="C",
        help="contrast threshold of the spiking runs (0.40: the smallest event frames)",
    )
    args = p.parse_args()
    run = Run()
    results = evaluate(args)
    rows = rows_of(results)
    image_rows = per_image_rows(results) + per_image_rows(results, "shift4")
    same_images = []  # the rate model on the spiking subset: like for like, in the extra file
    if args.spiking_images:
        sub = p.parse_args(
            [
                *(["--scheduler", args.scheduler] if args.scheduler else []),
                "--workers",
                "1",
                "--images",
                str(args.spiking_images),
            ]
            + (["--no-progress"] if args.no_progress else [])
        )
        # the settings of experiments.validation.spiking_groundtruth, so that the two share their cache
        spk = evaluate(
            sub,
            {
                **SETTINGS,
                "thresholds": (args.spiking_threshold,),
                "shift4_thresholds": (),
                "event_models": ("rate", "spiking"),
                "fbfg_operators": (),
                "fig6": False,
            },
        )
        spk_rows = rows_of(spk)
        rows += [r for r in spk_rows if r["model"] == "spiking"]
        same_images = [r for r in spk_rows if r["model"] == "rate"]
        image_rows += [r for r in per_image_rows(spk) if r["model"] == "spiking"]
    shift4 = [{**r, "motion": "shift4"} for r in rows_of(results, "shift4") if r["model"] == "rate"]
    from snn_fg.scoring.label_scores import pool_stats

    ceiling = pool_stats([r["ceiling"] for r in results.values()])
    extra = {
        "images": sorted(results, key=int),
        "shift4": shift4,
        "human_ceiling": ceiling,
        "authors_outputs": authors_outputs(),
        "run": run.record(),
    }
    if args.spiking_images:
        extra["rate_on_the_spiking_images"] = same_images
    # a subset (--images N, --quick, --ids) writes table1_<N>images.* and so on, never the full-set files
    stem = subset_name("table1", args, len(results))
    written = write_table(stem, rows, run=extra["run"]) + write_table(f"{stem}_per_image", image_rows, run=extra["run"])
    written.append(save_json(f"{stem}_extra", extra))
    written.append(save_figure(figure(rows, shift4, same_images), stem))
    named = (
        [(r["model"], r) for r in rows]
        + [("rate, `shift4` events", r) for r in shift4]
        + [(f"rate, the same {r['n_images']} images", r) for r in same_images]
    )
    header = (
        f"# Table 1 against the human labels\n\n{describe(extra['run'])} {len(results)} images (those in "
        f"the cache read back). Both labellers' figure pixels pooled; "
        f"intervals: 95 % of {BOOTSTRAP_RESAMPLES} bootstrap resamples of the images. Side accuracy: "
        "pixels within 90 deg of the labelled direction (chance 50 %); coverage: labelled pixels with a "
        "vector over all labelled pixels; the other scores count scored pixels only."
    )
    lines = markdown(named, ceiling, header)
    warnings = coverage_warnings(
        [(name + ("" if r["threshold"] is None else f", C = {r['threshold']}"), r) for name, r in named]
    )
    lines += ["", *warnings] if warnings else []
    written.append(save_markdown(stem, lines))
    print("\n".join(lines))
    print(f"paper (rate, C = 0.10, mean signed): {PAPER_BEST_DEG} deg; runtime {extra['run']['seconds']:.0f} s")
    print("wrote " + ", ".join(str(w) for w in written))


if __name__ == "__main__":
    main()
