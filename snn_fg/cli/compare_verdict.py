"""``snn-fg compare``'s verdict on a pair of maps (:mod:`.compare_maps`): their agreement pooled over
the compared windows (:func:`overall`), set beside what unrelated maps give and beside the
reference's agreement with itself (:func:`verdict`), and the note for a pair whose agreement an
axis flipped back would raise (:func:`axis_flip`)."""

from __future__ import annotations

import math

from ..scoring.metrics import SURE_CONFIDENCE, share_text

#: what two unrelated maps give: directions uniformly at random, so a quarter within 45 degrees, 90 degrees apart
CHANCE_WITHIN_45, CHANCE_MEAN_DEG = 0.25, 90.0
#: one unrelated pixel's spread: within 45 degrees or not (binomial, p = 0.25), and its difference,
#: uniform on 0-180 degrees
_PIXEL_SD_WITHIN, _PIXEL_SD_MEAN_DEG = math.sqrt(CHANCE_WITHIN_45 * (1 - CHANCE_WITHIN_45)), 180 / math.sqrt(12)
#: how far from chance a pooled figure of n pixels lies before the verdict tells it from chance:
#: CHANCE_SDS standard deviations of what n unrelated pixels give, and at least the floors
#: (neighbouring pixels' vectors are not independent: n pixels are fewer independent draws)
CHANCE_SDS, FLOOR_WITHIN_45, FLOOR_MEAN_DEG = 3.0, 0.10, 10.0


def chance_margins(n: int) -> tuple[float, float]:
    """How far from chance (:data:`CHANCE_SDS`) the share within 45 degrees and the mean difference
    of ``n`` compared pixels must lie to be told from unrelated maps'."""
    return (
        max(FLOOR_WITHIN_45, CHANCE_SDS * _PIXEL_SD_WITHIN / math.sqrt(n)),
        max(FLOOR_MEAN_DEG, CHANCE_SDS * _PIXEL_SD_MEAN_DEG / math.sqrt(n)),
    )


def _pooled(rows, key) -> float | None:
    """``key`` over the rows that have it, each weighted by its pixels compared (None: no such row)."""
    have = [r for r in rows if r.get(key) is not None and r.get("pixels_compared")]
    n = sum(r["pixels_compared"] for r in have)
    return sum(r["pixels_compared"] * r[key] for r in have) / n if n else None


def overall(rows) -> dict:
    """The figures the verdict gives, pooled over every compared window: the pixels compared, the
    share of them within 45 degrees and the mean difference (each window weighted by its pixels
    compared), the share of B's vectors they are (``coverage_of_b``) and of those within 45 degrees
    (``within_45_of_b``), both over all B's vectors, and where A stores a confidence the share of
    the pixels compared where A's vector is at least
    :data:`~snn_fg.scoring.metrics.SURE_CONFIDENCE` long (``confidence_sure_a``) and the lowest and
    highest of the windows' median confidence there; None where no row tells."""
    n = sum(r.get("pixels_compared") or 0 for r in rows)
    of_b = sum(r.get("pixels_b") or 0 for r in rows)
    within = _pooled(rows, "angle_within_45_frac")
    medians = [r["confidence_median_a"] for r in rows if r.get("pixels_compared") and "confidence_median_a" in r]
    return {
        "pixels_compared": n,
        "angle_within_45_frac": within,
        "angle_diff_mean_deg": _pooled(rows, "angle_diff_mean_deg"),
        "coverage_of_b": n / of_b if of_b else None,
        "within_45_of_b": within * n / of_b if of_b and within is not None else None,
        "confidence_sure_a": _pooled(rows, "confidence_sure_a"),
        "confidence_median_a_range": [min(medians), max(medians)] if medians else None,
    }


def over_what(rows) -> str:
    """What the verdict pools, in words: every image's windows, the one frame of each map, or every window."""
    if any("image" in r for r in rows):
        return "All images"
    frames = all("window_a" in r and r["window_a"] is None and r["window_b"] is None for r in rows)
    return "The frame" if frames else "All windows"


