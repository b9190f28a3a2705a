"""Two validation probes run as their pages say: spiking_deviations' whole-frame row (the default network's
twin and spiking run) and spiking_stages' noisy reference, whose maps must not depend on which of the rate
model's two threads reaches a level first."""

from __future__ import annotations

import numpy as np
import pytest

import snn_fg.models.rate.grouping as grouping
from experiments.validation.spiking_deviations import full_row
from experiments.validation.spiking_stages import noisy_reference
from snn_fg.events import image_to_frame
from snn_fg.frames import scenes
from snn_fg.models.rate.edfg import run_edfg
from snn_fg.params import ModelParams


@pytest.fixture(scope="module")
def disc():
    return image_to_frame(scenes.disc(16, True).image)


class _InOrder:
    """A stand-in for the rate model's thread pool that runs the levels one after another, in the order given
    (``backwards``: last first), and hands the results back in the order asked, as a pool does."""

    backwards = False

    def __init__(self, max_workers=None):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def map(self, fn, items):
        items = list(items)
        done = {i: fn(items[i]) for i in (reversed(range(len(items))) if self.backwards else range(len(items)))}
        return iter([done[i] for i in range(len(items))])


class _Backwards(_InOrder):
    backwards = True


def test_the_noisy_reference_does_not_depend_on_the_order_its_levels_are_computed_in(disc, monkeypatch):
    pos, neg = disc
    maps = []
    for pool in (_InOrder, _Backwards):
        monkeypatch.setattr(grouping, "ThreadPoolExecutor", pool)
        maps.append(noisy_reference(pos, neg, ModelParams(), 0.3, 0))
    noiseless = run_edfg(pos, neg)
    assert not np.array_equal(maps[0][0], noiseless.fg_x)  # the noise is there
    for a, b in zip(*maps):
        np.testing.assert_array_equal(a, b)


def test_spiking_deviations_scores_the_default_network_on_a_whole_frame(disc):
    pos, neg = disc
    r = run_edfg(pos, neg)
    row = full_row(pos, neg, {"fg_x": r.fg_x, "fg_y": r.fg_y, "grouping": r.grouping})
    assert row["twin_vs_ref"]["synapses"] > 0
    for part in ("twin_vs_ref", "spiking_vs_ref", "spiking_vs_twin"):
        assert 0.5 < row[part]["grouping_pearson_r"] <= 1.0, part
