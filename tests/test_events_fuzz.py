"""Property tests: truncated or corrupted input never escapes as anything but SnnFgError.

Each decoder is fed random truncations and byte flips of a small valid file: a
sample recording (dataset ``events``) when present, otherwise one generated here, so the
properties are exercised on a fresh clone as well.  Every property test first
checks that its unmodified base file decodes to the expected number of events,
so a decoder that refused everything could not pass.
"""

import functools
import importlib.util
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from snn_fg import datasets
from snn_fg.errors import InputError, SnnFgError
from snn_fg.events import EVENT_DTYPE, events_to_frame, iter_recording, iter_windows, open_recording, save_events
from snn_fg.events.writers import encode_es_atis

EVENTS = datasets.find("events")  # None on a machine without the sample recordings
SIZE = (64, 48)


def synthetic(n=400, seed=0):
    rng = np.random.default_rng(seed)
    ev = np.zeros(n, EVENT_DTYPE)
    ev["t"] = np.sort(rng.integers(0, 300_000, n))
    ev["x"] = rng.integers(0, SIZE[0], n)
    ev["y"] = rng.integers(0, SIZE[1], n)
    ev["p"] = rng.integers(0, 2, n)
    return ev


def _written(suffix, **kw):
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / f"f{suffix}"
        save_events(p, synthetic(), SIZE, **kw)
        return p.read_bytes()


def _dat_bytes():
    ev = synthetic()
    data = (ev["p"].astype(np.uint64) << 28) | (ev["y"].astype(np.uint64) << 14) | ev["x"].astype(np.uint64)
    words = (data << np.uint64(32)) | ev["t"].astype(np.uint64)
    return (
        b"% Data file containing CD events.\n% Version 2\n% Width 64\n% Height 48\n"
        + bytes([0x0C, 8])
        + words.astype("<u8").tobytes()
    )


def _nmnist_bytes():
    ev = synthetic()
    t = ev["t"].astype(np.int64)
    rec = np.stack(
        [ev["x"] % 34, ev["y"] % 34, (ev["p"].astype(np.int64) << 7) | (t >> 16), (t >> 8) & 0xFF, t & 0xFF], axis=1
    ).astype(np.uint8)
    return rec.tobytes()


def _yarp_bytes():
    ev = synthetic()
    addr = ev["p"].astype(np.int64) | (ev["x"].astype(np.int64) << 1) | (ev["y"].astype(np.int64) << 12)
    ticks = ev["t"].astype(np.int64) * 1000 // 80
    lines = [
        f"{i} {i * 0.001:.6f} AE ({' '.join(f'{a} {b}' for a, b in zip(ticks[i : i + 20], addr[i : i + 20]))})"
        for i in range(0, len(ev), 20)
    ]
    return ("\n".join(lines) + "\n").encode()


def _aedat2_bytes():
    """A DVS128 AEDAT 2.0 file: jAER's addresses (x and y mirrored, raw polarity 0 = ON), big-endian."""
    ev = synthetic()
    addr = ((127 - ev["y"].astype(np.int64)) << 8) | ((127 - ev["x"].astype(np.int64)) << 1) | (1 - ev["p"])
    records = np.stack([addr, ev["t"]], axis=1).astype(">u4")
    return b"#!AER-DAT2.0\r\n# AEChip: ch.unizh.ini.jaer.chip.retina.DVS128\r\n" + records.tobytes()


def _aedat3_bytes():
    """An AEDAT 3.1 file of a DVS128: polarity packets of 100 events (libcaer's layout)."""
    ev = synthetic()
    data = (ev["x"].astype(np.int64) << 17) | (ev["y"].astype(np.int64) << 2) | (ev["p"].astype(np.int64) << 1) | 1
    words = np.stack([data, ev["t"]], axis=1).astype("<u4")
    out = b"#!AER-DAT3.1\r\n#Format: RAW\r\n#Source 0: DVS128\r\n#!END-HEADER\r\n"
    for i in range(0, len(ev), 100):
        n = len(words[i : i + 100])
        out += np.array([1, 0], "<i2").tobytes() + np.array([8, 4, 0, n, n, n], "<i4").tobytes()
        out += words[i : i + 100].tobytes()
    return out


