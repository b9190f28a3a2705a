"""jAER's and cAER's recordings (``.aedat``): AEDAT 2.0 and AEDAT 3.1.

Both start with text header lines (``#`` to CRLF), the first naming the
version (``#!AER-DAT2.0``, ``#!AER-DAT3.1``), as iniVation's "AEDAT File
Formats" pages describe them.

**AEDAT 2.0** (jAER): after the header, 8-byte big-endian records, an int32
address and an int32 timestamp in microseconds (read unsigned; a drop of more
than 2**31 us is the counter wrapping). The address is the camera's, as
jAER's class for it (``# AEChip:`` header line, else the ``chip`` option)
reads it:

=========  =========================================  =========================================
chip       polarity event                             other records (counted, left out)
=========  =========================================  =========================================
DVS128     bits 15 and 31 clear; x bits 1-7, y bits   bit 15 or 31 set: external input events
           8-14, polarity bit 0 (**0 = ON**)
DAVIS      bit 31 clear, bits 10-11 not ``01``;       bit 31 set: APS (frame) samples, and IMU
           x bits 12-21, y bits 22-30, polarity bit   samples where bits 10-11 are ``11``;
           11 (1 = ON)                                bits 10-11 ``01``: external input events
=========  =========================================  =========================================

jAER mirrors the raw x (x = W - 1 - raw x, in both chips' extractors) and puts
(0, 0) at the lower left; snn-fg's (0, 0) is the upper left, as in AEDAT 3.1
and the other formats, so x = W - 1 - raw x and y = H - 1 - raw y: the picture
jAER shows. iniVation's page gives the DVS128's polarity bit as 1 = ON; jAER's
DVS128 extractor and its MATLAB reader take raw 0 as ON, and are followed here.
A header line must be text: a record whose first byte is ``#`` is not taken
for one.

**AEDAT 3.1** (cAER, libcaer's ``events/common.h`` and ``polarity.h``): after
``#!END-HEADER``, packets, little-endian: a 28-byte header (int16 eventType,
int16 eventSource, int32 eventSize, eventTSOffset, eventTSOverflow,
eventCapacity, eventNumber, eventValid), then eventCapacity events of
eventSize bytes, of which the first eventNumber are used. Polarity events
(type 1, 8 bytes): uint32 data (valid bit 0, polarity bit 1, y bits 2-16,
x bits 17-31, (0, 0) at the upper left), int32 timestamp; the time is
``eventTSOverflow << 31 | timestamp`` us. The first source the header names
(``#Source N: DVS128``) is read; its sensor is the camera's where the name is
known. Other packets, invalid (filtered) events and other sources' events are
counted and left out.

Every problem is an :class:`~snn_fg.errors.InputError` with its byte offset;
the events before it are returned first.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass

import numpy as np

from snn_fg import validate
from snn_fg.errors import InputError, Remedy
from snn_fg.events.core import SENSOR_SIZE, file_sensor_size, first_fault, infer_sensor_size, pack_events
from snn_fg.events.source import READ_BYTES, DecodeTally, Source

#: AEDAT 2.0 cameras by the ``chip`` option, with their sensors (W, H); ``"davis"``: a DAVIS of the size given
CHIPS = {
    "dvs128": (128, 128),
    "davis128": (128, 128),
    "davis208": (208, 192),
    "davis240": (240, 180),
    "davis346": (346, 260),
    "davis640": (640, 480),
    "davis": None,
}
CHIP = Remedy(
    "chip='dvs128' (or 'davis240', 'davis346', 'davis640', or 'davis' with sensor_size)",
    "--chip dvs128 (or davis240, davis346, davis640, or davis with --sensor-size WxH)",
)
_LINE_LIMIT = 1 << 16  # a longer '#' line is no header line
_RECORD = np.dtype([("a", ">u4"), ("t", ">u4")])  # AEDAT 2.0
_PACKET = struct.Struct("<hhiiiiii")  # AEDAT 3.1 packet header
_POLARITY = np.dtype([("data", "<u4"), ("t", "<i4")])
_TYPE_NAMES = {0: "special events", 2: "frames", 3: "IMU6 samples", 4: "IMU9 samples", 7: "configuration events"}


@dataclass(frozen=True)
class Header:
    """The text header of an AEDAT file: its version ("2.0", "3.1"), lines and where the data start."""

    version: str
    lines: tuple[str, ...]
    body_offset: int


def read_header(path) -> Header:
    """The header lines: each starts with ``#`` and is text; AEDAT 3.1's end with ``#!END-HEADER``."""
    lines = []
    with open(path, "rb") as fh:
        first = fh.readline(_LINE_LIMIT).rstrip(b"\r\n")
        version = first[len(b"#!AER-DAT") :].decode("latin-1") if first.startswith(b"#!AER-DAT") else None
        if version not in ("2.0", "3.1"):
            what = f"AEDAT {version}" if version else "a file without an AEDAT version line"
            raise InputError(
                path,
                f"{what} is not supported (.aedat: AEDAT 2.0 and 3.1; AEDAT 4 files end in .aedat4)",
                "byte offset 0",
            )
        at = fh.tell()
        while True:
            line = fh.readline(_LINE_LIMIT)
            text = line.rstrip(b"\r\n")
            if not line.startswith(b"#") or not line.endswith(b"\n") or any(c < 32 and c != 9 for c in text):
                break
            at = fh.tell()
            lines.append(text.decode("latin-1"))
            if version == "3.1" and text == b"#!END-HEADER":
                break
    if version == "3.1" and "#!END-HEADER" not in lines:
        raise InputError(path, "AEDAT 3.1 header has no '#!END-HEADER' line", f"byte offset {at}")
    return Header(version, tuple(lines), at)


