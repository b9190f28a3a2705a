"""The paper's evaluation on one BSDS image: models against human figure/ground labels.

:func:`evaluate_image` is the unit of work of the Table 1 / Fig. 6 sweeps
(``experiments.paper.table1``, ``fig6``, ``best_worst``): it turns the
image into events at every contrast threshold, runs the event model(s) and
the frame-based model with each edge operator through their public entry
points, scores every figure-ground map against both labellers, and compares
the maps with each other (Fig. 6). It returns a JSON-serialisable dict, so
that :func:`experiments.sweep.run_sweep` can cache it per image. The
scores are kept as sums to pool over images (:mod:`snn_fg.scoring.label_scores`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from skimage.metrics import structural_similarity

from snn_fg.events import image_to_frame
from snn_fg.events.images import read_image
from snn_fg.frames.scenes import disc
from snn_fg.models import MODELS, Still, get_model
from snn_fg.models.rate.fbfg import run_fbfg
from snn_fg.params import ModelParams
from snn_fg.results.figures import fg_rgb
from snn_fg.scoring.groundtruth import angle_errors, boundary_directions, load_bsds_fg
from snn_fg.scoring.label_scores import error_stats, field_errors
from snn_fg.scoring.metrics import grouping_peak, truth_scores

#: SSIM window of the paper (MATLAB's default).
SSIM_WINDOW = 11
#: The threshold of the Fig. 6 comparisons (the paper's best).
FIG6_THRESHOLD = 0.10
#: What an :func:`evaluate_image` result holds, for caches keyed on it (2: the
#: side-accuracy count and the labelled-pixel count of every score).
RESULT_VERSION = 2


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


def _model(name: str, params, spiking_options: dict):
    """The registered model ``name`` with ``params``; ``spiking_options`` go
    to a model that simulates a network on a backend (one that takes the
    option ``backend``)."""
    takes_backend = "backend" in getattr(MODELS.get(name), "options", ())
    return get_model(name, params, **(spiking_options if takes_backend else {}))


def _event_maps(unit, image, threshold, motion):
    """Maps of an event model ``unit`` on ``image`` (array or path) turned into events, and the event pixel count."""
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
                **field_errors(maps.fg_x, maps.fg_y, truths),
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
                **field_errors(maps.fg_x, maps.fg_y, truths),
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
    params = ModelParams(r0=r0)
    scene = disc(radius=diameter / 2, light_on_dark=False, margin=1.5)
    unit = _model(model, params, spiking_options or {})
    if unit.needs == "image":
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
            {"name": name, "seconds": time.perf_counter() - t0, **field_errors(maps.fg_x, maps.fg_y, truths)}
        )
    return out
