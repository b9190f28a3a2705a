"""Comparisons between maps, and scores against ground truth.

Figure-ground maps are compared only where they say something: on *vector
pixels*. Angle differences are circular (``|a - b|`` folded into
[0, 180] degrees) and taken on the pixels where both maps have a vector: their
mean, median and the fraction within 45 degrees (a median of quantised
angles alone can read 0 while a third of the pixels are wrong). ``angle_mse``
is the mean of ``(difference / 180)**2`` on those pixels (0 = equal,
1 = opposite everywhere). ``angle_ssim`` is the SSIM (11 x 11 window) of the
angle maps (``atan2(fg_y, fg_x)`` in turns, 0 off the vectors), averaged over
the pixels where either map has a vector, not over the empty background.
Since those figures are over the shared pixels only, ``coverage_of_b`` gives
the fraction of ``b``'s vectors that ``a`` has at all, and
``within_45_of_b`` the fraction it has within 45 degrees: a map that leaves
the hard pixels blank cannot look good on them.
Grouping maps are dense and compared whole: Pearson r, and SSIM after scaling
each map by its own maximum (the spiking model's grouping is in Hz, the rate
model's in its own units).
"""

from __future__ import annotations

import numpy as np
from skimage.metrics import structural_similarity

from .. import validate as check
from ..results.maps import CONFIDENCE, Maps, has_vector
from .pairing import Pairing, pair_windows


def angle_difference_deg(ax, ay, bx, by) -> np.ndarray:
    """Absolute circular difference between two direction fields, degrees (float64)."""
    f = lambda v: np.asarray(v, dtype=np.float64)  # noqa: E731 - float32 maps lose 1e-5 deg here
    d = np.arctan2(f(ay), f(ax)) - np.arctan2(f(by), f(bx))
    return np.abs(np.degrees(np.angle(np.exp(1j * d))))


def angle_map(fg_x, fg_y) -> np.ndarray:
    nz = has_vector(fg_x, fg_y)
    a = (np.degrees(np.arctan2(fg_y, fg_x)) % 360.0) / 360.0
    return np.where(nz, a, 0.0)


def _ssim(a, b, where=None):
    """SSIM (11 x 11 window), averaged over the pixels ``where`` (default: all)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    rng = max(float(np.ptp(a)), float(np.ptp(b)), 1e-12)
    if min(a.shape) < 11 or (where is not None and not where.any()):
        return float("nan")
    mean, full = structural_similarity(a, b, win_size=11, data_range=rng, full=True)
    return float(mean if where is None else full[where].mean())


def _unit(a):
    a = np.asarray(a, dtype=np.float64)
    peak = np.abs(a).max() if a.size else 0.0
    return a / peak if peak > 0 else a


def pearson(a, b) -> float:
    a = np.asarray(a, dtype=np.float64).ravel()
    b = np.asarray(b, dtype=np.float64).ravel()
    if a.size < 2 or a.std() == 0 or b.std() == 0:  # (no spread, or none to have one: undefined)
        return float("nan")
    return float(np.corrcoef(a, b)[0, 1])


def compare_frame(ax, ay, ag, bx, by, bg) -> dict:
    """Metrics between two single-frame maps (see the module docstring)."""
    has_a, has_b = has_vector(ax, ay), has_vector(bx, by)
    both = has_a & has_b
    diff = angle_difference_deg(ax, ay, bx, by)[both]
    nan = float("nan")
    return {
        "pixels_compared": int(both.sum()),
        "pixels_a": int(has_a.sum()),
        "pixels_b": int(has_b.sum()),
        "angle_diff_mean_deg": float(np.mean(diff)) if diff.size else nan,
        "angle_diff_median_deg": float(np.median(diff)) if diff.size else nan,
        "angle_within_45_frac": float(np.mean(diff <= 45)) if diff.size else nan,
        "coverage_of_b": float(both.sum() / has_b.sum()) if has_b.any() else nan,
        "within_45_of_b": float(np.sum(diff <= 45) / has_b.sum()) if has_b.any() else nan,
        "angle_mse": float(np.mean((diff / 180.0) ** 2)) if diff.size else nan,
        "angle_ssim": _ssim(angle_map(ax, ay), angle_map(bx, by), has_a | has_b),
        "grouping_pearson_r": pearson(ag, bg),
        "grouping_ssim": _ssim(_unit(ag), _unit(bg)),
    }


def agreement(a, b) -> dict:
    """The four numbers an experiment table gives for maps ``a`` against
    maps ``b`` (each ``(fg_x, fg_y, grouping)`` or an object with those
    attributes): mean absolute angle difference and fraction within 45 deg
    on the pixels where both have a vector, grouping Pearson r, and the
    fraction of ``b``'s vectors that ``a`` has at all (``coverage``)."""
    a, b = (m if isinstance(m, tuple) else (m.fg_x, m.fg_y, m.grouping) for m in (a, b))
    c = compare_frame(*a, *b)
    return {
        "mean_deg": c["angle_diff_mean_deg"],
        "within_45": c["angle_within_45_frac"],
        "grouping_r": c["grouping_pearson_r"],
        "coverage": c["coverage_of_b"],
    }


