"""Readers: the sample recordings (dataset ``events``), round trips, spec-encoded synthetic files,
mislabelled files."""

import numpy as np
import pytest

from snn_fg.errors import InputError
from snn_fg.events import EVENT_DTYPE, Recording, detect_format, iter_recording, open_recording, save_events


def random_events(n=2000, w=64, h=48, t_max=200_000, seed=0):
    rng = np.random.default_rng(seed)
    ev = np.zeros(n, EVENT_DTYPE)
    ev["t"] = np.sort(rng.integers(0, t_max, n))
    ev["x"] = rng.integers(0, w, n)
    ev["y"] = rng.integers(0, h, n)
    ev["p"] = rng.integers(0, 2, n)
    return ev


# ------------------------------------------------------------------ the sample recordings (their README table)
README_TABLE = [
    # file, sensor (W, H), span s (1 decimal or 2 decimals as printed), events, extra kwargs
    ("dvs.es", (320, 240), 1.0, 473_225, {}),
    ("tonic_sample_person.aedat4", (320, 240), 0.59, 111_954, {}),
    ("expelliarmus_evt2_spinner.raw", (640, 480), 0.050, 539_481, {"sensor_size": (640, 480)}),
    ("tonic_sample_nmnist.bin", (34, 34), 0.31, 4_325, {}),
]


@pytest.mark.parametrize("name,size,span_s,count,kw", README_TABLE)
def test_shared_recordings_match_readme(dataset, name, size, span_s, count, kw):
    rec = open_recording(dataset("events", name), **kw)
    assert isinstance(rec, Recording)
    assert rec.events.dtype == EVENT_DTYPE
    assert len(rec.events) == count
    assert rec.sensor_size == size + (2,)
    span = (int(rec.events["t"][-1]) - int(rec.events["t"][0])) / 1e6
    digits = len(str(span_s).split(".")[1])
    assert round(span, digits) == pytest.approx(span_s)
    assert (np.diff(rec.events["t"]) >= 0).all()
    assert set(np.unique(rec.events["p"])) == {0, 1}


def test_dvs_es_count_includes_reset_burst(dataset):
    rec = open_recording(dataset("events", "dvs.es"))
    burst = int((rec.events["t"] < 1000).sum())
    # README: 473,225 events, of which the first 1 ms is a ~77k-event reset burst
    assert len(rec.events) == 473_225
    assert 70_000 < burst < 85_000
    assert burst == 76_785  # what we find; 396,440 events remain after dropping t < 1 ms
    assert len(rec.events) - burst == 396_440


def test_shared_es_matches_event_stream_package(dataset):
    import event_stream  # a test extra: an independent decoder to check ours against

    path = dataset("events", "dvs.es")
    ours = open_recording(path).events
    ref = np.concatenate(list(event_stream.Decoder(str(path))))
    for ko, kr in (("t", "t"), ("x", "x"), ("y", "y"), ("p", "on")):
        np.testing.assert_array_equal(ours[ko], ref[kr].astype(np.int64))


def test_evt2_without_geometry_needs_sensor_size(dataset):
    with pytest.raises(InputError, match="gives no sensor size"):
        open_recording(dataset("events", "expelliarmus_evt2_spinner.raw"))


#: EVT2 words of two events (TIME_HIGH, then CD_ON), after a header that gives no sensor size
_NO_GEOMETRY_RAW = (
    b"% evt 2.0\n% end\n" + np.array([(0x8 << 28) | 100, (0x1 << 28) | (5 << 22) | (7 << 11) | 3], "<u4").tobytes()
)


def test_a_raw_file_without_its_sensor_size_is_told_in_the_api_s_words(tmp_path):
    path = tmp_path / "nogeom.raw"
    path.write_bytes(_NO_GEOMETRY_RAW)
    with pytest.raises(InputError) as err:
        open_recording(path)
    said = str(err.value)
    assert said.startswith(f"{path}: EVT2 file whose header gives no sensor size")
    assert "pass sensor_size=(W, H)" in said and "--sensor-size" not in said and "CLI" not in said


