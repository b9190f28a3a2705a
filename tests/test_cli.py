"""The CLI contract: outputs, one-line errors for bad input, atomic writes."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from snn_fg.cli import main
from snn_fg.params import ModelParams
from snn_fg.results import atomic
from snn_fg.results.maps import Maps

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)


def run_cli(*args):
    """Run the real console entry point in a subprocess (as a user would)."""
    return subprocess.run(
        [sys.executable, "-m", "snn_fg.cli", *map(str, args)], capture_output=True, text=True, timeout=300
    )


@pytest.mark.slow
def test_demo_rate_writes_maps_and_figure(tmp_path):
    res = run_cli("run", "demo", "--out", tmp_path, "--no-progress")
    assert res.returncode == 0, res.stderr
    m = Maps.load(tmp_path / "maps.npz")
    with np.load(tmp_path / "maps.npz") as d:
        assert set(d.files) >= {"fg_x", "fg_y", "grouping", "params"}
        for k in ("fg_x", "fg_y", "grouping"):
            assert d[k].dtype == np.float32 and d[k].shape == (120, 160)
        params = json.loads(str(d["params"]))
    assert params["levels"] == 10 and params["alpha"] == 2 and params["source"]["threshold"] == 0.1
    assert np.count_nonzero(m.magnitude) > 100
    assert (tmp_path / "maps.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(os.listdir(tmp_path)) == ["maps.npz", "maps.png"]


@pytest.mark.slow
def test_parameters_reach_the_model(tmp_path):
    assert (
        main(
            ["run", "demo", "--out", str(tmp_path), "--r0", "6", "--levels", "4", "--iterations", "3", "--no-progress"]
        )
        == 0
    )
    p = Maps.load(tmp_path / "maps.npz").params
    assert (p["r0"], p["levels"], p["iterations"]) == (6, 4, 3)


@pytest.mark.slow
def test_fbfg_on_image(tmp_path):
    import cv2

    from snn_fg.frames.scenes import disc

    img = tmp_path / "disc.png"
    cv2.imwrite(str(img), (disc(20).image * 255).astype(np.uint8))
    assert main(["run", str(img), "--out", str(tmp_path / "o"), "--model", "fbfg", "--no-progress"]) == 0
    assert Maps.load(tmp_path / "o" / "maps.npz").grouping.max() == pytest.approx(1.0)
    assert main(["run", str(img), "--out", str(tmp_path / "r"), "--model", "rate", "--no-progress"]) == 0


def _frame(tmp_path, name, **arrays):
    p = tmp_path / name
    np.savez(p, **arrays)
    return p


def _bad_inputs(tmp_path):
    ok = np.zeros((20, 30), np.uint8)
    ok[5, 5:20] = 1
    nan = np.zeros((20, 30))
    nan[3, 4] = np.nan
    (tmp_path / "broken.npz").write_bytes(b"PK\x03\x04 this is not a zip")
    (tmp_path / "text.png").write_text("not an image")
    (tmp_path / "zero.png").write_bytes(b"")
    import cv2

    square = np.zeros((40, 60), np.uint8)
    square[10:30, 15:45] = 255
    whole = cv2.imencode(".png", square)[1].tobytes()
    (tmp_path / "cut.png").write_bytes(whole[: len(whole) // 2])  # (libpng warns of it on stderr itself)
    return {
        "missing": (tmp_path / "nope.npz", "no such file"),
        "keys": (_frame(tmp_path, "keys.npz", on=ok, off=ok), "lacks key"),
        "dtype": (_frame(tmp_path, "dtype.npz", pos=ok.astype(np.int32), neg=ok.astype(np.int32)), "dtype"),
        "shape": (_frame(tmp_path, "shape.npz", pos=ok, neg=ok[:10]), "differ in shape"),
        "ndim": (_frame(tmp_path, "ndim.npz", pos=ok[None], neg=ok[None]), "2-D"),
        "empty": (_frame(tmp_path, "empty.npz", pos=ok * 0, neg=ok * 0), "empty"),
        "nan": (_frame(tmp_path, "nan.npz", pos=nan, neg=nan), "NaN"),
        "zip": (tmp_path / "broken.npz", "npz"),
        "image": (tmp_path / "text.png", "not an image: its first bytes are no image format's"),
        "empty_image": (tmp_path / "zero.png", "file is empty (at byte offset 0)"),
        "cut_image": (tmp_path / "cut.png", "a PNG file that OpenCV cannot decode: damaged or cut short"),
    }


@pytest.mark.slow
@pytest.mark.parametrize(
    "case", ["missing", "keys", "dtype", "shape", "ndim", "empty", "nan", "zip", "image", "empty_image", "cut_image"]
)
def test_bad_input_gives_one_clear_line(tmp_path, case):
    path, expect = _bad_inputs(tmp_path)[case]
    out = tmp_path / "out"
    res = run_cli("run", path, "--out", out, "--no-progress")
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    assert "Traceback" not in res.stderr
    assert str(path.name) in lines[0] and expect in lines[0]
    assert not (out / "maps.npz").exists()


def test_interrupted_write_leaves_nothing(tmp_path, monkeypatch):
    def explode(fh, value):  # Ctrl-C halfway through writing an array
        fh.write(b"\x93NUMPY partial")
        raise KeyboardInterrupt

    monkeypatch.setattr(atomic, "_write_npy", explode)
    rc = main(["run", "demo", "--out", str(tmp_path), "--iterations", "1", "--no-progress"])
    assert rc == 130
    assert os.listdir(tmp_path) == []


@pytest.mark.slow
def test_compare_prints_and_saves_metrics(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    assert main(["run", "demo", "--out", str(a), "--no-progress"]) == 0
    assert main(["run", "demo", "--out", str(b), "--r0", "6", "--no-progress"]) == 0
    res = run_cli("compare", a / "maps.npz", a / "maps.npz", "--json", tmp_path / "same.json")
    assert res.returncode == 0, res.stderr
    same = json.loads((tmp_path / "same.json").read_text())["windows"][0]
    assert same["grouping_pearson_r"] == pytest.approx(1.0)
    assert same["angle_diff_median_deg"] == 0 and same["angle_mse"] == 0
    assert main(["compare", str(a / "maps.npz"), str(b / "maps.npz"), "--json", str(tmp_path / "d.json")]) == 0
    diff = json.loads((tmp_path / "d.json").read_text())["windows"][0]
    assert diff["grouping_pearson_r"] < 1.0
    assert set(diff) >= {"grouping_ssim", "angle_ssim", "angle_diff_mean_deg", "angle_within_45_frac"}
    assert 0 <= diff["angle_within_45_frac"] <= 1 and same["angle_within_45_frac"] == 1


@pytest.mark.slow
def test_recording_gives_windows(tmp_path):
    from snn_fg.events import image_to_events, save_events
    from snn_fg.frames.scenes import disc

    rec = image_to_events(disc(16).image, motion="circle")
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
                "--window-ms",
                "100",
                "--max-windows",
                "3",
                "--sensor-size",
                "64x64",
                "--no-progress",
            ]
        )
        == 0
    )
    m = Maps.load(out / "maps.zarr")
    d = m.extra
    n = m.fg_x.shape[0]
    assert m.fg_x.shape[1:] == (64, 64) and 1 <= n <= 3
    assert np.all(np.diff(d["t_start_us"]) == 100_000)
    assert np.all(d["t_end_us"] - d["t_start_us"] == 100_000)
    # each window's event frame is stored beside its maps: +1 ON, -1 OFF
    assert d["event_frame"].shape == m.fg_x.shape and set(np.unique(d["event_frame"])) <= {-1, 0, 1}
    assert np.all((m.fg_x != 0) <= (d["event_frame"] != 0))
    assert sorted(os.listdir(out)) == ["maps.png", "maps.zarr", "timeline.png", "windows.csv"]
    assert not list(out.rglob("*.part"))  # no temporary parts left


@pytest.mark.slow
def test_rate_model_can_carry_its_state_from_window_to_window(tmp_path):
    from snn_fg.events import image_to_events, save_events
    from snn_fg.frames.scenes import disc

    rec = image_to_events(disc(16).image, motion="circle")
    path = tmp_path / "disc.npy"
    save_events(path, rec.events, rec.sensor_size)
    opts = ["--window-ms", "100", "--max-windows", "3", "--sensor-size", "64x64", "--no-progress"]
    assert main(["run", str(path), "--out", str(tmp_path / "fresh"), *opts]) == 0
    assert main(["run", str(path), "--out", str(tmp_path / "carried"), "--carry-state", "on", *opts]) == 0
    fresh, carried = Maps.load(tmp_path / "fresh" / "maps.zarr"), Maps.load(tmp_path / "carried" / "maps.zarr")
    assert carried.params["carry_state"] is True and "carry_state" not in fresh.params
    assert fresh.grouping.shape == carried.grouping.shape == (3, 64, 64)
    # the first window has nothing to carry; the next ones start from the one before
    assert np.array_equal(carried.grouping[0], fresh.grouping[0])
    for k in (1, 2):
        assert not np.allclose(carried.grouping[k], fresh.grouping[k])
    res = run_cli("run", path, "--out", tmp_path / "spk", "--model", "spiking", "--carry-state", "on", *opts)
    assert res.returncode == 2 and "--carry-state" in res.stderr


@pytest.mark.slow
@pytest.mark.parametrize("carry", ["off", "on"])
def test_an_interrupted_recording_keeps_its_complete_windows_and_resume_finishes_it(
    tmp_path, monkeypatch, capsys, carry
):
    """Interrupted in its third window, a run leaves two windows readable
    (marked incomplete); --resume runs the rest (with --carry-state, the
    windows before again, for their state) and gives the maps of a run never
    interrupted, bit for bit."""
    from snn_fg.events import image_to_events, save_events
    from snn_fg.frames.scenes import disc
    from snn_fg.models.rate import edfg
    from snn_fg.results.store import read_attrs

    rec = image_to_events(disc(16).image, motion="circle")
    path = tmp_path / "disc.npy"
    save_events(path, rec.events, rec.sensor_size)
    opts = [
        "--window-ms",
        "50",
        "--max-windows",
        "4",
        "--levels",
        "3",
        "--carry-state",
        carry,
        "--no-figures",
        "--no-progress",
    ]
    assert main(["run", str(path), "--out", str(tmp_path / "whole"), *opts]) == 0
    calls = []
    real = edfg.run_edfg_state  # (each window of either mode runs it once)

    def interrupted_at_the_third(*a, **k):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(*a, **k)

    monkeypatch.setattr(edfg, "run_edfg_state", interrupted_at_the_third)
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), *opts]) == 130
    early = Maps.load(out)
    assert early.fg_x.shape[0] == 2 and not read_attrs(out / "maps.zarr")["snn_fg"]["complete"]
    monkeypatch.setattr(edfg, "run_edfg_state", real)
    assert main(["run", str(path), "--out", str(out), *opts]) == 2  # not without --resume
    assert main(["run", str(path), "--out", str(out), *opts[:-1], "--resume"]) == 0
    done, whole = Maps.load(out), Maps.load(tmp_path / "whole")
    assert done.fg_x.shape[0] == 4 and read_attrs(out / "maps.zarr")["snn_fg"]["complete"]
    for key in ("fg_x", "fg_y", "grouping"):
        np.testing.assert_array_equal(getattr(done, key), getattr(whole, key))
    np.testing.assert_array_equal(done.extra["event_frame"], whole.extra["event_frame"])
    assert done.params["source"] == whole.params["source"]
    assert main(["run", str(path), "--out", str(out), *opts, "--resume", "--r0", "6"]) == 2  # another run
    # --resume on the finished run: says so and writes nothing
    stamp = [(p, p.stat().st_mtime_ns) for p in sorted(out.rglob("*"))]
    capsys.readouterr()
    assert main(["run", str(path), "--out", str(out), *opts, "--resume"]) == 0
    assert "is finished already (4 windows): nothing to resume, nothing written" in capsys.readouterr().out
    assert [(p, p.stat().st_mtime_ns) for p in sorted(out.rglob("*"))] == stamp


@pytest.mark.slow
def test_spiking_recording_runs_one_network_and_reads_each_window_from_its_own_spikes(tmp_path):
    """snn-fg run RECORDING --model spiking: one continuous run (one network
    build, each event a spike in its time step: the default network's
    ``events`` coding; simulated time = the recording plus the read-out lag);
    each window's stored spike counts are that run's spikes inside the window
    shifted by the lag, and equal run_spiking_windows called directly;
    frame-only options are refused for a recording."""
    from snn_fg.events import image_to_events, iter_windows, save_events
    from snn_fg.frames.scenes import disc
    from snn_fg.models.spiking.continuous import run_spiking_windows
    from snn_fg.results.maps import window_part

    rec = image_to_events(disc(12).image, motion="circle")
    path = tmp_path / "disc.npy"
    save_events(path, rec.events, rec.sensor_size)
    out = tmp_path / "out"
    opts = [
        "--window-ms",
        "60",
        "--max-windows",
        "3",
        "--levels",
        "3",
        "--sensor-size",
        "64x64",
        "--readout-lag-ms",
        "10",
        "--save-spikes",
    ]
    assert main(["run", str(path), "--out", str(out), "--model", "spiking", *opts, "--no-progress"]) == 0
    m = Maps.load(out / "maps.zarr")
    assert m.fg_x.shape[0] == 3
    sim = m.params["simulation"]
    assert sim["mode"] == "continuous" and sim["network_builds"] == 1 and sim["readout_lag_ms"] == 10
    assert sim["window_clock"] is True
    assert sim["simulated_ms"] == pytest.approx(60 + 10)  # (window 0's: what had been simulated when it was read)
    assert m.params["whole_run"]["simulated_ms"] == pytest.approx(180 + 10)
    # (the run cut at 3 windows reads the recording on through window 2's read-out lag, as a longer run does:
    # a list of windows has no events after its last, so the list that gives the same 3 windows holds a 4th)
    windows = list(iter_windows(path, window_ms=60, max_windows=4, sensor_size=(64, 64)))
    direct = run_spiking_windows(windows, params=ModelParams(levels=3), readout_lag_ms=10, progress=False)[:3]
    for i, d in enumerate(direct):
        np.testing.assert_array_equal(m.fg_x[i], d.fg_x)
        for name in ("simple_1", "bo_L1_1", "group_L_1"):
            np.testing.assert_array_equal(window_part(m.extra, f"spikes_{name}", i), d.extra[f"spikes_{name}"])
        w = m.params["windows"][i] if i else {}
        assert w.get("simulation", sim)["count_from_ms"] == pytest.approx(60 * i + 10)
    assert sum(int(window_part(m.extra, "spikes_bo_L1_1", i).sum()) for i in range(3)) > 0
    assert sorted(os.listdir(out)) == [
        "maps.png",
        "maps.zarr",
        "rate_histograms.png",
        "spike_raster.png",
        "timeline.png",
        "windows.csv",
    ]
    quiet = tmp_path / "quiet"
    assert (
        main(
            [
                "run",
                str(path),
                "--out",
                str(quiet),
                "--model",
                "spiking",
                *opts,
                "--window-clock",
                "off",
                "--no-progress",
            ]
        )
        == 0
    )
    m_off = Maps.load(quiet / "maps.zarr")
    assert m_off.params["simulation"]["window_clock"] is False
    second = [window_part(x.extra, "spikes_group_L_1", 1) for x in (m, m_off)]
    assert not np.array_equal(*second)  # the pulse changed the second window's grouping
    res = run_cli(
        "run", path, "--out", tmp_path / "x", "--model", "spiking", "--duration-ms", "80", "--sensor-size", "64x64"
    )
    assert res.returncode == 2 and "--duration-ms" in res.stderr and not (tmp_path / "x").exists()


def _disc_frame(tmp_path, radius=16):
    from snn_fg.events import image_to_frame
    from snn_fg.frames.scenes import disc

    pos, neg = image_to_frame(disc(radius).image)
    path = tmp_path / "disc.npz"
    np.savez(path, pos=pos, neg=neg)
    return path


@pytest.mark.slow
def test_a_stored_network_runs_from_the_command_line_and_an_edit_changes_it(tmp_path):
    """snn-fg run disc.npz --model spiking --network networks/default_321x481.json
    gives the default run's maps (the stored network is resized to the frame);
    editing one gain in the JSON changes them."""
    from pathlib import Path

    disc_npz = _disc_frame(tmp_path)
    stored = Path(__file__).resolve().parents[1] / "networks" / "default_321x481.json"
    opts = ["--model", "spiking", "--duration-ms", "150", "--no-progress"]
    assert main(["run", str(disc_npz), "--out", str(tmp_path / "default"), *opts]) == 0
    assert main(["run", str(disc_npz), "--out", str(tmp_path / "stored"), "--network", str(stored), *opts]) == 0
    a, b = Maps.load(tmp_path / "default" / "maps.npz"), Maps.load(tmp_path / "stored" / "maps.npz")
    for k in ("fg_x", "fg_y", "grouping"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    d = json.loads(stored.read_text())
    edited = next(p for p in d["projections"] if p["name"] == "bo_L1_1_to_group_L_1")
    edited["gain_mv"] *= 3
    (tmp_path / "edited.json").write_text(json.dumps(d))
    assert (
        main(
            ["run", str(disc_npz), "--out", str(tmp_path / "edited"), "--network", str(tmp_path / "edited.json"), *opts]
        )
        == 0
    )
    assert not np.array_equal(Maps.load(tmp_path / "edited" / "maps.npz").grouping, a.grouping)
    # a stored network carries its own model parameters
    res = run_cli("run", disc_npz, "--out", tmp_path / "x", "--network", stored, "--levels", "3", *opts)
    assert res.returncode == 2 and "--levels" in res.stderr and not (tmp_path / "x").exists()


@pytest.mark.slow
def test_output_folder_is_never_mixed_with_an_earlier_run(tmp_path):
    out = tmp_path / "out"
    assert main(["run", "demo", "--out", str(out), "--no-progress"]) == 0
    (out / "spike_raster.png").write_bytes((out / "maps.png").read_bytes())  # (a figure of an older run: marked)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    res = run_cli("run", "demo", "--out", out, "--r0", "6", "--no-progress")
    assert res.returncode == 2 and "--force" in res.stderr
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert main(["run", "demo", "--out", str(out), "--r0", "6", "--force", "--no-progress"]) == 0
    assert sorted(os.listdir(out)) == ["maps.npz", "maps.png"]  # replaced as a whole
    assert Maps.load(out / "maps.npz").params["r0"] == 6
    assert sorted(os.listdir(tmp_path)) == ["out"]  # no staging left


@pytest.mark.slow
@pytest.mark.parametrize(
    "args, message",
    [
        (["--window-ms", "50"], "--window-ms"),  # a recording option for a frame
        (["--carry-state", "on"], "--carry-state"),  # another one
        (["--window-clock", "off"], "--window-clock"),  # and the spiking model's
        (["--duration-ms", "50"], "--duration-ms"),  # a spiking option for the rate model
        (["--levels", "0"], "--levels"),  # argparse range check
        (["--r0", "nan"], "--r0"),
        (["--levels", "50"], "at most 14 pyramid levels"),  # the 120 x 160 demo has 14 levels of >= 2 x 2 px
    ],
)
def test_invalid_arguments_create_nothing(tmp_path, args, message):
    out = tmp_path / "a" / "b" / "out"
    res = run_cli("run", "demo", "--out", out, *args, "--no-progress")
    assert res.returncode == 2 and message in res.stderr and "Traceback" not in res.stderr
    assert not (tmp_path / "a").exists()


@pytest.mark.slow
def test_usage_errors_are_reported_under_the_subcommand(tmp_path):
    res = run_cli("run", "demo", "--out", tmp_path / "o", "--leves", "3")
    assert res.returncode == 2
    assert res.stderr.startswith("snn-fg run: error:") and "--leves" in res.stderr
    res = run_cli("run", "demo", "--out", tmp_path / "o", "--window", "3")  # no abbreviations
    assert res.returncode == 2 and "--window" in res.stderr
    res = run_cli("--version")
    from snn_fg import __version__

    assert res.returncode == 0 and res.stdout.strip() == f"snn-fg {__version__}" and __version__[0].isdigit()


@pytest.mark.slow
def test_compare_pairs_windows_by_time_and_reads_at_100_columns(tmp_path):
    from snn_fg.events import image_to_events, save_events
    from snn_fg.frames.scenes import disc

    rec = image_to_events(disc(16).image, motion="circle")
    path = tmp_path / "disc.npy"
    save_events(path, rec.events, rec.sensor_size)
    opts = ["--window-ms", "100", "--sensor-size", "64x64", "--no-progress"]
    assert main(["run", str(path), "--out", str(tmp_path / "all"), *opts]) == 0
    assert main(["run", str(path), "--out", str(tmp_path / "one"), "--max-windows", "1", *opts]) == 0
    a, b = tmp_path / "all" / "maps.zarr", tmp_path / "one" / "maps.zarr"
    res = run_cli("compare", a, b, "--json", tmp_path / "c.json")
    assert res.returncode == 0, res.stderr
    # the table and its legend; the last line names the JSON file, as long as its path
    table = [line for line in res.stdout.splitlines() if "saved to" not in line]
    assert len(table) >= 4 and max(len(line) for line in table) <= 100
    rows = json.loads((tmp_path / "c.json").read_text())["windows"]
    assert [(r["window_a"], r["window_b"], r["t_start_ms"]) for r in rows] == [(0, 0, 0.0)]  # paired by start time
    assert rows[0]["angle_mse"] == 0 and rows[0]["angle_within_45_frac"] == 1
    res = run_cli("compare", a, b, "--window", "2", "--json", tmp_path / "w.json")
    assert res.returncode == 0, res.stderr
    (row,) = json.loads((tmp_path / "w.json").read_text())["windows"]
    assert (row["window_a"], row["window_b"]) == (2, 0) and row["angle_within_45_frac"] < 1
    res = run_cli("compare", a, b, "--window", "9")
    assert (
        res.returncode == 2
        and "--window 9: " in res.stderr
        and "holds windows 0 to 3" in res.stderr
        and "Traceback" not in res.stderr
    )


def test_angle_metrics_ignore_the_empty_background():
    from snn_fg.scoring.metrics import compare_frame

    fx = np.zeros((40, 40))
    fy = np.zeros((40, 40))
    fx[20, 5:35] = 1.0  # one edge pointing right...
    c = compare_frame(fx, fy, fx, -fx, fy, fx)  # ...against the same edge pointing left
    assert c["pixels_compared"] == 30 and c["angle_diff_mean_deg"] == 180
    assert c["angle_mse"] == 1.0 and c["angle_within_45_frac"] == 0.0
    assert c["angle_ssim"] < 0.5  # over the whole image it would be ~0.99 (background agrees)


def test_agreement_scores_a_against_b_and_reads_maps_or_tuples():
    from snn_fg.results.maps import Maps
    from snn_fg.scoring.metrics import agreement

    fx, fy, g = np.zeros((30, 30)), np.zeros((30, 30)), np.zeros((30, 30))
    fx[10, 0:20] = 1.0  # b: 20 vectors pointing right
    ax = fx.copy()
    ax[10, 10:20] = 0.0  # a: only the first 10 of them...
    ax[10, 5:10] = -1.0  # ...5 of which point left
    g[10, 10] = 1.0
    a = (ax, fy, g)
    s = agreement(a, Maps(fx, fy, g))
    assert s["coverage"] == 0.5 and s["within_45"] == 0.5 and s["mean_deg"] == 90.0 and s["grouping_r"] == 1.0
    assert agreement(Maps(fx, fy, g), a)["coverage"] == 1.0  # every vector of a is in b


@pytest.mark.slow
def test_a_recording_whose_windows_give_no_vector_says_so(tmp_path, capsys):
    """A window with events but an empty figure-ground map (here a stand-in
    model that returns empty maps) is counted and reported in one line; a
    model that finds the disc's outline draws no such line."""
    from snn_fg.cli.runner import run_recording
    from snn_fg.events import image_to_events, iter_windows
    from snn_fg.frames.scenes import disc
    from snn_fg.models.interface import RateModel

    class Blank(RateModel):
        def run_window(self, window):
            return self.empty_maps(window.pos.shape)

    rec = image_to_events(disc(12).image, motion="circle")
    for model, name in ((Blank(ModelParams(levels=3)), "blank"), (RateModel(ModelParams(levels=3)), "rate")):
        (tmp_path / name).mkdir()
        n = run_recording(model, iter_windows(rec, window_ms=120), tmp_path / name, {"input": "disc"})
        err = capsys.readouterr().err
        if name == "blank":
            assert n >= 2 and f"{n} of {n} windows with events have no figure-ground vector" in err
            spans = [
                (int(w.events["t"].max()) - int(w.events["t"].min())) / 1000 for w in iter_windows(rec, window_ms=120)
            ]
            assert f"(their events last {min(spans):.0f}-{max(spans):.0f} ms)" in err  # (no hint: a rate model)
        else:
            assert "no figure-ground vector" not in err