def frame_of(m: Maps, i):
    """``(fg_x, fg_y, grouping)`` of window ``i`` of ``m`` (``None``: ``m`` is one frame)."""
    return (m.fg_x, m.fg_y, m.grouping) if i is None else (m.fg_x[i], m.fg_y[i], m.grouping[i])


#: how many standard errors of its spike counts a spiking vector is long before a spike or two no longer
#: decide it (about 1 where they do); the verdict says how many of A's compared vectors reach it
SURE_CONFIDENCE = 2.0


def share_text(x: float) -> str:
    """A share in words a title or a verdict can hold: "none", "under 1%", "25%"."""
    return "none" if x == 0 else "under 1%" if x < 0.005 else f"{x:.0%}"


def confident(m: Maps, i, min_confidence: float | None) -> np.ndarray | None:
    """Where window ``i`` of ``m`` has a vector at least ``min_confidence``
    standard errors long (:data:`~snn_fg.results.maps.CONFIDENCE`), or
    ``None``: no threshold, or ``m`` stores no confidence (a rate model's
    maps, which have no spike counts)."""
    conf = m.extra.get(CONFIDENCE)
    if min_confidence is None or conf is None:
        return None
    return (conf if i is None else conf[i]) >= min_confidence


def compared_pixels(a: Maps, b: Maps, ia, ib, where=None, min_confidence: float | None = None):
    """The pixels on which :func:`compare_maps` compares both maps' vectors
    (windows ``ia``, ``ib``): ``where``'s, where each map that stores a
    confidence has a vector at least ``min_confidence`` long; None: all
    (a reference's own baseline is scored on the same pixels)."""
    keep = None
    for k in (
        None if where is None else where(ia, ib),
        confident(a, ia, min_confidence),
        confident(b, ib, min_confidence),
    ):
        if k is not None:
            keep = k if keep is None else keep & k
    return keep


