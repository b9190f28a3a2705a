"""The event-driven rate model against a direct, dense transcription of docs/model.md.

The reference below is written from the model description with
scipy.ndimage.correlate and cv2.resize, independently of snn_fg.models.rate; every
path the event-driven code can choose (scatter or Fourier grouping input,
gathered or dense feedback, sparse or Fourier responses) is forced in turn.
"""

import cv2
import numpy as np
import pytest
from scipy import ndimage

from snn_fg.frames.pyramid import level_shape, resize
from snn_fg.models.rate import edfg, grouping
from snn_fg.models.rate.edfg import event_simple_cells, oriented_responses, responses_at
from snn_fg.models.rate.grouping import SparseGrouping
from snn_fg.models.rate.grouping_tables import Entries, cubic_taps
from snn_fg.network.kernels import von_mises_masks
from snn_fg.params import ModelParams

PARAMS = ModelParams(levels=2, iterations=2, n_ori=4)


def _frame(shape=(36, 44), seed=3):
    rng = np.random.default_rng(seed)
    img = np.zeros(shape)
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    img[np.hypot(yy - 18, xx - 20) < 10] = 1.0
    img[4:10, 30:40] = 0.5
    pos = ((np.abs(np.diff(img, axis=1, prepend=0)) > 0) & (rng.random(shape) < 0.9)).astype(np.uint8)
    neg = ((np.abs(np.diff(img, axis=0, prepend=0)) > 0) & (pos == 0)).astype(np.uint8)
    return pos, neg


def _dense_reference(s_levels, p):
    """Stages 5-8 as docs/model.md states them, on whole maps."""
    n = p.n_ori
    m1, m2 = von_mises_masks(p)
    corr = lambda a, k: ndimage.correlate(a, k, mode="constant")  # noqa: E731
    f = lambda z: 1 + p.alpha * (1 / (1 + np.exp(-z)) - 0.5)  # noqa: E731
    bl1 = [s[:n].copy() for s in s_levels]
    bd2 = [s[:n].copy() for s in s_levels]
    bl2 = [s[n:].copy() for s in s_levels]
    bd1 = [s[n:].copy() for s in s_levels]
    gl, gd = [None] * len(s_levels), [None] * len(s_levels)
    for _ in range(p.iterations):
        for i in range(len(s_levels)):
            L, D = 0.0, 0.0
            for o in range(n):
                w = 0.0 if np.allclose(bl1[i][o], bd2[i][o]) else p.w_inh
                L = L + corr(bl1[i][o] - w * bd2[i][o], m2[o]) + corr(bl2[i][o] - w * bd1[i][o], m1[o])
                D = D + corr(bd1[i][o] - w * bl2[i][o], m2[o]) + corr(bd2[i][o] - w * bl1[i][o], m1[o])
            L, D = np.maximum(L, 0), np.maximum(D, 0)
            gl[i], gd[i] = np.where(L > D, L, 0.0), np.where(D > L, D, 0.0)
        for i, s in enumerate(s_levels):
            shape = s.shape[1:]
            v1 = sum(
                0.5 ** (k - i)
                * resize(np.stack([corr(gl[k], m1[o]) - corr(gd[k], m2[o]) for o in range(n)], -1), shape)
                for k in range(i, len(s_levels))
            )
            v2 = sum(
                0.5 ** (k - i)
                * resize(np.stack([corr(gl[k], m2[o]) - corr(gd[k], m1[o]) for o in range(n)], -1), shape)
                for k in range(i, len(s_levels))
            )
            f1, f2 = f(np.moveaxis(v1, -1, 0)), f(np.moveaxis(v2, -1, 0))
            bl1[i], bd2[i] = np.maximum(s[:n] * f1, 0), np.maximum(s[:n] * (2 - f1), 0)
            bl2[i], bd1[i] = np.maximum(s[n:] * f2, 0), np.maximum(s[n:] * (2 - f2), 0)
    return bl1, bd2, gl, gd