def chip_of(name: str) -> str | None:
    """The ``chip`` of a jAER AEChip class or a cAER source (``"eu.seebetter.ini.chips.davis.DAVIS240C"``:
    ``"davis240"``); ``None`` for a camera not in :data:`CHIPS`."""
    n = name.rsplit(".", 1)[-1].lower()
    if n in ("dvs128", "tmpdiff128"):
        return "dvs128"
    return next((c for c in CHIPS if c.startswith("davis") and c != "davis" and n.startswith(c)), None)


def open_aedat(path, sensor_size, chunk_events, *, chip: str | None = None) -> Source:
    """Open an AEDAT 2.0 (decoder ``"aedat2"``) or 3.1 (``"aedat3"``) file; ``chip`` names
    an AEDAT 2.0 file's camera where its header does not."""
    header = read_header(path)
    if header.version == "2.0":
        return _open_aedat2(path, header, sensor_size, chip)
    if chip is not None:
        validate.fail(str(path), "chip", chip, "applies to AEDAT 2.0 files only (AEDAT 3.1 events carry x and y)")
    sources = [re.match(r"#Source (\d+): *(.*)", line) for line in header.lines]
    sources = [(int(m.group(1)), m.group(2).strip()) for m in sources if m]
    target = min(sources)[0] if sources else None
    named = dict(sources)[target] if sources else None
    camera = chip_of(named) if named else None
    stated = CHIPS.get(camera)
    if stated is None and sensor_size is None:
        events = iter_aedat3(path, header, target, None, DecodeTally())
        size = infer_sensor_size(path, events, camera=named if camera is None else None)
    else:
        size = file_sensor_size(path, sensor_size, stated)
    return Source(path, "aedat3", size, lambda n, tally: iter_aedat3(path, header, target, size, tally))


def _open_aedat2(path, header: Header, sensor_size, chip) -> Source:
    named = next((line.split(":", 1)[1].strip() for line in header.lines if re.match(r"# ?AEChip:", line)), None)
    known = chip_of(named) if named else None
    if chip is None and known is None:
        problem = (
            f"the header's AEChip {named} is not a camera snn-fg decodes (a DVS128 or a DAVIS)"
            if named
            else "the AEDAT 2.0 header names no camera (no '# AEChip:' line), and its addresses are the camera's"
        )
        raise InputError(path, problem, remedy=CHIP)
    if chip is not None and known is not None and chip != known:
        raise InputError(path, f"the chip given, {chip!r}, disagrees with the header's AEChip {named} ({known!r})")
    chip = chip or known
    if CHIPS[chip] is None and sensor_size is None:
        raise InputError(
            path,
            "a DAVIS's AEDAT 2.0 events are mirrored across its sensor, whose size is not known",
            remedy=SENSOR_SIZE,
        )
    size = file_sensor_size(path, sensor_size, CHIPS[chip])
    return Source(path, "aedat2", size, lambda n, tally: iter_aedat2(path, header, chip, size, tally))


def _addresses(a: np.ndarray, chip: str, tally: DecodeTally):
    """``(keep, raw x, raw y, p)`` of AEDAT 2.0 addresses ``a`` (uint32), as the table of the module says."""
    if chip == "dvs128":
        keep = (a & 0x80008000) == 0
        tally.skip("external input events", np.count_nonzero(~keep))
        return keep, (a >> 1) & 0x7F, (a >> 8) & 0x7F, 1 - (a & 1)
    dvs = (a & 0x80000000) == 0
    external = dvs & ((a & 0xC00) == 0x400)
    imu = (a & 0x80000C00) == 0x80000C00
    tally.skip("APS samples", np.count_nonzero(~dvs & ~imu))
    tally.skip("IMU samples", np.count_nonzero(imu))
    tally.skip("external input events", np.count_nonzero(external))
    return dvs & ~external, (a >> 12) & 0x3FF, (a >> 22) & 0x1FF, (a >> 11) & 1


