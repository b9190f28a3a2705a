"""experiments.validation.recording_ceiling.compact_dog: the compact network's DoG balanced, the kernel patch
that experiments.validation.compact_dog measures."""

import numpy as np

import snn_fg.network.nodes as nodes
from experiments.validation.recording_ceiling import compact_dog
from snn_fg.network.recipes import RECIPES


def test_the_balanced_dog_keeps_the_pruned_taps_and_sums_to_zero():
    params = RECIPES["compact"].params
    full = nodes.dog_kernels(params)
    context, options = compact_dog(0.3, True)
    with context:
        balanced = nodes.dog_kernels(params)
    kept = np.abs(full) >= 0.3 * np.abs(full).max(axis=(1, 2), keepdims=True)
    assert np.array_equal(balanced != 0, kept)  # the same taps as pruned at 30 %
    assert np.allclose(balanced.sum(axis=(1, 2)), 0.0, atol=1e-9)  # as pruned they sum to about +0.75
    assert np.all(np.where(kept, full, 0).sum(axis=(1, 2)) > 0.5)
    assert np.array_equal(balanced[balanced > 0], full[(full > 0) & kept])  # only the negative taps are scaled
    assert options["spiking"].connectivity.prune_dog == 0.0  # the projection keeps every tap left
    assert np.array_equal(nodes.dog_kernels(params), full)  # restored


def test_the_compact_dog_as_pruned_is_the_recipe():
    context, options = compact_dog(0.3, False)
    with context:
        assert options["spiking"] == RECIPES["compact"].spiking
        assert options["params"] == RECIPES["compact"].params