def compare_maps(
    a: Maps,
    b: Maps,
    window: int | None = None,
    where=None,
    min_confidence: float | None = None,
    pairing: Pairing | None = None,
) -> list[dict]:
    """Compare two Maps; one dict per compared pair of windows.

    Parameters
    ----------
    a, b : Maps
        One frame each, or one map per window of a recording.
    window : int, optional
        Compare only this window of each map that has several.
    where : callable, optional
        ``where(window_a, window_b)``: the pixels whose vectors are compared
        (a boolean map), e.g. the outline of the window's event region
        (:func:`snn_fg.scoring.outline.event_outlines`). The grouping metrics stay on
        the whole map.
    min_confidence : float, optional
        Compare only the vectors of a spiking run at least this many
        standard errors of their spike counts long
        (:data:`~snn_fg.results.maps.CONFIDENCE`; a map without it keeps
        every vector). ``coverage_of_b`` then says how much of ``b`` is left
        compared; ``confident_a``/``confident_b`` how much of each map's
        vectors passed.
    pairing : Pairing, optional
        The windows to compare, as :func:`~snn_fg.scoring.pairing.pair_windows`
        gives them for ``window`` (made here if not given).

    Returns
    -------
    list of dict
        Per pair: ``window_a``, ``window_b`` (the windows' places in the maps),
        ``number_a``, ``number_b`` (their numbers in their recording or stream),
        ``t_start_ms`` (B's window start after B's first event) and the metrics
        of :func:`compare_frame` (see the module docstring); where ``a`` stores a
        confidence (a spiking run), that of its vectors on the pixels compared:
        ``confidence_median_a`` and ``confidence_sure_a``, the share at least
        :data:`SURE_CONFIDENCE` long.

    Examples
    --------
    >>> import numpy as np
    >>> from snn_fg.results.maps import Maps
    >>> fx = np.zeros((16, 16), np.float32); fx[8, 2:14] = 1
    >>> a = Maps(fx, 0 * fx, fx.copy())
    >>> b = Maps(-fx, 0 * fx, fx.copy())          # the same edge, owned by the other side
    >>> row, = compare_maps(a, b)
    >>> row["pixels_compared"], row["angle_diff_mean_deg"], row["angle_within_45_frac"]
    (12, 180.0, 0.0)

    Two recordings are paired by the events their windows hold: by window start on
    the events' own clock where both runs keep it, keeping the windows both have
    (:mod:`snn_fg.scoring.pairing` says how, and how runs stored before are paired).
    ``window`` picks that place of each map that has more than one window, and
    compares them whatever their start times. Every row says which windows it
    compared.
    """
    if a.fg_x.shape[-2:] != b.fg_x.shape[-2:]:
        grids = [m.params.get("maps_grid", "sensor") for m in (a, b)]
        hint = (
            f" (maps on the {grids[0]} grid vs the {grids[1]} grid: run both with one --maps-grid)"
            if grids[0] != grids[1]
            else ""
        )
        (ha, wa), (hb, wb) = a.fg_x.shape[-2:], b.fg_x.shape[-2:]
        check.fail("compare_maps", None, None, f"frames differ in size: {wa} x {ha} vs {wb} x {hb}{hint}")
    pairing = pair_windows(a, b, window) if pairing is None else pairing
    rows = []
    for (ia, ib), (na, nb), t in zip(pairing.pairs, pairing.numbers, pairing.t_us, strict=True):
        (ax, ay, ag), (bx, by, bg) = frame_of(a, ia), frame_of(b, ib)
        if where is not None:
            keep = where(ia, ib)
            ax, ay, bx, by = (np.where(keep, v, 0) for v in (ax, ay, bx, by))
        share = {}
        for side, m, i in (("a", a, ia), ("b", b, ib)):
            keep = confident(m, i, min_confidence)
            if keep is not None:
                x, y = (ax, ay) if side == "a" else (bx, by)
                has = has_vector(x, y)
                share[f"confident_{side}"] = float((has & keep).sum() / has.sum()) if has.any() else float("nan")
                x, y = np.where(keep, x, 0), np.where(keep, y, 0)
                ax, ay, bx, by = (x, y, bx, by) if side == "a" else (ax, ay, x, y)
        rows.append(
            {
                "window_a": ia,
                "window_b": ib,
                "number_a": na,
                "number_b": nb,
                "t_start_ms": None if t is None else t / 1000.0,
                **compare_frame(ax, ay, ag, bx, by, bg),
                **share,
                **_sureness(a, ia, has_vector(ax, ay) & has_vector(bx, by)),
            }
        )
    return rows