def iter_aedat2(path, header: Header, chip: str, size, tally: DecodeTally, read_bytes: int = READ_BYTES):
    """Decode the polarity events of an AEDAT 2.0 file, ``read_bytes`` at a time."""
    w, h = size[0], size[1]
    step = max(read_bytes - read_bytes % _RECORD.itemsize, _RECORD.itemsize)
    at, last, wraps, prev_t = header.body_offset, None, 0, None  # (last: raw, prev_t: unwrapped)
    with open(path, "rb") as fh:
        fh.seek(at)
        while raw := fh.read(step):
            whole = len(raw) - len(raw) % _RECORD.itemsize
            rec = np.frombuffer(raw, _RECORD, whole // _RECORD.itemsize)
            keep, rx, ry, p = _addresses(rec["a"], chip, tally)
            index = np.flatnonzero(keep)
            stamp = rec["t"][keep].astype(np.int64)
            if len(stamp):  # the counter wraps after 2**32 us (71.6 min): a drop of more than half of it
                prev = np.concatenate([[stamp[0] if last is None else last], stamp[:-1]])
                wrap = wraps + np.cumsum(prev - stamp > (1 << 31))
                last, wraps = int(stamp[-1]), int(wrap[-1])
                stamp = stamp + (wrap << 32)
            rx, ry, p = rx[keep], ry[keep], p[keep]
            n, problem = first_fault(rx, ry, stamp, size, prev_t)
            yield pack_events(w - 1 - rx[:n], h - 1 - ry[:n], stamp[:n], p[:n])
            if problem:
                raise InputError(path, problem, f"byte offset {at + _RECORD.itemsize * int(index[n])}")
            prev_t = int(stamp[-1]) if len(stamp) else prev_t
            at += whole
            if whole < len(raw):
                raise InputError(
                    path,
                    f"file ends inside an event ({len(raw) - whole} of {_RECORD.itemsize} bytes)",
                    f"byte offset {at}",
                )


def iter_aedat3(path, header: Header, target, size, tally: DecodeTally, read_bytes: int = READ_BYTES):
    """Decode the polarity events of source ``target`` (``None``: the first with any) of an
    AEDAT 3.1 file, packet by packet (a big packet ``read_bytes`` at a time); ``size``
    ``None``: coordinates not checked (the sensor is being inferred)."""
    k, at, last = 0, header.body_offset, None
    with open(path, "rb") as fh:
        end = fh.seek(0, 2)
        fh.seek(at)
        while head := fh.read(_PACKET.size):
            if len(head) < _PACKET.size:
                raise InputError(
                    path,
                    f"file ends inside the header of AEDAT 3.1 packet {k} ({len(head)} of {_PACKET.size} bytes); "
                    "is the file cut short?",
                    f"byte offset {at}",
                )
            kind, source, ev_size, ts_offset, overflow, capacity, number, _ = _PACKET.unpack(head)
            body = _check_packet(path, k, at, end, kind, ev_size, ts_offset, capacity, number)
            if kind == 1 and target is None:
                target = source
            if kind != 1 or source != target:
                what = _TYPE_NAMES.get(kind, f"events of type {kind}") if kind != 1 else f"events of source {source}"
                tally.skip(what, number)
                at = fh.seek(at + _PACKET.size + body)
                k += 1
                continue
            first = at + _PACKET.size
            for i in range(0, number, max(read_bytes // 8, 1)):
                m = min(max(read_bytes // 8, 1), number - i)
                ev = np.frombuffer(fh.read(8 * m), _POLARITY)
                valid = (ev["data"] & 1) == 1
                tally.skip("invalid (filtered-out) events", np.count_nonzero(~valid))
                index = np.flatnonzero(valid)
                d, t = ev["data"][valid], (np.int64(overflow) << 31) + ev["t"][valid]
                x, y = (d >> 17) & 0x7FFF, (d >> 2) & 0x7FFF
                n, problem = first_fault(x, y, t, size, last)
                yield pack_events(x[:n], y[:n], t[:n], (d[:n] >> 1) & 1)
                if problem:
                    raise InputError(path, f"{problem} (packet {k})", f"byte offset {first + 8 * (i + int(index[n]))}")
                last = int(t[-1]) if len(t) else last
            at = fh.seek(at + _PACKET.size + body)
            k += 1


def _check_packet(path, k, at, end, kind, ev_size, ts_offset, capacity, number) -> int:
    """The bytes of AEDAT 3.1 packet ``k`` (at byte ``at``, of a file of ``end`` bytes) after its header."""
    problem = None
    if ev_size < 1 or capacity < 0 or not 0 <= number <= capacity:
        problem = f"holds {number} of {capacity} events of {ev_size} bytes"
    elif kind == 1 and (ev_size != 8 or ts_offset != 4):
        problem = f"holds polarity events of {ev_size} bytes with the time at byte {ts_offset} (not 8 and 4)"
    if problem:
        raise InputError(path, f"AEDAT 3.1 packet {k} {problem}: its header is damaged", f"byte offset {at}")
    body = capacity * ev_size
    if at + _PACKET.size + body > end:
        raise InputError(
            path,
            f"file ends inside AEDAT 3.1 packet {k} ({end - at} of the {_PACKET.size + body} bytes its header gives); "
            "is the file cut short?",
            f"byte offset {at}",
        )
    return body
