"""The grouping peaks' local maxima (snn_fg.results.peaks.local_maxima): the pixels
scipy's maximum filter finds, on maps with plateaus, edges and values at or below zero."""

import numpy as np
import pytest
from scipy import ndimage

from snn_fg.results.peaks import local_maxima


def _filtered(g, radius):
    return np.nonzero((g == ndimage.maximum_filter(g, size=2 * radius + 1, mode="constant")) & (g > 0))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("radius", [1, 3, 8])
def test_local_maxima_are_the_maximum_filters(dtype, radius):
    rng = np.random.default_rng(radius)
    for trial in range(20):
        h, w = rng.integers(1, 40, size=2)
        g = rng.integers(-2, 4, size=(h, w)).astype(dtype)  # (few values: plateaus, ties across a square)
        if trial % 2:
            g = ndimage.zoom(rng.normal(size=(max(h // 4, 1), max(w // 4, 1))), 4, order=1).astype(dtype)
        ys, xs = local_maxima(g, radius)
        want = _filtered(g, radius)
        np.testing.assert_array_equal(ys, want[0])
        np.testing.assert_array_equal(xs, want[1])


def test_a_map_without_positive_values_has_no_maxima():
    ys, xs = local_maxima(np.zeros((5, 6), np.float32), 2)
    assert ys.size == xs.size == 0
    ys, xs = local_maxima(np.full((5, 6), -1.0), 2)
    assert ys.size == 0
