"""iniVation AEDAT 4 (``.aedat4``) files, decoded by the ``aedat`` package.

The Rust decoder panics on some corrupt input; every such failure is turned
into an :class:`~snn_fg.errors.InputError`, and the XML description in the
header is checked here first so that its corruption is reported with a byte
offset. A DAVIS camera's file also holds its grey-level (APS) frames, on the
events' clock: :func:`iter_frames` reads them as the decoder gives them
(:mod:`snn_fg.events.aps` checks and pairs them with the event windows).
"""

from __future__ import annotations

import aedat
import numpy as np

from snn_fg.errors import InputError, SnnFgError
from snn_fg.events.core import SENSOR_SIZE, file_sensor_size, pack_events
from snn_fg.events.source import Source

MAGIC = b"#!AER-DAT4.0\r\n"
#: The magic is followed by the size of the header flatbuffer (little-endian uint32).
_BODY_OFFSET = len(MAGIC) + 4


def _panic_safe(path, what, fn, *args):
    try:
        return fn(*args)
    except SnnFgError:
        raise
    except (KeyboardInterrupt, SystemExit, GeneratorExit, MemoryError):
        raise
    except BaseException as exc:  # the Rust decoder can raise a pyo3 PanicException (a BaseException)
        raise InputError(path, f"{what}: {exc}".strip().rstrip(":")) from None


def _check_aedat4_header(path):
    """Light check of the AEDAT4 file header before the Rust decoder sees it.

    The header is ``#!AER-DAT4.0\r\n``, a 4-byte size and a flatbuffer
    holding an XML description; corrupt non-ASCII bytes in that XML make
    the decoder panic, so they are reported here with their offset.
    """
    with open(path, "rb") as fh:
        head = fh.read(_BODY_OFFSET)
        if len(head) < _BODY_OFFSET:
            raise InputError(path, "AEDAT4 header is truncated", f"byte offset {len(head)}")
        n = int.from_bytes(head[len(MAGIC) :], "little")
        body = fh.read(min(n, 1 << 24))
    if len(body) < n:
        raise InputError(
            path,
            f"AEDAT4 header announces {n} bytes but the file ends first",
            f"byte offset {_BODY_OFFSET + len(body)}",
        )
    start = body.find(b"<")
    end = body.rfind(b">")
    if start < 0 or end < start:
        raise InputError(path, "AEDAT4 header holds no XML description", f"byte offset {_BODY_OFFSET}")
    xml = np.frombuffer(body[start : end + 1], dtype=np.uint8)
    bad = xml >= 128
    if bad.any():
        raise InputError(
            path,
            "AEDAT4 header description is corrupt (non-ASCII byte)",
            f"byte offset {_BODY_OFFSET + start + int(np.argmax(bad))}",
        )


def _decoder(path):
    """The ``aedat`` decoder of ``path`` (header checked first), and its streams by id."""
    _check_aedat4_header(path)
    decoder = _panic_safe(path, "AEDAT4 decoder rejected the file", aedat.Decoder, str(path))
    return decoder, _panic_safe(path, "AEDAT4 decoder rejected the file", decoder.id_to_stream)


def _packets(path):
    """Every packet of the file in file order, as the decoder gives it (a dict
    with ``stream_id`` and its content); a packet that cannot be decoded is an
    :class:`InputError` naming it (its byte offset when the file ends inside it)."""
    it = iter(_panic_safe(path, "AEDAT4 decoder rejected the file", aedat.Decoder, str(path)))
    k = 0
    while True:
        try:
            packet = _panic_safe(path, f"AEDAT4 packet {k} could not be decoded", next, it, None)
        except InputError as exc:
            raise _packet_error(path, k, exc) from None
        if packet is None:
            return
        k += 1
        yield packet


def open_aedat4(path, sensor_size, chunk_events) -> Source:
    """Open an AEDAT 4 file; its first event stream is read, packet by packet.
    IMU samples, triggers and other event streams are counted in the decode
    tally and left out; APS frames are read by :func:`iter_frames`."""
    _, streams = _decoder(path)
    ids = [sid for sid, s in streams.items() if s.get("type") == "events"]
    if not ids:
        raise InputError(path, "AEDAT4 file has no event stream")
    target = min(ids)
    geom = (streams[target].get("width"), streams[target].get("height"))
    if sensor_size is None and None in geom:
        raise InputError(path, "AEDAT4 event stream whose description gives no width/height", remedy=SENSOR_SIZE)
    size = file_sensor_size(path, sensor_size, geom)

    def chunks(n, tally):
        for packet in _packets(path):
            if packet.get("stream_id") != target or "events" not in packet:
                _count_skipped(packet, tally)
                continue
            e = packet["events"]
            yield pack_events(e["x"], e["y"], e["t"], e["on"])

    return Source(path, "aedat4", size, chunks)


def frame_stream(path) -> tuple[int | None, int | None] | None:
    """``(width, height)`` of the file's first frame stream as its header
    declares it (``None`` for a size it does not declare); ``None`` when the
    file has no frame stream."""
    _, streams = _decoder(path)
    ids = [sid for sid, s in streams.items() if s.get("type") == "frame"]
    return None if not ids else (streams[min(ids)].get("width"), streams[min(ids)].get("height"))


def iter_frames(path):
    """The frames of the file's first frame stream in file order, each as the
    decoder gives it: a dict with ``t`` (the frame's timestamp, us), the
    exposure's ``exposure_begin_t`` and ``exposure_end_t``, ``format`` ("L",
    "RGB" or "RGBA"), ``width``, ``height``, ``offset_x``, ``offset_y`` and
    ``pixels`` (uint8, rows first)."""
    _, streams = _decoder(path)
    ids = [sid for sid, s in streams.items() if s.get("type") == "frame"]
    if not ids:
        return
    for packet in _packets(path):
        if packet.get("stream_id") == min(ids) and "frame" in packet:
            yield packet["frame"]


def _packet_error(path, k: int, error: InputError) -> InputError:
    """The decoder's ``error`` about packet ``k`` with where that packet lies: each packet is a
    stream id and a size (little-endian uint32 each), then that many bytes. When the file ends
    inside it (a recording cut short), an error that says so."""
    with open(path, "rb") as fh:
        fh.seek(len(MAGIC))
        at = _BODY_OFFSET + int.from_bytes(fh.read(4), "little")
        end = fh.seek(0, 2)
        for j in range(k + 1):
            fh.seek(at)
            head = fh.read(8)
            size = int.from_bytes(head[4:], "little") if len(head) == 8 else 0
            if len(head) < 8 or at + 8 + size > end:
                if j < k:
                    return error  # (the decoder read past this one: not a cut in the packet table)
                whole = f"{8 + size} bytes" if len(head) == 8 else "its 8 header bytes"
                return InputError(
                    path,
                    f"file ends inside AEDAT4 packet {k} ({end - at} of {whole}); is the file cut short?",
                    f"byte offset {at}",
                )
            if j < k:
                at += 8 + size
    return InputError(error.source, error.problem, f"byte offset {at}")


def _count_skipped(packet: dict, tally) -> None:
    """Add a packet the event models do not use (IMU samples, triggers,
    another event stream) to ``tally``; frames are not counted here, as
    :mod:`snn_fg.events.aps` reads them."""
    if "frame" in packet:
        return
    if "imus" in packet:
        tally.skip("IMU samples", len(packet["imus"]))
    elif "triggers" in packet:
        tally.skip("trigger events", len(packet["triggers"]))
    elif "events" in packet:
        tally.skip(f"events of stream {packet.get('stream_id')}", len(packet["events"]))
    else:
        tally.skip("packets of an unknown kind")
