"""ATIS Event Stream files: change detections are polarity events, exposure events are counted apart.

Specification: https://github.com/neuromorphic-paris/event_stream (version 2.0,
stream type 2).  Byte 0 of an ATIS event is ``t[5:0] << 2 | polarity << 1 |
is_tc``; idle bytes 0xFC (reset) and 0xFD-0xFF (overflow of 63 us x
``byte & 3``) are special.
"""

import argparse

import numpy as np
import pytest

from snn_fg.cli.events import add_events_command
from snn_fg.errors import InputError
from snn_fg.events import EVENT_DTYPE, iter_recording, open_recording
from snn_fg.events.eventstream import iter_atis, read_header
from snn_fg.events.source import DecodeTally
from snn_fg.events.writers import encode_es_atis

W, H = 304, 240
HEADER = b"Event Stream" + bytes([2, 0, 0, 2]) + W.to_bytes(2, "little") + H.to_bytes(2, "little")
RESET, OVERFLOW_1, OVERFLOW_2, OVERFLOW_3 = 0xFC, 0xFD, 0xFE, 0xFF


def atis_event(dt, x, y, polarity, is_tc):
    return bytes([(dt << 2) | (polarity << 1) | is_tc]) + x.to_bytes(2, "little") + y.to_bytes(2, "little")


def events(rows):
    ev = np.zeros(len(rows), EVENT_DTYPE)
    for i, (x, y, t, p) in enumerate(rows):
        ev[i] = (x, y, t, p)
    return ev


def test_hand_encoded_stream(tmp_path):
    body = (
        bytes([RESET])
        + atis_event(5, 300, 2, 1, 0)  # t = 5: change detection, ON
        + bytes([OVERFLOW_3, OVERFLOW_1])  # + 3 * 63 + 63 us
        + atis_event(10, 1, 1, 0, 1)  # t = 267: exposure, first crossing
        + atis_event(0, 1, 1, 1, 1)  # t = 267: exposure, second crossing
        + bytes([OVERFLOW_2])  # + 2 * 63 us
        + atis_event(62, 0, 239, 0, 0)  # t = 455: change detection, OFF
        + bytes([RESET] * 5)  # resets add no time
        + atis_event(0, 255, 0, 1, 0)
    )  # t = 455: x = 255, a 0xFF data byte
    path = tmp_path / "hand.es"
    path.write_bytes(HEADER + body)
    rec = open_recording(path)
    assert rec.format == "es-atis" and rec.sensor_size == (W, H, 2)
    want = events([(300, 2, 5, 1), (0, 239, 455, 0), (255, 0, 455, 1)])
    np.testing.assert_array_equal(rec.events, want)
    assert rec.exposure_events == 2
    tally = DecodeTally()  # one byte per read: every state carries across reads
    np.testing.assert_array_equal(np.concatenate(list(iter_atis(path, read_header(path), tally, read_bytes=1))), want)
    assert tally.exposure_events == 2


def random_atis(n_change=3000, n_exposure=2000, seed=0):
    """Change detections and exposure events with gaps that need every kind of overflow byte."""
    rng = np.random.default_rng(seed)
    n = n_change + n_exposure
    t = np.cumsum(rng.choice([0, 1, 62, 63, 64, 126, 189, 190, 5000], size=n))
    is_exposure = np.zeros(n, bool)
    is_exposure[rng.choice(n, n_exposure, replace=False)] = True
    ev = np.zeros(n, EVENT_DTYPE)
    ev["t"] = t
    ev["x"] = rng.integers(0, W, n)
    ev["y"] = rng.integers(0, H, n)
    ev["p"] = rng.integers(0, 2, n)
    return ev[~is_exposure], ev[is_exposure]


