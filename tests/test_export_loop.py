"""A user's loop around an exported network: ``snn-fg events --write-spikes``
makes run.py's input from a recording window, run.py simulates it on NEST
(as the export's folder runs it, without snn_fg), ``snn-fg decode`` turns its
counts into maps; and run.py's memory check."""

import json
import os
import signal
import subprocess
import sys

import numpy as np
import pytest

from snn_fg.backends import RunSettings, available_backends, get_backend
from snn_fg.backends.base import lif_populations
from snn_fg.cli import main
from snn_fg.events.frame import events_to_frame
from snn_fg.export.board import board_network
from snn_fg.export.loop import centroid_crop, export_network, input_frame, outline_crop, outline_pixels
from snn_fg.export.pynn import export_pynn, read_input, save_input
from snn_fg.frames.scenes import disc
from snn_fg.lowering.input_spikes import event_spikes
from snn_fg.models.spiking.decode import decode
from snn_fg.network import build_network
from snn_fg.params import ModelParams
from snn_fg.results.maps import Maps

NEST_OK, NEST_WHY = available_backends()["nest"]
needs_nest = pytest.mark.skipif(not NEST_OK, reason=f"backend nest: {NEST_WHY}")


def test_the_default_crop_holds_the_most_outline_not_the_inside_of_a_region():
    active = np.zeros((12, 16), bool)
    active[2:10, 2:14] = True  # a region of events 8 x 12: its inside has no edge
    assert outline_pixels(active).sum() == 2 * 8 + 2 * 12 - 4
    assert active[4:8, 6:10].all() and not outline_pixels(active)[4:8, 6:10].any()  # (dense, and no edge in it)
    r, c = outline_crop(active, (4, 4))
    assert outline_pixels(active)[r : r + 4, c : c + 4].sum() == 7  # (a corner of the region: 4 + 4 - 1)
    assert outline_crop(active, (12, 16)) == (0, 0)
    active = np.zeros((10, 12), bool)
    active[4:6, 5:7] = True  # every 6 x 6 crop around it holds all its outline: the centred one
    assert outline_crop(active, (6, 6)) == (2, 3)
    border = np.zeros((6, 6), bool)
    border[:, :3] = True  # (the input's own border is no outline: only column 2 is)
    assert outline_pixels(border).sum() == 6


def test_centroid_crop_centres_the_box_on_the_mean_event_inside_the_sensor():
    ev = np.zeros(4, dtype=[("x", "<i4"), ("y", "<i4")])
    ev["x"], ev["y"] = [10, 12, 10, 12], [5, 5, 7, 7]  # mean position x 11, y 6
    assert centroid_crop(ev, (5, 7), (20, 30)) == (4, 8)  # rows 4..8, columns 8..14: centred on it
    assert centroid_crop(ev, (4, 6), (20, 30)) == (5, 9)  # even sizes: the centre rounds up
    assert centroid_crop(ev, (16, 7), (20, 30)) == (0, 8)  # would start above the sensor: moved down
    ev["x"] = [28, 29, 29, 29]
    assert centroid_crop(ev, (5, 7), (20, 30)) == (4, 23)  # would end past the right edge: moved left


def test_decode_input_panel_is_each_pixels_last_spike_as_the_event_frame(tmp_path):
    """The panel ``snn-fg decode`` draws: each pixel the polarity of its last
    input spike, as ``snn-fg run`` draws each pixel's last event, not every
    pixel that ever had an OFF spike drawn OFF."""
    ev = np.zeros(7, dtype=[("x", "<i4"), ("y", "<i4"), ("t", "<i8"), ("p", "<i4")])
    # pixel (x, y): (0, 0) OFF then ON; (1, 0) ON then OFF; (2, 1) ON only; (3, 2) ON, OFF, ON
    ev["x"], ev["y"] = [0, 1, 0, 1, 2, 3, 3], [0, 0, 0, 0, 1, 2, 2]
    ev["t"], ev["p"] = [0, 1000, 2000, 3000, 4000, 5000, 6000], [0, 1, 1, 0, 1, 0, 1]
    ev = np.concatenate([ev[:5], np.array([(3, 2, 500, 1)], ev.dtype), ev[5:]])
    save_input(event_spikes(ev, (4, 3), 0.5, replay=True), tmp_path / "input.npz", 0.5)
    pos, neg = input_frame(tmp_path / "input.npz", (3, 4))
    want_pos, want_neg = events_to_frame(np.sort(ev, order="t"), (4, 3))
    assert np.array_equal(pos, want_pos) and np.array_equal(neg, want_neg)
    assert pos[0, 0] == 1 and neg[0, 0] == 0 and neg[0, 1] == 1 and pos[2, 3] == 1 and neg[2, 3] == 0
    assert not (pos | neg)[1, 0]
    # ON and OFF of one pixel in the same step: drawn OFF
    np.savez(
        tmp_path / "tie.npz",
        indices=np.array([5, 12 + 5]),
        steps=np.array([3, 3]),
        dt_ms=0.5,
        period_steps=-1,
        shape=np.array([3, 4]),
    )
    pos, neg = input_frame(tmp_path / "tie.npz", (3, 4))
    assert neg.sum() == 1 and neg[1, 1] == 1 and pos.sum() == 0
    assert input_frame(tmp_path / "absent.npz", (3, 4)) is None


