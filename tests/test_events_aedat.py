"""AEDAT 2.0 and 3.1 (``.aedat``): files built here byte by byte from the formats' documentation
(iniVation's "AEDAT 2.0" and "AEDAT 3.1" pages, libcaer's ``events/common.h`` and ``polarity.h``,
jAER's DVS128 and DAVIS extractors), decoded x, y, t, p checked exactly."""

import struct

import numpy as np
import pytest

from snn_fg.errors import InputError, ParameterError
from snn_fg.events import iter_recording, open_recording
from snn_fg.events.aedat23 import iter_aedat2, iter_aedat3, read_header
from snn_fg.events.source import DecodeTally

DVS128_HEADER = b"#!AER-DAT2.0\r\n# This is a raw AE data file\r\n# AEChip: ch.unizh.ini.jaer.chip.retina.DVS128\r\n"
DAVIS240_HEADER = b"#!AER-DAT2.0\r\n# AEChip: eu.seebetter.ini.chips.davis.DAVIS240C\r\n"


def dvs128_record(raw_x, raw_y, raw_p, t):
    """jAER's DVS128 address: y bits 8-14, x bits 1-7, polarity bit 0; big-endian int32 address, int32 time."""
    return struct.pack(">II", (raw_y << 8) | (raw_x << 1) | raw_p, t)


def davis_record(raw_x, raw_y, raw_p, t, flags=0):
    """jAER's DAVIS address: y bits 22-30, x bits 12-21, polarity bit 11 (``flags``: bit 31, bits 10-11)."""
    return struct.pack(">II", (raw_y << 22) | (raw_x << 12) | (raw_p << 11) | flags, t)


def packet(kind, source, events, overflow=0, size=8, capacity=None):
    """An AEDAT 3.1 packet: the 28-byte little-endian header, then the events' bytes."""
    n = len(events) // size
    cap = n if capacity is None else capacity
    return struct.pack("<hhiiiiii", kind, source, size, 4, overflow, cap, n, n) + events


def polarity(x, y, p, t, valid=1):
    """libcaer's polarity event: data (valid bit 0, polarity bit 1, y bits 2-16, x bits 17-31), int32 time."""
    return struct.pack("<Ii", (x << 17) | (y << 2) | (p << 1) | valid, t)


AEDAT31_HEADER = b"#!AER-DAT3.1\r\n#Format: RAW\r\n#Source 1: DVS128\r\n#Start-Time: 2017-03-21\r\n#!END-HEADER\r\n"


def write(tmp_path, data, name="rec.aedat"):
    path = tmp_path / name
    path.write_bytes(data)
    return path


def columns(rec):
    ev = rec.events if hasattr(rec, "events") else rec
    return [tuple(int(v) for v in e) for e in ev]


# ------------------------------------------------------------------ AEDAT 2.0
def test_dvs128_addresses_as_jaer_shows_them(tmp_path):
    body = dvs128_record(0, 0, 0, 10) + dvs128_record(5, 7, 1, 20) + dvs128_record(127, 127, 0, 30)
    body += struct.pack(">II", 0x8000, 35)  # an external input (sync) event: bit 15
    path = write(tmp_path, DVS128_HEADER + body)
    stream = iter_recording(path)
    events = np.concatenate(list(stream))
    # x = 127 - raw x (jAER mirrors x), y = 127 - raw y (jAER's origin is the lower left), raw polarity 0 is ON
    assert columns(events) == [(127, 127, 10, 1), (122, 120, 20, 0), (0, 0, 30, 1)]
    assert stream.format == "aedat2" and stream.sensor_size == (128, 128, 2)
    assert stream.skipped == {"external input events": 1}


def test_davis_addresses_and_other_records(tmp_path):
    body = davis_record(0, 0, 1, 10) + davis_record(239, 179, 0, 20) + davis_record(100, 50, 1, 21)
    body += davis_record(3, 3, 0, 25, flags=0x80000000)  # an APS sample
    body += struct.pack(">II", 0x80000C00, 26)  # an IMU sample
    body += davis_record(0, 0, 0, 27, flags=0x400)  # an external input event
    stream = iter_recording(write(tmp_path, DAVIS240_HEADER + body))
    assert columns(np.concatenate(list(stream))) == [(239, 179, 10, 1), (0, 0, 20, 0), (139, 129, 21, 1)]
    assert stream.sensor_size == (240, 180, 2)
    assert stream.skipped == {"APS samples": 1, "IMU samples": 1, "external input events": 1}


