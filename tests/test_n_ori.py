"""Nothing in the rate model assumes 8 orientations: with ``n_ori=4`` it is
the 8-orientation model with every edge's direction chosen among its even
(45-degree) directions only.

The kernels of 4 orientations are the even-numbered kernels of 8, each
pixel's direction is the arg-max of the 8-orientation responses over the
even directions, and stages 5-9 of the 8-orientation engine fed the 4-orientation
entries (channel ``c`` as ``2c``) give the 4-orientation maps bit for bit.
(What 4 orientations do lose on discs, docs/model.md, "Measured and not
taken", comes from that rounding, not from code written for 8.)
"""

import numpy as np

from snn_fg.events import image_to_frame
from snn_fg.frames.scenes import disc
from snn_fg.models.rate.edfg import event_entries, orientation_index, oriented_responses, run_edfg_state
from snn_fg.models.rate.grouping import SparseGrouping
from snn_fg.models.rate.grouping_tables import Entries
from snn_fg.network.kernels import dog_kernels, von_mises_masks
from snn_fg.params import ModelParams

P4, P8 = ModelParams(n_ori=4), ModelParams(n_ori=8)


def test_four_orientation_kernels_are_the_even_eight_orientation_ones():
    assert np.array_equal(dog_kernels(P4), dog_kernels(P8)[::2])
    for k4, k8 in zip(von_mises_masks(P4), von_mises_masks(P8)):
        assert np.array_equal(k4, k8[::2])


def test_four_orientations_are_eight_restricted_to_even_directions():
    pos, neg = image_to_frame(disc(radius=16).image)
    e4, shapes = event_entries(pos, neg, P4)
    e8, _ = event_entries(pos, neg, P8)
    assert all(np.array_equal(a.rows, b.rows) and np.array_equal(a.cols, b.cols) for a, b in zip(e4, e8))
    even = oriented_responses(pos.astype(float), neg.astype(float), P8)[::2]
    assert np.array_equal(oriented_responses(pos.astype(float), neg.astype(float), P4), even)
    rows, cols = e4[0].rows, e4[0].cols
    assert np.array_equal(e4[0].ch, orientation_index(even[:, rows, cols], P4)[1])
    step = (2 * e4[0].ch - e8[0].ch + 8) % 16 - 8  # most pixels: the nearest even direction
    assert np.mean(np.abs(step) <= 1) > 0.9
    state4 = run_edfg_state(pos, neg, P4)
    engine8 = SparseGrouping([Entries(e.rows, e.cols, 2 * e.ch, e.s) for e in e4], shapes, P8).run()
    fg_x, fg_y, grouping = engine8.readout(pos.shape)
    assert np.array_equal(fg_x, state4.fg_x) and np.array_equal(fg_y, state4.fg_y)
    # (the dense Fourier passes sum over 8 channels instead of 4: last-digit differences)
    assert np.abs(grouping - state4.grouping).max() <= 1e-6 * np.abs(state4.grouping).max()
