"""HDF5 recordings, what the file says beyond its events: MVSEC's two cameras (``channel``,
``--channel``), the sensor size a Metavision file states (its ``geometry`` attribute) and DSEC's
``ms_to_idx``, which a later start reads from. The files are written with h5py in the layouts
tests/test_events_hdf5.py writes, from each data set's documentation."""

import types
import warnings

import numpy as np
import pytest

from snn_fg.cli import main
from snn_fg.errors import InputError, InputWarning
from snn_fg.events import iter_recording, iter_windows, open_recording
from tests.test_events_hdf5 import columns, expected, write_dsec, write_mvsec, write_prophesee

h5py = pytest.importorskip("h5py")

T0_US = 1504645177_400000  # (write_mvsec's first stamp)


# ------------------------------------------------------------------ MVSEC's cameras
def test_mvsec_right_camera_through_the_api_and_the_command_line(tmp_path, capsys):
    c = columns(w=346, h=260)
    path = write_mvsec(tmp_path / "x_data.hdf5", c)  # (its right camera: the left's first 7 events)
    stream = iter_recording(path, sensor_size=(346, 260), channel=1)
    np.testing.assert_array_equal(np.concatenate(list(stream)), expected({k: v[:7] for k, v in c.items()}, T0_US))
    assert stream.skipped == {"events of the left camera": 500}
    assert main(["events", str(path), "--channel", "right", "--sensor-size", "346x260", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "events:     7 " in out and "format:     mvsec" in out, out
    assert main(["events", str(path), "--channel", "0", "--sensor-size", "346x260", "--no-progress"]) == 0
    assert "events:     500 " in capsys.readouterr().out


def test_a_camera_the_file_lacks_is_one_line_naming_those_it_has(tmp_path, capsys):
    c = columns(n=50, w=346, h=260)
    left_only = tmp_path / "left_data.hdf5"
    with h5py.File(left_only, "w") as f:
        f.create_dataset("davis/left/events", data=np.stack([c["x"], c["y"], c["t"] / 1e6, c["p"]], axis=1))
    out = tmp_path / "o"
    assert main(["run", str(left_only), "--channel", "1", "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err == (
        f"snn-fg: error: {left_only}: this MVSEC file has no right camera (channel 1): it has the left "
        "(channel 0, davis/left/events)\n"
    ), err
    assert not out.exists()
    with pytest.raises(InputError, match="read one at a time, not 'both': this file has the left .* and the right"):
        open_recording(write_mvsec(tmp_path / "two_data.hdf5", c), channel="both")
    dsec = write_dsec(tmp_path / "events.h5", columns())
    with pytest.raises(InputError, match="a DSEC file holds one camera's events .*so channel 1 does not apply"):
        open_recording(dsec, channel=1)


def test_compare_names_the_other_camera():
    from snn_fg.scoring.inputs import other_inputs

    def run(**source):
        return types.SimpleNamespace(params={"source": {"input": "x_data.hdf5", "kind": "recording", **source}})

    keys = {"sensor_size": [346, 260], "events_head": "0123456789abcdef"}
    assert other_inputs(run(**keys), run(**keys, channel=1)) == "both x_data.hdf5: channel 0 against 1, other cameras"
    assert other_inputs(run(**keys, channel=0), run(**keys)) is None


# ------------------------------------------------------------------ Metavision's geometry
def test_a_metavision_file_states_its_sensor_else_it_is_inferred_with_the_note(tmp_path):
    c = columns(w=300, h=200)
    stated = write_prophesee(tmp_path / "stated.hdf5", c)
    with h5py.File(stated, "a") as f:  # (a variable-length string, as Metavision's writeAttr writes it)
        f.attrs["geometry"] = "1280x720"
        f.attrs["generation"] = "4.1"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert open_recording(stated).sensor_size == (1280, 720, 2)
    with pytest.raises(InputError, match="the sensor size given, 640 x 480, disagrees with the file's own 1280 x 720"):
        open_recording(stated, sensor_size=(640, 480))
    with pytest.warns(InputWarning, match="no sensor size given; 300 x 200 from the events' extent"):
        assert open_recording(write_prophesee(tmp_path / "bare.hdf5", c)).sensor_size[:2] == (300, 200)
    small = write_prophesee(tmp_path / "small.hdf5", c)
    with h5py.File(small, "a") as f:
        f.attrs["geometry"] = np.bytes_(b"100x100")  # (a fixed-length string reads as bytes)
    with pytest.raises(InputError, match=r"outside the 100 x 100 sensor"):
        open_recording(small)


# ------------------------------------------------------------------ DSEC's ms_to_idx
def dsec_file(tmp_path, name="events.h5", table=None):
    c = columns(n=20_000)
    path = write_dsec(tmp_path / name, c, t_offset=5_000_000)
    if table is not None:
        with h5py.File(path, "a") as f:
            del f["ms_to_idx"]
            f.create_dataset("ms_to_idx", data=table(c["t"]))
    return path, c


def windows(source, start_ms, **read):
    return [
        (w.t_start_us, w.t_end_us, w.events.tobytes())
        for w in iter_windows(source, window_ms=40, start_ms=start_ms, max_windows=4, sensor_size=(640, 480), **read)
    ]


def first_read(monkeypatch):
    """The index of the first event read of events/x (a list, filled as the file is read)."""
    from snn_fg.events import hdf5

    reads, read = [], hdf5._slice

    def spy(f, path, name, i, j):
        if name == "events/x":
            reads.append(i)
        return read(f, path, name, i, j)

    monkeypatch.setattr(hdf5, "_slice", spy)
    return reads


@pytest.mark.parametrize("start_ms", [12.5, 1234.567, 2500])
def test_a_dsec_start_reads_from_ms_to_idx_and_gives_what_a_scan_gives(tmp_path, monkeypatch, start_ms):
    path, c = dsec_file(tmp_path)
    scan = windows(expected(c, 5_000_000), start_ms)  # (the same events as an array: read from the start)
    reads = first_read(monkeypatch)
    assert windows(path, start_ms) == scan
    t0 = c["t"][0]
    assert min(reads) == np.searchsorted(c["t"], (t0 + start_ms * 1000) // 1000 * 1000)  # (the table's index)
    assert min(reads) > 0


@pytest.mark.parametrize("start_ms", [12.5, 1234.567])
def test_a_dsec_replay_from_a_start_reads_from_ms_to_idx_and_sends_what_a_scan_sends(tmp_path, monkeypatch, start_ms):
    """``snn-fg stream --start-ms`` (:func:`~snn_fg.events.replay.recording_from_ms`): the events of a scan
    from the start, without reading those before it."""
    from snn_fg.events.replay import from_ms, recording_from_ms

    path, c = dsec_file(tmp_path)
    scan = np.concatenate(list(from_ms([expected(c, 5_000_000)], start_ms)))
    reads = first_read(monkeypatch)
    np.testing.assert_array_equal(np.concatenate(list(recording_from_ms(path, start_ms, sensor_size=(640, 480)))), scan)
    assert min(reads) == np.searchsorted(c["t"], (c["t"][0] + start_ms * 1000) // 1000 * 1000) > 0


@pytest.mark.parametrize(
    "table, said",
    [
        (lambda t: np.searchsorted(t, np.arange(3001) * 1000)[::-1].copy(), r"ms_to_idx\[\d+\] is \d+, not the first"),
        (lambda t: np.full(3001, 10**9), r"ms_to_idx\[\d+\] is 1000000000, outside the 20,000 events"),
        (lambda t: np.zeros((3001, 2)), "ms_to_idx is not a 1-D table of integers"),
    ],
)
def test_a_table_that_disagrees_with_the_events_is_warned_of_and_the_file_scanned(tmp_path, table, said):
    path, c = dsec_file(tmp_path, table=table)
    scan = windows(expected(c, 5_000_000), 1234.5)
    with pytest.warns(InputWarning, match=said) as caught:
        assert windows(path, 1234.5) == scan
    assert len(caught) == 1 and str(caught[0].message).endswith("; read from the start instead")


def test_a_start_beyond_the_table_or_without_one_scans(tmp_path, monkeypatch):
    path, c = dsec_file(tmp_path, table=lambda t: np.searchsorted(t, np.arange(100) * 1000))  # (the first 100 ms)
    reads = first_read(monkeypatch)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert windows(path, 1234.5) == windows(expected(c, 5_000_000), 1234.5)
    assert min(reads) == 0
    with h5py.File(path, "a") as f:
        del f["ms_to_idx"]
    assert windows(path, 1234.5) == windows(expected(c, 5_000_000), 1234.5)
    with pytest.raises(InputError, match="the start, 3100 ms, lies after the last event"):
        windows(path, 3100)


@pytest.mark.parametrize("channel", [2, -1, True, 1.0, "left", None])
def test_a_camera_other_than_left_right_or_both_is_refused(channel):
    from snn_fg.errors import ParameterError
    from snn_fg.events.formats import check_format_options

    if channel is None:  # (not given: nothing to check)
        assert check_format_options("open_recording", channel=channel) == {}
        return
    with pytest.raises(ParameterError, match="must be 0 \\(left camera\\), 1 \\(right camera\\) or 'both'"):
        check_format_options("open_recording", channel=channel)


@pytest.mark.parametrize("channel", [0, 1, np.int64(1), "both"])
def test_the_left_right_or_both_cameras_are_taken(channel):
    from snn_fg.events.formats import check_format_options

    assert check_format_options("open_recording", channel=channel) == {"channel": channel}
