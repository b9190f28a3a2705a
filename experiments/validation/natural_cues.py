"""How far local cues go: side accuracy that cues around each vector of the
natural-scene variant could reach on the labelled BSDS images, alone and combined.

    python -m experiments.validation.natural_cues [--workers N] [--scheduler ADDRESS]

Issue 38 asks for >= 70 % binary side accuracy. The variant (``--model
natural`` as it was before its side cue, ``side_cue = 0``: the cue was
chosen by this analysis) decides the side of a boundary by its grouping cells. This
experiment asks what else around a boundary pixel says which side is the
figure, and how much all of it together is worth, before any of it is built
into a network.

At every labelled boundary pixel where the variant has a vector ``n`` (the
pixels its side accuracy is scored on; both labellers), each cue is a number
whose sign says "the figure lies on ``n``'s side" (positive) or the other:

* ``events r``: event pixels in the half disc of radius ``r`` on ``n``'s side
  minus those on the other side, over the half disc's area (the events every
  model sees: ``--motion paper``, C = 0.10);
* ``grouping r``: the same of the variant's own grouping map;
* ``lower``: ``-n_y``, the figure below the boundary (the "lower region" cue);
* ``towards centre``: ``n`` projected on the direction to the image's centre,
  over the image's diagonal.

Each cue alone is scored as a rule that keeps the variant's vector where the
cue is positive and turns it round where it is negative. All cues together
are combined by a logistic regression (numpy, L2-regularised, standardised
cues, :func:`fit_logistic`) that predicts whether the variant's side is
right: on the tuning half by 5-fold cross-validation over images (so every
image is scored by a fit that never saw it), then fitted on the whole tuning
half and scored once on the reporting half. So are the fewest cues that carry
that combination on the tuning half (:data:`TO_BUILD`), the ones worth
building into the network. The halves are those of
``experiments.validation.natural_scenes`` (even / odd positions of the sorted
ids).

Side accuracy is pooled over pixels; the reporting half's has a 95 %
bootstrap interval over images. Writes experiments/results/natural_cues.{json,md,png}.
"""

from __future__ import annotations

import numpy as np

from experiments.common import CACHE, Run, dataset, describe, fail, markdown_table, save_figure, save_results
from experiments.paper.bsds import check_inputs, input_digest, parser
from experiments.paper.table1 import BOOTSTRAP_RESAMPLES
from snn_fg.network.kernels import half_disc

#: Radii (px) of the half discs of the event cue and of the grouping cue.
EVENT_RADII = (6, 12, 24, 48, 96, 160)
GROUPING_RADII = (12, 48)
#: Directions of the half-disc kernels (each vector takes its nearest).
N_DIRECTIONS = 16
#: Folds of the cross-validation on the tuning half (over images).
FOLDS = 5
#: L2 penalty of the logistic regression, per pixel, on standardised cues.
L2 = 1e-4
THRESHOLD, MOTION = 0.10, "paper"
CUES = [f"events {r}" for r in EVENT_RADII] + [f"grouping {r}" for r in GROUPING_RADII] + ["lower", "towards centre"]
#: The fewest cues that carry the combination on the tuning half (cross-validated there: events within 160 px
#: and the lower region 60.3 %, all ten 60.1 %; chosen among 8 subsets on that half only).
TO_BUILD = ("events 160", "lower")
#: Bumped when what an image's file holds changes (the cache keys on it).
VERSION = 3


def side_difference(image, radius: float, rows, cols, direction) -> np.ndarray:
    """``image``'s mean over the half disc of ``radius`` on the side of ``direction`` (radians, x right, y up)
    minus its mean over the other half, at the pixels ``(rows, cols)``."""
    from scipy.signal import fftconvolve

    step = 2 * np.pi / N_DIRECTIONS
    nearest = np.round(np.mod(direction, 2 * np.pi) / step).astype(int) % N_DIRECTIONS
    out = np.zeros(len(rows))
    half = N_DIRECTIONS // 2
    for b in range(half):  # direction b + half is direction b with the sign turned
        sel = nearest % half == b
        if not sel.any():
            continue
        kernel = half_disc(radius, b * step)
        # correlation with the kernel: its value at a pixel is the kernel laid on the image there
        conv = fftconvolve(np.asarray(image, np.float64), kernel[::-1, ::-1], mode="same")
        out[sel] = np.where(nearest[sel] < half, 1.0, -1.0) * conv[rows[sel], cols[sel]]
    return out