def _txt_bytes():
    ev = synthetic()
    return "".join(f"{t / 1e6:.6f} {x} {y} {p}\n" for x, y, t, p in ev.tolist()).encode()


def _atis_bytes():
    """An ATIS stream: the synthetic change detections, 200 exposure events, reset bytes after the header."""
    exposures = synthetic(200, seed=1)
    data = encode_es_atis(synthetic(), SIZE, exposures)
    return data[:20] + b"\xfc" * 5 + data[20:]


def _hdf5_bytes(layout):
    """DSEC's events/x, y, t, p (with t_offset) or MVSEC's N x 4 davis/left/events, as snn_fg.events.hdf5 reads."""
    import h5py

    ev = synthetic()
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "f.h5"
        with h5py.File(p, "w") as f:
            if layout == "dsec":
                for k, dtype in (("x", "u2"), ("y", "u2"), ("t", "u4"), ("p", "u1")):
                    f.create_dataset(f"events/{k}", data=ev[k].astype(dtype))
                f.create_dataset("t_offset", data=np.int64(1000))
            else:
                cols = [ev["x"], ev["y"], 1504645177.4 + ev["t"] / 1e6, 2.0 * ev["p"] - 1]
                f.create_dataset("davis/left/events", data=np.stack(cols, axis=1))
        return p.read_bytes()


def _shared(name, limit=None):
    return (EVENTS / name).read_bytes()[:limit] if EVENTS else None


N = len(synthetic())
CASES = {
    # name: (suffix, base bytes, open kwargs, events the base decodes to)
    # real files are cut at an event boundary; their counts agree with event_stream 1.6.3 (es),
    # expelliarmus 1.1.12 (evt2) and the README (aedat4, whole file)
    "es": (".es", _shared("dvs.es", 20 + 5 * 5996), {}, 5996) if EVENTS else (".es", _written(".es"), {}, N),
    "es-atis": (".es", _atis_bytes(), {}, N),
    "evt2": (".raw", _shared("expelliarmus_evt2_spinner.raw", 30_000), {"sensor_size": (640, 480)}, 7417)
    if EVENTS
    else (".raw", _written(".raw"), {}, N),
    "evt3": (".raw", _written(".raw", encoding="evt3"), {}, N),
    "dat": (".dat", _dat_bytes(), {}, N),
    "nmnist": (".bin", _shared("tonic_sample_nmnist.bin", 20_000), {}, 4000)
    if EVENTS
    else (".bin", _nmnist_bytes(), {}, N),
    "yarp": (".log", _yarp_bytes(), {}, N),
    "aedat2": (".aedat", _aedat2_bytes(), {}, N),
    "aedat3": (".aedat", _aedat3_bytes(), {}, N),
    "txt": (".txt", _txt_bytes(), {"sensor_size": SIZE}, N),
    "npy": (".npy", _written(".npy"), {}, N),
    "npz": (".npz", _written(".npz"), {}, N),
}
if importlib.util.find_spec("h5py"):
    CASES["dsec"] = (".h5", _hdf5_bytes("dsec"), {}, N)
    CASES["mvsec"] = (".hdf5", _hdf5_bytes("mvsec"), {}, N)
if EVENTS:  # no AEDAT4 encoder exists to make a base here
    CASES["aedat4"] = (".aedat4", _shared("tonic_sample_person.aedat4"), {}, 111_954)


@functools.cache
def decoded_count(case):
    """Events (and ATIS exposure events) of the unmodified base of ``case``."""
    suffix, base, kw, _ = CASES[case]
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / f"data{suffix}"
        path.write_bytes(base)
        rec = open_recording(path, **kw)
    return len(rec.events), rec.exposure_events


def mutate(data, base):
    # half the cases keep the whole file (flips only), the rest are cut anywhere
    cut = data.draw(st.one_of(st.just(len(base)), st.integers(min_value=0, max_value=len(base))), label="truncate_at")
    buf = bytearray(base[:cut])
    flips = data.draw(
        st.lists(st.tuples(st.integers(0, max(len(buf) - 1, 0)), st.integers(0, 255)), max_size=6), label="flips"
    )
    for i, b in flips:
        if buf:
            buf[i] = b
    return bytes(buf)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::snn_fg.events.EmptyWindowWarning")
