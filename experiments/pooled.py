"""Scores against human labels pooled over images, with intervals from
resampling the images.

Angle errors are kept as sums and a histogram of absolute errors
(:data:`HIST_BIN_DEG` bins, :func:`error_stats`), so that pooled means are
exact and the pooled median is good to half a bin, without storing every
pixel (:func:`pool_stats`). The scores (:data:`SCORES`): **side accuracy**,
the field's own metric (the share of scored pixels whose direction is within
90 degrees of the labelled one, i.e. on the figure's side; chance 50 %);
**coverage** (labelled pixels that get a vector, over all labelled pixels);
the share within 45 degrees; the mean absolute and the mean signed error (the
paper's). :func:`bootstrap_scores` gives each, pooled over pixels and as a
mean over images, with an interval from resampling the images;
:func:`bootstrap_difference` the same for the difference of two models.
"""

from __future__ import annotations

import warnings

import numpy as np

from snn_fg.scoring.groundtruth import SIDE_DEG, WITHIN_DEG

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


def _field(p: dict, name: str) -> float:
    """One sum of an :func:`error_stats` part (nan for a coverage denominator it was made without)."""
    return p.get(name, float("nan"))


def pool_stats(parts) -> dict:
    """Pooled scores of :data:`RATIO_OF` (over every pixel of every part), the median
    absolute error (to half a histogram bin), the pixel count and labelled-pixel count."""
    parts = list(parts)
    n = sum(p["n"] for p in parts)
    sums = {f: sum(_field(p, f) for p in parts) for pair in RATIO_OF.values() for f in pair}
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


def _check_bootstrap(n_resamples, level, keys, what):
    if not (isinstance(n_resamples, int) and n_resamples >= 1):
        raise ValueError(f"n_resamples must be a positive integer, got {n_resamples!r}")
    if not 0 < level < 1:
        raise ValueError(f"level must lie between 0 and 1, got {level!r}")
    unknown = [k for k in keys if k not in RATIO_OF]
    if unknown:
        raise ValueError(f"{what} has no score {unknown[0]!r}; it knows {', '.join(RATIO_OF)}")


class _ImageSums:
    """Per image, every sum behind the scores of :data:`RATIO_OF`, so that a
    resample of images pools by adding rows."""

    fields = tuple(dict.fromkeys(f for pair in RATIO_OF.values() for f in pair))

    def __init__(self, parts):
        self.table = np.array([[sum(_field(p, f) for p in ps) for f in self.fields] for ps in parts], np.float64)

    def pooled(self, key, rows=None):
        """The pooled score over all images, or over each resample of ``rows`` (resamples x images)."""
        t = self.table if rows is None else self.table[rows]
        tot = t.sum(axis=-2)
        a, b = (self.fields.index(f) for f in RATIO_OF[key])
        with np.errstate(invalid="ignore", divide="ignore"):
            return tot[..., a] / tot[..., b]

    def image_mean(self, key, rows=None):
        """The mean over images of each image's own score (images without pixels left out)."""
        a, b = (self.fields.index(f) for f in RATIO_OF[key])
        with np.errstate(invalid="ignore", divide="ignore"):
            per = self.table[:, a] / self.table[:, b]
        return np.nanmean(per if rows is None else per[rows], axis=-1)


def _interval(values, level):
    lo, hi = np.nanquantile(values, [(1 - level) / 2, (1 + level) / 2])
    return float(lo), float(hi)


def bootstrap_scores(parts, n_resamples: int = 2000, seed: int = 0, keys=SCORES, level: float = 0.95) -> dict:
    """Each score pooled over the images, and the mean of the per-image scores,
    with the central ``level`` interval of a bootstrap over images.

    ``parts[i]`` lists image ``i``'s :func:`error_stats` parts (one per
    labeller, say). Each resample draws as many images as there are, with
    replacement. Pixels within one image are not independent, so resampling
    images, not pixels, says how much a score owes to which images were picked.

    Returns ``{key: {"pooled", "low", "high", "image_mean", "image_low", "image_high"}}``.
    """
    if not parts:
        raise ValueError("bootstrap_scores needs a non-empty list of images")
    _check_bootstrap(n_resamples, level, keys, "bootstrap_scores")
    s = _ImageSums(parts)
    pick = np.random.default_rng(seed).integers(0, len(parts), size=(n_resamples, len(parts)))
    out = {}
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a resample whose images have no pixels: nan
        for key in keys:
            lo, hi = _interval(s.pooled(key, pick), level)
            ilo, ihi = _interval(s.image_mean(key, pick), level)
            out[key] = {
                "pooled": float(s.pooled(key)),
                "low": lo,
                "high": hi,
                "image_mean": float(s.image_mean(key)),
                "image_low": ilo,
                "image_high": ihi,
            }
    return out


def bootstrap_difference(
    parts_a,
    parts_b,
    n_resamples: int = 2000,
    seed: int = 0,
    keys=("mean_signed_deg", "mean_abs_deg", "within45"),
    level: float = 0.95,
) -> dict:
    """How far the pooled difference ``b - a`` of each score could move with
    the choice of images: a paired bootstrap over images.

    ``parts_a[i]`` and ``parts_b[i]`` are the :func:`error_stats` parts of
    image ``i`` for the two models; each resample draws the same images for
    both (see :func:`bootstrap_scores`).

    Returns ``{key: {"difference", "low", "high"}}`` (the observed pooled
    difference and the central ``level`` interval of the resampled ones).
    """
    if len(parts_a) != len(parts_b) or not parts_a:
        raise ValueError("bootstrap_difference needs the same, non-empty list of images for both models")
    _check_bootstrap(n_resamples, level, keys, "bootstrap_difference")
    a, b = _ImageSums(parts_a), _ImageSums(parts_b)
    pick = np.random.default_rng(seed).integers(0, len(parts_a), size=(n_resamples, len(parts_a)))
    out = {}
    for key in keys:
        lo, hi = _interval(b.pooled(key, pick) - a.pooled(key, pick), level)
        out[key] = {"difference": float(b.pooled(key) - a.pooled(key)), "low": lo, "high": hi}
    return out
