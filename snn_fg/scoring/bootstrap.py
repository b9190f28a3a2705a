"""Intervals for the scores against human labels, from resampling the images.

The scores and their pooling over pixels are :mod:`snn_fg.scoring.label_scores`'
(:func:`~snn_fg.scoring.label_scores.error_stats`, :func:`~snn_fg.scoring.label_scores.pool_stats`,
the scores :data:`SCORES`). :func:`bootstrap_scores` gives each score, pooled over pixels and as a
mean over images, with an interval from resampling the images; :func:`bootstrap_difference` the
same for the difference of two models. The experiment pages' intervals come from here
(``experiments/pooled.py`` hands these on), and so do those ``snn-fg compare RUN LABELS`` prints
under a table of several images: one implementation, so that the command's interval is the pages'.
"""

from __future__ import annotations

import warnings

import numpy as np

from snn_fg.scoring.label_scores import RATIO_OF, SCORES
from snn_fg.scoring.label_scores import stats_field as _field

#: resamples of the images behind every interval the experiment pages and ``snn-fg compare RUN LABELS`` give
RESAMPLES = 2000


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


def bootstrap_scores(parts, n_resamples: int = RESAMPLES, seed: int = 0, keys=SCORES, level: float = 0.95) -> dict:
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
    n_resamples: int = RESAMPLES,
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
