"""Photos as a phone takes them: larger than the model's scale (``--image-scale``
resizes them, and a large image without it gets one note saying what it costs
and what scale fits) and stored on their side with an EXIF orientation."""

import json

import cv2
import numpy as np
import pytest

from snn_fg.cli import main
from snn_fg.results.maps import Maps


def _square(path, w, h, x0, x1, y0, y1):
    """A grey image, a bright rectangle between columns x0..x1 and rows y0..y1."""
    img = np.full((h, w), 60, np.uint8)
    img[y0:y1, x0:x1] = 200
    cv2.imwrite(str(path), img)
    return path


def _event_columns(maps):
    return np.flatnonzero(np.hypot(maps.fg_x, maps.fg_y).any(axis=0))


def test_image_scale_runs_the_model_on_the_resized_image_and_records_both_sizes(tmp_path, capsys):
    img = _square(tmp_path / "big.png", 1200, 800, 400, 800, 200, 600)
    out = tmp_path / "o"
    assert main(["run", str(img), "--image-scale", "0.25", "--out", str(out), "--no-figures", "--no-progress"]) == 0
    assert "warning" not in capsys.readouterr().err  # (a scale given: no note)
    maps = Maps.load(out)
    assert maps.fg_x.shape == (200, 300)
    cols = _event_columns(maps)  # the rectangle's sides, at 400 / 4 and 800 / 4
    assert abs(cols.min() - 100) <= 2 and abs(cols.max() - 200) <= 2
    source = maps.params["source"]
    assert source["image_size"] == [1200, 800] and source["image_scale"] == 0.25


def test_a_large_image_gets_one_note_with_the_scale_that_brings_it_to_the_bsds_size(tmp_path, capsys):
    img = _square(tmp_path / "big.png", 2000, 1200, 600, 1400, 300, 900)
    from snn_fg.frames.still import load_frame

    with pytest.warns(UserWarning) as caught:
        still, source = load_frame(str(img), "image")
    (note,) = [str(w.message) for w in caught]
    assert "a 2000 x 1200 image (2.4 MP)" in note
    assert "--image-scale 0.24 makes it 480 x 288" in note  # 481 / 2000 = 0.2405
    assert "3.6 GB for the rate model, 103 GB for the default spiking network" in note  # 1.5 and 43 kB a pixel
    assert still.image.shape[:2] == (1200, 2000) and "image_scale" not in source