@pytest.mark.slow
@needs_nest
def test_recording_window_to_board_input_to_nest_to_maps(tmp_path, disc_recording, capsys, run_py):
    net = build_network(ModelParams(levels=1, r0=4), (32, 32))
    folder = export_pynn(net, tmp_path / "model")
    spikes = folder / "input.npz"
    assert (
        main(
            [
                "events",
                str(disc_recording),
                "--write-spikes",
                str(spikes),
                "--export",
                str(folder),
                "--window-ms",
                "85",
                "--no-progress",
            ]
        )
        == 0
    )
    said = capsys.readouterr().out
    assert "crop at x=16, y=16" in said  # the disc: centred in the 64 x 64 sensor
    assert "export " + str(folder) + " (a 32 x 32 sensor)" in said
    done = run_py(
        folder, "--input", "input.npz", "--out", "counts.npz", "--duration-ms", "150", "--count-from-ms", "75"
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert "expect about" in done.stdout and "simulated 150/150 ms" in done.stderr
    assert main(["decode", str(folder / "counts.npz"), "--export", str(folder), "--out", str(tmp_path / "maps")]) == 0
    assert sorted(p.name for p in (tmp_path / "maps").iterdir()) == ["maps.npz", "maps.png"]
    ours = Maps.load(tmp_path / "maps" / "maps.npz")
    assert ours.params["backend"]["name"] == ours.params["network"]["origin"] == "pynn-export"
    # the NEST backend on the same input file and the board network
    inp = read_input(spikes)
    backend = get_backend("nest").simulate(
        board_network(net), inp, RunSettings(duration_ms=150.0, dt_ms=net.dt_ms, count_from_ms=75.0, instantiate="all")
    )
    fx, fy, g, _ = decode(backend)
    assert np.abs(ours.grouping).max() > 0
    assert np.array_equal(ours.fg_x, fx.astype(np.float32)) and np.array_equal(ours.fg_y, fy.astype(np.float32))
    assert np.array_equal(ours.grouping, g.astype(np.float32))
    # --reference: the same network run by our own NEST backend over the counts' span (150 ms, counted
    # from 75 ms), beside the board's maps, and the agreement said; a span or network of its own would differ
    capsys.readouterr()
    ref = tmp_path / "checked"
    cmd = ["decode", str(folder / "counts.npz"), "--export", str(folder), "--out", str(ref), "--reference", "nest"]
    assert main(cmd) == 0
    said = capsys.readouterr().out
    head = "against snn-fg's nest backend on the same network and input: grouping r 1.000, within 45 degrees on 100.0 %"
    assert head in said and "pixels where both have a vector" in said
    assert "mean absolute difference 0.0 degrees" in said and "at 100.0 % of the reference's" in said
    checked = Maps.load(ref / "reference" / "maps.npz")
    assert checked.params["backend"]["name"] == "nest" and checked.params["simulation"]["count_window_ms"] == 75.0
    for a, b in ((checked.fg_x, ours.fg_x), (checked.fg_y, ours.fg_y), (checked.grouping, ours.grouping)):
        assert np.array_equal(a, b)
    assert (ref / "reference" / "maps.png").is_file() and (ref / "maps.npz").is_file()


@pytest.mark.slow
def test_write_spikes_refusals_leave_nothing(tmp_path, disc_recording, capsys):
    folder = export_pynn(build_network(ModelParams(levels=1, r0=4), (32, 32)), tmp_path / "model")
    out = tmp_path / "in.npz"
    cases = [
        ([], "--write-spikes needs --export"),
        (["--export", str(tmp_path)], "network.json: no such file"),
        (["--export", str(folder), "--crop-at", "40,0"], "must lie inside the input's 64 x 64"),
        (["--export", str(folder), "--crop-at", "a,b"], "--crop-at 'a,b': expected X,Y"),
        (["--export", str(folder), "--start-ms", "5000"], "disc.es"),
    ]
    for extra, fragment in cases:
        assert main(["events", str(disc_recording), "--write-spikes", str(out), "--no-progress"] + extra) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and fragment in err[0], err
        assert not out.exists()
    small = export_pynn(build_network(ModelParams(levels=1, r0=4), (24, 80)), tmp_path / "wide")
    assert main(["events", str(disc_recording), "--write-spikes", str(out), "--export", str(small)]) == 2
    assert "an input of 64 x 64 is smaller than the export's frame of 80 x 24" in capsys.readouterr().err


def test_export_pointed_at_a_nir_graph_says_what_it_takes_in_one_line(tmp_path, disc_recording, capsys):
    """--export given the NIR file snn-fg export wrote (before: "net.nir/network.json: Not a directory"): the
    line names the folder that has a loop (--format nir --nir-profile snntorch --out DIR)."""
    graph = tmp_path / "net.nir"
    graph.write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(64))
    out = tmp_path / "in.npz"
    events = ["events", str(disc_recording), "--write-spikes", str(out), "--export", str(graph), "--no-progress"]
    decode = ["decode", str(out), "--export", str(graph), "--out", str(tmp_path / "maps")]
    for cmd in (events, decode):
        assert main(cmd) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"{graph}: a NIR graph alone, not an export folder: --export takes" in err[0]
        assert "--format nir --nir-profile snntorch with --out DIR" in err[0], err
        assert not out.exists() and not (tmp_path / "maps").exists()


