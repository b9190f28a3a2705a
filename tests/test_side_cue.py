"""The side cue of the natural-scene variant (``ModelParams.side_cue``): the
busier side of a border within a wide half disc is taken for the figure's,
in the rate model and in its spiking form."""

import numpy as np
import pytest

from snn_fg.errors import ParameterError
from snn_fg.models.rate.natural import run_natural
from snn_fg.network import build_network
from snn_fg.network.kernels import side_cue_kernels, von_mises_masks
from snn_fg.params import NATURAL_PARAMS, ModelParams

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)

#: small frames: five levels, the cue read at the coarsest, over 40 px, at three times the variant's gain
SMALL = NATURAL_PARAMS.replace(levels=5, side_cue_radius=40.0, side_cue=1e4)


def _box_beside_texture(texture_right: bool, shape=(64, 97), seed=0):
    """The right side of an empty box (an outline of ON events) as the border
    at column ``mid``, and sparse specks of OFF events (a textured region,
    3 % of pixels) from 8 px beyond it; mirrored when ``texture_right`` is
    False. Grouping alone gives the border to the box."""
    rng = np.random.default_rng(seed)
    pos, neg = np.zeros(shape), np.zeros(shape)
    mid = shape[1] // 2
    pos[12:-12, mid] = pos[12:-12, mid - 24] = 1.0
    pos[12, mid - 24 : mid + 1] = pos[-13, mid - 24 : mid + 1] = 1.0
    rows, cols = np.arange(shape[0])[:, None], np.arange(shape[1])[None, :]
    neg[(rng.random(shape) < 0.03) & (cols > mid + 8) & (rows > 4) & (rows < shape[0] - 4)] = 1.0
    if not texture_right:
        pos, neg = pos[:, ::-1].copy(), neg[:, ::-1].copy()
    return pos, neg, mid


def _share_towards_texture(fx, mid, texture_right: bool):
    """Of the border's vectors (away from its corners), the share pointing to the textured side."""
    v = fx[20:-20, mid]
    v = v[v != 0]
    assert v.size > 15
    return float(np.mean(v > 0 if texture_right else v < 0))


def test_the_half_discs_weigh_the_side_the_grouping_ring_m1_weighs():
    # two constructions of "side 1" of each orientation, from independent code, must agree
    k = side_cue_kernels(SMALL)
    m1, m2 = von_mises_masks(SMALL)
    h = m1.shape[-1] // 2
    for o in range(SMALL.n_ori):
        pad = max(h - k.shape[-1] // 2, 0)
        big = np.pad(k[o], pad)
        c = big.shape[-1] // 2
        crop = big[c - h : c + h + 1, c - h : c + h + 1]
        assert (np.sign(crop) * m1[o]).sum() > 0.5 * m1[o].sum()
        assert (np.sign(crop) * m2[o]).sum() < -0.5 * m2[o].sum()
        assert abs(k[o].sum()) < 1e-12 and np.isclose(k[o][k[o] > 0].sum(), 1.0)  # mean minus mean
        assert np.array_equal(k[o], -k[o][::-1, ::-1])  # the two halves are one another turned round
    # a border along an axis: mirrored along the border, its half disc is itself (no pixel row of the
    # dividing line kept on one side only)
    assert np.array_equal(k[0], k[0][:, ::-1]) and np.array_equal(k[SMALL.n_ori // 2], k[SMALL.n_ori // 2][::-1])


def test_the_side_cue_gives_a_border_to_its_textured_side():
    for right in (True, False):
        pos, neg, mid = _box_beside_texture(right)
        assert _share_towards_texture(run_natural(pos, neg, SMALL).fg_x, mid, right) >= 0.9
        # without it the grouping gives the border to the box
        assert _share_towards_texture(run_natural(pos, neg, SMALL.replace(side_cue=0.0)).fg_x, mid, right) <= 0.1


def test_the_side_cue_is_checked():
    assert ModelParams().side_cue == 0 and NATURAL_PARAMS.side_cue > 0
    with pytest.raises(ParameterError, match="side_cue=-1"):
        ModelParams(side_cue=-1)
    with pytest.raises(ParameterError, match="side_cue_radius=0"):
        ModelParams(side_cue_radius=0)
    assert ModelParams(levels=4).cue_level == 4 and ModelParams().cue_level == 9


def test_the_spiking_side_cells_carry_the_cue_and_turn_the_border():
    from snn_fg.models import Still, get_model
    from snn_fg.models.rate.side_cue import side_cue_maps
    from snn_fg.models.spiking import run_spiking_result

    for right in (True, False):
        pos, neg, mid = _box_beside_texture(right)
        res = run_spiking_result(pos, neg, params=SMALL, backend="fast", progress=False, record_spikes=False)
        net = res.result.network
        q = side_cue_maps(pos, neg, SMALL)
        rate = res.result.grid(net.one("side_p", 5).name) - res.result.grid(net.one("side_n", 5).name)
        # each side cell fires 100 Hz at a cue of 0.02 (SIDE_CUE_REF), in proportion over 50-400 Hz
        mid_range = (np.abs(q) > 0.01) & (np.abs(q) < 0.08)
        assert mid_range.sum() > 10
        ratio = rate[mid_range] / (5000.0 * q[mid_range])
        assert 0.7 < np.median(ratio) < 1.3
        assert np.mean(np.sign(rate[mid_range]) == np.sign(q[mid_range])) > 0.95
        # the spiking form turns most of the border (measured 0.70-0.71; 0.75 at three times the gain), none without
        spiking = {
            gain: get_model("natural-spiking", SMALL.replace(side_cue=gain), backend="fast").run_still(Still(pos, neg))
            for gain in (SMALL.side_cue, 0.0)
        }
        assert _share_towards_texture(spiking[SMALL.side_cue].fg_x, mid, right) >= 0.6
        assert _share_towards_texture(spiking[0.0].fg_x, mid, right) <= 0.1


def test_the_network_feeds_the_cue_into_z1_and_against_z2_at_level_1():
    net = build_network(SMALL, (64, 97))
    into = {(p.source, p.target): p.sign for p in net.projections if p.source.startswith("side_")}
    assert into == {
        ("side_p_5", "feedback_1p_1"): 1,
        ("side_p_5", "feedback_1n_1"): -1,
        ("side_p_5", "feedback_2p_1"): -1,
        ("side_p_5", "feedback_2n_1"): 1,
        ("side_n_5", "feedback_1p_1"): -1,
        ("side_n_5", "feedback_1n_1"): 1,
        ("side_n_5", "feedback_2p_1"): 1,
        ("side_n_5", "feedback_2n_1"): -1,
    }
    sources = sorted(p.source for p in net.projections if p.target == "side_p_5")
    assert sources == ["relay_off_5", "relay_on_5"]
    assert not [
        p for p in build_network(SMALL.replace(side_cue=0.0), (64, 97)).populations if p.role.startswith("side_")
    ]


def test_a_negative_zero_gain_is_stored_as_zero_and_a_non_finite_one_refused():
    """`--side-cue -0` was kept as -0.0 in a run's params (a new user's find)."""
    assert str(ModelParams(side_cue=-0.0).side_cue) == "0.0"
    for bad in (float("inf"), float("nan"), -1.0):
        with pytest.raises(ParameterError, match="side_cue"):
            ModelParams(side_cue=bad)
