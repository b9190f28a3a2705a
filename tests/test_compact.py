"""The compact network's parts: input pooling, octave levels, the input
adapter, strided excess cells, quantised weights in the fast engine, and
the recipes by name on the command line and in the export report."""

import json
import os

import numpy as np
import pytest

from snn_fg.cli import main
from snn_fg.frames.pool import (
    NORMAL_SIGMA,
    edge_normals,
    event_pixels,
    pool_events,
    pool_frame,
    pooled_shape,
    unpool_maps,
)
from snn_fg.frames.pyramid import level_shape, max_levels
from snn_fg.network import Connectivity, SpikingParams, build_network
from snn_fg.network.nodes import Kernel
from snn_fg.network.recipes import RECIPES, model_params_of, network_for
from snn_fg.params import ModelParams
from snn_fg.results.maps import Maps

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)


def test_a_block_is_on_where_any_of_its_pixels_is_and_a_partial_block_counts():
    pos = np.zeros((5, 7), np.uint8)
    neg = np.zeros_like(pos)
    pos[0, 0] = 1  # block (0, 0)
    neg[1, 1] = 1  # block (0, 0) too: both polarities
    pos[4, 6] = 1  # the partial block at the corner
    on, off = pool_frame(pos, neg, 2)
    assert on.shape == off.shape == pooled_shape(pos.shape, 2) == (3, 4)
    assert on[0, 0] == 1 and off[0, 0] == 1 and on[2, 3] == 1
    assert on.sum() == 2 and off.sum() == 1
    ev = np.zeros(2, dtype=[("x", "<i2"), ("y", "<i2"), ("t", "<i8"), ("p", "i1")])
    ev["x"], ev["y"] = (6, 3), (4, 2)
    assert pool_events(ev, 3)[["x", "y"]].tolist() == [(2, 1), (1, 0)]


def test_maps_come_back_at_the_sensor_size_on_its_event_pixels_only():
    edges = np.zeros((5, 7), bool)
    edges[0, 1] = edges[1, 0] = edges[4, 6] = True
    fx = np.zeros((3, 4), np.float32)
    fx[0, 0], fx[2, 3] = 2.0, -1.0
    g = np.arange(12, dtype=np.float32).reshape(3, 4)
    ux, uy, ug = unpool_maps(fx, fx, g, edges, 2)
    assert ux.shape == uy.shape == ug.shape == (5, 7)
    # every event pixel keeps its block's vector's length; no other pixel gets one
    length = np.hypot(ux, uy)
    root2 = np.sqrt(2)
    np.testing.assert_allclose(length[[0, 1, 4], [1, 0, 6]], [2 * root2, 2 * root2, root2], rtol=1e-6)
    assert np.count_nonzero(length) == 3
    assert ug.min() >= g.min() and ug.max() <= g.max()


def test_a_blocks_vector_turns_onto_the_edge_normal_and_keeps_its_side():
    """On a straight line of events a block's vector, 30 degrees off the
    line's normal, comes back along the normal, on the side it pointed to
    and as long; a lone event (no direction around it) keeps the block's."""
    edges = np.zeros((24, 36), bool)
    edges[:, 10] = True  # a vertical edge: normal along x
    edges[12, 31] = True  # a lone event, 7 blocks from it
    for side in (1, -1):
        angle = np.radians(30 if side > 0 else 210)
        fx = np.full((8, 12), 0.5 * np.cos(angle), np.float32)
        fy = np.full((8, 12), 0.5 * np.sin(angle), np.float32)
        ux, uy, _ = unpool_maps(fx, fy, np.zeros((8, 12), np.float32), edges, 3)
        line = np.degrees(np.arctan2(uy[4:20, 10], ux[4:20, 10]))
        np.testing.assert_allclose(np.abs(line), 0 if side > 0 else 180, atol=1.0)
        np.testing.assert_allclose(np.hypot(ux, uy)[edges], 0.5, rtol=1e-5)
        lone = np.degrees(np.arctan2(uy[12, 31], ux[12, 31])) % 360
        assert abs(lone - np.degrees(angle) % 360) < 1.0


