"""``--maps-grid blocks``: the maps of a network that pools its input kept on its blocks, what
the sensor's maps are made from (each event pixel takes its block's vector, turned onto its
own edge; the grouping map resized bilinearly), with the event frame pooled beside them and
positions still told in sensor pixels."""

import csv
import json

import numpy as np
import pytest

from snn_fg.cli.main import main
from snn_fg.events import image_to_events, image_to_frame, iter_windows, save_events
from snn_fg.frames.pool import frame_polarities
from snn_fg.frames.scenes import disc
from snn_fg.models.rate.edfg import run_edfg
from snn_fg.network.recipes import model_params_of
from snn_fg.params import ModelParams
from snn_fg.results.figures import on_sensor
from snn_fg.results.maps import Maps, has_vector
from snn_fg.results.peaks import grouping_peaks

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)

POOL = 3


def _blocks_of(sensor: np.ndarray) -> np.ndarray:
    """Each pixel's block index (rows, cols) as a map of the sensor's shape."""
    rows, cols = np.indices(sensor.shape)
    return rows // POOL, cols // POOL


def _check_sensor_maps_come_from_the_blocks(sensor: Maps, blocks: Maps):
    """Unpooling keeps a block's vector's length and side at each event pixel, and the bilinear
    grouping map at a block's centre pixel is the block's value."""
    h, w = sensor.fg_x.shape
    assert blocks.fg_x.shape == (-(-h // POOL), -(-w // POOL))
    br, bc = _blocks_of(sensor.fg_x)
    bx, by = blocks.fg_x[br, bc], blocks.fg_y[br, bc]
    has = np.hypot(sensor.fg_x, sensor.fg_y) > 0
    assert has.sum() > 100
    np.testing.assert_allclose(np.hypot(sensor.fg_x, sensor.fg_y)[has], np.hypot(bx, by)[has], rtol=1e-5)
    assert (sensor.fg_x * bx + sensor.fg_y * by)[has].min() >= 0  # (turned onto the edge, never past it)
    centres = sensor.grouping[POOL // 2 :: POOL, POOL // 2 :: POOL][: h // POOL, : w // POOL]
    np.testing.assert_allclose(centres, blocks.grouping[: h // POOL, : w // POOL], rtol=1e-5, atol=1e-6)


def test_the_spiking_networks_maps_on_blocks_are_what_its_sensor_maps_are_made_from(tmp_path):
    out = {}
    for grid in ("sensor", "blocks"):
        argv = ["run", "demo", "--out", str(tmp_path / grid), "--model", "spiking", "--network", "compact"]
        assert main([*argv, "--maps-grid", grid, "--no-figures", "--no-progress"]) == 0
        out[grid] = Maps.load(tmp_path / grid / "maps.npz")
    _check_sensor_maps_come_from_the_blocks(out["sensor"], out["blocks"])
    assert out["blocks"].params["maps_grid"] == "blocks" and "maps_grid" not in out["sensor"].params
    # the strongest proto-objects are told in sensor pixels, where the sensor's maps put them
    assert [(p["x"], p["y"]) for p in grouping_peaks(out["blocks"])] == [
        (p["x"], p["y"]) for p in grouping_peaks(out["sensor"])
    ]


def test_a_still_inputs_figure_shows_the_blocks_its_maps_are_on():
    from snn_fg.frames.still import Still
    from snn_fg.models import get_model

    pos, neg = image_to_frame(disc(radius=24).image)
    shown = get_model("rate", model_params_of("compact"), maps_grid="blocks").figure_input(Still(pos, neg))
    assert shown.shape[:2] == (-(-pos.shape[0] // POOL), -(-pos.shape[1] // POOL))
    assert (shown == 1.0).all(axis=2).sum() > 10 and (shown == 0.0).all(axis=2).sum() > 10  # (ON and OFF blocks)


def test_the_rate_models_maps_on_blocks_are_what_its_sensor_maps_are_made_from():
    scene = disc(radius=24)
    pos, neg = image_to_frame(scene.image)
    params = ModelParams(input_pool=POOL, levels=3, levels_per_octave=1, r0=4)
    _check_sensor_maps_come_from_the_blocks(run_edfg(pos, neg, params), run_edfg(pos, neg, params, on_blocks=True))


def test_a_recording_on_blocks_stores_the_pooled_event_frame_and_sensor_positions(tmp_path, capsys):
    rec = image_to_events(disc(20).image, motion="circle")
    path = tmp_path / "disc.npy"
    save_events(path, rec.events, rec.sensor_size)
    runs = {}
    for grid in ("sensor", "blocks"):
        argv = ["run", str(path), "--out", str(tmp_path / grid), "--network", "compact", "--window-ms", "60"]
        assert main([*argv, "--max-windows", "2", "--maps-grid", grid, "--no-figures", "--no-progress"]) == 0
        with open(tmp_path / grid / "windows.csv") as f:
            runs[grid] = Maps.load(tmp_path / grid / "maps.zarr"), list(csv.DictReader(f))
    (sensor, sensor_rows), (blocks, block_rows) = runs["sensor"], runs["blocks"]
    frame = np.asarray(sensor.extra["event_frame"])  # (n, 64, 64): a block has events where any of its pixels has
    n, h, w = frame.shape
    bh, bw = -(-h // POOL), -(-w // POOL)  # (a partial block at the edge counts)
    pad = np.zeros((n, bh * POOL, bw * POOL), bool)
    pad[:, :h, :w] = frame != 0
    has_events = pad.reshape(n, bh, POOL, bw, POOL).any(axis=(2, 4))
    stored = np.asarray(blocks.extra["event_frame"])
    assert stored.shape == has_events.shape and has_events.sum() > 50
    np.testing.assert_array_equal(stored != 0, has_events)
    for polarity, blocks_of in zip((frame > 0, frame < 0), frame_polarities(stored), strict=True):  # (ON, OFF)
        pad[:] = False
        pad[:, :h, :w] = polarity
        np.testing.assert_array_equal(blocks_of, pad.reshape(n, bh, POOL, bw, POOL).any(axis=(2, 4)))
    for a, b in zip(sensor_rows, block_rows, strict=True):  # (the rate model's peaks, at a block's centre pixel)
        assert (a["peak_x"], a["peak_y"], a["events"]) == (b["peak_x"], b["peak_y"], b["events"])
        assert int(b["peak_x"]) % POOL == POOL // 2
    # a crop in sensor pixels (the figures' axes) takes the blocks it touches
    crop = ["--crop", "6,3,50,40", "--force"]
    assert main(["plot", str(tmp_path / "blocks"), "--windows", "1", *crop]) == 0
    assert (tmp_path / "blocks" / "windows" / "window_0001.png").is_file()
    capsys.readouterr()
    assert main(["plot", str(tmp_path / "blocks"), "--windows", "1", "--crop", "6,3,60,50", "--force"]) == 2
    err = capsys.readouterr().err.strip().splitlines()  # (told in the sensor's pixels, as given)
    assert len(err) == 1 and "--crop: crop x0,y0,x1,y1 = 6,3,60,50 must satisfy 0 <= x0 < x1 <= 54" in err[0], err
    assert on_sensor(blocks.params, (6, 3, 50, 40)) == {"crop": (2, 1, 17, 14), "placed": (0, 0, POOL)}
    assert on_sensor(sensor.params, (6, 3, 60, 50)) == {"crop": (6, 3, 60, 50)}


@pytest.mark.parametrize(
    "argv, said",
    [
        (["--maps-grid", "blocks"], "--maps-grid blocks: this network sees every sensor pixel"),
        (["--model", "fbfg", "--maps-grid", "blocks"], "--maps-grid: applies to the rate and spiking models only"),
        (["--model", "natural", "--maps-grid", "blocks"], "--maps-grid: applies to the rate and spiking models only"),
    ],
)
def test_blocks_where_there_are_none_is_one_line_and_no_folder(tmp_path, capsys, argv, said):
    assert main(["run", "demo", "--out", str(tmp_path / "x"), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and said in err[0]
    assert not (tmp_path / "x").exists()


def test_the_rate_models_baseline_on_blocks_runs_on_the_blocks_it_stored(tmp_path, capsys):
    """compare's baseline runs the rate model again on each window's stored frame: on blocks, those
    blocks (both polarities of a block kept), not pooled again."""
    rec = image_to_events(disc(20).image, motion="circle")
    path = tmp_path / "disc.npy"
    save_events(path, rec.events, rec.sensor_size)
    for name in ("a", "b"):
        argv = ["run", str(path), "--out", str(tmp_path / name), "--network", "compact", "--window-ms", "60"]
        assert main([*argv, "--max-windows", "2", "--maps-grid", "blocks", "--no-figures", "--no-progress"]) == 0
    assert main(["compare", str(tmp_path / "a"), str(tmp_path / "b"), "--json", str(tmp_path / "c.json")]) == 0
    rows = json.loads((tmp_path / "c.json").read_text())["windows"]
    # what the baseline must be: the rate model at 20 iterations on each window's own events, kept on blocks
    params = model_params_of("compact").replace(iterations=20)
    b = Maps.load(tmp_path / "b" / "maps.zarr")
    for k, w in enumerate(iter_windows(path, window_ms=60, max_windows=2)):
        ref = run_edfg(w.pos, w.neg, params, on_blocks=True)
        both = has_vector(b.fg_x[k], b.fg_y[k]) & has_vector(ref.fg_x, ref.fg_y)
        assert rows[k]["baseline_pixels"] == both.sum() > 20
        assert rows[k]["baseline_grouping_r"] == pytest.approx(
            np.corrcoef(b.grouping[k].ravel(), ref.grouping.ravel())[0, 1]
        )


def test_maps_on_two_grids_are_not_compared_and_the_line_says_why(tmp_path, capsys):
    for grid in ("sensor", "blocks"):
        argv = ["run", "demo", "--out", str(tmp_path / grid), "--network", "compact", "--maps-grid", grid]
        assert main([*argv, "--no-figures", "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["compare", str(tmp_path / "sensor"), str(tmp_path / "blocks")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "on the sensor grid vs the blocks grid: run both with one --maps-grid" in err[0]