def test_davis346_agrees_with_tonic(tmp_path):
    from tonic.io import read_davis_346  # (tonic's DVS128 and AEDAT 3.1 readers fail to unpack their header: 1.7)

    rng = np.random.default_rng(1)
    raw = [(int(rng.integers(346)), int(rng.integers(260)), int(rng.integers(2)), 10 * k) for k in range(200)]
    header = b"#!AER-DAT2.0\r\n# AEChip: eu.seebetter.ini.chips.davis.Davis346B\r\n"
    path = write(tmp_path, header + b"".join(davis_record(*r) for r in raw))
    ours = open_recording(path).events
    _, _, ref = read_davis_346(str(path))
    for k in "xytp":
        np.testing.assert_array_equal(ours[k], ref[k].astype(np.int64))


def test_a_header_without_a_camera_asks_for_the_chip(tmp_path, capsys):
    from snn_fg.cli import main

    path = write(
        tmp_path, b"#!AER-DAT2.0\r\n# created by hand\r\n" + dvs128_record(1, 2, 1, 5) + dvs128_record(1, 2, 0, 9)
    )
    with pytest.raises(InputError, match="names no camera.*pass chip='dvs128'"):
        open_recording(path)
    assert columns(open_recording(path, chip="DVS128")) == [(126, 125, 5, 0), (126, 125, 9, 1)]
    assert main(["events", str(path), "--no-progress"]) == 2
    assert "give --chip dvs128" in capsys.readouterr().err
    assert main(["events", str(path), "--no-progress", "--chip", "dvs128"]) == 0


def test_chip_disagreeing_unknown_or_without_size_is_refused(tmp_path):
    path = write(tmp_path, DVS128_HEADER + dvs128_record(1, 2, 1, 5))
    with pytest.raises(InputError, match="the chip given, 'davis240', disagrees with the header's AEChip"):
        open_recording(path, chip="davis240")
    other = write(tmp_path, b"#!AER-DAT2.0\r\n# AEChip: ch.unizh.ini.jaer.chip.dvs320.DVS320\r\n", "b.aedat")
    with pytest.raises(InputError, match="AEChip ch.unizh.ini.jaer.chip.dvs320.DVS320 is not a camera"):
        open_recording(other)
    bare = write(tmp_path, b"#!AER-DAT2.0\r\n" + davis_record(2, 3, 1, 5), "c.aedat")
    with pytest.raises(InputError, match="mirrored across its sensor.*pass sensor_size"):
        open_recording(bare, chip="davis")
    assert columns(open_recording(bare, chip="davis", sensor_size=(10, 8))) == [(7, 4, 5, 1)]
    with pytest.raises(ParameterError, match="chip='dvs256' must be one of"):
        open_recording(bare, chip="dvs256")


def test_a_record_starting_with_a_hash_is_no_header_line(tmp_path):
    # raw y 140 puts 0x23 ('#') in the address's first byte, and time 10 ends the record with 0x0A ('\n')
    body = davis_record(5, 140, 1, 10) + davis_record(6, 1, 0, 20)
    assert body[0:1] == b"#" and body[7:8] == b"\n"
    path = write(tmp_path, DAVIS240_HEADER + body)
    assert read_header(path).body_offset == len(DAVIS240_HEADER)
    assert columns(open_recording(path)) == [(234, 39, 10, 1), (233, 178, 20, 0)]


def test_a_wrapped_counter_is_unwrapped(tmp_path):
    body = dvs128_record(0, 0, 0, 0xFFFFFFF0) + dvs128_record(0, 0, 0, 0x10)
    assert open_recording(write(tmp_path, DVS128_HEADER + body)).events["t"].tolist() == [0xFFFFFFF0, (1 << 32) + 16]


def test_aedat2_chunks_give_the_same_events(tmp_path):
    rng = np.random.default_rng(0)
    body = b"".join(
        davis_record(int(rng.integers(240)), int(rng.integers(180)), int(rng.integers(2)), 3 * k) for k in range(500)
    )
    path = write(tmp_path, DAVIS240_HEADER + body)
    whole = open_recording(path).events
    header = read_header(path)
    parts = list(iter_aedat2(path, header, "davis240", (240, 180, 2), DecodeTally(), read_bytes=24))
    assert len(parts) > 100
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    np.testing.assert_array_equal(np.concatenate(list(iter_recording(path, chunk_events=7))), whole)


