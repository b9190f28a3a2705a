"""Scores of a figure-ground map against human figure/ground labels, kept as sums so that they
pool over labellers and images exactly: the one home of the numbers ``snn-fg compare RUN LABELS``
prints and the BSDS experiments (Table 1, Fig. 6, the spiking and compact validations) report.

Angle errors are kept as sums and a histogram of absolute errors
(:data:`HIST_BIN_DEG` bins, :func:`error_stats`), so that pooled means are
exact and the pooled median is good to half a bin, without storing every
pixel (:func:`pool_stats`). The scores (:data:`SCORES`, the words of docs/glossary.md):

* **side accuracy**: the share of scored pixels whose direction lies within 90 degrees of the
  labelled one, so on the figure's side (chance 50 %), the field's own metric;
* **coverage**: labelled pixels that get a vector, over all labelled pixels (read side accuracy
  with it: a map that leaves hard pixels blank scores high on the rest);
* **within 45°**: the share of scored pixels within 45 degrees (chance 25 %);
* **mean absolute difference** (chance 90 degrees) and the **mean signed difference**, the number
  the paper reports (errors of both signs cancel in it, so it is no measure of agreement alone).

A pixel is *labelled* where a labeller's figure (+1) pixel got a direction
(:func:`~snn_fg.scoring.groundtruth.boundary_directions`) and *scored* where the map also has a
vector there. :func:`labeller_errors` gives one part per labeller; :func:`field_errors` both
labellers' pixels as one part (the experiments' per-image unit); ``pool_stats`` of either
gives the same scores.
"""

from __future__ import annotations

import numpy as np

from .groundtruth import SIDE_DEG, WITHIN_DEG, angle_errors

#: Width (degrees) of the bins of the absolute-error histogram.
HIST_BIN_DEG = 0.5
_N_BINS = int(round(180 / HIST_BIN_DEG))


def error_stats(signed, n_truth: int | None = None) -> dict:
    """Sums and histogram of signed errors (degrees), to pool over images with :func:`pool_stats`.

    ``n_truth``: the labelled pixels the errors were taken on (with or without
    a model vector), so that the pooled coverage can be formed."""
    signed = np.asarray(signed, np.float64)
    a = np.abs(signed)
    hist = np.bincount(np.minimum((a / HIST_BIN_DEG).astype(int), _N_BINS - 1), minlength=_N_BINS)
    out = {
        "n": int(a.size),
        "sum_signed": float(signed.sum()),
        "sum_abs": float(a.sum()),
        "n_within45": int((a <= WITHIN_DEG).sum()),
        "n_side": int((a < SIDE_DEG).sum()),
        "hist_abs": hist.tolist(),
    }
    if n_truth is not None:
        out["n_truth"] = int(n_truth)
    return out


def labeller_errors(fg_x, fg_y, truths) -> list[dict]:
    """One :func:`error_stats` part per labeller: the field ``(fg_x, fg_y)`` against each of
    ``truths`` (``(x, y, valid)`` of :func:`~snn_fg.scoring.groundtruth.boundary_directions`)."""
    return [error_stats(angle_errors(fg_x, fg_y, *t), n_truth=int(t[2].sum())) for t in truths]


def field_errors(fg_x, fg_y, truths) -> dict:
    """One :func:`error_stats` part for every labeller's pixels together (a pixel two labellers
    label counts twice): what the experiments keep per image and model."""
    signed = np.concatenate([angle_errors(fg_x, fg_y, *t) for t in truths])
    return error_stats(signed, n_truth=sum(int(t[2].sum()) for t in truths))


#: the pooled scores that are one sum of :func:`error_stats` divided by another:
#: ``score: (numerator, denominator)``
RATIO_OF = {
    "mean_signed_deg": ("sum_signed", "n"),
    "mean_abs_deg": ("sum_abs", "n"),
    "within45": ("n_within45", "n"),
    "side_accuracy": ("n_side", "n"),
    "coverage": ("n", "n_truth"),
}
#: the scores of :data:`RATIO_OF` that a table reports, in its order
SCORES = ("side_accuracy", "coverage", "within45", "mean_abs_deg", "mean_signed_deg")


def stats_field(p: dict, name: str) -> float:
    """One sum of an :func:`error_stats` part (nan for a coverage denominator it was made without)."""
    return p.get(name, float("nan"))


def pool_stats(parts) -> dict:
    """Pooled scores of :data:`RATIO_OF` (over every pixel of every part), the median
    absolute error (to half a histogram bin), the pixel count and labelled-pixel count."""
    parts = list(parts)
    n = sum(p["n"] for p in parts)
    sums = {f: sum(stats_field(p, f) for p in parts) for pair in RATIO_OF.values() for f in pair}
    with np.errstate(invalid="ignore", divide="ignore"):
        out = {
            key: float(np.float64(sums[a]) / sums[b]) if sums[b] else float("nan") for key, (a, b) in RATIO_OF.items()
        }
    if n:
        hist = np.sum([p["hist_abs"] for p in parts], axis=0)
        out["median_abs_deg"] = (int(np.searchsorted(np.cumsum(hist), n / 2)) + 0.5) * HIST_BIN_DEG
    else:
        out["median_abs_deg"] = float("nan")
    out["n_pixels"] = n
    out["n_truth"] = sums["n_truth"] if np.isnan(sums["n_truth"]) else int(sums["n_truth"])
    return out