@pytest.mark.parametrize("command", [["events"], ["run", "--out", "OUT"]])
def test_a_raw_file_without_its_sensor_size_is_told_in_the_command_line_s_words(tmp_path, capsys, command):
    from snn_fg.cli.main import main

    path = tmp_path / "nogeom.raw"
    path.write_bytes(_NO_GEOMETRY_RAW)
    argv = [command[0], str(path)] + [str(tmp_path / "out") if a == "OUT" else a for a in command[1:]]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith(f"snn-fg: error: {path}: EVT2 file whose header gives no sensor size")
    assert "give --sensor-size WxH (a Prophesee Gen3 VGA sensor is 640 x 480)" in err
    assert "sensor_size=" not in err and "CLI" not in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "name,kw",
    [
        ("dvs.es", {}),
        ("expelliarmus_evt2_spinner.raw", {"sensor_size": (640, 480)}),
        ("tonic_sample_person.aedat4", {}),
    ],
)
def test_streaming_equals_whole(dataset, name, kw):
    whole = open_recording(dataset("events", name), **kw).events
    stream = iter_recording(dataset("events", name), chunk_events=33_333, **kw)
    assert stream.streams
    chunks = list(stream)
    assert all(len(c) <= 33_333 for c in chunks)
    np.testing.assert_array_equal(np.concatenate(chunks), whole)


# ------------------------------------------------------------------ round trips
@pytest.mark.parametrize(
    "suffix,enc", [(".npy", None), (".npz", None), (".raw", "evt2"), (".raw", "evt3"), (".es", None)]
)
def test_write_read_round_trip_identical(tmp_path, suffix, enc):
    ev = random_events(seed=3, t_max=20_000_000)  # > 2**24 us: crosses an EVT3 counter wrap
    path = tmp_path / f"rec{suffix}"
    save_events(path, ev, (64, 48), encoding=enc)
    rec = open_recording(path)
    assert rec.sensor_size == (64, 48, 2)
    np.testing.assert_array_equal(rec.events, ev)
    assert rec.format == {".npy": "npy", ".npz": "npz", ".es": "es"}.get(suffix, enc)
    chunks = list(iter_recording(path, chunk_events=77))
    np.testing.assert_array_equal(np.concatenate(chunks), ev)


@pytest.mark.slow
def test_es_decoder_state_carries_across_reads(tmp_path):
    from snn_fg.events.eventstream import iter_dvs, read_header

    ev = random_events(500, t_max=400_000, seed=5)  # gaps of ~800 us: runs of overflow bytes
    path = tmp_path / "s.es"
    save_events(path, ev, (64, 48))
    for read_bytes in (1, 4, 5, 7, 64):
        got = np.concatenate(list(iter_dvs(path, read_header(path), read_bytes=read_bytes)))
        np.testing.assert_array_equal(got, ev)


def test_npy_streams_memory_mapped_and_converts_dtype(tmp_path):
    ev = np.zeros(5, dtype=[("t", "f8"), ("x", "u2"), ("y", "u2"), ("p", "i1")])
    ev["t"] = [0, 1, 2, 3, 4]
    ev["x"] = [0, 1, 2, 3, 4]
    ev["p"] = [1, -1, 1, -1, 0]
    np.save(tmp_path / "a.npy", ev)
    rec = open_recording(tmp_path / "a.npy")
    assert rec.sensor_size == (5, 1, 2)  # inferred from max x, y
    assert rec.events["p"].tolist() == [1, 0, 1, 0, 0]
    ev["t"][2] = 2.5
    np.save(tmp_path / "b.npy", ev)
    with pytest.raises(InputError, match="event 2"):
        open_recording(tmp_path / "b.npy")


def test_in_memory_array_and_recording_inputs():
    ev = random_events(50)
    rec = open_recording(ev, sensor_size=(64, 48))
    assert rec.format == "array" and rec.path is None
    np.testing.assert_array_equal(rec.events, ev)
    again = open_recording(rec)
    np.testing.assert_array_equal(again.events, ev)
    with pytest.raises(InputError, match="outside"):
        open_recording(ev, sensor_size=(10, 10))


