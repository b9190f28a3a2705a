"""Rate and frame-based models against the analytic ground truth of synthetic scenes."""

import numpy as np
import pytest

from snn_fg.events import image_to_frame
from snn_fg.frames import scenes
from snn_fg.models.rate.edfg import run_edfg
from snn_fg.models.rate.fbfg import run_fbfg
from snn_fg.scoring.metrics import grouping_peak_inside, truth_scores


@pytest.mark.parametrize("radius", [16, 28, 40, 64])
@pytest.mark.parametrize("light", [True, False], ids=["light-on-dark", "dark-on-light"])
def test_rate_model_on_discs(radius, light):
    sc = scenes.disc(radius, light_on_dark=light)
    pos, neg = image_to_frame(sc.image, threshold=0.10)
    m = run_edfg(pos, neg)
    s = truth_scores(m.fg_x, m.fg_y, sc)
    assert s["scored_pixels"] > 4 * radius  # most of the rim carries a vector
    assert s["frac_within_45"] >= 0.80, s
    assert s["median_err_deg"] <= 10, s
    assert grouping_peak_inside(m.grouping, sc)


@pytest.mark.parametrize(
    "scene", [scenes.disc(28, True), scenes.disc(40, False), scenes.square(24, True)], ids=lambda s: s.name
)
def test_fbfg_on_shapes(scene):
    m = run_fbfg(scene.image)
    s = truth_scores(m.fg_x, m.fg_y, scene)
    assert s["frac_within_45"] >= 0.80, s
    assert grouping_peak_inside(m.grouping, scene)
    assert m.grouping.max() == pytest.approx(1.0)
    assert np.all((m.grouping == 0) | (m.grouping >= 0.1))


def test_occluder_owns_most_of_the_shared_border():
    sc = scenes.occlusion()
    pos, neg = image_to_frame(sc.image, threshold=0.10)
    m = run_edfg(pos, neg)
    frac, n = scenes.shared_border_ownership(sc, m.fg_x, m.fg_y, front=1, back=0)
    assert n > 30
    assert frac > 0.5


def test_scene_truth_points_into_owner():
    sc = scenes.disc(20)
    r, c = np.nonzero(sc.boundary)
    centre = np.array(sc.shapes[0].centre)
    # a step of 3 px along the truth vector (y up) gets closer to the centre
    step_r = r - 3 * sc.truth_y[r, c]
    step_c = c + 3 * sc.truth_x[r, c]
    before = np.hypot(r - centre[0], c - centre[1])
    after = np.hypot(step_r - centre[0], step_c - centre[1])
    assert np.all(after < before)
    assert np.allclose(np.hypot(sc.truth_x[r, c], sc.truth_y[r, c]), 1.0)


def test_rate_model_is_deterministic():
    sc = scenes.demo()
    pos, neg = image_to_frame(sc.image)
    a, b = run_edfg(pos, neg), run_edfg(pos, neg)
    assert np.array_equal(a.fg_x, b.fg_x) and np.array_equal(a.grouping, b.grouping)


def test_grouping_comparison_ignores_the_maps_units():
    """Spiking grouping maps are in Hz, the rate model's in its own units:
    a map and a scaled copy of it compare as identical, on r and on SSIM."""
    from snn_fg.scoring.metrics import compare_frame

    sc = scenes.disc(20)
    pos, neg = image_to_frame(sc.image)
    m = run_edfg(pos, neg)
    same = compare_frame(m.fg_x, m.fg_y, m.grouping, 3 * m.fg_x, 3 * m.fg_y, 30.0 * m.grouping)
    assert same["grouping_pearson_r"] == pytest.approx(1.0)
    assert same["grouping_ssim"] == pytest.approx(1.0)
    assert same["angle_diff_median_deg"] == pytest.approx(0, abs=1e-4) and same["angle_within_45_frac"] == 1.0
    other = compare_frame(m.fg_x, m.fg_y, m.grouping, m.fg_x, m.fg_y, np.roll(m.grouping, 15, axis=1))
    assert other["grouping_ssim"] < 0.9
