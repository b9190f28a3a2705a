"""Unrolling the description into cells and synapses (numpy only, no Brian2).

The unrolled projections are checked against independent scipy/OpenCV
computations of the model's own operations: DoG convolution with wrap-around
(stage 3), von Mises correlation with zero padding (stage 7), the pyramid's
bicubic resize (stage 2).
"""

import cv2
import numpy as np
import pytest
from scipy import ndimage

from snn_fg.errors import ParameterError
from snn_fg.events import image_to_frame
from snn_fg.frames.scenes import disc
from snn_fg.lowering.interp import interp_matrix, resize_matrix
from snn_fg.lowering.unroll import dense_drive, to_grid, unroll
from snn_fg.network import Connectivity, SpikingParams, build_network
from snn_fg.network.kernels import dog_kernels, von_mises_masks
from snn_fg.params import ModelParams

EXACT = SpikingParams(connectivity=Connectivity(prune_dog=0.0, prune_vm=0.0))


@pytest.fixture(scope="module")
def frame():
    pos, neg = image_to_frame(disc(12, True).image)
    return pos > 0, neg > 0


@pytest.fixture(scope="module")
def unrolled(frame):
    pos, neg = frame
    net = build_network(ModelParams(levels=2), pos.shape, EXACT)
    return unroll(net, {"input_on_1": pos, "input_off_1": neg})


def _conn(un, name):
    return next(c for c in un.connections if c.projection.name == name)


@pytest.mark.parametrize("shape_in, shape_out", [((321, 481), (227, 341)), ((40, 52), (15, 22)), ((15, 22), (40, 52))])
def test_resize_matrices_reproduce_opencv(shape_in, shape_out):
    x = np.random.default_rng(0).random(shape_in)
    for interp, flag in (("cubic", cv2.INTER_CUBIC), ("linear", cv2.INTER_LINEAR)):
        a = resize_matrix(shape_in[0], shape_out[0], interp)
        b = resize_matrix(shape_in[1], shape_out[1], interp)
        want = cv2.resize(x, (shape_out[1], shape_out[0]), interpolation=flag)
        np.testing.assert_allclose(a @ x @ b.T, want, atol=1e-12)
        assert interp_matrix(shape_in[0], shape_out[0], 1, 1, interp) is a