# ------------------------------------------------------------------ EVT3 against the specification
def evt3_file(tmp_path, words, header=True):
    hdr = b"% evt 3.0\n% format EVT3;height=48;width=64\n% geometry 64x48\n% end\n" if header else b""
    path = tmp_path / "v.raw"
    path.write_bytes(hdr + np.array(words, dtype="<u2").tobytes())
    return path


def test_evt3_vectors_and_time_words(tmp_path):
    TH, TL, Y, X, BX, V12, V8 = 0x8000, 0x6000, 0x0000, 0x2000, 0x3000, 0x4000, 0x5000
    words = [
        Y | 5,
        X | 3,  # before any TIME_HIGH: dropped
        TH | 1,
        TL | 7,
        Y | 10,
        X | (1 << 11) | 20,  # t = 4096 + 7, ON event at (20, 10)
        BX | 30,  # base x 30, OFF
        V12 | 0b000000000101,  # x = 30, 32
        V8 | 0b10000001,  # x = 42, 49
        TL | 9,
        Y | 11,
        BX | (1 << 11) | 2,
        V8 | 0b00000011,  # t = 4096 + 9, ON x = 2, 3 at y 11
        TH | 2,
        X | 1,  # t = 8192 (TIME_LOW reset by TIME_HIGH)
        TH | 3,
        TL | 4000,
        TH | 4,
        TL | 5,
        X | 2,  # t = 4*4096 + 5: no 4096 drift from TIME_LOW wraps
        0xA000 | 1,
        0xE000,
        0x7000,
        0xF000,  # trigger / others / continued words are ignored
    ]
    ev = open_recording(evt3_file(tmp_path, words)).events
    want = [
        (20, 10, 4103, 1),
        (30, 10, 4103, 0),
        (32, 10, 4103, 0),
        (42, 10, 4103, 0),
        (49, 10, 4103, 0),
        (2, 11, 4105, 1),
        (3, 11, 4105, 1),
        (1, 11, 8192, 0),
        (2, 11, 4 * 4096 + 5, 0),
    ]
    got = [(int(e["x"]), int(e["y"]), int(e["t"]), int(e["p"])) for e in ev]
    assert got == want


def test_evt3_counter_wrap_unwrapped(tmp_path):
    TH, TL, Y, X = 0x8000, 0x6000, 0x0000, 0x2000
    words = [TH | 4095, TL | 4095, Y | 1, X | 1, TH | 0, TL | 1, X | 2]
    ev = open_recording(evt3_file(tmp_path, words)).events
    assert ev["t"].tolist() == [(1 << 24) - 1, (1 << 24) + 1]


def test_evt3_unknown_word_names_byte_offset(tmp_path):
    path = evt3_file(tmp_path, [0x8001, 0x0001, 0x9000])
    hdr_len = len(b"% evt 3.0\n% format EVT3;height=48;width=64\n% geometry 64x48\n% end\n")
    with pytest.raises(InputError, match=f"byte offset {hdr_len + 4}"):
        open_recording(path)


def test_evt2_spec_words(tmp_path):
    # EVT2: type<<28 | t_low(6)<<22 | x(11)<<11 | y(11); TIME_HIGH 0x8<<28 | t>>6
    words = [
        (0x8 << 28) | 100,
        (0x1 << 28) | (5 << 22) | (7 << 11) | 3,
        (0x0 << 28) | (63 << 22) | (1 << 11) | 2,
        (0xA << 28),
        (0x8 << 28) | 101,
        (0x1 << 28) | (0 << 22) | (0 << 11) | 0,
    ]
    path = tmp_path / "e.raw"
    path.write_bytes(b"% evt 2.0\n% geometry 16x8\n% end\n" + np.array(words, "<u4").tobytes())
    ev = open_recording(path).events
    assert [(int(e["x"]), int(e["y"]), int(e["t"]), int(e["p"])) for e in ev] == [
        (7, 3, 100 * 64 + 5, 1),
        (1, 2, 100 * 64 + 63, 0),
        (0, 0, 101 * 64, 1),
    ]
    bad = tmp_path / "bad.raw"
    bad.write_bytes(b"% evt 2.0\n% geometry 16x8\n% end\n" + np.array(words[:2] + [0x3 << 28], "<u4").tobytes())
    with pytest.raises(InputError, match="unknown EVT2 word type 0x3.*byte offset"):
        open_recording(bad)
    outside = tmp_path / "out.raw"
    outside.write_bytes(b"% evt 2.0\n% geometry 4x4\n% end\n" + np.array(words[:2], "<u4").tobytes())
    with pytest.raises(InputError, match="outside the 4 x 4 sensor"):
        open_recording(outside)


