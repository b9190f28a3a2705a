"""Usage errors and refused options: one line each, naming the real reason."""

import subprocess
import sys

import numpy as np
import pytest


def run_cli(*args):
    return subprocess.run(
        [sys.executable, "-m", "snn_fg.cli", *map(str, args)], capture_output=True, text=True, timeout=300
    )


@pytest.mark.slow
@pytest.mark.parametrize(
    "args, says",
    [
        (["run", "demo", "--out", "o", "--window-ms", "-5"], "--window-ms: must be > 0"),
        (["run", "demo", "--out", "o", "--max-windows", "0"], "--max-windows: must be >= 1"),
        (["run", "demo", "--out", "o", "--window-ms", "inf"], "--window-ms: must be a finite number > 0, got inf"),
        (["run", "demo", "--out", "o", "--side-cue", "nan"], "--side-cue: must be a finite number >= 0, got nan"),
        (["run", "demo", "--out", "o", "--leves", "3"], "unrecognized arguments: --leves 3"),
        (["run", "demo"], "required: --out"),
        (["compare", "a.npz"], "required: B"),
        (["events"], "required: INPUT"),
        (["export", "--format", "report", "--levels", "x"], "--levels: expected an integer"),
        (["run", "demo", "--out", "o", "--sensor-size", "0x0"], "--sensor-size: width and height must be 1 to 32768"),
    ],
)
def test_a_usage_error_is_one_line_without_the_usage_block(tmp_path, args, says):
    res = run_cli(*args)
    assert res.returncode == 2
    assert res.stderr.count("\n") == 1 and "usage:" not in res.stderr, res.stderr
    assert res.stderr.startswith(f"snn-fg {args[0]}: error:") and says in res.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
@pytest.mark.parametrize(
    "args, says, not_says",
    [
        (
            ["--seed", "3"],
            "--seed: applies to the spiking and natural-spiking models only (--model spiking)",
            "they do not apply",
        ),
        (["--window-ms", "20"], "--window-ms: applies to event recordings only; the demo is one image", "rate model"),
        (["--model", "spiking", "--window-ms", "20"], "event recordings only", "spiking model"),
        (["--model", "fbfg", "--motion", "circle"], "reads the image itself", "rate model"),
        (
            ["--model", "fbfg", "--side-cue", "1"],
            "--side-cue: the fbfg model reads the image itself; the side cue counts events",
            "border_ownership_grouping",
        ),
        (
            ["--model", "natural", "--network", "default"],
            "--network: the natural model has its own parameters, and a network carries others",
            "wrote",
        ),
        (["--model", "fbfg", "--network", "compact"], "--network: the fbfg model has no network", "rate model"),
        (
            ["--duration-ms", "5", "--dt-ms", "1"],
            "--duration-ms, --dt-ms: apply to the spiking and natural-spiking models only",
            "they",
        ),
    ],
)
def test_a_refused_option_names_the_real_reason(tmp_path, args, says, not_says):
    res = run_cli("run", "demo", "--out", tmp_path / "o", *args, "--no-progress")
    assert res.returncode == 2 and res.stderr.count("\n") == 1
    assert says in res.stderr and not_says not in res.stderr, res.stderr


@pytest.mark.slow
def test_a_read_error_is_not_preceded_by_an_empty_progress_bar(tmp_path):
    bad = tmp_path / "bad.es"  # a DVS Event Stream whose first event lies far outside its 320 x 240 sensor
    bad.write_bytes(b"Event Stream\x02\x00\x00\x01\x40\x01\xf0\x00" + bytes([0x02, 0x51, 0x4C, 0x3D, 0x20]))
    res = run_cli("run", bad, "--out", tmp_path / "o")  # with progress bars
    assert res.returncode == 2
    assert res.stderr.count("\n") == 1 and "windows" not in res.stderr, res.stderr
    assert res.stderr.startswith(f"snn-fg: error: {bad}: event at (x=19537") and "byte offset 20" in res.stderr