def _normals_by_scipy(edges, pool, at):
    """The structure tensor's normal and coherence written with scipy.ndimage and numpy."""
    from scipy.ndimage import gaussian_filter

    d_row, d_col = np.gradient(gaussian_filter(edges.astype(np.float64), NORMAL_SIGMA))
    gx, gy = d_col, -d_row
    jxx, jyy, jxy = (gaussian_filter(a, float(pool))[at] for a in (gx * gx, gy * gy, gx * gy))
    trace = jxx + jyy
    coherence = np.divide(np.hypot(jxx - jyy, 2.0 * jxy), trace, out=np.zeros_like(trace), where=trace > 1e-12)
    phi = 0.5 * np.arctan2(2.0 * jxy, jxx - jyy)
    return np.cos(phi), np.sin(phi), np.clip(coherence, 0.0, 1.0)


@pytest.mark.parametrize(
    "shape, pool, density",
    [((60, 80), 3, 0.15), ((5, 7), 3, 0.15), ((2, 30), 2, 0.15), ((40, 3), 4, 0.15), ((90, 120), 3, 0.004)],
)
def test_edge_normals_are_scipys_gaussians_bit_for_bit_at_the_pixels_asked_for(shape, pool, density):
    """The compiled structure tensor (the block average taken only at the
    pixels asked for, each pass only where the next reads it) gives what
    scipy.ndimage's Gaussians and numpy's gradient give, to the last bit,
    also on frames narrower than the kernel and on a few scattered pixels."""
    rng = np.random.default_rng(sum(shape) + pool)
    edges = rng.random(shape) < density
    at = np.nonzero(edges)
    want = _normals_by_scipy(edges, pool, at)
    for got in (edge_normals(edges, pool, at), [a[at] for a in edge_normals(edges, pool)]):
        for g, w in zip(got, want, strict=True):
            assert np.array_equal(g, w)


@pytest.mark.parametrize(
    "shape, pool, box",
    [
        ((60, 80), 2, (slice(20, 35), slice(30, 50))),
        ((60, 80), 3, (slice(0, 12), slice(70, 80))),
        ((9, 40), 2, (slice(None), slice(3, 6))),
        ((30, 40), 3, (slice(5, 25), slice(0, 40))),
    ],
)
def test_edge_normals_of_events_in_part_of_the_frame_are_scipys_bit_for_bit(shape, pool, box):
    """The products of the gradients are taken only between the columns the
    block average reads (events in part of the frame, away from or at its
    edges, or across it): the same bits."""
    rng = np.random.default_rng(shape[0] + pool)
    edges = np.zeros(shape, bool)
    edges[box] = rng.random(shape)[box] < 0.3
    at = np.nonzero(edges)
    for g, w in zip(edge_normals(edges, pool, at), _normals_by_scipy(edges, pool, at), strict=True):
        assert np.array_equal(g, w)


def test_the_smoothing_passes_over_the_rows_within_reach_of_a_value_only_and_gives_scipys_bits():
    """The two smoothing passes of the edge normals leave out the rows no value reaches
    (and, along axis 0, the columns outside the values'): the same bits as
    scipy.ndimage's Gaussian, a -0.0 included, and the rows they left out."""
    from scipy.ndimage import gaussian_filter

    from snn_fg.frames.pool import _gaussian_weights, _smooth_cols, _smooth_rows

    rng = np.random.default_rng(5)
    x = np.zeros((40, 50))
    x[10:14, 20:30] = rng.random((4, 10))
    x[30, 5], x[38, 49] = -0.0, 1.0
    w = _gaussian_weights(NORMAL_SIGMA)
    smooth, e, live = np.zeros_like(x), np.zeros_like(x), np.empty(40, bool)
    _smooth_rows(x, w, smooth, live)
    _smooth_cols(smooth, w, e, live)
    want = gaussian_filter(x, NORMAL_SIGMA)
    assert np.array_equal(e, want) and np.array_equal(np.signbit(e), np.signbit(want))
    assert np.flatnonzero(live).tolist() == [*range(6, 18), *range(26, 40)]


@pytest.mark.parametrize("dtype", [bool, np.uint8, np.int8, np.float32])
@pytest.mark.parametrize("shape", [(24, 32), (1, 7), (7, 1), (0, 5), (5, 0)])
def test_event_pixels_are_nonzeros_arrays(shape, dtype):
    rng = np.random.default_rng(shape[0] * 10 + shape[1])
    signs = rng.choice([-1, 1], shape) if dtype in (np.int8, np.float32) else 1  # (OFF pixels as -1, too)
    frame = np.where(rng.random(shape) < 0.2, signs, 0).astype(dtype)
    got, want = event_pixels(frame), np.nonzero(frame)
    assert len(got) == len(want) == 2
    for g, w in zip(got, want, strict=True):
        assert g.dtype == w.dtype and np.array_equal(g, w)