# ------------------------------------------------------------------ DAT
def dat_file(tmp_path, ts, xs, ys, ps, w=64, h=48):
    data = (np.asarray(ps, np.uint64) << 28) | (np.asarray(ys, np.uint64) << 14) | np.asarray(xs, np.uint64)
    words = (data << np.uint64(32)) | np.asarray(ts, np.uint64)
    path = tmp_path / "c.dat"
    path.write_bytes(
        f"% Data file containing CD events.\n% Version 2\n% Width {w}\n% Height {h}\n".encode()
        + bytes([0x0C, 8])
        + words.astype("<u8").tobytes()
    )
    return path


def test_dat_reader(tmp_path):
    path = dat_file(tmp_path, [10, 20, 30], [1, 63, 5], [2, 47, 0], [1, 0, 1])
    rec = open_recording(path)
    assert rec.format == "dat" and rec.sensor_size == (64, 48, 2)
    assert rec.events["t"].tolist() == [10, 20, 30]
    assert rec.events["x"].tolist() == [1, 63, 5] and rec.events["y"].tolist() == [2, 47, 0]
    assert rec.events["p"].tolist() == [1, 0, 1]
    with pytest.raises(InputError, match="outside"):
        open_recording(dat_file(tmp_path, [10], [64], [0], [1]))


# ------------------------------------------------------------------ YARP data.log
def yarp_addr24(x, y, p, ch=0):
    # event-driven CODEC_304x240_24: p bit 0, x bits 1-10, y bits 12-20, channel bit 22
    return p | (x << 1) | (y << 12) | (ch << 22)


def yarp_addr20(x, y, p, ch=0):
    # CODEC_304x240_20: p bit 0, x bits 1-9, y bits 10-17, channel bit 20
    return p | (x << 1) | (y << 10) | (ch << 20)


