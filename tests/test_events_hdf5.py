"""HDF5 event files (snn_fg.events.hdf5): DSEC's, MVSEC's and Prophesee's layouts written here with h5py
as their documentation describes them (dataset names and dtypes), each error's one line, the refusals."""

import warnings

import numpy as np
import pytest

from snn_fg.errors import InputError, InputWarning
from snn_fg.events import EVENT_DTYPE, iter_recording, open_recording
from snn_fg.events.hdf5 import ECF_FILTER, seconds_to_us

h5py = pytest.importorskip("h5py")

N = 500


def columns(n=N, w=640, h=480, seed=0):
    rng = np.random.default_rng(seed)
    return {
        "x": rng.integers(0, w, n),
        "y": rng.integers(0, h, n),
        "t": np.sort(rng.integers(0, 3_000_000, n)),
        "p": rng.integers(0, 2, n),
    }


def write_dsec(path, c, t_offset=None, **kw):
    """DSEC's events.h5 (dsec.ifi.uzh.ch/data-format; uzh-rpg/DSEC scripts/utils/eventslicer.py)."""
    with h5py.File(path, "w") as f:
        for k, dtype in (("x", "u2"), ("y", "u2"), ("t", "u4"), ("p", "u1")):
            f.create_dataset(f"events/{k}", data=np.asarray(c[k]).astype(dtype), **kw)
        f.create_dataset("ms_to_idx", data=np.searchsorted(c["t"], np.arange(0, 3001) * 1000).astype("u8"))
        if t_offset is not None:
            f.create_dataset("t_offset", data=np.int64(t_offset))
    return path


def write_mvsec(path, c, t0_s=1504645177.4):
    """MVSEC's *_data.hdf5 (daniilidis-group/mvsec tools/mvsec_simple_reader: x, y, ts.to_sec(), +-1)."""
    a = np.stack([c["x"], c["y"], t0_s + np.asarray(c["t"]) / 1e6, 2.0 * np.asarray(c["p"]) - 1], axis=1)
    with h5py.File(path, "w") as f:
        f.create_dataset("davis/left/events", data=a.astype("f8"))
        f.create_dataset("davis/right/events", data=a[:7].astype("f8"))
        f.create_dataset("davis/left/image_raw", data=np.zeros((2, 260, 346), "u1"))
    return path


PROPHESEE_DTYPE = np.dtype([("x", "<u2"), ("y", "<u2"), ("p", "<i2"), ("t", "<i8")])


def write_prophesee(path, c, ecf=False):
    """Metavision's HDF5 event file: compound CD/events (x, y, p, t), ECF-compressed (filter 0x8ECF)."""
    ev = np.empty(len(c["t"]), PROPHESEE_DTYPE)
    for k in "xypt":
        ev[k] = c[k]
    with h5py.File(path, "w") as f:
        if ecf:  # chunks h5py cannot decode, as a file of Metavision's is without the plugin
            ds = f.create_dataset(
                "CD/events",
                shape=ev.shape,
                dtype=ev.dtype,
                chunks=ev.shape,
                compression=ECF_FILTER,
                allow_unknown_filter=True,
            )
            ds.id.write_direct_chunk((0,), b"not ECF data")
        else:
            f.create_dataset("CD/events", data=ev)
        f.create_dataset("EXT_TRIGGER/events", data=np.zeros(3, [("p", "<i2"), ("t", "<i8"), ("id", "<i2")]))
    return path


def expected(c, t_add=0):
    ev = np.zeros(len(c["t"]), EVENT_DTYPE)
    for k in "xyp":
        ev[k] = c[k]
    ev["t"] = np.asarray(c["t"], np.int64) + t_add
    return ev


# ------------------------------------------------------------------ the layouts, decoded exactly
def test_dsec_decodes_exactly_with_t_offset_added(tmp_path):
    c = columns()
    rec = open_recording(write_dsec(tmp_path / "events.h5", c, t_offset=52_000_123), sensor_size=(640, 480))
    assert rec.format == "dsec" and rec.sensor_size == (640, 480, 2)
    np.testing.assert_array_equal(rec.events, expected(c, 52_000_123))
    rec = open_recording(write_dsec(tmp_path / "no_offset.h5", c), sensor_size=(640, 480))
    np.testing.assert_array_equal(rec.events, expected(c))


def test_dsec_compressed_as_dsec_is_read(tmp_path):
    hdf5plugin = pytest.importorskip("hdf5plugin")
    c = columns()
    path = write_dsec(tmp_path / "events.h5", c, 7, **hdf5plugin.Blosc(cname="zstd"))
    np.testing.assert_array_equal(open_recording(path, sensor_size=(640, 480)).events, expected(c, 7))