def test_octave_levels_halve_the_frame_and_the_default_steps_are_unchanged():
    assert level_shape((240, 304), 2, per_octave=1) == (121, 153)
    assert level_shape((240, 304), 3, per_octave=1) == (61, 77)
    assert level_shape((321, 481), 2) == (227, 341)  # 1/sqrt(2), as before
    assert max_levels((80, 102), per_octave=1) < max_levels((80, 102))
    net = build_network(ModelParams(levels=3, levels_per_octave=1, n_ori=4), (40, 52))
    assert net.one("simple", 3).level_shape == (11, 14)


def test_the_rate_model_pools_its_input_and_answers_at_the_sensor_size():
    from snn_fg.events import image_to_frame
    from snn_fg.frames.scenes import disc
    from snn_fg.models.rate.edfg import run_edfg
    from snn_fg.scoring.metrics import grouping_peak_inside, truth_scores

    scene = disc(radius=24)
    pos, neg = image_to_frame(scene.image)
    maps = run_edfg(pos, neg, ModelParams(input_pool=2, levels=3, levels_per_octave=1, r0=4))
    assert maps.fg_x.shape == pos.shape
    has = np.hypot(maps.fg_x, maps.fg_y) > 0
    assert not (has & ~((pos | neg) > 0)).any()  # vectors only at event pixels
    assert truth_scores(maps.fg_x, maps.fg_y, scene)["frac_within_45"] >= 0.9
    assert grouping_peak_inside(maps.grouping, scene)


def _events(rows):
    ev = np.zeros(len(rows), dtype=[("x", "<i2"), ("y", "<i2"), ("t", "<i8"), ("p", "i1")])
    for i, (x, t) in enumerate(rows):
        ev[i] = (x, 0, t, 1)
    return ev


def test_the_input_adapter_passes_one_event_per_refractory_period_and_source():
    from snn_fg.lowering.input_spikes import event_spikes

    ev = _events([(0, 1000 * k) for k in range(10)] + [(1, 0), (1, 500)])  # pixel 0 every ms
    ev = ev[np.argsort(ev["t"], kind="stable")]
    every = event_spikes(ev, (2, 1), 0.5, replay=False)
    assert every.steps[every.indices == 0].tolist() == list(range(0, 20, 2))
    gap = event_spikes(ev, (2, 1), 0.5, replay=False, refractory_ms=2.5)
    assert gap.steps[gap.indices == 0].tolist() == [0, 6, 12, 18]  # 0, 3, 6, 9 ms
    assert gap.steps[gap.indices == 1].tolist() == [0]


def test_block_mean_hands_each_source_pixel_one_over_stride_squared():
    k = Kernel(ref="block_mean", args={"channels": 3, "stride": 2}).array(ModelParams())
    assert k.shape == (3, 3, 3, 3) and k[0, 1].sum() == 0
    assert k[1, 1].sum() == pytest.approx(1.0)
    # a source pixel at an odd offset reaches two lattice points, at half weight each
    assert k[0, 0, 1, 0] + k[0, 0, 1, 2] == pytest.approx(k[0, 0, 1, 1])


def test_strided_excess_cells_sit_on_the_grouping_lattice():
    net = build_network(
        ModelParams(levels=2, n_ori=4), (24, 32), SpikingParams(connectivity=Connectivity(excess_stride=2))
    )
    ex = net.one("excess_L1", 1)
    assert ex.stride == 2 and ex.size == 4 * 12 * 16
    full = build_network(ModelParams(levels=2, n_ori=4), (24, 32))
    assert full.one("excess_L1", 1).size == 4 * ex.size