def _sureness(a: Maps, i, compared) -> dict:
    """How sure A's vectors on the ``compared`` pixels of its window ``i`` are, where A stores a
    confidence (a spiking run): their median confidence and the share at least
    :data:`SURE_CONFIDENCE` long (nan: no pixel compared); ``{}`` otherwise."""
    conf = a.extra.get(CONFIDENCE)
    if conf is None:
        return {}
    c = np.asarray(conf if i is None else conf[i], dtype=np.float64)[compared]
    nan = float("nan")
    return {
        "confidence_median_a": float(np.median(c)) if c.size else nan,
        "confidence_sure_a": float(np.mean(c >= SURE_CONFIDENCE)) if c.size else nan,
    }


def truth_errors(fg_x, fg_y, scene) -> np.ndarray:
    """Angle (deg) between each scored pixel's vector and the analytic
    direction: the boundary pixels where the model has a vector; NaN
    elsewhere."""
    m = scene.boundary & has_vector(fg_x, fg_y)
    err = np.full(np.shape(fg_x), np.nan)
    err[m] = angle_difference_deg(fg_x[m], fg_y[m], scene.truth_x[m], scene.truth_y[m])
    return err


def truth_scores(fg_x, fg_y, scene) -> dict:
    """Figure-ground direction against a scene's analytic ground truth.

    Scored on boundary pixels where the model vector is non-zero; ``coverage``
    is the fraction of boundary pixels that have a model vector at all.
    """
    b = scene.boundary
    err_map = truth_errors(fg_x, fg_y, scene)
    m = np.isfinite(err_map)
    err = err_map[m]
    return {
        "boundary_pixels": int(b.sum()),
        "scored_pixels": int(m.sum()),
        "coverage": float(m.sum() / max(b.sum(), 1)),
        "frac_within_45": float(np.mean(err <= 45)) if err.size else float("nan"),
        "median_err_deg": float(np.median(err)) if err.size else float("nan"),
        "mean_err_deg": float(np.mean(err)) if err.size else float("nan"),
    }


def grouping_peak(grouping) -> tuple[int, int]:
    """(row, col) of the grouping maximum."""
    return tuple(int(v) for v in np.unravel_index(np.argmax(grouping), grouping.shape))


def grouping_peak_inside(grouping, scene, shape_index: int | None = 0) -> bool:
    """Whether the grouping maximum lies inside ``scene.shapes[shape_index]``
    (inside any of the scene's shapes with ``shape_index=None``)."""
    r, c = grouping_peak(grouping)
    shapes = scene.shapes if shape_index is None else (scene.shapes[shape_index],)
    return any(s.contains(float(r), float(c)) for s in shapes)


def flipped_within_45(a: Maps, b: Maps, pairing: Pairing, where=None, min_confidence: float | None = None) -> dict:
    """Over the windows ``pairing`` pairs and the pixels :func:`compare_maps` compares there, the
    share of A's vectors within 45 degrees of B's once B's ``"y"`` axis, its ``"x"`` axis, or
    ``"both"`` (B negated) are flipped: an export that writes an axis the other way round agrees
    only so. Pooled by pixel; ``{}`` when no pixel is compared."""
    hits, n = {"both": 0, "y": 0, "x": 0}, 0
    for ia, ib in pairing.pairs:
        (ax, ay, _), (bx, by, _) = frame_of(a, ia), frame_of(b, ib)
        keep = compared_pixels(a, b, ia, ib, where, min_confidence)
        both = has_vector(ax, ay) & has_vector(bx, by) & (True if keep is None else keep)
        ax, ay, bx, by = (np.asarray(v)[both] for v in (ax, ay, bx, by))
        n += ax.size
        hits["y"] += int(np.sum(angle_difference_deg(ax, ay, bx, -by) <= 45))
        hits["x"] += int(np.sum(angle_difference_deg(ax, ay, -bx, by) <= 45))
        hits["both"] += int(np.sum(angle_difference_deg(ax, ay, -bx, -by) <= 45))
    return {axis: k / n for axis, k in hits.items()} if n else {}