def image_cues(*, root: str, image_id: str, cache: str, key: str | None = None) -> dict:
    """The cues of :data:`CUES` and whether the variant's side is right, at every labelled pixel of one image
    where the variant has a vector; written to ``cache/<key>.npz`` (``key``: the sweep task's, by default
    the image id; the sweep's result is its summary)."""
    from pathlib import Path

    from snn_fg.events import image_to_frame
    from snn_fg.models.rate.natural import run_natural
    from snn_fg.params import NATURAL_PARAMS
    from snn_fg.results.atomic import save_npz
    from snn_fg.scoring.groundtruth import SIDE_DEG, boundary_directions, load_bsds_fg, signed_angle_deg

    gt = load_bsds_fg(root, image_id)
    pos, neg = image_to_frame(str(gt.image_path), threshold=THRESHOLD, motion=MOTION)
    maps = run_natural(pos, neg, NATURAL_PARAMS.replace(side_cue=0.0))  # the variant the cues were read on
    fx, fy = maps.fg_x.astype(np.float64), maps.fg_y.astype(np.float64)
    rows, cols, tx, ty = [], [], [], []
    for labels in gt.fg:
        x, y, valid = boundary_directions(labels)
        r, c = np.nonzero(valid & (np.hypot(fx, fy) > 0))
        rows.append(r), cols.append(c), tx.append(x[r, c]), ty.append(y[r, c])
    r, c, tx, ty = (np.concatenate(a) for a in (rows, cols, tx, ty))
    nx, ny = fx[r, c], fy[r, c]
    length = np.hypot(nx, ny)
    nx, ny = nx / length, ny / length
    direction = np.arctan2(ny, nx)
    events = ((pos != 0) | (neg != 0)).astype(np.float64)
    cues = [side_difference(events, rad, r, c, direction) for rad in EVENT_RADII]
    cues += [side_difference(maps.grouping, rad, r, c, direction) for rad in GROUPING_RADII]
    h, w = events.shape
    to_x, to_y = (w - 1) / 2 - c, r - (h - 1) / 2  # towards the centre, y up
    cues += [-ny, (nx * to_x + ny * to_y) / np.hypot(h, w)]
    right = np.abs(signed_angle_deg(nx, ny, tx, ty)) < SIDE_DEG  # as the side accuracy of every table
    save_npz(Path(cache, f"{key or image_id}.npz"), cues=np.stack(cues, 1).astype(np.float32), right=right)
    return {"pixels": int(len(right)), "right": int(right.sum()), "version": VERSION}


def fit_logistic(x, y, l2: float = L2, iterations: int = 50):
    """Weights ``(mean, scale, w, b)`` of an L2-regularised logistic regression of ``y`` (bool) on ``x``
    (pixels x cues), by Newton's method on standardised cues; :func:`predict` applies them."""
    mean, scale = x.mean(0), x.std(0)
    scale[scale == 0] = 1
    z = np.column_stack([(x - mean) / scale, np.ones(len(x))])
    beta = np.zeros(z.shape[1])
    penalty = l2 * len(x) * np.diag(np.r_[np.ones(z.shape[1] - 1), 0.0])
    for _ in range(iterations):
        p = 1 / (1 + np.exp(-z @ beta))
        grad = z.T @ (p - y) + penalty @ beta
        hess = (z * (p * (1 - p))[:, None]).T @ z + penalty
        step = np.linalg.solve(hess, grad)
        beta -= step
        if np.abs(step).max() < 1e-8:
            break
    return mean, scale, beta[:-1], beta[-1]


def predict(model, x) -> np.ndarray:
    """Whether the variant's side is right, as the fitted ``model`` of :func:`fit_logistic` says."""
    mean, scale, w, b = model
    return ((x - mean) / scale) @ w + b > 0


def _pooled(correct_per_image) -> float:
    return float(np.concatenate(correct_per_image).mean())