def _how_many(figures: dict) -> str:
    """How much of B the pixels compared are, and how sure A's vectors on them are, in words."""
    said = "" if figures["coverage_of_b"] is None else f", which are {figures['coverage_of_b']:.0%} of B's vectors"
    sure = figures["confidence_sure_a"]
    if sure is None:
        return said
    low, high = figures["confidence_median_a_range"]
    median = f"median {low:.1f}" + ("" if f"{low:.1f}" == f"{high:.1f}" else f" to {high:.1f} a window")
    share = share_text(sure)
    at = f"at confidence {SURE_CONFIDENCE:g} or more"
    if sure < 0.5:
        return f"{said}, most of A's decided by a spike or two ({'only ' * (sure > 0)}{share} {at}, {median})"
    return f"{said}, {share} of A's {at} ({median})"


#: a mean absolute difference under this (degrees) is two maps with the same directions (a run against
#: itself, or a board against the reference bit for bit), said so rather than "above chance"
SAME_DEG = 0.01


def verdict(rows) -> str:
    """One line over every compared window (pixel-weighted, :func:`overall`): A's agreement with B
    beside what unrelated maps give and, where the rows have it, beside B's agreement with itself;
    with how much of B's vectors it was measured on, and how sure A's vectors there are. Within
    :func:`chance_margins` of chance is near chance; the share within 45 degrees that far below it
    is below chance, and with the mean difference that far above 90 degrees, opposed (B reversed)."""
    figures = overall(rows)
    n, over, how = figures["pixels_compared"], over_what(rows), _how_many(figures)
    if not n:
        return f"{over}: no pixel where both maps have a vector; nothing to judge."
    within, mean = figures["angle_within_45_frac"], figures["angle_diff_mean_deg"]
    own = _pooled(rows, "baseline_within_45")
    near_within, near_mean = chance_margins(n)
    if mean < SAME_DEG:
        word = f"the same directions on every compared pixel (under {SAME_DEG:g}° apart)"
    elif within <= CHANCE_WITHIN_45 - near_within and mean >= CHANCE_MEAN_DEG + near_mean:
        word = "opposed: B points the other way on most pixels (a sign or axis flip?)"
    elif within <= CHANCE_WITHIN_45 - near_within:
        word = "below chance: B's directions are turned from A's, not unrelated (an axis swapped?)"
    elif within < CHANCE_WITHIN_45 + near_within:
        word = "near chance: the two maps' directions are unrelated"
    elif own is not None and within >= own - 0.05:
        word = "as close as B's model comes to itself"
    else:
        word = "above chance" + ("" if own is None else ", short of how close B's model comes to itself")
    against = f"chance {CHANCE_WITHIN_45:.0%} and {CHANCE_MEAN_DEG:.0f}°" + (
        "" if own is None else f"; B against itself {own:.1%}"
    )
    return (
        f"{over}: A within 45° of B on {within:.1%} of {n:,} pixels{how}{';' if how else ','} "
        f"mean absolute difference {mean:.1f}° "
        f"({against}): {word}."
    )


def axis_flip(rows, flipped: dict) -> str | None:
    """The note for a pair that agrees far better once one of B's axes is flipped
    (:func:`~snn_fg.scoring.metrics.flipped_within_45`): above chance by :func:`chance_margins`,
    that far above the agreement as stored, and better than B negated (which the verdict calls
    opposed); None otherwise."""
    n = sum(r.get("pixels_compared") or 0 for r in rows)
    if not n or not flipped:
        return None
    margin, _ = chance_margins(n)
    within = _pooled(rows, "angle_within_45_frac")
    axis = max(flipped, key=flipped.get)  # (B negated first among equals: an edge's one axis flipped reads so too)
    if axis == "both" or flipped[axis] < max(CHANCE_WITHIN_45, within) + margin:
        return None
    return (
        f"A agrees with B once B's {axis} axis is flipped (within 45° on {flipped[axis]:.1%} of the pixels, "
        f"against {within:.1%} as stored): does one of them draw {axis} the other way round?"
    )