def test_a_file_that_is_not_an_npz_is_refused_as_such_not_as_a_pickle(tmp_path):
    """numpy reads a file that is not a zip archive as a pickle and says
    "allow_pickle"; each reader of a user's .npz says what the file is not
    and what it should be instead (the text appears nowhere in the file)."""
    from snn_fg.errors import InputError
    from snn_fg.export.loop import decode_counts, input_frame
    from snn_fg.frames.still import read_npz_arrays
    from snn_fg.network import build_network
    from snn_fg.params import ModelParams
    from snn_fg.results.maps import Maps

    fake = tmp_path / "fake.npz"
    fake.write_text("fg_x fg_y grouping\n")
    net = build_network(ModelParams(levels=1, r0=4), (16, 16))
    readers = {
        "maps": lambda: Maps.load(fake),
        "counts": lambda: decode_counts(net, fake),
        "input": lambda: input_frame(fake, (16, 16)),
        "frame": lambda: read_npz_arrays(fake, ("pos", "neg"), what="an event frame"),
    }
    for name, read in readers.items():
        with pytest.raises(InputError) as err:
            read()
        text = str(err.value)
        assert text.startswith(f"{fake}: not an .npz file (expected ") and "pickle" not in text, (name, text)


def test_a_missing_extra_names_the_install_command_from_the_folder(tmp_path, monkeypatch, capsys):
    """snn-fg is installed from its folder, not from a package index, so the
    hint is pip install -e ".[nir]" there (pip install "snn-fg[nir]" would
    look for snn-fg on the index)."""
    from snn_fg.cli import main

    monkeypatch.setitem(sys.modules, "nir", None)  # import fails as if not installed
    status = main(
        [
            "export",
            "--format",
            "nir",
            "--network",
            "compact",
            "--sensor-size",
            "32x24",
            "--out",
            str(tmp_path / "g.nir"),
        ]
    )
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1, err
    assert 'pip install -e ".[nir]" in the snn-fg folder' in err
    assert not (tmp_path / "g.nir").exists()