def test_resize_kept_mass_equals_the_sum_over_every_product():
    from snn_fg.lowering.connect import resize_kept_mass
    from snn_fg.lowering.interp import interp_matrix

    ar, ac = interp_matrix(40, 29, 1, 1, "cubic"), interp_matrix(52, 37, 1, 1, "cubic")
    peak = np.abs(ar).max() * np.abs(ac).max()
    prod = np.abs(ar)[:, None, :, None] * np.abs(ac)[None, :, None, :]
    for prune in (0.01, 0.1, 0.3):
        want = (prod * (prod >= prune * peak)).sum() / prod.sum()
        assert resize_kept_mass(ar, ac, prune, peak) == pytest.approx(want, rel=1e-12)
    big = interp_matrix(480, 340, 1, 1, "cubic")  # once recursed without end (4e6 products and more)
    assert 0.9 < resize_kept_mass(big, big, 0.01, np.abs(big).max() ** 2) < 1.0


def test_the_fast_engine_runs_the_weights_a_board_holds():
    from snn_fg.backends.fast import tables as ft

    net = build_network(
        ModelParams(levels=2, n_ori=4), (20, 24), SpikingParams(connectivity=Connectivity(prune_resize=0.01))
    )
    exact, q = ft.build_tables(net, 0.5), ft.build_tables(net, 0.5, weight_bits=4)
    for p, pr in enumerate(net.projections):
        a, b = q.spans[p]
        if b > a:
            k = np.abs(pr.kernel.array(net.params)).max()
            steps = q.st_k[a:b] / (k / 7)
            assert np.allclose(steps, np.round(steps)) and np.abs(steps).max() <= 7
    assert np.count_nonzero(q.st_k) < np.count_nonzero(exact.st_k)  # taps that round to 0 are gone
    assert (q.prj_w[:, 2] > 0).sum() == sum(1 for pr in net.projections if pr.type_name == "resize")


def test_recipes_build_for_any_sensor_and_carry_their_model_parameters():
    net, origin = network_for("compact", (260, 346))  # a DAVIS346
    c = RECIPES["compact"].params
    assert origin == {"origin": "recipe", "recipe": "compact"}
    assert net.frame_shape == pooled_shape((260, 346), c.input_pool) and net.params == c
    assert model_params_of("compact") == c and model_params_of("default") == ModelParams()
    assert network_for("default", (40, 52))[0] == build_network(ModelParams(), (40, 52))
    stored, how = network_for(net, (240, 304))  # a description resized to another sensor
    assert stored.frame_shape == pooled_shape((240, 304), c.input_pool) and how["resized_from"] == [87, 116]


def test_a_network_carries_its_time_step_into_runs_and_exports():
    """A network names the time step it is made for: a stored description
    keeps it (and omits the default 0.5 ms, so older files read the same), a
    run and an export use it unless given another, and 0 is refused."""
    from snn_fg.errors import ParameterError
    from snn_fg.events import image_to_frame
    from snn_fg.export.pynn import pynn_model
    from snn_fg.export.report import resource_report
    from snn_fg.frames.scenes import disc
    from snn_fg.models.spiking import run_spiking
    from snn_fg.network.graph import Network

    net = RECIPES["compact"].build((64, 64))
    assert net.dt_ms == 1.0 and net.to_dict()["dt_ms"] == 1.0 and Network.from_dict(net.to_dict()) == net
    assert "dt_ms" not in RECIPES["default"].build((40, 52)).to_dict()
    with pytest.raises(ParameterError, match="dt_ms"):
        Network.from_dict({**net.to_dict(), "dt_ms": 0})
    assert resource_report(net)["dt_ms"] == 1.0 and resource_report(net, dt_ms=0.5)["dt_ms"] == 0.5
    assert pynn_model(net)[0]["dt_ms"] == 1.0
    pos, neg = image_to_frame(disc(radius=16).image)  # (a 64 x 64 frame)
    own = run_spiking(pos, neg, network=net, duration_ms=60, settle_ms=30, progress=False)
    half = run_spiking(pos, neg, network=net, duration_ms=60, settle_ms=30, dt_ms=0.5, progress=False)
    assert own.params["simulation"]["dt_ms"] == 1.0 and half.params["simulation"]["dt_ms"] == 0.5
    assert own.params["backend_stats"]["active_cell_steps"] < half.params["backend_stats"]["active_cell_steps"]