@pytest.fixture(scope="module")
def reference():
    s_levels = event_simple_cells(*_frame(), PARAMS)[0]
    return s_levels, _dense_reference(s_levels, PARAMS)


@pytest.mark.slow
@pytest.mark.parametrize("path", ["scatter+gather", "fourier"])
def test_grouping_matches_dense_transcription(monkeypatch, reference, path):
    s_levels, (bl1, bd2, gl, gd) = reference
    if path == "scatter+gather":  # every level sparse
        monkeypatch.setattr(grouping, "_FFT_COST_PER_CELL", 1e9)
        monkeypatch.setattr(grouping, "_FFT_COST_PER_CELL_SINGLE", 1e9)
    elif path == "fourier":  # every level dense
        monkeypatch.setattr(grouping, "_FFT_COST_PER_CELL", 0.0)
        monkeypatch.setattr(grouping, "_FFT_COST_PER_CELL_SINGLE", 0.0)
    got = (
        SparseGrouping([Entries.from_dense(s) for s in s_levels], [s.shape[1:] for s in s_levels], PARAMS).run().dense()
    )
    # The dense feedback correlation runs in single precision: 1e-4 relative.
    tol = 1e-9 if path == "scatter+gather" else 1e-4
    for i in range(PARAMS.levels):
        scale = max(1.0, np.abs(gl[i]).max())
        assert np.abs(got.gl[i] - gl[i]).max() <= tol * scale
        assert np.abs(got.gd[i] - gd[i]).max() <= tol * scale
        assert np.abs(got.bl1[i] - bl1[i]).max() <= tol * 2
        assert np.abs(got.bd2[i] - bd2[i]).max() <= tol * 2
    assert max(g.max() for g in gl) > 1.0  # the scene does group


def test_cubic_taps_reproduce_opencv_resize():
    rng = np.random.default_rng(0)
    src = rng.random(level_shape((40, 52), 3))
    dst_shape = (40, 52)
    assert src.shape == (20, 26)
    rs, rw = cubic_taps(src.shape[0], dst_shape[0])
    cs, cw = cubic_taps(src.shape[1], dst_shape[1])
    # interpolate columns, then rows (OpenCV's order), with the taps
    cols = (src[:, cs[:, None] + np.arange(4)] * cw[None]).sum(-1)  # (h_src, w_dst)
    ours = (cols[rs[:, None] + np.arange(4)] * rw[:, :, None]).sum(1)  # (h_dst, w_dst)
    ref = cv2.resize(src, dst_shape[::-1], interpolation=cv2.INTER_CUBIC)
    assert np.abs(ours - ref).max() < 1e-12


@pytest.mark.parametrize("level", [1, 2])
def test_sparse_responses_equal_fourier_ones(level):
    pos, neg = _frame()
    shape = level_shape(pos.shape, level)
    p_l = resize(pos.astype(float), shape)
    n_l = resize(neg.astype(float), shape)
    rows, cols = np.nonzero(resize(((pos | neg) > 0).astype(float), shape))
    low = ModelParams(edge_threshold=0.05, sum_threshold=0.0)  # keep the weaker coarse responses
    dense = oriented_responses(p_l, n_l, low)[:, rows, cols]
    sparse = responses_at(p_l, n_l, rows.astype(np.int64), cols.astype(np.int64), low)
    assert dense.any()
    assert np.abs(sparse - dense).max() < 1e-9