def test_an_unknown_network_name_lists_the_recipes(tmp_path, capsys):
    """A mistyped --network is neither a recipe nor a file: the line says so
    and names the recipes (it said only "no such file")."""
    from snn_fg.cli import main

    for argv in (
        ["run", "demo", "--out", str(tmp_path / "o"), "--network", "compcat", "--no-progress"],
        ["run", "demo", "--out", str(tmp_path / "o"), "--network", "compcat", "--model", "spiking", "--no-progress"],
        ["export", "--format", "report", "--network", "compcat"],
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "compcat: neither a network name (default, compact) nor a stored" in err, err
    assert not (tmp_path / "o").exists()


def test_a_stored_description_that_is_not_there_is_named_as_a_missing_file(tmp_path, capsys, monkeypatch):
    """docs/usage.md's networks/default_321x481.json run from another folder: the line says the file is not
    there, from which folder (it said "neither a network name nor a stored description (.json)")."""
    from snn_fg.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["export", "--format", "report", "--network", "networks/default_321x481.json"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert f"networks/default_321x481.json: no such file (from {tmp_path})" in err


def test_run_names_every_kind_of_input_for_an_unknown_extension_and_reads_webp(tmp_path, capsys):
    """A .webp photo was refused as an 'unknown event file extension' whose list left out the images."""
    import cv2

    from snn_fg.cli import main

    image = np.zeros((48, 64, 3), np.uint8)
    image[12:36, 16:48] = 255
    assert cv2.imwrite(str(tmp_path / "sq.webp"), image, [cv2.IMWRITE_WEBP_QUALITY, 101])
    (tmp_path / "sq.xyz").write_bytes(b"?")
    assert main(["run", str(tmp_path / "sq.xyz"), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "sq.xyz: unknown extension '.xyz': INPUT is an image (" in err
    assert ".webp" in err and ".aedat4" in err and "'demo'" in err
    assert (
        main(
            [
                "run",
                str(tmp_path / "sq.webp"),
                "--out",
                str(tmp_path / "o"),
                "--no-progress",
                "--no-figures",
                "--levels",
                "4",
            ]
        )
        == 0
    )
    from snn_fg.results.maps import Maps

    maps = Maps.load(tmp_path / "o")
    assert maps.fg_x.shape == (48, 64) and np.hypot(maps.fg_x, maps.fg_y).max() > 0


def test_a_sensor_given_by_hand_too_small_for_the_levels_is_questioned(tmp_path, capsys):
    """An N-MNIST recording (34 x 34) run with --sensor-size 20x20 was refused for its levels alone
    ("--levels 10 asks for more"); the real problem, the sensor, showed only at --levels 9."""
    from snn_fg.cli import main
    from snn_fg.events import EVENT_DTYPE, save_events

    ev = np.zeros(40, EVENT_DTYPE)
    ev["x"], ev["y"], ev["t"], ev["p"] = np.arange(40) % 34, np.arange(40) % 30, np.arange(40) * 1000, 1
    save_events(tmp_path / "nmnist.npy", ev, (34, 34))
    argv = ["run", str(tmp_path / "nmnist.npy"), "--out", str(tmp_path / "o"), "--no-progress"]
    assert main([*argv, "--sensor-size", "20x20"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "a 20 x 20 frame (width x height) has at most 9 pyramid levels" in err
    assert "(is --sensor-size 20x20 right?); give --levels 9 or fewer" in err


def test_too_many_levels_are_refused_in_each_front_doors_own_words():
    """The Python API names its keyword, the command line its option (a script author was told
    of --levels, an option of a command they never ran)."""
    from snn_fg.errors import InputError
    from snn_fg.frames.pyramid import check_levels

    with pytest.raises(InputError) as caught:
        check_levels((20, 20), 10, "<frame>")
    assert str(caught.value).endswith("and 10 were asked for; pass levels=9 or fewer")
    assert caught.value.for_command_line().endswith("and 10 were asked for; give --levels 9 or fewer")
    check_levels((20, 20), 9, "<frame>")  # (as many as it can have: no error)


def test_a_run_out_of_memory_is_one_line_naming_the_size_and_the_smaller_network(tmp_path, monkeypatch, capsys):
    # numpy's own error for an allocation the machine cannot give (the default network on a large sensor)
    from snn_fg.backends.fast import run as fast_run
    from snn_fg.cli.main import main

    monkeypatch.setattr(fast_run, "zeroed", lambda n, dtype: np.zeros((1 << 40, 1 << 20), np.uint8))
    out = tmp_path / "o"
    rc = main(["run", "demo", "--out", str(out), "--model", "spiking", "--network", "compact", "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith("snn-fg: error: out of memory (Unable to allocate 1.00 EiB)"), err
    assert "--network compact" in err and "shape" not in err
    assert not out.exists()


@pytest.mark.slow
@pytest.mark.parametrize(
    "args, starts",
    [
        (["--backend", "nest"], "snn-fg: error: --backend: applies to the spiking"),  # (any input: the option first)
        (["--window-ms", "20"], "snn-fg: error: demo: --window-ms: applies to event recordings only"),
    ],
)
def test_a_refusal_names_the_input_only_where_the_input_is_the_reason(tmp_path, args, starts):
    res = run_cli("run", "demo", "--out", tmp_path / "o", *args, "--no-progress")
    assert res.returncode == 2 and res.stderr.startswith(starts), res.stderr


@pytest.mark.parametrize(
    "argv",
    [
        ["run", "demo", "--model", "spiking", "--network", "compact", "--seed", "-1"],
        ["run", "demo", "--model", "natural-spiking", "--seed", "-2"],
        ["events", "demo", "--seed", "-1"],
    ],
)
def test_a_negative_seed_is_one_line_not_numpys_traceback(argv, tmp_path, capsys):
    """``--seed -1`` ended in numpy's traceback ('expected non-negative integer')."""
    from snn_fg.cli import main

    with pytest.raises(SystemExit) as ended:  # (argparse's own refusal: its usage line, then the error)
        main([*argv, "--out", str(tmp_path / "o")] if argv[0] == "run" else argv)
    err = capsys.readouterr().err
    assert ended.value.code == 2 and "argument --seed: must be >= 0, got -" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_a_negative_seed_is_refused_where_a_model_or_the_camera_is_made():
    import numpy as np

    from snn_fg.errors import ParameterError
    from snn_fg.events.esim import simulate_frames
    from snn_fg.models import get_model

    with pytest.raises(ParameterError, match="seed=-1 must be >= 0"):
        get_model("spiking", seed=-1)
    with pytest.raises(ParameterError, match="simulate_frames: seed=-1 must be >= 0"):
        simulate_frames(np.zeros((2, 4, 4)), [0, 10], seed=-1)
    assert get_model("spiking", seed=0) is not None


def test_a_stored_network_made_for_another_frame_is_said_to_run_resized(tmp_path, capsys):
    """A 304 x 240 network read back ran on a 320 x 240 recording without a word (a new user's trial)."""
    from snn_fg.cli import main
    from snn_fg.network import build_network
    from snn_fg.params import ModelParams

    desc = tmp_path / "net.json"
    build_network(ModelParams(levels=2), (20, 24)).save(desc)
    common = ["demo", "--network", str(desc), "--no-figures", "--no-progress"]
    assert main(["run", *common, "--model", "spiking", "--duration-ms", "40", "--out", str(tmp_path / "s")]) == 0
    out = capsys.readouterr().out
    assert f"snn-fg: note: {desc} was made for a 24 x 20 frame and runs resized to this input's " in out
    assert main(["run", *common, "--model", "rate", "--out", str(tmp_path / "r")]) == 0  # (its parameters only)
    assert "resized" not in capsys.readouterr().out


def test_an_error_met_part_way_keeps_its_remedy_when_the_run_says_where_it_stopped(tmp_path, capsys):
    """An N-MNIST event outside --sensor-size met part way through a recording lost its
    '--sensor-size 34x18' when the run added where it had stopped."""
    from snn_fg.cli import main

    n = 400
    t = np.arange(n) * 500
    rec = np.zeros((n, 5), np.uint8)
    rec[:, 0], rec[:, 1] = np.where(np.arange(n) < 300, np.arange(n) % 18, np.arange(n) % 34), np.arange(n) % 18
    rec[:, 2], rec[:, 3], rec[:, 4] = ((t >> 16) & 0x7F) | 0x80, (t >> 8) & 0xFF, t & 0xFF
    rec.tofile(tmp_path / "digit.bin")
    argv = ["run", str(tmp_path / "digit.bin"), "--out", str(tmp_path / "o"), "--model", "rate", "--levels", "3"]
    assert main([*argv, "--window-ms", "20", "--sensor-size", "20x20", "--no-figures", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "(the file's events span 34x18); give --sensor-size 34x18 or the camera's size (at byte offset 1500, " in err
    assert "; stopped there: the 7 windows complete before it are written to" in err and err.count("\n") == 1


@pytest.mark.parametrize(
    "argv",
    [
        ["run", "REC", "--threshold", "0.2"],
        ["run", "REC", "--model", "spiking", "--network", "compact", "--threshold", "0.3"],
        ["events", "REC", "--motion", "circle"],
        ["events", "REC", "--threshold-sigma", "0.02"],
    ],
)
def test_a_simulated_cameras_option_set_on_a_recording_is_refused(argv, tmp_path, capsys):
    """`run dvs.es --threshold 0.2` and `events dvs.es --motion ...` ran as if the option had not been given."""
    from snn_fg.cli import main
    from snn_fg.events import image_to_events, save_events
    from snn_fg.frames.scenes import disc

    rec = image_to_events(disc(6).image, motion="circle")
    save_events(tmp_path / "r.es", rec.events, rec.sensor_size)
    argv = [str(tmp_path / "r.es") if a == "REC" else a for a in argv]
    out = ["--out", str(tmp_path / "o")] if argv[0] == "run" else []
    assert main([*argv, *out, "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "applies to images turned into events only" in err and not (tmp_path / "o").exists()