def test_a_spiking_recording_run_to_its_end_keeps_the_whole_runs_counters(tmp_path, monkeypatch):
    """A recording read as a stream (in chunks, as a long one is) is laid out
    for more windows than it holds and stopped at its last one: the whole
    run's record still holds the engine's synaptic events and CPU time (how
    the bench measures the engine), beyond those of window 0's read-out."""
    from snn_fg.cli import runner
    from snn_fg.events import image_to_events, save_events
    from snn_fg.frames.scenes import disc
    from snn_fg.results.maps import Maps

    rec = image_to_events(disc(8).image, motion="circle")
    path = tmp_path / "disc.npy"
    save_events(path, rec.events, rec.sensor_size)
    monkeypatch.setattr(runner, "RUN_CHUNK_EVENTS", max(1, len(rec.events) // 8))
    out = tmp_path / "out"
    opts = ["--window-ms", "60", "--levels", "2", "--sensor-size", "64x64", "--no-progress", "--no-figures"]
    assert main(["run", str(path), "--out", str(out), "--model", "spiking", *opts]) == 0
    m = Maps.load(out / "maps.zarr")
    whole = m.params["whole_run"]
    assert m.fg_x.shape[0] == whole["windows"] > 1
    assert whole["backend_stats"]["synaptic_events_total"] > m.params["backend_stats"]["synaptic_events_total"] > 0
    assert whole["timings_s"]["run_cpu"] > 0


def test_pearson_r_is_undefined_without_two_values_and_says_nothing_of_it():
    import warnings

    from snn_fg.scoring.metrics import pearson

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # (an empty pair warned twice on its way to nan)
        assert np.isnan(pearson([], [])) and np.isnan(pearson([1.0], [2.0])) and np.isnan(pearson([1, 1], [1, 2]))
        assert pearson([1.0, 2.0, 3.0], [2.0, 4.0, 7.0]) == pytest.approx(0.9933, abs=1e-4)