def test_rate_state_dense_views_agree_with_entries():
    pos, neg = _frame()
    st = edfg.run_edfg_state(pos, neg, PARAMS)
    g = st.grouping_result
    e = st.engine.levels[0].e
    n_dir = PARAMS.n_dir
    assert (st.winner.shape == pos.shape) and st.resp.shape == (n_dir,) + pos.shape
    # every entry's channel is the orientation index the dense winner gives
    assert np.array_equal((st.winner[e.rows, e.cols] + n_dir // 4) % n_dir, e.ch)
    assert np.allclose(g.gl[0] + g.gd[0], st.engine.grouping_maps()[0][0] + st.engine.grouping_maps()[0][1])


def _engine(pos, neg, p):
    entries, shapes = edfg.event_entries(pos, neg, p)
    return SparseGrouping(entries, shapes, p)


def test_continuing_a_frame_from_its_own_state_adds_iterations():
    """Stopping after 4 iterations and continuing a new engine from there for
    6 more gives the 10-iteration maps: the seeded first feedback is exactly
    the one the uninterrupted run computes next."""
    pos, neg = _frame()
    p4, p6, p10 = (ModelParams(levels=2, n_ori=4, iterations=k) for k in (4, 6, 10))
    whole = _engine(pos, neg, p10).run()
    first = _engine(pos, neg, p4).run()
    rest = _engine(pos, neg, p6)
    rest.continue_from(first)
    rest.run()
    four = first.readout(pos.shape)
    for got, want in zip(rest.readout(pos.shape), whole.readout(pos.shape)):
        assert np.allclose(got, want, rtol=1e-6, atol=1e-9 * np.abs(want).max())
    # (and 4 iterations alone are not yet there, so the comparison can fail)
    assert not np.allclose(four[0], whole.readout(pos.shape)[0], rtol=1e-3, atol=1e-6)


def test_continuing_from_another_shape_or_more_than_all_is_refused():
    from snn_fg.errors import ParameterError

    pos, neg = _frame()
    other = _engine(*_frame(shape=(40, 44)), PARAMS).run()
    with pytest.raises(ParameterError, match="continue_from: the previous frame's levels have other shapes"):
        _engine(pos, neg, PARAMS).continue_from(other)
    same = _engine(pos, neg, PARAMS).run()
    with pytest.raises(ParameterError, match="carry=1.5 must be <= 1"):
        _engine(pos, neg, PARAMS).continue_from(same, carry=1.5)


def test_loading_a_dense_state_and_stepping_each_stage_is_one_more_iteration():
    """The hooks that put another implementation's state (a spiking network's
    decoded rates) through the model's own stages: a fresh engine loaded with
    the dense state after 3 iterations, then stage 7 and stage 8 once, holds
    the 4-iteration state; ``pooled_z`` is the z that stage 8 turned into B."""
    pos, neg = _frame()
    p3, p4 = (ModelParams(levels=2, n_ori=4, iterations=k) for k in (3, 4))
    three, four = _engine(pos, neg, p3).run(), _engine(pos, neg, p4).run()
    fresh = _engine(pos, neg, p3).load(three.dense())
    assert np.allclose(fresh.readout(pos.shape)[0], three.readout(pos.shape)[0])
    fresh.group_step()
    for (gl, gd), (wl, wd) in zip(fresh.grouping_maps(), four.grouping_maps()):
        assert np.allclose(gl, wl, atol=1e-9 * max(np.abs(wl).max(), 1)) and np.allclose(
            gd, wd, atol=1e-9 * max(np.abs(wd).max(), 1)
        )
    z = fresh.pooled_z()
    fresh.feedback_step()
    for got, want in zip(fresh.readout(pos.shape), four.readout(pos.shape)):
        assert np.allclose(got, want, rtol=1e-6, atol=1e-9 * max(np.abs(want).max(), 1))
    lv = fresh.levels[0]
    f = 1 + PARAMS.alpha * (1 / (1 + np.exp(-z)) - 0.5)
    assert np.allclose(lv.bl, lv.e.s * f) and np.allclose(lv.bd, lv.e.s * (2 - f))
    # (and loading only the grouping maps leaves B at S, which differs from the 3-iteration B)
    only_g = _engine(pos, neg, p3).load(three.dense(), border=False)
    assert not np.allclose(only_g.levels[0].bl, three.levels[0].bl)
