"""The paper's evaluation on one BSDS image: models against human figure/ground labels.

:func:`evaluate_image` is the unit of work of the Table 1 / Fig. 6 sweeps
(``experiments.paper.table1``, ``fig6``, ``best_worst``): it turns the
image into events at every contrast threshold, runs the event model(s) and
the frame-based model with each edge operator through their public entry
points, scores every figure-ground map against both labellers, and compares
the maps with each other (Fig. 6). It returns a JSON-serialisable dict, so
that :func:`snn_fg.scoring.sweep.run_sweep` can cache it per image.

Angle errors are kept as sums and a histogram of absolute errors
(:data:`HIST_BIN_DEG` bins), so that pooled means are exact and the pooled
median is good to half a bin, without storing every pixel. The scores
(:data:`SCORES`): **side accuracy**, the field's own metric (the share of
scored pixels whose direction is within 90 degrees of the labelled one, i.e.
on the figure's side; chance 50 %); **coverage** (labelled pixels that get a
vector, over all labelled pixels); the share within 45 degrees; the mean
absolute and the mean signed error (the paper's). :func:`bootstrap_scores`
gives each, pooled over pixels and as a mean over images, with an interval
from resampling the images.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from skimage.metrics import structural_similarity

from .groundtruth import SIDE_DEG, WITHIN_DEG, angle_errors, boundary_directions, load_bsds_fg

#: Width (degrees) of the bins of the absolute-error histogram.
HIST_BIN_DEG = 0.5
_N_BINS = int(round(180 / HIST_BIN_DEG))
#: SSIM window of the paper (MATLAB's default).
SSIM_WINDOW = 11
#: The threshold of the Fig. 6 comparisons (the paper's best).
FIG6_THRESHOLD = 0.10
#: What an :func:`evaluate_image` result holds, for caches keyed on it (2: the
#: side-accuracy count and the labelled-pixel count of every score).
RESULT_VERSION = 2


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


def _unit(x, y):
    mag = np.hypot(x, y)
    has = mag > 0
    return np.where(has, x / np.where(has, mag, 1), 0.0), np.where(has, y / np.where(has, mag, 1), 0.0)


def angle_image(x, y) -> np.ndarray:
    """The angle map: direction in turns [0, 1) where there is a vector, 0 elsewhere."""
    turns = (np.arctan2(y, x) % (2 * np.pi)) / (2 * np.pi)
    return np.where(np.hypot(x, y) > 0, turns, 0.0)


def map_similarity(a, b) -> dict:
    """SSIM (11 x 11, whole image) and MSE of two direction fields ``(x, y)``, on angle maps
    (turns, 0 off the vectors) and on their colour-wheel renderings (the paper's)."""
    return _similarity(_views(a), _views(b))


def _views(field):
    """The angle map and the colour-wheel rendering of a direction field ``(x, y)``."""
    from ..results.figures import fg_rgb

    return angle_image(*field), fg_rgb(*_unit(*field))


def _similarity(va, vb) -> dict:
    """:func:`map_similarity` of two fields given by their :func:`_views`."""
    (ia, ra), (ib, rb) = va, vb
    return {
        "ssim_angle": float(structural_similarity(ia, ib, win_size=SSIM_WINDOW, data_range=1.0)),
        "mse_angle": float(np.mean((ia - ib) ** 2)),
        "ssim_render": float(structural_similarity(ra, rb, win_size=SSIM_WINDOW, data_range=1.0, channel_axis=-1)),
        "mse_render": float(np.mean((ra - rb) ** 2)),
    }


def _scores(fx, fy, truths) -> dict:
    """Error stats of a field against every labeller's directions, pooled."""
    signed = np.concatenate([angle_errors(fx, fy, *t) for t in truths])
    return error_stats(signed, n_truth=sum(int(t[2].sum()) for t in truths))


def _model(name: str, params, spiking_options: dict):
    """The registered model ``name`` with ``params``; ``spiking_options`` go
    to a model that simulates a network on a backend (one that takes the
    option ``backend``)."""
    from ..models import MODELS, get_model

    takes_backend = "backend" in getattr(MODELS.get(name), "options", ())
    return get_model(name, params, **(spiking_options if takes_backend else {}))


def _event_maps(unit, image, threshold, motion):
    """Maps of an event model ``unit`` on ``image`` (array or path) turned into events, and the event pixel count."""
    from ..events import image_to_frame
    from ..frames.still import Still

    pos, neg = image_to_frame(image, threshold=threshold, motion=motion)
    return unit.run_still(Still(pos, neg)), int((pos | neg).sum())


@dataclass(frozen=True, kw_only=True)
class ImageEvaluation:
    """What :func:`evaluate_image` runs on each image: the event models
    (``event_models``, of "rate" and "spiking", with ``spiking_options``) on
    ``--motion paper`` events at each of ``thresholds`` and on the built-in
    ``shift4`` events at each of ``shift4_thresholds``; the frame-based model
    on the image once per edge operator (``fbfg_operators``, of "gaussian" and
    "corf"); grouping radius ``r0`` (default: the paper's 8 px); with ``fig6``
    the maps compared with each other (needs threshold 0.10 and both kinds
    of model)."""

    thresholds: tuple = (0.10,)
    shift4_thresholds: tuple = ()
    event_models: tuple = ("rate",)
    fbfg_operators: tuple = ("gaussian", "corf")
    r0: float | None = None
    spiking_options: dict | None = None
    fig6: bool = True


def evaluate_image(*, root: str, image_id: str, settings: ImageEvaluation | None = None) -> dict:
    """Everything the Table 1 / Fig. 6 sweeps need from one image.

    Parameters
    ----------
    root : str
        The ``bsds-fg`` folder.
    image_id : str
    settings : ImageEvaluation
        Which models run, on which events (default: the rate model at 0.10 and both frame-based operators).

    Returns
    -------
    dict
        ``units``: one entry per (model, motion, threshold) with its error stats
        (:func:`error_stats`) against both labellers; ``ceiling``: labeller 2
        against labeller 1; ``fig6``: :func:`map_similarity` of the pairs.
    """
    from ..events.images import read_image
    from ..models.rate.fbfg import run_fbfg
    from ..params import ModelParams

    opts = settings or ImageEvaluation()
    params = ModelParams() if opts.r0 is None else ModelParams(r0=opts.r0)
    gt = load_bsds_fg(root, image_id)
    truths = [boundary_directions(m) for m in gt.fg]
    a, b = truths[0], truths[1] if len(truths) > 1 else truths[0]
    out = {
        "image_id": str(image_id),
        "shape": list(gt.fg.shape[1:]),
        "units": [],
        "ceiling": error_stats(
            angle_errors(np.where(b[2], b[0], 0), np.where(b[2], b[1], 0), *a), n_truth=int(a[2].sum())
        ),
    }
    fields = {"GT": a[:2], "GT2": (np.where(b[2], b[0], 0), np.where(b[2], b[1], 0))}
    runs = [(m, "paper", t) for m in opts.event_models for t in opts.thresholds]
    runs += [(m, "shift4", t) for m in opts.event_models for t in opts.shift4_thresholds]
    for model, motion, threshold in runs:
        maps, n_events = _event_maps(
            _model(model, params, opts.spiking_options or {}), str(gt.image_path), threshold, motion
        )
        out["units"].append(
            {
                "model": model,
                "motion": motion,
                "threshold": threshold,
                "event_pixels": n_events,
                **_scores(maps.fg_x, maps.fg_y, truths),
            }
        )
        if motion == "paper" and np.isclose(threshold, FIG6_THRESHOLD):
            fields[f"ED-{model}"] = (maps.fg_x, maps.fg_y)
    image = read_image(gt.image_path, grey=False)
    for op in opts.fbfg_operators:
        maps = run_fbfg(image, params, edge_operator=op)
        name = "fbfg" if op == "gaussian" else f"fbfg-{op}"
        out["units"].append(
            {
                "model": name,
                "motion": "image",
                "threshold": None,
                "event_pixels": None,
                **_scores(maps.fg_x, maps.fg_y, truths),
            }
        )
        fields[f"FB-{name}"] = (maps.fg_x, maps.fg_y)
    if opts.fig6:
        views = {k: _views(f) for k, f in fields.items()}  # each field rendered once, not once per pair
        out["fig6"] = {f"{p}|{q}": _similarity(views[p], views[q]) for p, q in combinations(sorted(fields), 2)}
    return out


#: A grouping peak within this fraction of the radius (and at least HIT_MIN_PX) of a disc's centre hits it.
HIT_RADIUS_FRACTION = 0.25
#: 3 px: the spiking network's grouping cells sit on a stride-2 lattice (up to 1.4 px off), plus 1.5 px.
HIT_MIN_PX = 3.0


def evaluate_disc(
    *, model: str, r0: float, diameter: float, threshold: float = 0.10, spiking_options: dict | None = None
) -> dict:
    """One dark disc of ``diameter`` px on a white canvas (the paper's Fig. S3 stimulus) through
    ``model`` (``rate`` / ``spiking`` on shift4 events, ``fbfg`` on the image) with grouping radius ``r0``.

    Returns the grouping peak's distance from the centre and whether it hits
    the centre, the rim's angle errors (:func:`snn_fg.scoring.metrics.truth_scores`),
    and SSIM / MSE of the map against the ideal one (:func:`map_similarity`).
    """
    from ..frames.scenes import disc
    from ..params import ModelParams
    from .metrics import grouping_peak, truth_scores

    params = ModelParams(r0=r0)
    scene = disc(radius=diameter / 2, light_on_dark=False, margin=1.5)
    unit = _model(model, params, spiking_options or {})
    if unit.needs == "image":
        from ..frames.still import Still

        maps = unit.run_still(Still(image=scene.image))
    else:
        maps, _ = _event_maps(unit, scene.image, threshold, "shift4")
    row, col = grouping_peak(maps.grouping)
    cr, cc = scene.shapes[0].centre
    dist = float(np.hypot(row - cr, col - cc))
    truth = (np.where(scene.boundary, scene.truth_x, 0), np.where(scene.boundary, scene.truth_y, 0))
    return {
        "model": model,
        "r0": r0,
        "diameter": diameter,
        "peak_distance_px": dist,
        "hit": bool(dist <= max(HIT_MIN_PX, HIT_RADIUS_FRACTION * diameter / 2)),
        **truth_scores(maps.fg_x, maps.fg_y, scene),
        **map_similarity((maps.fg_x, maps.fg_y), truth),
    }


def evaluate_models(*, root: str, image_id: str, models: dict, threshold: float = 0.10, motion: str = "paper") -> dict:
    """Named models (variants) on one image, each scored against both labellers.

    Parameters
    ----------
    root : str
        The ``bsds-fg`` folder.
    image_id : str
    models : dict
        ``{name: {"model": a name of snn_fg.models.MODELS, "params": changes to
        that model's own parameters, "options": its options}}``; ``params`` and
        ``options`` may be left out.
    threshold, motion : float, str
        How the image becomes events (:func:`snn_fg.events.image_to_frame`);
        the frame-based models see the image.

    Returns
    -------
    dict
        ``units``: one entry per name with its :func:`error_stats` against both
        labellers (and ``seconds``, the model's run time).
    """
    import time

    from ..events import image_to_frame
    from ..events.images import read_image
    from ..models import MODELS, Still, get_model

    gt = load_bsds_fg(root, image_id)
    truths = [boundary_directions(m) for m in gt.fg]
    pos, neg = image_to_frame(str(gt.image_path), threshold=threshold, motion=motion)
    frame = Still(pos, neg, read_image(gt.image_path, grey=False))
    out = {
        "image_id": str(image_id),
        "shape": list(gt.fg.shape[1:]),
        "event_pixels": int((pos | neg).sum()),
        "units": [],
    }
    for name, spec in models.items():
        kind = spec["model"]
        params = MODELS[kind].base_params.replace(**spec.get("params", {}))
        t0 = time.perf_counter()
        maps = get_model(kind, params, **spec.get("options", {})).run_still(frame)
        out["units"].append(
            {"name": name, "seconds": time.perf_counter() - t0, **_scores(maps.fg_x, maps.fg_y, truths)}
        )
    return out
