"""Scoring figure-ground vectors along an object's outline (snn_fg.scoring.outline)."""

import numpy as np

from snn_fg.scoring.outline import inward_angles, inward_score


def _disc(turn_deg):
    """A disc region and unit vectors at every pixel pointing to its centre,
    turned by ``turn_deg`` (counter-clockwise, y up)."""
    r, c = np.mgrid[0:64, 0:64].astype(float)
    region = (r - 32) ** 2 + (c - 32) ** 2 <= 20**2
    ang = np.arctan2(r - 32, 32 - c) + np.radians(turn_deg)  # towards the centre, y up
    return np.cos(ang), np.sin(ang), region


def test_vectors_to_the_centre_are_inward_and_turned_ones_are_not():
    fx, fy, region = _disc(0)
    mean, within = inward_angles(fx, fy, region)
    assert mean < 5 and within == 1.0
    assert inward_score(fx, fy, region)[0] == 1.0
    fx, fy, region = _disc(80)  # along the outline: the sign test still calls most of them inward
    mean, within = inward_angles(fx, fy, region)
    assert 75 < mean < 85 and within == 0.0
    assert inward_score(fx, fy, region)[0] > 0.9
    fx, fy, region = _disc(180)
    mean, within = inward_angles(fx, fy, region)
    assert mean > 175 and within == 0.0 and inward_score(fx, fy, region)[0] == 0.0


def test_no_vectors_scores_nan():
    region = np.zeros((16, 16), bool)
    region[4:12, 4:12] = True
    zero = np.zeros((16, 16))
    assert all(np.isnan(v) for v in inward_angles(zero, zero, region))


def test_outline_scores_gives_both_scores_from_one_pass():
    from snn_fg.scoring.outline import outline_scores

    fx, fy, region = _disc(80)
    o = outline_scores(fx, fy, region)
    assert 75 < o["mean_deg"] < 85 and o["within45"] == 0.0 and o["inward"] > 0.9 and o["vectors"] > 100
    assert (o["inward"], o["vectors"]) == inward_score(fx, fy, region)
    zero = np.zeros_like(fx)
    empty = outline_scores(zero, zero, region)
    assert empty["vectors"] == 0 and all(np.isnan(empty[k]) for k in ("inward", "mean_deg", "within45"))
