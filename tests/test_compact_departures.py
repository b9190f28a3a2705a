"""experiments.validation.compact_departures: the compact network with one of its levers reverted."""

import pytest

from experiments.validation.compact_departures import leave_one_out, variants
from snn_fg.network.recipes import COMPACT_LEVERS, RECIPES, Lever

INDEX = {lv.name: k for k, lv in enumerate(COMPACT_LEVERS)}


def test_each_reverted_lever_takes_back_only_what_it_sets():
    compact, default = RECIPES["compact"], RECIPES["default"]
    unpooled = leave_one_out(INDEX["pooled input"])
    assert (unpooled.params.input_pool, unpooled.params.r0) == (1, default.params.r0)
    assert (unpooled.params.levels, unpooled.params.levels_per_octave) == (3, 1)  # the octave levels stay
    assert unpooled.spiking == compact.spiking
    half_octave = leave_one_out(INDEX["octave levels"])
    assert (half_octave.params.levels, half_octave.params.levels_per_octave) == (7, 2)  # the pooled input's levels
    unpruned = leave_one_out(INDEX["pruned kernels"])
    assert unpruned.spiking.connectivity == compact.spiking.connectivity.replace(
        prune_dog=default.spiking.connectivity.prune_dog, prune_vm=default.spiking.connectivity.prune_vm
    )
    assert unpruned.params == compact.params


def test_a_lever_that_changes_nothing_is_refused(monkeypatch):
    import snn_fg.network.recipes as recipes

    monkeypatch.setattr(recipes, "COMPACT_LEVERS", (*COMPACT_LEVERS, Lever(name="nothing", does="")))
    with pytest.raises(ValueError, match="nothing"):
        leave_one_out(len(COMPACT_LEVERS))


def test_the_rows_are_the_compact_network_each_lever_reverted_and_the_default_based_ones_asked_for():
    rows = variants(["default", "pruned kernels"])
    assert [k for _, k, _ in rows] == ["compact", *["leave one out"] * len(COMPACT_LEVERS), "default", "one at a time"]
    assert rows[-1][2] == COMPACT_LEVERS[INDEX["pruned kernels"]].apply(RECIPES["default"])