@pytest.mark.slow
def test_the_compact_network_fits_one_loihi2_chip_at_the_icub_size(tmp_path):
    """Acceptance of the compact network's size (issue 36 item 2): the
    report for 304 x 240 has 1 Loihi 2 chip and no violated Loihi 2 or
    SpiNNaker limit; SpiNNaker needs more than one board, so the report says
    how large a sensor one board holds."""
    out = tmp_path / "r.json"
    assert (
        main(["export", "--format", "report", "--network", "compact", "--sensor-size", "304x240", "--out", str(out)])
        == 0
    )
    rep = json.loads(out.read_text())
    assert rep["sensor_shape"] == [240, 304] and rep["input_pool"] == 3
    lo, sp = rep["targets"]["loihi2"], rep["targets"]["spinnaker1"]
    assert lo["chips"] == 1 and lo["violations"] == []
    assert sp["violations"] == []
    one = sp["largest_sensor_one_board"]
    assert sp["boards_spinn5"] > 1 and 0 < one["width"] < 304 and one["chips"] <= 48
    assert rep["totals"]["neurons"] < 1_000_000


@pytest.mark.slow
def test_a_recording_runs_through_the_compact_network_all_or_nothing(tmp_path):
    """snn-fg run REC --model spiking --network compact: one continuous run on
    the pooled sensor, maps at the sensor's size with each window's own
    time, the input adapter recorded; a bad option leaves no folder."""
    from snn_fg.events import image_to_events, save_events
    from snn_fg.frames.scenes import disc

    rec = image_to_events(disc(20).image, motion="circle")
    path = tmp_path / "disc.npy"
    save_events(path, rec.events, rec.sensor_size)
    out = tmp_path / "out"
    assert (
        main(
            [
                "run",
                str(path),
                "--out",
                str(out),
                "--model",
                "spiking",
                "--network",
                "compact",
                "--window-ms",
                "60",
                "--max-windows",
                "3",
                "--sensor-size",
                "72x72",
                "--no-progress",
            ]
        )
        == 0
    )
    m = Maps.load(out / "maps.zarr")
    assert m.fg_x.shape == (3, 72, 72)
    p = m.params
    assert p["network"]["origin"] == "recipe" and p["network"]["frame_shape"] == [24, 24]
    assert p["simulation"]["network_builds"] == 1
    assert p["simulation"]["dt_ms"] == RECIPES["compact"].spiking.time.dt_ms == 1.0  # (the network's own step)
    times = [p["timings_s"]["window"]] + [w["timings_s"]["window"] for w in p["windows"][1:]]
    assert len(times) == 3 and all(t > 0 for t in times)
    assert sorted(os.listdir(out)) == [
        "maps.png",
        "maps.zarr",
        "timeline.png",
        "windows.csv",
    ]  # (spike figures need --save-spikes)
    bad = tmp_path / "bad"
    assert (
        main(
            [
                "run",
                str(path),
                "--out",
                str(bad),
                "--model",
                "spiking",
                "--network",
                "compact",
                "--duration-ms",
                "50",
                "--sensor-size",
                "72x72",
            ]
        )
        == 2
    )
    assert not bad.exists()


@pytest.mark.slow
def test_run_takes_a_network_by_name_for_both_models_and_can_skip_figures(tmp_path):
    for model in ("rate", "spiking"):
        out = tmp_path / model
        assert (
            main(
                [
                    "run",
                    "demo",
                    "--out",
                    str(out),
                    "--model",
                    model,
                    "--network",
                    "compact",
                    "--no-figures",
                    "--no-progress",
                ]
            )
            == 0
        )
        assert os.listdir(out) == ["maps.npz"]
        m = Maps.load(out / "maps.npz")
        assert m.fg_x.shape == (120, 160)
        assert m.params["input_pool"] == RECIPES["compact"].params.input_pool
        assert np.count_nonzero(m.magnitude) > 100
        assert m.params["timings_s"]["run" if model == "rate" else "total"] > 0
    assert main(["run", "demo", "--out", str(tmp_path / "x"), "--network", "compact", "--r0", "5"]) == 2
    assert main(["run", "demo", "--out", str(tmp_path / "y"), "--model", "fbfg", "--network", "compact"]) == 2
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()


def test_stored_compact_network_is_current():
    """networks/compact_304x240.json is the compact network for the iCub's
    sensor: it loads, validates and equals what the recipe builds today."""
    from pathlib import Path

    from snn_fg.network.graph import Network

    stored = Network.load(Path(__file__).resolve().parents[1] / "networks" / "compact_304x240.json")
    assert stored == RECIPES["compact"].build((240, 304))
