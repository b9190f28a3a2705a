"""experiments.validation.natural_cues: the half-disc side cue and the combination of cues (issue 38)."""

import numpy as np
import pytest

from experiments.validation.natural_cues import N_DIRECTIONS, analyse, fit_logistic, predict, side_difference


@pytest.mark.parametrize("radius", [6, 24])
def test_the_side_cue_points_to_the_half_with_the_events(radius):
    image = np.zeros((80, 80))
    image[40:, :] = 1.0  # events fill the lower half (rows grow downwards)
    angles = np.arange(N_DIRECTIONS) * 2 * np.pi / N_DIRECTIONS
    rows, cols = np.full(len(angles), 39), np.full(len(angles), 40)
    cue = side_difference(image, radius, rows, cols, angles)
    down = -np.sin(angles)  # y is up: the filled half lies at -y
    assert np.all(np.sign(cue[np.abs(down) > 0.5]) == np.sign(down[np.abs(down) > 0.5]))
    assert cue[np.argmin(np.sin(angles))] == pytest.approx(1.0, abs=0.1)  # straight down: all of one side
    assert abs(cue[0]) < 0.1 and abs(cue[N_DIRECTIONS // 2]) < 0.1  # along the border: no side


def test_the_logistic_combination_learns_which_cues_say_the_side():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(4000, 3))
    right = x[:, 0] - 0.5 * x[:, 2] + 0.2 * rng.normal(size=4000) > 0.3
    model = fit_logistic(x[:3000], right[:3000])
    assert np.mean(predict(model, x[3000:]) == right[3000:]) > 0.9
    w = model[2]
    assert w[0] > 0 > w[2] and abs(w[1]) < 0.2 * w[0]


def test_a_cue_that_knows_the_side_turns_every_wrong_vector_round():
    rng = np.random.default_rng(2)
    images = []
    for _ in range(10):
        right = rng.random(200) < 0.55
        knows = np.where(right, 1.0, -1.0)
        images.append((np.column_stack([knows] + [rng.normal(size=200)] * 9), right))
    out = analyse(images[:5], images[5:])
    assert out["cues"]["events 6"]["report"] == 1.0  # the first cue is the one that knows
    assert 0.4 < out["cues"]["events 12"]["report"] < 0.7
    assert out["combined"]["report"] > 0.95
    assert out["variant"]["report"] == pytest.approx(np.mean(np.concatenate([r for _, r in images[5:]])))