def _interval(correct_per_image, seed: int = 0) -> tuple[float, float]:
    """95 % bootstrap interval over images of the pooled share."""
    hits = np.array([c.sum() for c in correct_per_image], np.float64)
    n = np.array([len(c) for c in correct_per_image], np.float64)
    pick = np.random.default_rng(seed).integers(0, len(n), size=(BOOTSTRAP_RESAMPLES, len(n)))
    share = hits[pick].sum(1) / n[pick].sum(1)
    lo, hi = np.quantile(share, [0.025, 0.975])
    return float(lo), float(hi)


def _combination(tune: list, report: list, columns) -> dict:
    """The logistic regression over the cues ``columns`` (indices into :data:`CUES`): cross-validated over the
    tuning half's images, then fitted on that half and scored on the reporting half."""
    columns = list(columns)
    folds = np.arange(len(tune)) % FOLDS
    cv = [None] * len(tune)
    for f in range(FOLDS):
        train = [tune[i] for i in np.flatnonzero(folds != f)]
        model = fit_logistic(np.concatenate([x[:, columns] for x, _ in train]), np.concatenate([r for _, r in train]))
        for i in np.flatnonzero(folds == f):
            x, r = tune[i]
            cv[i] = predict(model, x[:, columns]) == r
    model = fit_logistic(np.concatenate([x[:, columns] for x, _ in tune]), np.concatenate([r for _, r in tune]))
    held = [predict(model, x[:, columns]) == r for x, r in report]
    names = [CUES[k] for k in columns]
    return {
        "cues": names,
        "tune_cross_validated": _pooled(cv),
        "report": _pooled(held),
        "report_interval": _interval(held),
        "weights": dict(zip(names, (model[2] / model[1]).tolist())),
        "standardised_weights": dict(zip(names, model[2].tolist())),
        "intercept": float(model[3]),
    }


def analyse(tune: list, report: list) -> dict:
    """Side accuracies of the variant, each cue alone, all cues combined and the cues of :data:`TO_BUILD`
    combined (see the module docstring). ``tune`` / ``report``: per image ``(cues, right)`` arrays."""

    def as_is(images):
        return [r for _, r in images]

    def cue_rule(images, k):  # keep the variant's side where the cue is positive, turn it round elsewhere
        return [np.where(x[:, k] > 0, r, np.where(x[:, k] < 0, ~r, r)) for x, r in images]

    out = {
        "variant": {
            "tune": _pooled(as_is(tune)),
            "report": _pooled(as_is(report)),
            "report_interval": _interval(as_is(report)),
        }
    }
    out["cues"] = {
        name: {"tune": _pooled(cue_rule(tune, k)), "report": _pooled(cue_rule(report, k))}
        for k, name in enumerate(CUES)
    }
    out["combined"] = _combination(tune, report, range(len(CUES)))
    out["to_build"] = _combination(tune, report, [CUES.index(c) for c in TO_BUILD])
    out["pixels"] = {"tune": int(sum(len(r) for _, r in tune)), "report": int(sum(len(r) for _, r in report))}
    return out


def _figure(result: dict):
    import matplotlib.pyplot as plt

    names = ["natural, no side cue"] + CUES + ["all cues combined", " + ".join(TO_BUILD)]
    combos = (result["combined"], result["to_build"])
    tune = (
        [result["variant"]["tune"]]
        + [result["cues"][c]["tune"] for c in CUES]
        + [c["tune_cross_validated"] for c in combos]
    )
    report = [result["variant"]["report"]] + [result["cues"][c]["report"] for c in CUES] + [c["report"] for c in combos]
    fig, ax = plt.subplots(figsize=(9, 4.2))
    at = np.arange(len(names))
    ax.bar(at - 0.2, 100 * np.array(tune), 0.4, label="tuning half (combination: cross-validated)")
    ax.bar(at + 0.2, 100 * np.array(report), 0.4, label="reporting half")
    for level, text in ((50, "chance"), (70, "issue 38's bar")):
        ax.axhline(level, color="k", lw=0.8, ls=":" if level == 50 else "--")
        ax.text(len(names) - 0.5, level + 0.4, text, ha="right", fontsize=8)
    ax.set_xticks(at, names, rotation=40, ha="right")
    ax.set_ylim(45, 75)
    ax.set_ylabel("binary side accuracy (%)")
    ax.set_title("What local cues say about the side of a labelled BSDS boundary")
    ax.legend(fontsize=8, loc="upper left")
    return fig


