"""Ground truth: the boundary-to-direction converter on shapes with analytic normals,
the scores, and the bsds-fg loader."""

import numpy as np
import pytest
from scipy import ndimage as ndi

from snn_fg.errors import InputError
from snn_fg.frames.scenes import disc, square
from snn_fg.scoring.groundtruth import (
    boundary_directions,
    bsds_ids,
    labeller_agreement,
    load_bsds_fg,
    score_directions,
    signed_angle_deg,
    summarise_errors,
)


def _labels(scene):
    """A bsds-fg style map of a one-shape scene: +1 strip inside its outline, -1 strip outside."""
    inside = scene.labels > 0
    fig = inside & ~ndi.binary_erosion(inside)
    ground = ~inside & ndi.binary_dilation(inside)
    return fig.astype(np.int8) - ground.astype(np.int8), fig


@pytest.mark.parametrize(
    "scene", [disc(20), disc(45), disc(60, light_on_dark=False), square(50), square(70)], ids=lambda s: s.name
)
def test_converter_recovers_analytic_normals(scene):
    # measured within 10 deg: discs r 20, 45, 60: 100 %, 100 %, >= 95 %; squares h 50, 70: 96 %, 97 %
    # (the misses are the 2 px next to each corner). Discs of radius 80-120 give 94.7-95.3 %: near the axes
    # a 5 x 5 window spans one step of the digital outline and tilts the line by up to 13 deg.
    fg, fig = _labels(scene)
    x, y, valid = boundary_directions(fg)
    assert valid[fig].all() and not valid[~fig].any()
    r, c = np.nonzero(fig)
    tx, ty = scene.shapes[0].inward(r.astype(float), c.astype(float))
    err = np.abs(signed_angle_deg(x[fig], y[fig], tx, ty))
    assert np.mean(err <= 10) >= 0.95, f"{np.mean(err <= 10):.3f} within 10 deg"
    assert np.allclose(np.hypot(x[fig], y[fig]), 1.0)


def test_direction_points_to_the_figure_side_whichever_side_it_is():
    fg = np.zeros((30, 30), np.int8)
    fg[:, 12] = -1
    fg[:, 13] = 1  # figure on the right of a vertical boundary
    x, y, valid = boundary_directions(fg)
    assert valid[:, 13].all()
    assert np.allclose(x[:, 13], 1) and np.allclose(y[:, 13], 0, atol=1e-12)
    x2, _, _ = boundary_directions(-fg)  # now the figure is the left strip
    assert np.allclose(x2[:, 12], -1)


def test_a_lone_pixel_has_no_direction():
    fg = np.zeros((25, 25), np.int8)
    fg[12, 12] = 1
    _, _, valid = boundary_directions(fg)
    assert not valid.any()


def test_signed_and_absolute_means_differ_when_errors_cancel():
    s = summarise_errors([90.0, -90.0, 10.0, -10.0])
    assert s["mean_signed_deg"] == 0.0 and s["mean_abs_deg"] == 50.0
    assert s["within45"] == 0.5 and s["median_abs_deg"] == 50.0 and s["n_pixels"] == 4
    # a vector exactly along the boundary names no side: the two at 90 deg count as wrong
    assert s["side_accuracy"] == 0.5
    assert summarise_errors([89.9, -120.0, 179.0, 0.0])["side_accuracy"] == 0.5
    assert signed_angle_deg(
        np.cos(np.radians(170)), np.sin(np.radians(170)), np.cos(np.radians(-170)), np.sin(np.radians(-170))
    ) == pytest.approx(-20.0)


def test_score_counts_only_pixels_with_a_model_vector():
    truth_x = np.zeros((4, 4))
    truth_y = np.ones((4, 4))
    valid = np.zeros((4, 4), bool)
    valid[1, :] = True
    fx = np.zeros((4, 4))
    fy = np.zeros((4, 4))
    fy[1, :2] = 1.0  # right on two pixels
    fx[1, 2] = 1.0  # 90 degrees off on one
    s = score_directions(fx, fy, (truth_x, truth_y, valid))
    assert s["n_pixels"] == 3 and s["coverage"] == 0.75
    assert s["mean_abs_deg"] == pytest.approx(30.0) and s["mean_signed_deg"] == pytest.approx(-30.0)
    assert s["side_accuracy"] == pytest.approx(2 / 3)


def test_loader_names_the_file_on_bad_input(tmp_path):
    (tmp_path / "labels").mkdir()
    np.savez(tmp_path / "labels" / "1.npz", other=np.zeros(3))
    np.savez(tmp_path / "labels" / "2.npz", fg=np.full((2, 4, 4), 3, np.int8))
    (tmp_path / "labels" / "3.npz").write_bytes(b"not a zip")
    for i in ("1", "2", "3", "4"):
        with pytest.raises(InputError, match=f"{i}.npz"):
            load_bsds_fg(tmp_path, i)
    assert bsds_ids(tmp_path) == ["1", "2", "3"]