def read_until_error(path, **kw):
    """The events read before the error, and the error."""
    got = []
    with pytest.raises(InputError) as err:
        for chunk in iter_recording(path, **kw):
            got.append(chunk)
    return (np.concatenate(got) if got else []), str(err.value)


def test_aedat2_damage_is_one_line_after_the_events_before_it(tmp_path):
    h = len(DAVIS240_HEADER)
    back = write(tmp_path, DAVIS240_HEADER + davis_record(0, 0, 1, 100) + davis_record(0, 0, 1, 50), "a.aedat")
    got, msg = read_until_error(back)
    assert len(got) == 1 and msg.endswith(
        f"timestamp goes backwards (50 us after 100 us) (at byte offset {h + 8}, event 1)"
    )
    cut = write(tmp_path, DAVIS240_HEADER + davis_record(0, 0, 1, 100) + davis_record(1, 1, 1, 150)[:5], "b.aedat")
    got, msg = read_until_error(cut)
    assert len(got) == 1 and msg.endswith(f"file ends inside an event (5 of 8 bytes) (at byte offset {h + 8}, event 1)")
    out = write(tmp_path, DAVIS240_HEADER + davis_record(0, 0, 1, 100) + davis_record(250, 1, 1, 150), "c.aedat")
    got, msg = read_until_error(out)
    assert len(got) == 1 and msg.endswith(
        f"event at (x=250, y=1) lies outside the 240 x 180 sensor (at byte offset {h + 8}, event 1)"
    )


# ------------------------------------------------------------------ AEDAT 3.1
def test_aedat31_polarity_packets(tmp_path):
    imu = packet(3, 1, bytes(36 * 2), size=36)  # two IMU6 samples: skipped
    first = packet(1, 1, polarity(3, 4, 1, 100) + polarity(9, 9, 1, 150, valid=0) + polarity(127, 0, 0, 200))
    later = packet(1, 1, polarity(64, 127, 1, 5), overflow=1)  # eventTSOverflow << 31
    other = packet(1, 2, polarity(1, 1, 1, 300))  # another source's events
    stream = iter_recording(write(tmp_path, AEDAT31_HEADER + imu + first + later + other))
    assert columns(np.concatenate(list(stream))) == [(3, 4, 100, 1), (127, 0, 200, 0), (64, 127, (1 << 31) + 5, 1)]
    assert stream.format == "aedat3" and stream.sensor_size == (128, 128, 2)
    assert stream.skipped == {"IMU6 samples": 2, "invalid (filtered-out) events": 1, "events of source 2": 1}


def test_aedat31_agrees_with_tonic_s_packet_reading(tmp_path):
    from tonic.io import get_aer_events_from_file, read_aedat_header_from_file

    rng = np.random.default_rng(2)
    events = [(int(rng.integers(128)), int(rng.integers(128)), int(rng.integers(2)), 7 * k) for k in range(300)]
    data = b"".join(packet(1, 1, b"".join(polarity(*e) for e in events[i : i + 64])) for i in range(0, 300, 64))
    path = write(tmp_path, AEDAT31_HEADER + data)
    ours = open_recording(path).events
    version, start, _ = read_aedat_header_from_file(str(path))
    ref = get_aer_events_from_file(str(path), version, start)  # tonic's packet framing, raw words
    assert (version, start) == (3.1, len(AEDAT31_HEADER))
    np.testing.assert_array_equal(ours["t"], ref["timeStamp"])
    np.testing.assert_array_equal(ours["x"], (ref["address"] >> 17) & 0x1FFF)  # (tonic's read_dvs_ibm masks)
    np.testing.assert_array_equal(ours["y"], (ref["address"] >> 2) & 0x1FFF)
    np.testing.assert_array_equal(ours["p"], (ref["address"] >> 1) & 1)


def test_aedat31_chunks_and_an_unknown_camera(tmp_path):
    header = AEDAT31_HEADER.replace(b"DVS128", b"Prototype9")
    data = b"".join(
        packet(1, 1, b"".join(polarity(k % 40, k % 30, k % 2, k) for k in range(i, i + 50))) for i in (0, 50)
    )
    path = write(tmp_path, header + data)
    with pytest.warns(UserWarning) as said:
        whole = open_recording(path).events
    (note,) = [str(w.message) for w in said]
    assert note == (
        f"{path}: no sensor size given, and the header's camera 'Prototype9' is not one snn-fg knows; 40 x 30 "
        "from the events' extent (a larger sensor gives other maps: --sensor-size WxH)"
    )
    parts = list(iter_aedat3(path, read_header(path), 1, (40, 30), DecodeTally(), read_bytes=16))
    assert len(parts) == 50
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    assert open_recording(path, sensor_size=(64, 64)).sensor_size == (64, 64, 2)
    with pytest.raises(ParameterError, match="chip='dvs128' applies to AEDAT 2.0 files only"):
        open_recording(path, chip="dvs128", sensor_size=(64, 64))


