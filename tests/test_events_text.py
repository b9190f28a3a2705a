"""Events as text (``.txt``), the Event Camera Dataset's ``events.txt`` layout: ``t x y p``, t in seconds."""

import numpy as np
import pytest

from snn_fg.errors import InputError, InputWarning
from snn_fg.events import iter_recording, open_recording
from snn_fg.events.text_events import iter_txt

SENSOR = (240, 180)  # the data set's DAVIS240C (its calib.txt, not events.txt, says so)


def write(tmp_path, text, name="events.txt"):
    path = tmp_path / name
    path.write_bytes(text.encode() if isinstance(text, str) else text)
    return path


def test_lines_decode_to_exact_microseconds(tmp_path):
    text = (
        "1468939993.067416019 33 39 1\n"  # an absolute stamp: float64 would keep it to ~0.2 us
        "1468939993.0674165 34 39 0\n"  # rounds half up
        "\n# a comment\n"
        "1468939994 1 2 1\r\n"  # no fraction, a CRLF line
        "  1468939994.5\t239\t179\t-1  \n"  # tabs, spaces, -1 for OFF
    )
    stream = iter_recording(write(tmp_path, text), sensor_size=SENSOR)
    ev = np.concatenate(list(stream))
    assert ev["t"].tolist() == [1468939993067416, 1468939993067417, 1468939994000000, 1468939994500000]
    assert ev["x"].tolist() == [33, 34, 1, 239] and ev["y"].tolist() == [39, 39, 2, 179]
    assert ev["p"].tolist() == [1, 0, 1, 0]
    assert stream.format == "txt" and stream.sensor_size == SENSOR + (2,) and stream.streams


def test_an_hour_of_stamps_keeps_every_microsecond(tmp_path):
    us = 1468939993_000000 + np.arange(0, 3600_000_000, 7_777_777) + 1  # odd microseconds through an hour
    lines = [f"{t // 1_000_000}.{t % 1_000_000:06d}123 5 6 1\n" for t in us]  # nanoseconds written, rounded down
    rec = open_recording(write(tmp_path, "".join(lines)), sensor_size=SENSOR)
    np.testing.assert_array_equal(rec.events["t"], us)


def test_without_a_sensor_size_it_is_the_events_extent_with_a_warning(tmp_path):
    path = write(tmp_path, "0.1 10 20 1\n0.2 99 5 0\n")
    with pytest.warns(InputWarning, match="no sensor size given; 100 x 21 from the events' extent") as said:
        assert open_recording(path).sensor_size == (100, 21, 2)
    assert str(said[0].message).endswith("(a larger sensor gives other maps: --sensor-size WxH)")  # (no .npz here)


def test_reads_in_chunks_the_same_events(tmp_path):
    rng = np.random.default_rng(0)
    t = np.sort(rng.integers(0, 10_000_000, 3000))
    lines = [f"{v / 1e6:.6f} {rng.integers(240)} {rng.integers(180)} {rng.integers(2)}\n" for v in t]
    path = write(tmp_path, "".join(lines))
    whole = open_recording(path, sensor_size=SENSOR).events
    np.testing.assert_array_equal(whole["t"], t)
    parts = list(iter_txt(path, SENSOR, read_bytes=50))  # (a read cuts lines anywhere)
    assert len(parts) > 500
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    np.testing.assert_array_equal(np.concatenate(list(iter_recording(path, sensor_size=SENSOR, chunk_events=7))), whole)


def read_until_error(path, **kw):
    got = []
    with pytest.raises(InputError) as err:
        for chunk in iter_recording(path, sensor_size=SENSOR, **kw):
            got.append(chunk)
    return sum(len(c) for c in got), str(err.value)


@pytest.mark.parametrize(
    "bad,problem",
    [
        ("0.3 x 2 1", "line does not read as 't x y p' (t in seconds, x and y pixels, p 1 or 0): '0.3 x 2 1'"),
        ("0.3 1 2", "line does not read as 't x y p' (t in seconds, x and y pixels, p 1 or 0): '0.3 1 2'"),
        ("0.3 1 2 2", "line does not read as 't x y p' (t in seconds, x and y pixels, p 1 or 0): '0.3 1 2 2'"),
        ("1e-3 1 2 1", "line does not read as 't x y p' (t in seconds, x and y pixels, p 1 or 0): '1e-3 1 2 1'"),
        ("0.15 1 2 1", "timestamp goes backwards (150000 us after 200000 us)"),
        ("0.3 240 2 1", "event at (x=240, y=2) lies outside the 240 x 180 sensor"),
    ],
)
def test_a_bad_line_is_one_error_naming_line_offset_and_event(tmp_path, bad, problem):
    path = write(tmp_path, f"0.1 1 2 1\n\n0.2 3 4 0\n{bad}\n0.4 5 6 1\n")
    n, msg = read_until_error(path)
    assert n == 2  # the events before it are read
    assert msg == f"{path}: {problem} (at line 4, byte offset 21, event 2)"
    for read_bytes in (3, 7, 11):  # reads that cut the lines anywhere
        with pytest.raises(InputError, match=r"\(at line 4, byte offset 21\)$"):
            list(iter_txt(path, SENSOR, read_bytes=read_bytes))


def test_a_binary_file_named_txt_is_refused_in_one_line(tmp_path):
    path = write(tmp_path, bytes(range(256)) * 8)
    with pytest.raises(InputError, match="mislabelled"):
        open_recording(path, sensor_size=SENSOR)


def test_run_takes_an_events_txt_and_still_takes_a_list_of_recordings(tmp_path):
    from snn_fg.cli.batch import is_dataset

    events = write(tmp_path, "0.1 1 2 1\n")
    listing = write(tmp_path, "# recordings\nrec1.es\nrec2.aedat\n", "list.txt")
    assert not is_dataset(str(events)) and is_dataset(str(listing))