@pytest.mark.parametrize("kind", ["recording", "frame"])
def test_image_scale_is_refused_for_a_recording_or_an_event_frame(tmp_path, capsys, kind):
    if kind == "recording":
        ev = np.zeros(3, dtype=[("x", "<i2"), ("y", "<i2"), ("t", "<i8"), ("p", "i1")])
        ev["t"] = [0, 10, 20]
        path = tmp_path / "rec.npz"
        np.savez(path, events=ev, sensor_size=np.array([64, 48, 2]))
    else:
        path = tmp_path / "frame.npz"
        np.savez(path, pos=np.eye(48, 64, dtype=np.uint8), neg=np.zeros((48, 64), np.uint8))
    assert main(["run", str(path), "--image-scale", "0.5", "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--image-scale: applies to images only" in err, err
    assert not (tmp_path / "o").exists()


def test_compare_reruns_the_reference_on_the_scaled_image(tmp_path, capsys):
    img = _square(tmp_path / "big.png", 960, 640, 300, 660, 160, 480)
    out = tmp_path / "o"
    args = ["run", str(img), "--image-scale", "0.5", "--iterations", "1", "--no-figures", "--no-progress"]
    assert main([*args, "--out", str(out)]) == 0
    assert main(["compare", str(out), str(out), "--json", str(tmp_path / "c.json")]) == 0
    report = json.loads((tmp_path / "c.json").read_text())
    assert "cannot be read again" not in json.dumps(report)
    assert "at 2 iterations instead of 1" in capsys.readouterr().out  # (the baseline ran on the 480 x 320 image)


def test_compare_says_so_when_the_image_changed_size_since_the_run(tmp_path, capsys):
    img = _square(tmp_path / "im.png", 480, 320, 150, 330, 80, 240)
    out = tmp_path / "o"
    assert main(["run", str(img), "--iterations", "1", "--out", str(out), "--no-figures", "--no-progress"]) == 0
    _square(img, 960, 640, 300, 660, 160, 480)  # (the file replaced by a larger one)
    assert main(["compare", str(out), str(out)]) == 0
    said = capsys.readouterr()
    text = " ".join((said.out + said.err).split())  # (compare wraps its notes)
    assert "is 960 x 640 now, the run's maps 480 x 320: not the image it ran on" in text
    assert "--seed" not in text  # (a rate run: no spiking run's spread to point to)
    assert "Traceback" not in said.err


def test_a_photo_is_read_upright_as_its_exif_orientation_says(tmp_path):
    from PIL import Image

    from snn_fg.events.images import read_image

    stored = np.zeros((40, 80), np.uint8)
    stored[:, :40] = 255  # stored wide, its left half white
    im = Image.fromarray(stored)
    exif = im.getexif()
    exif[0x0112] = 6  # EXIF orientation 6: shown turned a quarter clockwise (a phone held upright)
    im.save(tmp_path / "phone.jpg", exif=exif, quality=95)
    img = read_image(tmp_path / "phone.jpg")
    assert img.shape == (80, 40)  # upright: tall
    assert img[:40].mean() > 0.9 and img[40:].mean() < 0.1  # the stored left half is now the top half


def test_an_image_whose_model_would_not_fit_the_memory_is_refused_with_the_scale_that_fits(tmp_path):
    from snn_fg.errors import InputError
    from snn_fg.frames.still import RATE_BYTES_PER_PIXEL, check_fits, large_image_note

    shape = (3000, 4000)  # 12 MP: 18 GB for the rate model at 1.5 kB a pixel
    with pytest.raises(InputError) as caught:
        check_fits("phone.jpg", shape, "rate model", RATE_BYTES_PER_PIXEL, available=8e9)
    said, on_command_line = str(caught.value), caught.value.for_command_line()
    assert "a 4000 x 3000 image: the rate model needs about 18.0 GB for it, more than the 8.0 GB" in said
    # (each front door names its own spelling: the API's keyword, the command line's option)
    scale = float(said.split("pass image_scale=")[1].split()[0])
    assert f"give --image-scale {scale:g} to make it " in on_command_line and "--" not in said
    assert 4000 * 3000 * scale**2 * RATE_BYTES_PER_PIXEL <= 8e9 * 0.8  # (the F it gives fits, with room)
    # (and is the large-image note's own, which fits too: the two lines gave two scales before)
    assert f"--image-scale {scale:g} makes it" in large_image_note("phone.jpg", shape)
    check_fits("phone.jpg", shape, "rate model", RATE_BYTES_PER_PIXEL, available=20e9)  # (fits: no error)


def test_out_of_memory_on_an_image_names_the_image_scale_not_the_network():
    from snn_fg.cli.main import out_of_memory

    err = MemoryError("Unable to allocate 759. MiB for an array with shape (3000, 4000) and data type float64")
    on_image = out_of_memory(err, "phone.jpg")
    assert on_image.startswith("out of memory (Unable to allocate 759. MiB)") and "--image-scale" in on_image
    assert "--network" not in on_image and "1280 x 720" not in on_image
    assert "--network compact" in out_of_memory(err, "rec.aedat4")
    # (a command that runs no model is not told of one: snn-fg events blamed "the model", 1 Dec)
    on_events = out_of_memory(err, "rec.aedat4", "events")
    assert on_events.endswith("snn-fg events needs more than this machine gives it") and "model" not in on_events


def test_run_refuses_an_image_too_large_for_the_memory_before_it_runs(tmp_path, monkeypatch, capsys):
    from snn_fg.pynn import memory

    monkeypatch.setattr(memory, "available_bytes", lambda: 1e8)  # (a machine with 100 MB free)
    img = _square(tmp_path / "im.png", 640, 480, 200, 440, 120, 360)  # 0.3 MP: 0.46 GB for the rate model
    out = tmp_path / "o"
    assert main(["run", str(img), "--out", str(out), "--no-progress"]) == 2
    (err,) = capsys.readouterr().err.strip().splitlines()
    assert err.startswith(f"snn-fg: error: {img}: a 640 x 480 image: the rate model needs about 0.5 GB for it")
    assert "--image-scale" in err and not out.exists()


def test_a_network_whose_cells_do_not_fit_the_memory_is_refused_before_it_runs():
    from snn_fg.backends.fast.backend import check_cells_fit
    from snn_fg.errors import InputError
    from snn_fg.network import build_network

    net = build_network(frame_shape=(720, 1280))
    with pytest.raises(InputError) as caught:
        check_cells_fit(net, 166_831_483, available=4e9)  # (the default network's cells on a 1280 x 720 sensor)
    said = str(caught.value)
    assert said.startswith("the network for a 1280 x 720 frame: its 166,831,483 cells need at least 5.3 GB")
    assert "4.0 GB this machine has available" in said and "--network compact" in said
    check_cells_fit(net, 166_831_483, available=8e9)  # (fits: no error)


def test_events_on_a_large_image_gives_the_note_and_takes_image_scale(tmp_path, capsys):
    img = _square(tmp_path / "big.png", 2000, 1200, 600, 1400, 300, 900)
    assert main(["events", str(img)]) == 0
    said = capsys.readouterr()
    assert said.err.count("\n") == 1 and "--image-scale 0.24 makes it 480 x 288" in said.err, said.err
    assert "sensor:     2000 x 1200" in said.out
    assert main(["events", str(img), "--image-scale", "0.25"]) == 0
    said = capsys.readouterr()
    assert "warning" not in said.err  # (a scale given: no note)
    assert "image:      2000 x 1200, resized by --image-scale 0.25 to 500 x 300" in said.out
    assert "sensor:     500 x 300" in said.out


def test_events_refuses_image_scale_for_a_recording_in_run_s_words(tmp_path, capsys):
    ev = np.zeros(3, dtype=[("x", "<i2"), ("y", "<i2"), ("t", "<i8"), ("p", "i1")])
    ev["t"] = [0, 10, 20]
    path = tmp_path / "rec.npz"
    np.savez(path, events=ev, sensor_size=np.array([64, 48, 2]))
    said = f"snn-fg: error: {path}: --image-scale: applies to images only; INPUT is an event recording\n"
    assert main(["events", str(path), "--image-scale", "0.5"]) == 2
    assert capsys.readouterr().err == said
    assert main(["run", str(path), "--image-scale", "0.5", "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    assert capsys.readouterr().err == said


def test_events_refuses_an_image_whose_simulated_camera_would_not_fit_the_memory(tmp_path, monkeypatch, capsys):
    from snn_fg.pynn import memory

    monkeypatch.setattr(memory, "available_bytes", lambda: 1e8)  # (a machine with 100 MB free)
    img = _square(tmp_path / "im.png", 1000, 800, 300, 700, 200, 600)  # 0.8 MP: 0.24 GB under shift4
    written = tmp_path / "ev.npy"
    assert main(["events", str(img), "--write-events", str(written)]) == 2
    (err,) = capsys.readouterr().err.strip().splitlines()
    assert err.startswith(
        f"snn-fg: error: {img}: a 1000 x 800 image: the event-camera simulator (shift4 motion) needs about 0.2 GB"
    ), err
    assert "--image-scale" in err and not written.exists()
    scale = float(err.split("--image-scale ")[1].split()[0])
    assert main(["events", str(img), "--image-scale", str(scale), "--write-events", str(written)]) == 0
    assert written.exists()


def test_a_recording_named_as_an_image_is_said_to_look_like_one(tmp_path, capsys):
    """Event Stream bytes in a .png said only 'not an image', where a .txt list of them names the format."""
    from snn_fg.events import image_to_events, save_events
    from snn_fg.frames.scenes import disc

    rec = image_to_events(disc(6).image, motion="circle")
    save_events(tmp_path / "r.es", rec.events, rec.sensor_size)
    (tmp_path / "r.png").write_bytes((tmp_path / "r.es").read_bytes())
    assert main(["run", str(tmp_path / "r.png"), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "not an image: its first bytes are no image format's: it looks like an Event Stream (.es) file; " in err
    assert "give it the suffix .es (at byte offset 0)" in err and err.count("\n") == 1