def test_mvsec_decodes_absolute_seconds_to_the_microsecond(tmp_path):
    c = columns(w=346, h=260)
    rec = open_recording(write_mvsec(tmp_path / "x_data.hdf5", c), sensor_size=(346, 260))
    assert rec.format == "mvsec"
    np.testing.assert_array_equal(rec.events, expected(c, 1504645177_400000))
    stream = iter_recording(tmp_path / "x_data.hdf5", sensor_size=(346, 260))
    list(stream)
    assert stream.skipped == {"events of the right camera": 7}


def test_seconds_to_us_keeps_microseconds_of_absolute_stamps():
    us = np.arange(1504645177_000000, 1504645177_000000 + 2_000_000, 997, dtype=np.int64)
    s = us // 1_000_000 + (us % 1_000_000) / 1e6  # the double nearest each stamp, as MVSEC stores it
    np.testing.assert_array_equal(seconds_to_us(s, "f", "t"), us)
    assert seconds_to_us(np.array([1504645177.4]), "f", "t")[0] == 1504645177_400000
    us = np.arange(2_000_000, dtype=np.int64)  # relative stamps: truncating t * 1e6 loses one in 87
    np.testing.assert_array_equal(seconds_to_us(us / 1e6, "f", "t"), us)
    with pytest.raises(InputError, match=r"t holds nan, not a time in seconds \(float64.*\(at event 3\)"):
        seconds_to_us(np.array([1.0, 2.0, 3.0, np.nan]), "f", "t")


def test_prophesee_uncompressed_is_read_and_triggers_counted(tmp_path):
    c = columns()
    path = write_prophesee(tmp_path / "rec.hdf5", c)
    stream = iter_recording(path, sensor_size=(640, 480))
    np.testing.assert_array_equal(np.concatenate(list(stream)), expected(c))
    assert stream.format == "prophesee-hdf5" and stream.skipped == {"external trigger events": 3}


def test_chunks_of_any_size_join_to_the_whole(tmp_path):
    c = columns()
    path = write_dsec(tmp_path / "events.h5", c, t_offset=5)
    whole = open_recording(path, sensor_size=(640, 480)).events
    for n in (1, 7, 499, 500, 10_000):
        parts = list(iter_recording(path, sensor_size=(640, 480), chunk_events=n))
        assert all(len(p) <= n for p in parts) and len(parts) == -(-N // n)
        np.testing.assert_array_equal(np.concatenate(parts), whole)
    assert iter_recording(path, sensor_size=(640, 480)).streams


# ------------------------------------------------------------------ sensor size
def test_sensor_size_given_else_inferred_with_the_warning(tmp_path):
    c = columns(w=300, h=200)
    c["x"][0], c["y"][1] = 299, 199
    path = write_dsec(tmp_path / "events.h5", c)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert open_recording(path, sensor_size=(640, 480)).sensor_size == (640, 480, 2)
    with pytest.warns(InputWarning, match="no sensor size given; 300 x 200 from the events' extent") as said:
        assert open_recording(path).sensor_size == (300, 200, 2)
    assert str(said[0].message).endswith("(a larger sensor gives other maps: --sensor-size WxH)")  # (no .npz here)


# ------------------------------------------------------------------ errors: one line each
def one_line(excinfo):
    msg = str(excinfo.value)
    assert "\n" not in msg and "Traceback" not in msg
    return msg


def test_events_outside_the_stated_sensor_name_event_and_datasets(tmp_path):
    c = columns()
    c["x"][123] = 640
    with pytest.raises(InputError) as e:
        open_recording(write_dsec(tmp_path / "events.h5", c), sensor_size=(640, 480))
    msg = one_line(e)
    assert "events.h5: event at (x=640" in msg and "outside the 640 x 480 sensor" in msg
    assert "event 123; events/x, events/y" in msg


def test_timestamps_going_backwards_name_event_and_dataset(tmp_path):
    c = columns()
    c["t"][300] = c["t"][299] - 1
    with pytest.raises(InputError) as e:
        list(iter_recording(write_dsec(tmp_path / "events.h5", c), sensor_size=(640, 480), chunk_events=100))
    msg = one_line(e)
    assert "timestamp goes backwards" in msg and "(at event 300; events/t)" in msg
    c = columns(w=346, h=260)
    c["t"][150] = c["t"][149] - 1  # inside a chunk
    with pytest.raises(InputError) as e:
        list(iter_recording(write_mvsec(tmp_path / "m.hdf5", c), sensor_size=(346, 260), chunk_events=100))
    assert "(at event 150; davis/left/events column 2 (t))" in one_line(e)


def test_datasets_of_unequal_length_are_named(tmp_path):
    c = columns()
    path = write_dsec(tmp_path / "events.h5", c)
    with h5py.File(path, "a") as f:
        del f["events/t"]
        f.create_dataset("events/t", data=c["t"][:-2].astype("u4"))
    with pytest.raises(InputError) as e:
        open_recording(path, sensor_size=(640, 480))
    msg = one_line(e)
    assert "DSEC datasets of unequal length (events/x 500, events/y 500, events/t 498, events/p 500)" in msg
    assert msg.endswith("(at dataset events/t)")


def test_polarity_outside_0_1_names_its_dataset(tmp_path):
    c = columns()
    c["p"][42] = 2
    with pytest.raises(InputError) as e:
        open_recording(write_dsec(tmp_path / "events.h5", c), sensor_size=(640, 480))
    assert "field p must be 1 (ON) and 0 or -1 (OFF)" in one_line(e) and "(at event 42; events/p)" in str(e.value)


def test_a_truncated_file_says_where_it_ends(tmp_path):
    path = write_dsec(tmp_path / "events.h5", columns())
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError) as e:
        open_recording(path, sensor_size=(640, 480))
    msg = one_line(e)
    assert f"HDF5 file is cut short: it ends at byte {len(data) // 2} of the {len(data)} it announces" in msg