@pytest.mark.slow
def test_decode_refuses_counts_of_another_export(tmp_path, capsys):
    folder = export_pynn(build_network(ModelParams(levels=1, r0=4), (24, 24)), tmp_path / "model")
    net, _ = export_network(folder)
    bogus = tmp_path / "counts.npz"
    np.savez(bogus, duration_ms=100.0, count_from_ms=50.0, dt_ms=0.5, count_nothing=np.zeros(3))
    assert main(["decode", str(bogus), "--export", str(folder), "--out", str(tmp_path / "maps")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "counts.npz: not a run.py counts file of this export: no count_" in err[0]
    assert "Error" not in err[0] and not (tmp_path / "maps").exists() and net.frame_shape == (24, 24)
    # counts with this export's names but another frame's sizes (a trial's Lava counts of 64 x 48 against
    # a 32 x 24 export): until 30 Nov a traceback ("cannot reshape array of size ...")

    pops = lif_populations(board_network(net))
    other = {f"count_{p.name}": np.zeros(p.size * 4, np.int64) for p in pops}
    np.savez(bogus, duration_ms=100.0, count_from_ms=50.0, dt_ms=0.5, **other)
    assert main(["decode", str(bogus), "--export", str(folder), "--out", str(tmp_path / "maps")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    p = pops[0]
    assert (
        len(err) == 1
        and (
            f"counts.npz: not the counts of this export: count_{p.name} holds {4 * p.size:,} cells, where this "
            f"export's {p.name} has {p.size:,} (its frame is 24 x 24)"
        )
        in err[0]
    )
    assert not (tmp_path / "maps").exists()
    # run.py's input handed to decode instead of its output: said so, with the step between
    np.savez(
        tmp_path / "input.npz",
        indices=np.zeros(1, np.int64),
        steps=np.zeros(1, np.int64),
        dt_ms=0.5,
        period_steps=-1,
        shape=np.array([24, 24]),
    )
    assert main(["decode", str(tmp_path / "input.npz"), "--export", str(folder), "--out", str(tmp_path / "maps")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "input.npz: an input spike file (run.py's --input), not the counts" in err[0]
    assert not (tmp_path / "maps").exists()
    # --reference without the input file run.py ran: one line, nothing written
    counts = tmp_path / "run" / "counts.npz"
    counts.parent.mkdir()
    silent = {f"count_{q.name}": np.zeros(q.size, np.int64) for q in lif_populations(board_network(net))}
    np.savez(counts, duration_ms=100.0, count_from_ms=50.0, dt_ms=0.5, **silent)
    cmd = ["decode", str(counts), "--export", str(folder), "--out", str(tmp_path / "maps"), "--reference", "fast"]
    assert main(cmd) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "input.npz: no such file: --reference runs the export's network on the input" in err[0]
    assert not (tmp_path / "maps").exists()
    assert main(cmd[:-2]) == 0  # (the same counts decode without it)


@pytest.mark.slow
@needs_nest
def test_run_py_refuses_a_network_that_will_not_fit_before_building(tmp_path, run_py):
    folder = export_pynn(build_network(ModelParams(levels=1, r0=4), (24, 24)), tmp_path / "model")
    np.savez(
        folder / "input.npz",
        indices=np.zeros(1, np.int64),
        steps=np.zeros(1, np.int64),
        dt_ms=0.5,
        period_steps=-1,
        shape=np.array([24, 24]),
    )
    done = run_py(folder, "--input", "input.npz", "--out", "counts.npz", "--memory-gb", "0.01")
    assert done.returncode == 1 and not (folder / "counts.npz").exists()
    last = done.stderr.strip().splitlines()
    assert len(last) == 1 and "needs about" in last[0] and "more than the 0.0 GB given (--memory-gb)" in last[0]
    meta = json.loads((folder / "network.json").read_text())
    assert sum(pr["synapses"] for pr in meta["projections"]) > 0


def test_export_input_rate_hz_sets_the_gains_network_calibrated_sets(tmp_path, capsys):
    from snn_fg.network.recipes import RECIPES

    out = tmp_path / "model"
    assert (
        main(
            [
                "export",
                "--format",
                "pynn",
                "--out",
                str(out),
                "--sensor-size",
                "24x20",
                "--levels",
                "1",
                "--input-rate-hz",
                "35",
            ]
        )
        == 0
    )
    meta = json.loads((out / "network.json").read_text())
    base = RECIPES["default"].params.replace(levels=1)
    net = board_network(build_network(base, (20, 24)))
    want = {pr.name: pr.gain_mv for pr in net.calibrated(35.0).projections}
    got = {pr["name"]: pr["gain_mv"] for pr in meta["projections"]}
    assert got.keys() == want.keys()
    assert all(got[k] == pytest.approx(want[k], rel=1e-12) for k in want)
    uncalibrated = {pr.name: pr.gain_mv for pr in net.projections}
    moved = [k for k in want if got[k] != pytest.approx(uncalibrated[k], rel=1e-9)]
    assert moved and all(got[k] == pytest.approx(200.0 / 35.0 * uncalibrated[k], rel=1e-12) for k in moved)
    assert meta["input_rate_hz"] == 35.0 and export_network(out)[0].input_rate_hz == 35.0
    assert meta["export_command"] == f"snn-fg export --format pynn --out {out} --sensor-size 24x20 --levels 1"


def test_the_recorded_export_command_gives_back_every_option_but_the_rate_and_force():
    """export_command: the options given, parsed again from the command it
    writes, are the options given (less --input-rate-hz and --force); the
    command line below sets every option the export parser has, so an option
    added to the parser fails here until it is set below too."""
    import shlex

    from snn_fg.cli import build_parser
    from snn_fg.cli.export import export_command

    argv = [
        "export",
        "--format",
        "pynn",
        "--out",
        "dir with space",
        "--force",
        "--network",
        "compact",
        "--sensor-size",
        "64x48",
        "--levels",
        "2",
        "--n-ori",
        "4",
        "--r0",
        "5.5",
        "--target",
        "spinnaker",
        "--weight-bits",
        "8",
        "--input-rate-hz",
        "35",
        "--dt-ms",
        "0.25",
        "--nir-profile",
        "snntorch",
        "--nir-one-grid",
        "--nir-refractory-as-deeper-reset",
    ]
    parser, subs = build_parser()
    flags = {f for a in subs["export"]._actions for f in a.option_strings if f.startswith("--")} - {"--help"}
    assert flags <= set(argv)
    given = parser.parse_args(argv)
    command = export_command(given)
    assert command.startswith("snn-fg export --format pynn --out 'dir with space' --network compact")
    again = parser.parse_args(shlex.split(command)[1:])
    left_out = {"force", "input_rate_hz", "handler", "export_options"}
    assert {k: v for k, v in vars(again).items() if k not in left_out} == {
        k: v for k, v in vars(given).items() if k not in left_out
    }
    assert again.input_rate_hz is None and again.force is False


def test_write_spikes_says_how_to_re_export_for_the_inputs_rate():
    from snn_fg.export.loop import recalibration_hint

    hint = recalibration_hint(35.24, 200.0, "snn-fg export --format pynn --out m --levels 2")
    assert "re-export: snn-fg export --format pynn --out m --levels 2 --input-rate-hz 35.2 --force" in hint
    assert recalibration_hint(239.0, 200.0, "x") is None and recalibration_hint(166.7, 200.0, "x") is None
    assert "--input-rate-hz 241" in recalibration_hint(241.0, 200.0, "x")
    assert "with --input-rate-hz 35.2" in recalibration_hint(35.24, 200.0, None)
    # (the folder as the user names it now: `--export .` inside the export made with `--out out/lava`
    # was told to re-export into ./out/lava, a new export, the folder keeping its old gains)
    here = recalibration_hint(12.6, 200.0, "snn-fg export --format lava --out out/lava --network compact", folder=".")
    assert "re-export: snn-fg export --format lava --out . --network compact --input-rate-hz 12.6 --force" in here


@pytest.mark.slow
@needs_nest
def test_run_py_imports_nest_without_pynns_extension_build_output(tmp_path):
    """PyNN warns, with cmake's output, each time it fails to build its optional
    NEST extensions (which the network does not use); an export's
    fg_simulator.py imports pyNN.nest without that and without NEST's banner."""
    import os
    import shutil
    from pathlib import Path

    from snn_fg.pynn import HERE

    shutil.copyfile(HERE / "simulator.py", tmp_path / "fg_simulator.py")
    env = {k: v for k, v in os.environ.items() if k != "PYNEST_QUIET"}
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"  # (its nest-config, if any)
    noise = ("nest-config", "cmake", "Configuring incomplete", "NEST extensions")

    def imported(code):
        done = subprocess.run(
            [sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300
        )
        assert done.returncode == 0, done.stderr[-2000:]
        return done.stdout + done.stderr

    plain = imported("import pyNN.nest")
    if not any(w in plain for w in noise):
        pytest.skip("PyNN loads or builds its NEST extensions here: it prints nothing to leave out")
    quiet = imported("import fg_simulator; sim = fg_simulator.import_simulator('nest'); print(sim.__name__)")
    assert not any(w in quiet for w in noise) and "N E S T" in plain and "N E S T" not in quiet
    assert quiet.strip().splitlines()[-1] == "pyNN.nest"


def test_sizes_are_width_by_height_and_blocks_are_called_blocks(tmp_path, disc_recording, capsys):
    """A compact export (3 x 3 pooling) of a 57 x 48 sensor: 19 x 16 blocks; the
    disc's 64 x 64 recording is 22 x 22 blocks, its busiest crop at block (1, 3)."""
    out = tmp_path / "model"
    assert (
        main(["export", "--format", "pynn", "--network", "compact", "--sensor-size", "57x48", "--out", str(out)]) == 0
    )
    readme = (out / "README.md").read_text()
    assert "for a 57 x 48 sensor as 19 x 16 blocks of 3 x 3 pixels," in readme
    assert "cut to 19 x 16 blocks," in readme
    capsys.readouterr()
    spikes = tmp_path / "in.npz"
    assert (
        main(["events", str(disc_recording), "--write-spikes", str(spikes), "--export", str(out), "--no-progress"]) == 0
    )
    said = capsys.readouterr().out
    assert "(a 57 x 48 sensor as 19 x 16 blocks of 3 x 3 pixels)" in said and "per active block" in said
    assert "crop at block x=1, y=3" in said and read_input(spikes).shape == (16, 19)
    # the input file keeps where its crop lies on the sensor: decode's params and figure place the maps there
    from snn_fg.export.pynn import input_origin
    from snn_fg.results.figures import maps_figure

    origin = input_origin(spikes)
    assert (origin["crop_x_px"], origin["crop_y_px"], origin["pool"]) == (3, 9, 3)
    assert origin["input"] == str(disc_recording) and origin["made_from"].startswith("window ")
    z = np.zeros((16, 19))
    fig = maps_figure(np.zeros((16, 19, 3)), z, z, z, placed=(3, 9, 3))
    (shown,) = [ax for ax in fig.axes if ax.get_title() == "input"]
    assert shown.images[0].get_extent() == [2.5, 3 + 57 - 0.5, 9 + 48 - 0.5, 8.5]
    assert (
        main(
            [
                "events",
                str(disc_recording),
                "--write-spikes",
                str(spikes),
                "--export",
                str(out),
                "--crop-at",
                "4,0",
                "--no-progress",
                "--force",
            ]
        )
        == 2
    )
    assert (
        "--crop-at 4,0: a crop of 19 x 16 blocks must lie inside the input's 22 x 22 blocks" in capsys.readouterr().err
    )


def test_run_py_predicts_its_time_from_the_measured_rates_scaled_by_the_exports_synapses(capsys):
    from snn_fg.pynn import memory

    def said(synapses, duration_ms):
        meta = {"populations": [{"size": 1000}], "projections": [{"synapses": synapses}]}
        memory.check_memory(meta, memory_gb=1000.0, duration_ms=duration_ms)
        return capsys.readouterr().out

    small, large = said(10**6, 400.0), said(10**8, 100.0)
    per_ms = 10**6 * memory.NEST_S_PER_MS_PER_SYNAPSE
    assert f"{per_ms:.2g} s per simulated ms ({memory.duration_text(400 * per_ms)} for 400 ms)" in small
    assert f"{100 * per_ms:.2g} s per simulated ms ({memory.duration_text(10_000 * per_ms)} for 100 ms)" in large
    assert f"{memory.duration_text(1e8 / memory.NEST_SYNAPSES_PER_S)} to build" in large
    assert memory.TIMES_MEASURED in small and "load" in memory.TIMES_MEASURED
    assert [memory.duration_text(s) for s in (0.052, 7.23, 57.8, 119, 150, 7100, 7300)] == [
        "0.052 s",
        "7.2 s",
        "58 s",
        "119 s",
        "2 min",
        "118 min",
        "2.0 h",
    ]


def test_a_forced_re_export_for_another_rate_keeps_the_folders_input(tmp_path, capsys):
    """The README's loop writes input.npz into the export; re-exporting with
    --input-rate-hz and --force (what --write-spikes advises) keeps it, since
    its spikes depend on the frame and time step only; an export of another
    frame drops it."""
    from snn_fg.events import image_to_frame
    from snn_fg.export.pynn import save_input
    from snn_fg.lowering.input_spikes import frame_spikes

    out = tmp_path / "model"
    export = ["export", "--format", "pynn", "--out", str(out), "--sensor-size", "24x20", "--levels", "1"]
    assert main(export) == 0
    pos, neg = image_to_frame(disc(6).image[:20, :24])
    save_input(frame_spikes(pos, neg, 200.0, 0.5, 20.0), out / "input.npz", 0.5)
    written = (out / "input.npz").read_bytes()
    capsys.readouterr()
    assert main([*export, "--input-rate-hz", "35", "--force"]) == 0
    assert (out / "input.npz").read_bytes() == written
    assert "input.npz kept" in capsys.readouterr().out
    assert json.loads((out / "network.json").read_text())["input_rate_hz"] == 35.0
    assert main([*export[:-4], "--sensor-size", "28x20", "--levels", "1", "--force"]) == 0
    assert not (out / "input.npz").exists() and "kept" not in capsys.readouterr().out


def test_a_forced_re_export_keeps_the_environment_its_readme_has_the_user_make(tmp_path, capsys):
    """A Lava export's README has the user make .venv-lava inside the folder; the re-export
    --write-spikes advises (--input-rate-hz ... --force) keeps it where it is, untouched (before: refused,
    "holds .venv-lava, which snn-fg did not write"), and says so without counting it as written."""
    from snn_fg.export.folder import LAVA_ENV

    out = tmp_path / "lava2"
    export = ["export", "--format", "lava", "--out", str(out), "--sensor-size", "16x16", "--levels", "1"]
    assert main(export) == 0
    assert f"python3.10 -m venv {LAVA_ENV}" in (out / "README.md").read_text()
    env = out / LAVA_ENV
    (env / "bin").mkdir(parents=True)
    (env / "pyvenv.cfg").write_text("home = /usr/bin\n")
    (env / "bin" / "python").symlink_to("/usr/bin/python3.10")
    made = env.stat().st_ino
    capsys.readouterr()
    assert main([*export, "--input-rate-hz", "35", "--force"]) == 0, capsys.readouterr().err
    said = capsys.readouterr().out
    assert env.stat().st_ino == made and (env / "pyvenv.cfg").read_text() == "home = /usr/bin\n"
    assert os.readlink(env / "bin" / "python") == "/usr/bin/python3.10"
    assert f"; {LAVA_ENV} kept where it was" in said and f"{LAVA_ENV}," not in said, said
    assert json.loads((out / "network.json").read_text())["input_rate_hz"] == 35.0
    assert not [p for p in out.iterdir() if p.name.startswith(".snn-fg.")]  # (no working folder left)


def test_a_forced_re_export_never_deletes_run_py_counts(tmp_path, capsys):
    """counts.npz (under any name) is a simulator's or a board's run of the export there: --force
    refuses the folder in one line naming it, and leaves everything as it was."""
    out = tmp_path / "model"
    export = ["export", "--format", "pynn", "--out", str(out), "--sensor-size", "24x20", "--levels", "1"]
    assert main(export) == 0
    np.savez(out / "board_run.npz", duration_ms=400.0, dt_ms=0.5, count_from_ms=200.0, count_simple_1=np.zeros(3))
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    capsys.readouterr()
    assert main([*export, "--input-rate-hz", "35", "--force"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "holds board_run.npz: run.py's counts" in err[0] and "nothing was deleted" in err[0]
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before


def test_run_py_refuses_bad_input_and_a_missing_simulator_in_one_line(tmp_path, run_py):
    """What a user gets wrong with run.py ends in one line naming the file
    or option and the problem, exit status 1, no traceback and no output."""
    folder = export_pynn(build_network(ModelParams(levels=1, r0=4), (24, 24)), tmp_path / "model")
    np.savez(
        folder / "small.npz",
        indices=np.zeros(1, np.int64),
        steps=np.zeros(1, np.int64),
        dt_ms=0.5,
        period_steps=-1,
        shape=np.array([20, 20]),
    )
    # (sources: 24 x 24 ON, as many OFF, and the clock: 1153)
    np.savez(
        folder / "far.npz",
        indices=np.array([0, 2 * 24 * 24 + 5]),
        steps=np.zeros(2, np.int64),
        dt_ms=0.5,
        period_steps=-1,
        shape=np.array([24, 24]),
    )
    (folder / "text.npz").write_text("not an archive")
    np.savez(folder / "other.npz", counts=np.zeros(3))
    cases = [
        (["--input", "nope.npz"], "nope.npz: no such file"),
        (["--input", "text.npz"], "text.npz: not an .npz file"),
        (["--input", "other.npz"], "other.npz: not an input spike file: no indices, steps, dt_ms"),
        (["--input", "small.npz"], "small.npz: spikes of a 20 x 20 frame; this network's frame is 24 x 24"),
        (["--input", "far.npz"], "far.npz: spike 1 comes from source 1157; the network has 1153 sources"),
        (["--input", "small.npz", "--simulator", "nset"], "--simulator nset: PyNN has no simulator module"),
    ]
    for args, said in cases:
        done = run_py(folder, *args, "--out", "counts.npz")
        err = done.stderr.strip().splitlines()
        assert done.returncode == 1 and len(err) == 1 and err[0].startswith("run.py: error: "), args
        assert said in err[0] and "Traceback" not in done.stderr and not (folder / "counts.npz").exists(), args
    code = (
        "import sys, importlib.util; real = importlib.util.find_spec; "
        "importlib.util.find_spec = lambda n, *a: None if n == 'pyNN' else real(n, *a); "
        "sys.modules['snn_fg'] = None; "
        "sys.argv = ['run.py', '--input', 'small.npz', '--out', 'c.npz']; exec(open('run.py').read())"
    )
    done = subprocess.run([sys.executable, "-c", code], cwd=folder, capture_output=True, text=True, timeout=300)
    assert done.returncode == 1 and done.stderr.strip().splitlines() == [
        'run.py: error: PyNN is not installed: pip install -e ".[nest]" in the snn-fg folder, or pip install '
        "PyNN==0.13.0 nest-simulator==3.10.0"
    ]


def test_write_spikes_notes_a_crop_that_lies_inside_a_filled_object(tmp_path, capsys):
    """A crop whose pixels nearly all carry events (inside a filled object)
    holds texture, not an outline: --write-spikes says so and names
    --crop-at; a crop across an outline gets no such note. The share goes
    into the input file's origin."""
    from snn_fg.export.pynn import input_origin

    folder = export_pynn(build_network(ModelParams(levels=1, r0=4), (24, 24)), tmp_path / "model")
    filled, edges = np.zeros((40, 40), np.uint8), np.zeros((40, 40), np.uint8)
    filled[5:35, 5:35] = 1
    edges[10, 5:35] = edges[30, 5:35] = 1
    for name, pos, noted in (("filled", filled, True), ("edges", edges, False)):
        np.savez(tmp_path / f"{name}.npz", pos=pos, neg=np.zeros_like(pos))
        spikes = tmp_path / f"in_{name}.npz"
        assert (
            main(["events", str(tmp_path / f"{name}.npz"), "--write-spikes", str(spikes), "--export", str(folder)]) == 0
        )
        out = capsys.readouterr().out
        assert ("events cover 100% of the crop's pixels" in out and "--crop-at X,Y" in out) == noted, name
        assert (input_origin(spikes)["event_share"] > 0.5) == noted


def test_run_py_progress_is_throttled_but_always_says_the_last_step(capsys):
    """run.py reports at most every 5 s, so a short run's "simulated 150/150 ms"
    used to vanish when it fell within 5 s of the line before."""
    import time

    from snn_fg.pynn import memory

    memory._last[0] = time.monotonic()
    memory.progress("simulated 100/150 ms")
    memory.progress("simulated 150/150 ms", last=True)
    assert capsys.readouterr().err == "run.py: simulated 150/150 ms\n"


@pytest.mark.slow
@needs_nest
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_run_py_interrupted_says_so_in_one_line_and_writes_nothing(tmp_path, disc_recording, capsys, sig):
    """Ctrl-C on an export's run.py gave a KeyboardInterrupt traceback. Now one line, exit 130
    (SIGTERM: 143), and neither the counts file nor a part of it."""
    folder = export_pynn(build_network(ModelParams(levels=1), (16, 16)), tmp_path / "model")
    argv = ["events", str(disc_recording), "--write-spikes", str(folder / "input.npz"), "--export", str(folder)]
    assert main([*argv, "--no-progress"]) == 0
    code = (
        "import sys; sys.modules['snn_fg'] = None; sys.argv = ['run.py', '--input', 'input.npz', '--out', "
        "'counts.npz', '--duration-ms', '100000']; exec(open('run.py').read())"
    )
    before = sorted(p.name for p in folder.iterdir())
    # (started with SIGINT ignored, as a shell starts a command in the background: run.py takes it all the same)
    ignored = lambda: signal.signal(signal.SIGINT, signal.SIG_IGN)  # noqa: E731
    proc = subprocess.Popen(
        [sys.executable, "-c", code], cwd=folder, stderr=subprocess.PIPE, text=True, preexec_fn=ignored
    )
    said = [proc.stderr.readline()]  # (its first progress line: the network is being built)
    assert said[0].startswith("run.py: "), said
    proc.send_signal(sig)
    said += proc.stderr.read().splitlines()
    assert proc.wait(timeout=300) == (130 if sig == signal.SIGINT else 143), said
    name = "Ctrl-C" if sig == signal.SIGINT else "SIGTERM"
    assert said[-1] == f"run.py: interrupted ({name}); nothing written" and "Traceback" not in "".join(said)
    assert sorted(p.name for p in folder.iterdir() if p.name != "__pycache__") == before


def test_an_exports_result_file_is_whole_or_absent(tmp_path):
    """fg_files.py (both exports' run.py write through it): a write that fails part way
    leaves the file as it was and no temporary part; one that completes replaces it."""
    from snn_fg.pynn import files

    path = tmp_path / "counts.npz"
    path.write_bytes(b"before")

    def fails(tmp):
        with open(tmp, "wb") as fh:
            fh.write(b"half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        files.save_atomically(path, fails)
    assert path.read_bytes() == b"before" and sorted(p.name for p in tmp_path.iterdir()) == ["counts.npz"]
    assert files.save_npz(str(tmp_path / "counts"), {"a": np.arange(3)}) == str(path)
    assert np.load(path)["a"].tolist() == [0, 1, 2]
    files.write_json(tmp_path / "m.json", {"x": 1})
    assert (tmp_path / "m.json").read_text() == '{\n "x": 1\n}'


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_exports_run_py_ends_an_interrupt_in_one_line(sig):
    """fg_files.run_main (the ending of both exports' run.py; Lava's gave a traceback): Ctrl-C,
    taken even where the run was started with SIGINT ignored, and SIGTERM end it in one line,
    exit 130 / 143."""
    from snn_fg.pynn import files

    code = (
        "import os, signal, sys, time; sys.path.insert(0, sys.argv[1]); import files; "
        f"files.run_main(lambda: os.kill(os.getpid(), {int(sig)}) or time.sleep(30))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, os.path.dirname(files.__file__)],
        capture_output=True,
        text=True,
        timeout=60,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN),
    )
    name = "Ctrl-C" if sig == signal.SIGINT else "SIGTERM"
    assert done.returncode == (130 if sig == signal.SIGINT else 143), done.stderr
    assert done.stderr == f"run.py: interrupted ({name}); nothing written\n"


def test_decode_refuses_counts_made_by_another_export_of_the_same_size(tmp_path, capsys):
    """Counts of a 14 Hz export decoded with a 200 Hz export of the same frame said nothing, and blamed
    the input's rate when the maps parted: run.py's counts now name the network.json it ran."""
    from snn_fg.pynn.files import EXPORT_KEY, network_digest

    a = export_pynn(build_network(ModelParams(levels=1, r0=4), (24, 24)), tmp_path / "a")
    b = export_pynn(build_network(ModelParams(levels=1, r0=6), (24, 24)), tmp_path / "b")
    net, _ = export_network(a)
    counts = {f"count_{p.name}": np.zeros(p.size, np.int64) for p in lif_populations(board_network(net))}
    made = tmp_path / "counts.npz"
    np.savez(made, duration_ms=100.0, count_from_ms=50.0, dt_ms=0.5, **counts,
             **{EXPORT_KEY: network_digest(str(a / "network.json"))})  # fmt: skip
    assert main(["decode", str(made), "--export", str(b), "--out", str(tmp_path / "maps")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "counts.npz: not the counts of this export: run.py made them with a network.json" in err[0]
    assert not (tmp_path / "maps").exists()
    assert main(["decode", str(made), "--export", str(a), "--out", str(tmp_path / "maps")]) == 0  # (its own)
