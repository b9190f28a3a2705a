"""`snn-fg events` sub-command (registered on a local parser; the main CLI wires it in)."""

import argparse

import cv2
import numpy as np
import pytest

from snn_fg.cli.events import add_events_command
from snn_fg.errors import InputError
from snn_fg.events import EVENT_DTYPE, events_to_frame, image_to_frame, open_recording, save_events


def run(argv):
    ap = argparse.ArgumentParser(prog="snn-fg")
    sub = ap.add_subparsers(dest="command")
    add_events_command(sub)
    args = ap.parse_args(["events"] + [str(a) for a in argv] + ["--no-progress"])
    return args.func(args)


@pytest.fixture
def recording(tmp_path):
    ev = np.zeros(300, EVENT_DTYPE)
    ev["t"] = np.arange(300) * 1000 + 5000  # 5 ms .. 304 ms
    ev["x"] = np.arange(300) % 20
    ev["y"] = (np.arange(300) // 20) % 10
    ev["p"] = np.arange(300) % 3 == 0
    path = tmp_path / "rec.es"
    save_events(path, ev, (20, 10))
    return path, ev


def test_summary(recording, capsys):
    path, ev = recording
    assert run([path]) == 0
    out = capsys.readouterr().out
    assert "format:" in out and " es" in out
    assert "20 x 10" in out
    assert "300 (ON 33.3 %)" in out
    assert "0.299000 s" in out
    assert f"{300 / 0.299:,.0f} events/s" in out
    assert "format:     es\n" in out  # (streamed: nothing said)


def test_a_format_read_whole_says_what_that_means(recording, tmp_path, capsys):
    """An .npz is read into memory whole (an .es is streamed): said as that, not "(read whole)" alone."""
    from snn_fg.events import save_events

    _, ev = recording
    path = save_events(tmp_path / "rec.npz", ev, (20, 10))
    assert run([path]) == 0
    assert "format:     npz (read into memory whole, not streamed)" in capsys.readouterr().out


def test_write_frame_of_chosen_window(recording, tmp_path):
    path, ev = recording
    out = tmp_path / "frame.npz"
    run([path, "--window-ms", "50", "--start-ms", "100", "--write-frame", out])
    z = np.load(out)
    assert set(z.files) == {"pos", "neg", "t_start_us", "t_end_us", "written_by"}  # (the mark: results.outputs)
    assert int(z["t_start_us"]) == 105_000 and int(z["t_end_us"]) == 155_000
    sel = ev[(ev["t"] >= 105_000) & (ev["t"] < 155_000)]
    pos, neg = events_to_frame(sel, (20, 10))
    assert z["pos"].dtype == np.uint8
    np.testing.assert_array_equal(z["pos"], pos)
    np.testing.assert_array_equal(z["neg"], neg)


def test_image_simulation_and_outputs(tmp_path, capsys):
    img = np.zeros((30, 40), np.uint8)
    img[10:20, 12:28] = 200
    png = tmp_path / "img.png"
    cv2.imwrite(str(png), img)
    frame, evs = tmp_path / "f.npz", tmp_path / "e.npy"
    run([png, "--threshold", "0.2", "--write-frame", frame, "--write-events", evs])
    out = capsys.readouterr().out
    assert "simulated" in out and "40 x 30" in out
    pos, neg = image_to_frame(img, threshold=0.2)
    z = np.load(frame)
    np.testing.assert_array_equal(z["pos"], pos)
    np.testing.assert_array_equal(z["neg"], neg)
    assert "keeps no sensor size" in out
    rec = open_recording(evs, sensor_size=(40, 30))
    from snn_fg.events import image_to_events

    np.testing.assert_array_equal(rec.events, image_to_events(img, threshold=0.2).events)


def test_bad_inputs_raise_input_error(tmp_path, recording):
    path, _ = recording
    with pytest.raises(InputError, match="no such file"):
        run([tmp_path / "nope.es"])
    bad = tmp_path / "bad.raw"
    bad.write_bytes(path.read_bytes())
    with pytest.raises(InputError, match="mislabelled"):
        run([bad])
    with pytest.raises(InputError, match="npz"):
        run([path, "--write-frame", tmp_path / "f.png"])
    with pytest.raises(InputError, match="after the last event"):
        run([path, "--start-ms", "5000", "--write-frame", tmp_path / "f.npz"])
    assert not (tmp_path / "f.npz").exists()  # no half-written output


def test_raw_sensor_size_option(dataset, capsys):
    raw = dataset("events", "expelliarmus_evt2_spinner.raw")
    with pytest.raises(InputError, match="geometry"):
        run([raw])
    run([raw, "--sensor-size", "640x480"])
    assert "539,481" in capsys.readouterr().out