def test_ecf_compressed_prophesee_file_gets_the_way_out(tmp_path):
    path = write_prophesee(tmp_path / "rec.hdf5", columns(), ecf=True)
    with pytest.raises(InputError) as e:
        open_recording(path, sensor_size=(640, 480))
    msg = one_line(e)
    assert "a Prophesee Metavision HDF5 file: CD/events is compressed with Prophesee's ECF codec" in msg
    assert "metavision_file_to_dat -i rec.hdf5 (a .dat is read here)" in msg and "HDF5_PLUGIN_PATH" in msg


def test_blosc_without_hdf5plugin_and_h5py_missing_name_the_extra(tmp_path, monkeypatch):
    from snn_fg.events import hdf5

    line = hdf5.unreadable_line("DSEC", "events/x", [hdf5.BLOSC_FILTER])
    assert line.startswith("DSEC dataset events/x is compressed with Blosc (HDF5 filter 32001): pip install")
    assert '".[h5]"' in line
    path = write_dsec(tmp_path / "events.h5", columns())
    monkeypatch.setattr(hdf5, "_h5py", lambda: None)
    with pytest.raises(InputError) as e:
        open_recording(path)
    assert "events.h5: reading HDF5 files needs h5py (and hdf5plugin for DSEC): pip install -e" in one_line(e)


def test_an_unknown_layout_lists_its_datasets_and_what_is_read(tmp_path):
    path = tmp_path / "other.h5"
    with h5py.File(path, "w") as f:
        for i in range(8):
            f.create_dataset(f"group/d{i}", data=np.zeros((i + 1, 2)))
    with pytest.raises(InputError) as e:
        open_recording(path)
    msg = one_line(e)
    assert "an HDF5 file of no event layout read here (datasets group/d0 (1, 2), group/d1 (2, 2)" in msg
    assert "group/d5 (6, 2), ... (8 in all)); DSEC's events/x, y, t, p, MVSEC's" in msg


def test_the_magic_bytes_are_checked(tmp_path):
    path = tmp_path / "fake.h5"
    path.write_bytes(b"\x93NUMPY not an HDF5 file")
    with pytest.raises(InputError, match="extension says an HDF5 file but the content looks like a numpy .npy"):
        open_recording(path)


# ------------------------------------------------------------------ end to end
@pytest.mark.slow
def test_run_on_a_dsec_file_gives_maps_with_vectors(tmp_path):
    from snn_fg.cli import main
    from snn_fg.results.maps import Maps

    # a bright bar 60 px wide moving right by one column a millisecond: its edges' events
    t = np.arange(100) * 1000
    xs, ys, ts, ps = [], [], [], []
    for i, ti in enumerate(t):
        for x, p in ((280 + i, 1), (220 + i, 0)):
            ys.append(np.arange(180, 300))
            xs.append(np.full(120, x))
            ts.append(np.full(120, ti))
            ps.append(np.full(120, p))
    c = {k: np.concatenate(v) for k, v in zip("xytp", (xs, ys, ts, ps))}
    order = np.argsort(c["t"], kind="stable")
    c = {k: v[order] for k, v in c.items()}
    path = write_dsec(tmp_path / "events.h5", c, t_offset=1_000_000)
    out = tmp_path / "out"
    opts = ["--model", "rate", "--max-windows", "1", "--sensor-size", "640x480", "--no-progress"]
    assert main(["run", str(path), "--out", str(out), *opts]) == 0
    m = Maps.load(out)
    assert m.fg_x.shape == (1, 480, 640)
    assert np.hypot(m.fg_x[0], m.fg_y[0]).max() > 0