def test_bsds_fg_labels_load_and_the_labellers_mostly_agree(dataset):
    root = dataset("bsds-fg")
    ids = bsds_ids(root)
    assert len(ids) == 160
    gt = load_bsds_fg(root, "8143")
    assert gt.fg.shape == (2, 321, 481) and gt.image_path is not None and len(gt.labellers) == 2
    ceiling = labeller_agreement(gt)
    assert ceiling["n_pixels"] > 5000 and ceiling["within45"] > 0.95  # measured 0.988


def test_map_similarity_is_perfect_only_for_the_same_field():
    from experiments.evaluation import map_similarity

    x, y, valid = boundary_directions(_labels(disc(20))[0])
    assert valid.sum() > 50
    same = map_similarity((x, y), (x.copy(), y.copy()))
    assert same["ssim_angle"] == pytest.approx(1.0) and same["ssim_render"] == pytest.approx(1.0)
    assert same["mse_angle"] == 0.0 and same["mse_render"] == 0.0
    flipped = map_similarity((x, y), (-x, -y))  # every vector turned by half a turn
    assert flipped["ssim_angle"] < 0.9 and flipped["ssim_render"] < 0.9
    # in turns, every vector moved by 0.5 (either way round the wheel): 0.25 per vector pixel
    assert flipped["mse_angle"] == pytest.approx(0.25 * valid.mean())
    assert flipped["mse_render"] > 0


def test_bootstrap_over_images_separates_a_steady_shift_from_one_image_s_outlier():
    from experiments.pooled import bootstrap_difference
    from snn_fg.scoring.label_scores import error_stats

    rng = np.random.default_rng(3)
    errs = [rng.uniform(-120, 120, size=rng.integers(200, 400)) for _ in range(20)]
    a = [[error_stats(e)] for e in errs]
    # every image 10 deg further round: the difference is 10 whichever images are drawn
    shifted = bootstrap_difference(a, [[error_stats(e + 10)] for e in errs], n_resamples=500)
    s = shifted["mean_signed_deg"]
    assert s["difference"] == pytest.approx(10) and s["low"] == pytest.approx(10) and s["high"] == pytest.approx(10)
    # one image 90 deg off, the rest identical: a pooled difference that the images
    # left out of a third of the resamples do not have
    one = [[error_stats(e + (90 if i == 0 else 0))] for i, e in enumerate(errs)]
    b = bootstrap_difference(a, one, n_resamples=500)["mean_signed_deg"]
    assert b["difference"] > 2 and b["low"] == 0.0 and b["high"] > b["difference"]
    assert bootstrap_difference(a, one, n_resamples=500) == bootstrap_difference(a, one, n_resamples=500)
    with pytest.raises(ValueError, match="same, non-empty"):
        bootstrap_difference(a, one[:-1])
    with pytest.raises(ValueError, match="no score 'median_abs_deg'"):
        bootstrap_difference(a, one, keys=("median_abs_deg",))


def test_pooled_scores_add_pixels_over_images_and_coverage_counts_labelled_pixels():
    from snn_fg.scoring.label_scores import error_stats, pool_stats

    # image 1: 3 scored of 4 labelled, sides right, wrong, right; image 2: 1 scored of 6, wrong
    a = error_stats([10.0, 100.0, -30.0], n_truth=4)
    b = error_stats([-170.0], n_truth=6)
    s = pool_stats([a, b])
    assert s["n_pixels"] == 4 and s["n_truth"] == 10 and s["coverage"] == pytest.approx(0.4)
    assert s["side_accuracy"] == pytest.approx(0.5) and s["within45"] == pytest.approx(0.5)
    assert s["mean_abs_deg"] == pytest.approx(77.5) and s["mean_signed_deg"] == pytest.approx(-22.5)
    # parts made without the labelled count (a labeller against another) have no coverage
    assert np.isnan(pool_stats([error_stats([5.0])])["coverage"])
    assert np.isnan(pool_stats([])["side_accuracy"])


def test_bootstrap_scores_pool_over_images_and_the_image_mean_weighs_images_alike():
    from experiments.pooled import bootstrap_scores
    from snn_fg.scoring.label_scores import error_stats

    # 10 images all right on 100 pixels each, one image all wrong on 1000 pixels
    parts = [[error_stats(np.zeros(100), n_truth=200)] for _ in range(10)]
    parts.append([error_stats(np.full(1000, 180.0), n_truth=1000)])
    s = bootstrap_scores(parts, n_resamples=400)
    side = s["side_accuracy"]
    assert side["pooled"] == pytest.approx(0.5) and side["image_mean"] == pytest.approx(10 / 11)
    # resamples without the big image are all right, those with it twice mostly wrong
    assert side["high"] == 1.0 and side["low"] < 0.4 and side["image_low"] < side["image_mean"] <= side["image_high"]
    assert s["coverage"]["pooled"] == pytest.approx(2000 / 3000)
    assert bootstrap_scores(parts, n_resamples=400) == s  # seeded
    with pytest.raises(ValueError, match="no score 'median_abs_deg'"):
        bootstrap_scores(parts, keys=("median_abs_deg",))