def main():
    from experiments.sweep import SweepTask, run_sweep
    from experiments.validation.natural_scenes import halves
    from snn_fg.errors import SnnFgError

    p = parser(__doc__)
    args = p.parse_args()
    if args.images or args.quick or args.ids:
        p.error("--images, --quick and --ids do not apply: the cues are read on every labelled image")
    run = Run()
    split = halves()
    cache = CACHE / f"natural-cues-v{VERSION}"
    cache.mkdir(parents=True, exist_ok=True)
    ids = split["tune"] + split["report"]
    root = str(dataset("bsds-fg"))
    check_inputs(root, ids)
    # as the BSDS experiments' cache: named by a digest of the image and label files, so that a changed
    # label file is read again rather than its old cues
    keys = {i: f"{i}-{input_digest(root, i)}" for i in ids}
    tasks = [SweepTask(keys[i], {"root": root, "image_id": i, "cache": str(cache), "key": keys[i]}) for i in ids]
    try:
        run_sweep(
            image_cues, tasks, cache, scheduler=args.scheduler, workers=args.workers, progress=not args.no_progress
        )
    except SnnFgError as exc:
        fail(exc.for_command_line())
    missing = [i for i in ids if not (cache / f"{keys[i]}.npz").exists()]
    if missing:
        fail(
            f"{cache} holds results without their cue files ({', '.join(missing[:3])}...): delete the folder "
            "and run again"
        )

    def read(part):
        images = []
        for i in split[part]:
            with np.load(cache / f"{keys[i]}.npz") as d:
                images.append((d["cues"].astype(np.float64), d["right"]))
        return images

    result = analyse(read("tune"), read("report"))
    result["run"] = run.record()
    v, comb = result["variant"], result["combined"]
    rows = [
        [
            "natural without the side cue",
            f"{100 * v['tune']:.1f}",
            f"{100 * v['report']:.1f} [{100 * v['report_interval'][0]:.1f}, {100 * v['report_interval'][1]:.1f}]",
        ]
    ]
    rows += [
        [f"cue alone: {c}", f"{100 * result['cues'][c]['tune']:.1f}", f"{100 * result['cues'][c]['report']:.1f}"]
        for c in CUES
    ]
    rows += [
        [
            "all cues, logistic regression",
            f"{100 * comb['tune_cross_validated']:.1f} (cross-validated)",
            f"{100 * comb['report']:.1f} [{100 * comb['report_interval'][0]:.1f}, "
            f"{100 * comb['report_interval'][1]:.1f}]",
        ]
    ]
    two = result["to_build"]
    rows += [
        [
            f"{' and '.join(TO_BUILD)}, logistic regression",
            f"{100 * two['tune_cross_validated']:.1f} (cross-validated)",
            f"{100 * two['report']:.1f} [{100 * two['report_interval'][0]:.1f}, {100 * two['report_interval'][1]:.1f}]",
        ]
    ]
    weights = "; ".join(
        ", ".join(f"{c} {w:+.2f}" for c, w in part["standardised_weights"].items()) for part in (comb, two)
    )
    lines = [
        "# How far local cues go (issue 38)",
        "",
        describe(result["run"]) + " (Images in the cache are read back.)",
        "",
        f"Binary side accuracy (%) on the labelled boundary pixels where `--model natural --side-cue 0` has a "
        f"vector (both labellers; {result['pixels']['tune']:,} pixels on the tuning half, "
        f"{result['pixels']['report']:,} on the reporting half). A cue alone keeps the variant's side "
        "where it is positive and turns it round where it is negative; the combination is a logistic "
        f"regression over all {len(CUES)} cues, {FOLDS}-fold cross-validated over the tuning half's images, "
        "then fitted on that half and scored once on the reporting half. Intervals: 95 % of "
        f"{BOOTSTRAP_RESAMPLES} bootstrap resamples of the images.",
        "",
        *markdown_table(["rule", "tuning half", "reporting half"], rows),
        "",
        f"Weights of the combinations (standardised cues): {weights}.",
        "",
        "![side accuracy of each cue](natural_cues.png)",
    ]
    save_figure(_figure(result), "natural_cues")
    save_results("natural_cues", result, lines)


if __name__ == "__main__":
    main()