def test_lattice_interpolation_is_hand_computable():
    # stride-2 lattice -> full grid of the same level, linear: even pixels copy
    # their lattice point, odd pixels average the two neighbours (last one clamps).
    a = interp_matrix(7, 7, 2, 1, "linear")  # lattice points at 0, 2, 4, 6
    assert a.shape == (7, 4)
    want = np.zeros((7, 4))
    for x in range(7):
        if x % 2 == 0:
            want[x, x // 2] = 1
        else:
            want[x, x // 2] = want[x, x // 2 + 1] = 0.5
    np.testing.assert_allclose(a, want)
    # cubic weights sum to one on every row, whatever the strides
    c = interp_matrix(40, 29, 2, 2, "cubic")
    np.testing.assert_allclose(c.sum(1), 1.0)


@pytest.mark.slow
def test_dog_projection_is_the_wraparound_convolution(unrolled, frame):
    pos, neg = frame
    k = dog_kernels(ModelParams())
    want = np.stack(
        [ndimage.convolve(pos.astype(float) if d < 8 else neg.astype(float), k[d], mode="wrap") for d in range(16)]
    )
    on, off = _conn(unrolled, "input_on_1_to_simple_1"), _conn(unrolled, "input_off_1_to_simple_1")
    g = on.projection.gain_mv
    got = (
        dense_drive(unrolled, on, pos.ravel().astype(float)) + dense_drive(unrolled, off, neg.ravel().astype(float))
    ) / g
    sites = unrolled.sites["simple_1"]
    assert sites.size > 100
    np.testing.assert_allclose(got, want.ravel()[sites], atol=1e-12)
    assert on.kept_mass == pytest.approx(1.0)


def test_simple_cells_exist_where_excitation_alone_can_reach_threshold(unrolled, frame):
    # the hint keeps event-pixel cells whose positive DoG taps could bring them
    # drive_min of the way to threshold (the gate cancels the bias at event pixels)
    pos, neg = frame
    kp = np.maximum(dog_kernels(ModelParams()), 0)
    bound = np.stack(
        [ndimage.convolve(pos.astype(float) if d < 8 else neg.astype(float), kp[d], mode="wrap") for d in range(16)]
    )
    edges = pos | neg
    reach = bound >= unrolled.network.drive_min * ModelParams().edge_threshold - 1e-12
    want = np.flatnonzero((reach & edges[None]).ravel())
    np.testing.assert_array_equal(unrolled.sites["simple_1"], want)


@pytest.mark.slow
def test_von_mises_gather_onto_the_grouping_lattice(frame):
    pos, neg = frame
    net = build_network(ModelParams(levels=1), pos.shape, EXACT)  # grouping stride 2
    un = unroll(net, {"input_on_1": pos, "input_off_1": neg})
    m1, m2 = von_mises_masks(ModelParams())
    b = np.zeros(net.population("bo_L1_1").size)
    b[un.sites["bo_L1_1"]] = np.random.default_rng(1).random(un.n_cells("bo_L1_1"))
    c = _conn(un, "bo_L1_1_to_group_L_1")
    got = to_grid(un, "group_L_1", dense_drive(un, c, b[un.sites["bo_L1_1"]]) / c.projection.gain_mv)[0]
    b = b.reshape(net.population("bo_L1_1").shape)
    want = sum(ndimage.correlate(b[o], m2[o], mode="constant") for o in range(8))[::2, ::2]
    np.testing.assert_allclose(got, want, atol=1e-9)
    # every lattice point with input exists, and none without
    g_sites = np.zeros(want.size, bool)
    g_sites[un.sites["group_L_1"]] = True
    support = sum(
        ndimage.correlate((b[o] > 0).astype(float), (m2[o] > 0) | (m1[o] > 0), mode="constant") for o in range(8)
    )[::2, ::2]
    np.testing.assert_array_equal(g_sites.reshape(want.shape), support > 0)


@pytest.mark.slow
def test_von_mises_scatter_between_lattices(frame):
    pos, neg = frame
    net = build_network(ModelParams(levels=1), pos.shape, EXACT)
    un = unroll(net, {"input_on_1": pos, "input_off_1": neg})
    m1, _ = von_mises_masks(ModelParams())
    gl = np.zeros(net.population("group_L_1").size)
    gl[un.sites["group_L_1"]] = np.random.default_rng(2).random(un.n_cells("group_L_1"))
    c = _conn(un, "group_L_1_to_feedback_1p_1")
    st = net.population("group_L_1").stride
    # the gain holds the stride**2 density compensation; divide it out
    got = to_grid(un, "feedback_1p_1", dense_drive(un, c, gl[un.sites["group_L_1"]]) / c.projection.gain_mv)
    sp = SpikingParams()
    fb = sp.neurons.feedback
    assert c.projection.gain_mv == pytest.approx(
        st * st * sp.gains.group_to_feedback * fb.v_th_mv / (100 * fb.tau_exc_ms / 1000)
    )
    full = np.zeros(pos.shape)
    full[::2, ::2] = gl.reshape(net.population("group_L_1").grid)
    want = np.stack([ndimage.correlate(full, m1[o], mode="constant")[::2, ::2] for o in range(8)])
    z = np.zeros(want.size, bool)
    z[un.sites["feedback_1p_1"]] = True
    np.testing.assert_allclose(got.ravel()[z], want.ravel()[z], atol=1e-9)


def test_relays_carry_the_bicubic_pyramid(unrolled, frame):
    pos, _ = frame
    c = _conn(unrolled, "input_on_1_to_relay_on_2")
    got = dense_drive(unrolled, c, pos.ravel().astype(float)) / c.projection.gain_mv
    shape2 = unrolled.network.population("relay_on_2").grid
    want = cv2.resize(pos.astype(float), (shape2[1], shape2[0]), interpolation=cv2.INTER_CUBIC)
    np.testing.assert_allclose(got, want.ravel()[unrolled.sites["relay_on_2"]], atol=1e-12)
    # relays exist exactly where some active pixel reaches them with a positive weight
    assert np.all(np.abs(want.ravel()[unrolled.sites["relay_on_2"]]) > 0)


def test_pruning_drops_small_taps_and_reports_the_kept_mass(frame):
    pos, neg = frame
    net = build_network(
        ModelParams(levels=1), pos.shape, SpikingParams(connectivity=Connectivity(prune_dog=0.1, prune_vm=0.2))
    )
    un = unroll(net, {"input_on_1": pos, "input_off_1": neg})
    k = dog_kernels(ModelParams())[:8]
    keep = np.abs(k) >= 0.1 * np.abs(k).max()
    c = _conn(un, "input_on_1_to_simple_1")
    assert c.kept_mass == pytest.approx(np.abs(k[keep]).sum() / np.abs(k).sum())
    assert c.taps == int(keep.sum())
    assert set(np.round(np.abs(c.w) / c.projection.gain_mv, 12)) <= set(np.round(np.abs(k[keep]), 12))
    m2 = von_mises_masks(ModelParams())[1]
    v = _conn(un, "bo_L1_1_to_group_L_1")
    assert v.kept_mass == pytest.approx(m2[m2 >= 0.2].sum() / m2.sum())


def test_counts_table_lists_every_population(unrolled):
    table = unrolled.table()
    for p in unrolled.network.populations:
        assert p.name in table
    syn = unrolled.synapses_in()
    assert syn["simple_1"] == sum(c.n for c in unrolled.connections if c.projection.target == "simple_1")


def test_missing_input_mask_names_the_population():
    net = build_network(ModelParams(levels=1), (20, 20))
    with pytest.raises(ParameterError, match="Population 'input_off_1'"):
        unroll(net, {"input_on_1": np.zeros((20, 20), bool)})
    with pytest.raises(ParameterError, match="Population 'input_on_1'.*shape"):
        unroll(net, {"input_on_1": np.zeros((5, 5), bool), "input_off_1": np.zeros((20, 20), bool)})


@pytest.mark.slow
@pytest.mark.parametrize("light", [True, False])
def test_unrolled_network_iterated_like_the_rate_model_reproduces_it(light):
    """The rate twin (the unrolled cells and synapses, iterated with the rate
    model's stages 4-8) against run_edfg: the whole structure - pruning,
    lattices, site rules, top-down pooling - changes little."""
    from snn_fg.models.rate.edfg import run_edfg
    from snn_fg.models.spiking.twin import run_twin
    from snn_fg.scoring.metrics import compare_frame

    pos, neg = image_to_frame(disc(16, light).image)
    un = unroll(
        build_network(ModelParams(), pos.shape, SpikingParams()), {"input_on_1": pos > 0, "input_off_1": neg > 0}
    )
    fx, fy, g, _ = run_twin(un)
    ref = run_edfg(pos, neg)
    c = compare_frame(fx, fy, g, ref.fg_x, ref.fg_y, ref.grouping)
    assert c["pixels_compared"] > 150
    assert c["angle_diff_median_deg"] < 1e-3  # float rounding of the unrolled weights only
    assert c["grouping_pearson_r"] > 0.98


def test_synapse_counts_survive_freeing_the_arrays(unrolled):
    """A simulator frees each projection's arrays once it holds them; the
    counts table must still report the synapses."""
    import copy

    un = copy.deepcopy(unrolled)
    before = un.synapses_in()
    assert before["simple_1"] > 0
    for c in un.connections:
        c.free()
    assert all(c.pre.size == 0 for c in un.connections)
    assert un.synapses_in() == before


@pytest.mark.slow
def test_source_and_target_enumeration_give_the_same_synapses(frame):
    """Conv synapses are enumerated from whichever side has fewer (tap, cell)
    pairs; both sides must give the same set, on every kind of Conv (DoG with
    wrap-around, channel maps, von Mises gather and scatter across lattices)."""
    from snn_fg.lowering.connect import conv_cell_pairs
    from snn_fg.network import Conv

    pos, neg = frame
    net = build_network(ModelParams(levels=2), pos.shape, SpikingParams())
    un = unroll(net, {"input_on_1": pos, "input_off_1": neg})
    checked = 0
    for c in un.connections:
        pr = c.projection
        if not isinstance(pr, Conv):
            continue
        src, tgt = net.population(pr.source), net.population(pr.target)
        act = un.active[src.name].ravel() if src.is_source else None
        got = []
        for side in ("sources", "targets"):
            pre, post, k, _, _ = conv_cell_pairs(pr, src, tgt, un.sites[src.name], un.sites[tgt.name], net, act, side)
            order = np.lexsort((pre, post))
            got.append((pre[order], post[order], k[order]))
        np.testing.assert_array_equal(got[0][0], got[1][0], err_msg=pr.name)
        np.testing.assert_array_equal(got[0][1], got[1][1], err_msg=pr.name)
        np.testing.assert_allclose(got[0][2], got[1][2], rtol=0, atol=0, err_msg=pr.name)
        checked += got[0][0].size > 0
    assert checked > 20