@pytest.mark.parametrize("case", sorted(CASES))
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_corrupt_input_raises_only_snnfg_errors(case, data):
    suffix, base, kw, expected = CASES[case]
    assert decoded_count(case)[0] == expected
    blob = mutate(data, base)
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / f"data{suffix}"
        path.write_bytes(blob)
        try:
            rec = open_recording(path, **kw)
        except SnnFgError:
            return
        ev = rec.events
        w, h = rec.sensor_size[:2]
        assert ev.dtype == EVENT_DTYPE
        assert ((ev["x"] >= 0) & (ev["x"] < w) & (ev["y"] >= 0) & (ev["y"] < h)).all()
        # only an Event Stream file can hold ATIS exposure events, each in at least one byte
        assert rec.exposure_events == 0 if suffix != ".es" else rec.exposure_events <= len(blob)
        pos, neg = events_to_frame(ev, rec.sensor_size)
        assert not (pos & neg).any()
        try:
            for _ in iter_windows(rec, window_ms=50, max_windows=3):
                pass
        except SnnFgError:
            pass


def test_atis_base_counts_exposures():
    assert decoded_count("es-atis") == (N, 200)


def test_aedat4_garbage_after_magic_is_refused():
    """Without the sample recordings there is no valid AEDAT4 base to fuzz; random bytes after the magic must be
    refused."""
    for seed in range(5):
        blob = b"#!AER-DAT4.0\r\n" + bytes(np.random.default_rng(seed).integers(0, 256, 3000, dtype=np.uint8))
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "data.aedat4"
            path.write_bytes(blob)
            with pytest.raises(SnnFgError):
                open_recording(path)


@pytest.mark.skipif(not EVENTS, reason="needs the shared sample recordings (../shared/data/events)")
def test_an_aedat4_file_cut_inside_a_packet_says_where_and_why():
    base = _shared("tonic_sample_person.aedat4")
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "cut.aedat4"
        path.write_bytes(base[:100_000])
        with pytest.raises(InputError) as err:
            open_recording(path)
        read = _events_before_the_error(path)
    at, k = _packet_holding(base, 100_000)
    assert str(err.value) == (
        f"{path}: file ends inside AEDAT4 packet {k} ({100_000 - at} of "
        f"{8 + int.from_bytes(base[at + 4 : at + 8], 'little')} bytes); is the file cut short? "
        f"(at byte offset {at}, event {read})"
    )


def _packet_holding(base: bytes, offset: int) -> tuple[int, int]:
    """Where the AEDAT4 packet that holds byte ``offset`` of the file ``base`` starts, and its number:
    the packet table walked by hand (each packet a stream id and a size, uint32 each, then its bytes)."""
    at = 18 + int.from_bytes(base[14:18], "little")
    k = 0
    while at + 8 + int.from_bytes(base[at + 4 : at + 8], "little") <= offset:
        at, k = at + 8 + int.from_bytes(base[at + 4 : at + 8], "little"), k + 1
    return at, k


def _events_before_the_error(path) -> int:
    """How many events a reading of ``path`` hands over before its error."""
    n = 0
    with pytest.raises(InputError):
        for chunk in iter_recording(path):
            n += len(chunk)
    return n


def test_an_aedat4_packet_that_cannot_be_decoded_is_named_with_its_byte_offset_and_event():
    """Zeroed bytes inside a compressed packet: the decoder's error, with where the packet
    starts and the index of the first event not read (those before it are handed over)."""
    base = bytearray(_shared("tonic_sample_person.aedat4"))
    base[400_000:400_400] = bytes(400)
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "zeros.aedat4"
        path.write_bytes(bytes(base))
        with pytest.raises(InputError) as err:
            open_recording(path)
        read = _events_before_the_error(path)
    at, k = _packet_holding(base, 400_000)
    assert read > 0 and str(err.value) == (
        f"{path}: AEDAT4 packet {k} could not be decoded: LZ4 error: ERROR_decompressionFailed "
        f"(at byte offset {at}, event {read})"
    )
