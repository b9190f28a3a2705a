"""Where the spiking and rate models miss the analytic truth on the synthetic
scenes with more than one shape (issue 11's second acceptance item).

For the occlusion and demo scenes (``snn_fg.frames.scenes``, made here, not shared
data): both models' figure-ground vectors on the scored boundary pixels,
green within 45 degrees of the analytic direction (towards the centre of the
front shape that owns the pixel), red beyond, and per owning shape the
fraction within 45 degrees and the mean absolute angle. Whether the spiking
network's misses are its own or the model's shows in the figure: the same
pixels red in both panels are the model's.

Writes experiments/results/truth_errors.{json,md,png}.
Usage: python -m experiments.validation.truth_errors
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from experiments.common import Run, describe, markdown_table, save_figure, save_json, save_markdown  # noqa: E402
from snn_fg.events import image_to_frame  # noqa: E402
from snn_fg.frames import scenes  # noqa: E402
from snn_fg.models.rate.edfg import run_edfg  # noqa: E402
from snn_fg.models.spiking import run_spiking  # noqa: E402
from snn_fg.scoring.metrics import truth_errors, truth_scores  # noqa: E402


def _per_owner(err, sc) -> list:
    out = []
    for i, shape in enumerate(sc.shapes):
        e = err[(sc.owner == i + 1) & np.isfinite(err)]
        out.append(
            {
                "shape": f"{type(shape).__name__.lower()} {i + 1}",
                "scored": int(e.size),
                "within_45": float(np.mean(e <= 45)) if e.size else float("nan"),
                "mean_deg": float(np.mean(e)) if e.size else float("nan"),
            }
        )
    return out


def main():
    run = Run()
    rows = []
    fig, axes = plt.subplots(2, 2, figsize=(13, 10))
    for ax_row, sc in zip(axes, (scenes.occlusion(), scenes.demo())):
        pos, neg = image_to_frame(sc.image)
        for ax, (model, maps) in zip(
            ax_row, (("spiking", run_spiking(pos, neg, progress=False)), ("rate", run_edfg(pos, neg)))
        ):
            fx, fy = maps.fg_x, maps.fg_y
            err = truth_errors(fx, fy, sc)
            t = truth_scores(fx, fy, sc)
            rows.append(
                {
                    "scene": sc.name,
                    "model": model,
                    "within_45": t["frac_within_45"],
                    "mean_deg": t["mean_err_deg"],
                    "coverage": t["coverage"],
                    "shapes": _per_owner(err, sc),
                }
            )
            mag = np.hypot(fx, fy)
            rr, cc = np.nonzero(np.isfinite(err))
            ux, uy = fx[rr, cc] / mag[rr, cc], fy[rr, cc] / mag[rr, cc]
            bad = err[rr, cc] > 45
            ax.imshow(sc.image, cmap="gray", vmin=0, vmax=1)
            # (the maps are x right, y up; quiver's default draws v up on screen)
            ax.quiver(cc[~bad], rr[~bad], ux[~bad], uy[~bad], color="lime", scale=40, width=0.002)
            ax.quiver(cc[bad], rr[bad], ux[bad], uy[bad], color="red", scale=40, width=0.003)
            ax.set_title(
                f"{sc.name}, {model}: {100 * t['frac_within_45']:.0f} % within 45 deg, mean {t['mean_err_deg']:.1f} deg"
            )
            ax.set_axis_off()
            print(f"{sc.name} {model}: {rows[-1]}", flush=True)
    fig.suptitle("Figure-ground vectors on the scored boundary pixels: green within 45 deg of the truth, red beyond")
    fig.tight_layout()
    save_figure(fig, "truth_errors", dpi=90, bbox_inches=None)
    rec = {"rows": rows, "run": run.record()}
    save_json("truth_errors", rec)
    save_markdown(
        "truth_errors",
        [
            "# Where the models miss the truth on the multi-shape scenes",
            "",
            f"{describe(rec['run'])} Fast engine. Per scene, model and owning shape: % of "
            "scored boundary pixels within 45 deg of the analytic direction / mean absolute "
            "angle (deg) / scored pixels. Figure: `truth_errors.png`.",
            "",
        ]
        + markdown_table(["scene", "model", "all", "shape 1", "shape 2", "shape 3"], map(_row, rows)),
    )
    print(f"wrote experiments/results/truth_errors.md ({rec['run']['seconds']:.0f} s)")


def _row(r) -> list:
    cells = [f"{s['shape']}: {100 * s['within_45']:.0f} % / {s['mean_deg']:.1f} / {s['scored']}" for s in r["shapes"]]
    return (
        [r["scene"], r["model"], f"{100 * r['within_45']:.0f} % / {r['mean_deg']:.1f}"]
        + cells
        + [""] * (3 - len(cells))
    )


if __name__ == "__main__":
    main()