def yarp_log(path, pairs, numbered=True):
    lines = []
    for k in range(0, len(pairs), 3):
        vals = " ".join(f"{ts} {a}" for ts, a in pairs[k : k + 3])
        lines.append((f"{k} {1000.5 + k:.6f} " if numbered else "") + f"AE ({vals})")
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("codec,enc", [("24", yarp_addr24), ("20", yarp_addr20)])
def test_yarp_codecs(tmp_path, codec, enc):
    rng = np.random.default_rng(1)
    n = 1500
    xs = rng.integers(0, 304, n)
    ys = rng.integers(0, 240, n)
    ps = rng.integers(0, 2, n)
    ticks = np.cumsum(rng.integers(1, 200, n))
    pairs = [(int(t), enc(int(x), int(y), int(p))) for t, x, y, p in zip(ticks, xs, ys, ps)]
    for auto in ("auto", codec):
        rec = open_recording(yarp_log(tmp_path / "data.log", pairs), codec=auto)
        assert rec.format == "yarp" and rec.sensor_size == (304, 240, 2)
        np.testing.assert_array_equal(rec.events["x"], xs)
        np.testing.assert_array_equal(rec.events["y"], ys)
        np.testing.assert_array_equal(rec.events["p"], ps)
        np.testing.assert_array_equal(rec.events["t"], ticks * 80 // 1000)


def test_yarp_wrap_flag_bit_channels_and_samples(tmp_path):
    period = 1 << 30
    pairs = [
        ((period - 100) | (1 << 31), yarp_addr24(1, 1, 1)),  # bit 31 flag set (older logs): ignored
        (period - 50, yarp_addr24(2, 1, 0, ch=1)),  # right camera: skipped by default
        (30, yarp_addr24(3, 2, 1)),  # counter wrapped
        (40, (1 << 23) | 5),  # non-vision sample: skipped
        (60, yarp_addr24(4, 2, 0)),
    ]
    path = yarp_log(tmp_path / "data.log", pairs, numbered=False)
    rec = open_recording(path)
    want_ticks = [period - 100, period + 30, period + 60]
    assert rec.events["x"].tolist() == [1, 3, 4]
    assert rec.events["t"].tolist() == [t * 80 // 1000 for t in want_ticks]
    both = open_recording(path, channel="both")
    assert both.events["x"].tolist() == [1, 2, 3, 4]


def test_yarp_errors_name_line(tmp_path):
    p = tmp_path / "data.log"
    p.write_text("0 1.0 AE (10 2 20 4)\n1 1.1 AE (30 5 40)\n")
    with pytest.raises(InputError, match="line 2"):
        open_recording(p)
    p.write_text("0 1.0 AE (10 2)\nhello world\n")
    with pytest.raises(InputError, match="line 2"):
        open_recording(p)
    p.write_text(f"0 1.0 AE (10 {yarp_addr24(400, 1, 1)})\n")  # x beyond 304
    with pytest.raises(InputError, match="outside the ATIS.*line 1"):
        open_recording(p, codec="24")


# ------------------------------------------------------------------ detection and mislabelled files
def test_mislabelled_files_are_refused(tmp_path):
    ev = random_events(20)
    es = tmp_path / "a.es"
    save_events(es, ev, (64, 48))
    fake = tmp_path / "a.raw"
    fake.write_bytes(es.read_bytes())
    with pytest.raises(InputError, match="Event Stream.*mislabelled"):
        open_recording(fake, sensor_size=(64, 48))
    npy = tmp_path / "b.npy"
    save_events(npy, ev, (64, 48))
    fake = tmp_path / "b.aedat4"
    fake.write_bytes(npy.read_bytes())
    with pytest.raises(InputError, match="mislabelled"):
        open_recording(fake)
    fake = tmp_path / "c.es"
    fake.write_bytes(b"0 1.0 AE (1 2)\n")
    with pytest.raises(InputError, match="YARP"):
        open_recording(fake)
    with pytest.raises(InputError, match="unknown event file extension"):
        open_recording(tmp_path / "x.mp4")
    with pytest.raises(InputError, match="no such file"):
        open_recording(tmp_path / "missing.es")
    (tmp_path / "empty.es").write_bytes(b"")
    with pytest.raises(InputError, match="empty"):
        open_recording(tmp_path / "empty.es")
    assert detect_format(es) == "es"


@pytest.mark.slow  # reads through tonic, whose import brings torch (3 s on an idle core)
def test_nmnist_synthetic_and_truncated(tmp_path):
    # N-MNIST record: x, y, p<<7 | t[22:16], t[15:8], t[7:0]
    recs = [(1, 2, 1, 100), (33, 33, 0, 70000), (0, 0, 1, 80000)]
    raw = bytearray()
    for x, y, p, t in recs:
        raw += bytes([x, y, (p << 7) | (t >> 16), (t >> 8) & 0xFF, t & 0xFF])
    path = tmp_path / "d.bin"
    path.write_bytes(bytes(raw))
    rec = open_recording(path)
    assert [(int(e["x"]), int(e["y"]), int(e["t"]), int(e["p"])) for e in rec.events] == [
        (x, y, t, p) for x, y, p, t in recs
    ]
    path.write_bytes(bytes(raw[:-2]))
    with pytest.raises(InputError, match="byte offset 10"):
        open_recording(path)
    bad = bytearray(raw)
    bad[5] = 40
    path.write_bytes(bytes(bad))
    with pytest.raises(
        InputError,
        match=r"outside the 34 x 34 sensor \(the file's events span 41x34\); pass sensor_size=\(41, 34\) or the camera",
    ):
        open_recording(path)
    assert open_recording(path, sensor_size=(41, 34)).events["x"].max() == 40  # (the size it named holds them)


def test_es_truncated_names_offset(tmp_path):
    path = tmp_path / "t.es"
    save_events(path, random_events(10), (64, 48))
    data = path.read_bytes()
    path.write_bytes(data[:-2])
    with pytest.raises(InputError, match="ends inside an event.*byte offset"):
        open_recording(path)
    path.write_bytes(data[:14])
    with pytest.raises(InputError, match="truncated"):
        open_recording(path)


# ------------------------------------------------------------------ format options
def test_option_typos_are_type_errors(tmp_path):
    from snn_fg.events import RecordingStream, iter_windows

    path = tmp_path / "a.es"
    save_events(path, random_events(20), (64, 48))
    for call in (open_recording, iter_recording, RecordingStream, lambda p, **kw: list(iter_windows(p, **kw))):
        with pytest.raises(TypeError, match="unexpected keyword argument 'encodng'"):
            call(path, encodng="evt3")


@pytest.mark.parametrize(
    "option,value,applies_to",
    [
        ("encoding", "evt3", "Prophesee RAW"),
        ("codec", "24", "YARP"),
        ("channel", 1, "YARP"),
        ("timer_bits", 24, "YARP"),
    ],
)
def test_option_of_another_format_is_a_parameter_error(tmp_path, option, value, applies_to):
    from snn_fg.errors import ParameterError
    from snn_fg.events import iter_windows

    ev = random_events(20)
    path = tmp_path / "a.es"
    save_events(path, ev, (64, 48))
    msg = f"{option}={value!r} does not apply to an Event Stream file \\(it is an option for (a|an) {applies_to}"
    with pytest.raises(ParameterError, match=msg):
        open_recording(path, **{option: value})
    with pytest.raises(ParameterError, match=msg):
        list(iter_windows(path, **{option: value}))
    with pytest.raises(ParameterError, match=f"{option}=.* does not apply to an in-memory recording"):
        open_recording(ev, sensor_size=(64, 48), **{option: value})


def test_option_values_are_checked(tmp_path):
    from snn_fg.errors import ParameterError

    path = tmp_path / "a.raw"
    save_events(path, random_events(20), (64, 48))
    for bad in (
        {"encoding": "evt21"},
        {"encoding": 3},
        {"codec": 24},
        {"channel": 2},
        {"channel": True},
        {"timer_bits": 0},
        {"timer_bits": 30.0},
    ):
        ((name, value),) = bad.items()
        with pytest.raises(ParameterError, match=f"open_recording: {name}="):
            open_recording(path, **bad)
    with pytest.raises(ParameterError, match="chunk_events"):
        iter_recording(path, chunk_events=0)


def test_encoding_option_reads_headerless_raw(tmp_path):
    ev = random_events(300)
    path = tmp_path / "h.raw"
    save_events(path, ev, (64, 48), encoding="evt3")
    data = path.read_bytes()
    path.write_bytes(data[data.index(b"% end\n") + len(b"% end\n") :])
    rec = open_recording(path, encoding="EVT3", sensor_size=(64, 48))
    assert rec.format == "evt3"
    np.testing.assert_array_equal(rec.events, ev)


def test_bad_sensor_size_argument_is_a_parameter_error(tmp_path):
    from snn_fg.errors import ParameterError
    from snn_fg.events import events_to_frame, iter_windows

    ev = random_events(20)
    path = tmp_path / "a.es"
    save_events(path, ev, (64, 48))
    for bad in ((0, 48), (64,), "64x48", (64.5, 48), (40000, 48)):
        with pytest.raises(ParameterError, match="open_recording: sensor_size="):
            open_recording(path, sensor_size=bad)
        with pytest.raises(ParameterError, match="iter_windows: sensor_size="):
            list(iter_windows(ev, sensor_size=bad))
        with pytest.raises(ParameterError, match="events_to_frame: sensor_size="):
            events_to_frame(ev, bad)
        with pytest.raises(ParameterError, match="save_events: sensor_size="):
            save_events(tmp_path / "b.npy", ev, bad)
    with pytest.raises(ParameterError, match="save_events: encoding='evt4'"):
        save_events(tmp_path / "b.raw", ev, (64, 48), encoding="evt4")


@pytest.mark.parametrize("suffix", [".es", ".raw", ".npz"])
def test_a_file_refuses_a_sensor_size_other_than_its_own(tmp_path, suffix):
    """A file that states its sensor (.es and .raw with their header, .npz with its sensor_size) and
    a size given that differs: refused up front, naming both (a larger one was taken without a word
    until 30 Nov: snn-fg events dvs.es --sensor-size 640x480 said 'sensor: 640 x 480'); its own is taken."""
    ev = random_events(50)
    path = tmp_path / f"a{suffix}"
    save_events(path, ev, (64, 48))
    for other in ((32, 48), (80, 60)):
        with pytest.raises(InputError, match=rf"given, {other[0]} x {other[1]}, disagrees with the file's own 64 x 48"):
            open_recording(path, sensor_size=other)
    assert open_recording(path, sensor_size=(64, 48)).sensor_size == open_recording(path).sensor_size == (64, 48, 2)


def _tonic_like(n=100_000):
    ev = np.zeros(n, [("x", "<i2"), ("y", "<i2"), ("t", "<i8"), ("p", "?")])
    ev["x"], ev["y"], ev["t"], ev["p"] = np.arange(n) % 320, np.arange(n) % 240, np.arange(n), np.arange(n) % 2
    return ev


def test_an_array_without_a_sensor_size_says_the_size_it_takes_from_its_events(tmp_path):
    np.save(tmp_path / "a.npy", _tonic_like())
    with pytest.warns(
        UserWarning,
        match=r"a\.npy: no sensor size given; 320 x 240 from the events' extent \(a larger sensor gives other "
        r"maps: --sensor-size WxH, or sensor_size in an \.npz\)",
    ):
        rec = open_recording(tmp_path / "a.npy")
    assert rec.sensor_size[:2] == (320, 240)


def test_a_few_far_out_events_do_not_set_the_sensor_size(tmp_path):
    """One stray x = 30000 among a 320 x 240 sensor's events would make a frame of 30001 columns
    (gigabytes for the model's tables); it is refused naming the event, and a given size refuses it too."""
    ev = _tonic_like()
    ev["x"][500] = 30000
    np.save(tmp_path / "far.npy", ev)
    with pytest.raises(
        InputError,
        match=r"far\.npy: no sensor size given, and a few events lie far beyond the "
        r"others \(x = 30000 at event 500; 1 of 100000 events outside the "
        r"320 x 240 the others fill\)",
    ):
        open_recording(tmp_path / "far.npy")
    with pytest.raises(InputError, match=r"lies outside the 320 x 240 sensor \(at event 500\)"):
        list(iter_recording(tmp_path / "far.npy", sensor_size=(320, 240)))
    ev["x"][500] = 600  # within twice the others' extent: a sensor that size
    np.save(tmp_path / "near.npy", ev)
    with pytest.warns(UserWarning, match="601 x 240 from the events' extent"):
        assert open_recording(tmp_path / "near.npy").sensor_size[:2] == (601, 240)


@pytest.mark.parametrize("p, shown", [(0.7, "0.7"), (5, "5"), (-2, "-2")])
def test_a_polarity_other_than_on_or_off_is_refused_naming_the_event(tmp_path, p, shown):
    ev = np.zeros(10, [("x", "<i2"), ("y", "<i2"), ("t", "<i8"), ("p", "<f8")])
    ev["t"], ev["p"] = np.arange(10), [1, 0, -1, 1, 0, 1, p, 1, 0, 1]
    np.save(tmp_path / "p.npy", ev)
    with pytest.raises(
        InputError,
        match=rf"p\.npy: field p must be 1 \(ON\) and 0 or -1 \(OFF\), or boolean, "
        rf"got {shown}(\.0)? \(at event 6\)",
    ):
        list(iter_recording(tmp_path / "p.npy", sensor_size=(4, 4)))


def test_an_event_frame_given_as_a_recording_is_named_as_a_frame(tmp_path):
    np.savez(tmp_path / "f.npz", pos=np.zeros((4, 4), np.uint8), neg=np.zeros((4, 4), np.uint8))
    with pytest.raises(InputError, match=r"f\.npz: holds an event frame \(pos, neg\), not a recording's events"):
        open_recording(tmp_path / "f.npz")