@pytest.mark.slow
def test_writer_round_trip_with_reset_and_overflow_bytes(tmp_path):
    change, exposure = random_atis()
    data = encode_es_atis(change, (W, H), exposure)
    assert data[:20] == HEADER
    body = np.frombuffer(data[20:], np.uint8)
    assert {OVERFLOW_1, OVERFLOW_2, OVERFLOW_3} <= set(body.tolist())  # all three overflow sizes occur
    path = tmp_path / "w.es"
    path.write_bytes(HEADER + bytes([RESET] * 5) + data[20:])
    rec = open_recording(path)
    np.testing.assert_array_equal(rec.events, change)
    assert rec.exposure_events == len(exposure)
    # chunked reading, and reads so short that events and overflow runs straddle them
    stream = iter_recording(path, chunk_events=77)
    np.testing.assert_array_equal(np.concatenate(list(stream)), change)
    assert stream.exposure_events == len(exposure)
    for read_bytes in (3, 7, 64):
        tally = DecodeTally()
        got = np.concatenate(list(iter_atis(path, read_header(path), tally, read_bytes=read_bytes)))
        np.testing.assert_array_equal(got, change)
        assert tally.exposure_events == len(exposure)


def test_matches_event_stream_package(tmp_path):
    event_stream = pytest.importorskip("event_stream")  # an independent encoder and decoder
    change, exposure = random_atis(seed=1)
    both = np.concatenate([change, exposure])
    order = np.argsort(both["t"], kind="stable")
    theirs = np.zeros(len(both), event_stream.atis_dtype)
    theirs["t"] = both["t"][order]
    theirs["x"] = both["x"][order]
    theirs["y"] = both["y"][order]
    theirs["polarity"] = both["p"][order]
    theirs["exposure"] = np.arange(len(both))[order] >= len(change)
    their_file = tmp_path / "theirs.es"
    with event_stream.Encoder(str(their_file), "atis", W, H) as encoder:
        encoder.write(theirs)
    rec = open_recording(their_file)
    np.testing.assert_array_equal(rec.events, change)
    assert rec.exposure_events == len(exposure)
    our_file = tmp_path / "ours.es"
    our_file.write_bytes(encode_es_atis(change, (W, H), exposure))
    decoded = np.concatenate(list(event_stream.Decoder(str(our_file))))
    np.testing.assert_array_equal(decoded["t"], theirs["t"])
    cd = decoded[~decoded["exposure"]]
    for ours, their in (("x", "x"), ("y", "y"), ("p", "polarity")):
        np.testing.assert_array_equal(cd[their].astype(np.int64), change[ours])
    assert int(decoded["exposure"].sum()) == len(exposure)


def test_cli_summary_reports_exposure_events(tmp_path, capsys):
    change, exposure = random_atis(n_change=500, n_exposure=1234)
    path = tmp_path / "a.es"
    path.write_bytes(encode_es_atis(change, (W, H), exposure))
    ap = argparse.ArgumentParser(prog="snn-fg")
    add_events_command(ap.add_subparsers(dest="command"))
    args = ap.parse_args(["events", str(path), "--no-progress"])
    assert args.func(args) == 0
    out = capsys.readouterr().out
    assert "format:     es-atis" in out
    assert "events:     500 (" in out
    assert "skipped:    1,234 ATIS exposure events (read, not used by the model)" in out.splitlines()


@pytest.mark.parametrize("kind,name", [(0, "generic"), (3, "asynchronous display"), (4, "colour"), (9, "unknown")])
def test_other_stream_types_are_refused_by_name(tmp_path, kind, name):
    path = tmp_path / "o.es"
    path.write_bytes(b"Event Stream" + bytes([2, 0, 0, kind]) + bytes(20))
    with pytest.raises(InputError, match=f"holds {name} events \\(stream type {kind}\\).*byte offset 15"):
        open_recording(path)


def test_truncated_and_corrupt_atis_name_byte_offsets(tmp_path):
    path = tmp_path / "t.es"
    data = HEADER + atis_event(1, 3, 4, 1, 0) + bytes([OVERFLOW_3]) + atis_event(2, 5, 6, 0, 1)
    path.write_bytes(data[:-2])
    with pytest.raises(InputError, match="ends inside an event \\(3 of 5 bytes\\).*byte offset 26"):
        open_recording(path)
    path.write_bytes(HEADER + atis_event(1, 3, 4, 1, 0) + atis_event(2, W, 0, 0, 1))  # exposure off-sensor
    with pytest.raises(InputError, match="outside the 304 x 240 sensor.*byte offset 25"):
        open_recording(path)