def test_aedat31_damage_is_one_line(tmp_path):
    h = len(AEDAT31_HEADER)
    good = packet(1, 1, polarity(1, 1, 1, 100))
    cut = write(tmp_path, AEDAT31_HEADER + good + packet(1, 1, polarity(2, 2, 1, 200) * 3)[:40], "a.aedat")
    got, msg = read_until_error(cut)
    assert len(got) == 1 and msg.endswith(
        f"file ends inside AEDAT 3.1 packet 1 (40 of the 52 bytes its header gives); is the file cut short? "
        f"(at byte offset {h + 36}, event 1)"
    )
    short = write(tmp_path, AEDAT31_HEADER + good + b"\x01\x00\x01", "b.aedat")
    assert "inside the header of AEDAT 3.1 packet 1 (3 of 28 bytes)" in read_until_error(short)[1]
    wrong = write(tmp_path, AEDAT31_HEADER + good + packet(1, 1, bytes(12), size=12), "c.aedat")
    assert read_until_error(wrong)[1].endswith(
        f"AEDAT 3.1 packet 1 holds polarity events of 12 bytes with the time at byte 4 (not 8 and 4): "
        f"its header is damaged (at byte offset {h + 36}, event 1)"
    )
    back = write(tmp_path, AEDAT31_HEADER + good + packet(1, 1, polarity(2, 2, 1, 90)), "d.aedat")
    assert read_until_error(back)[1].endswith(
        f"timestamp goes backwards (90 us after 100 us) (packet 1) (at byte offset {h + 36 + 28}, event 1)"
    )
    out = write(tmp_path, AEDAT31_HEADER + good + packet(1, 1, polarity(200, 2, 1, 190)), "e.aedat")
    assert "event at (x=200, y=2) lies outside the 128 x 128 sensor (packet 1)" in read_until_error(out)[1]


def test_other_aedat_versions_are_refused_by_name(tmp_path):
    for head, said in ((b"#!AER-DAT3.0\r\n", "AEDAT 3.0 is not supported"), (b"#!AER-DAT1.0\r\n", "AEDAT 1.0")):
        with pytest.raises(InputError, match=said):
            open_recording(write(tmp_path, head + bytes(16)))
    with pytest.raises(InputError, match="no '#!END-HEADER' line"):
        open_recording(write(tmp_path, b"#!AER-DAT3.1\r\n#Format: RAW\r\n" + bytes(28)))


# ------------------------------------------------------------------ end to end
def moving_square(n_ms=90, side=24, x0=40, y0=50):
    """(x, y, t us, p) of a square's left and right edges moving right one pixel a millisecond."""
    out = []
    for ms in range(n_ms):
        left = x0 + ms // 3
        for y in range(y0, y0 + side):
            out += [(left + side, y, 1000 * ms + y, 1), (left, y, 1000 * ms + y, 0)]
    return out


@pytest.mark.parametrize("suffix", [".aedat", ".txt"])
def test_run_gives_maps_with_vectors(tmp_path, suffix):
    from snn_fg import Maps
    from snn_fg.cli import main

    events = moving_square()
    if suffix == ".aedat":  # DVS128 addresses: raw x = 127 - x, raw y = 127 - y, raw polarity 0 = ON
        data = DVS128_HEADER + b"".join(dvs128_record(127 - x, 127 - y, 1 - p, t) for x, y, t, p in events)
    else:
        data = "".join(f"{t // 1_000_000}.{t % 1_000_000:06d} {x} {y} {p}\n" for x, y, t, p in events).encode()
    path = write(tmp_path, data, f"square{suffix}")
    extra = ["--sensor-size", "128x128"] if suffix == ".txt" else []
    argv = ["run", str(path), "--out", str(tmp_path / "out"), "--model", "rate", "--max-windows", "1"]
    assert main(argv + extra + ["--no-progress", "--no-figures"]) == 0
    maps = Maps.load(tmp_path / "out")
    assert maps.fg_x.shape == (1, 128, 128)
    assert np.count_nonzero(np.hypot(maps.fg_x, maps.fg_y) > 0) > 100
