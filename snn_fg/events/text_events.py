"""Events as text (``.txt``), one a line, as the Event Camera Dataset gives them
(Mueggler et al. 2017, ``events.txt``): ``t x y p``, whitespace separated, ``t``
in seconds with a decimal fraction (``1468939993.067416019``), x and y pixels,
p 1 (ON) or 0 (OFF; -1 is taken too).

The file holds no sensor size (the data set gives it in a separate calibration
file: 240 x 180 for its DAVIS240C sequences): it is given, or taken from the
events' extent with a warning. Times are parsed as decimal digits, never as
floats, and rounded to the microsecond: a float64 of 1468939993.067416 s is
only good to about 0.2 us, and the error grows with the seconds. Blank lines
and lines starting with ``#`` are skipped. The file is read
:data:`~snn_fg.events.source.READ_BYTES` at a time; every problem is an
:class:`~snn_fg.errors.InputError` naming its line and byte offset.
"""

from __future__ import annotations

import re

import numpy as np

from snn_fg.errors import InputError
from snn_fg.events.core import check_sensor_size, first_fault, infer_sensor_size, pack_events
from snn_fg.events.source import READ_BYTES, Source

#: one line: an event (seconds, fraction, x, y, p), a blank or ``#`` line, or anything else (group 6)
_LINE = re.compile(
    rb"^(?:[ \t]*(\d{1,12})(?:\.(\d{0,18}))?[ \t]+(\d{1,6})[ \t]+(\d{1,6})[ \t]+(-1|0|1)[ \t]*\r?"
    rb"|[ \t]*\r?|[ \t]*#[^\n]*|([^\n]*))$",
    re.MULTILINE,
)
#: the fraction digits kept: one past the microsecond, to round on
_DIGITS = 7
_TEN = 10 ** np.arange(19, dtype=np.int64)
_LONGEST_LINE = 1 << 20
LAYOUT = "'t x y p' (t in seconds, x and y pixels, p 1 or 0)"


def open_txt(path, sensor_size, chunk_events) -> Source:
    """Open an Event Camera Dataset ``events.txt``; without ``sensor_size``, the file
    is read once more first to find the events' extent."""
    if sensor_size is None:
        size = infer_sensor_size(path, iter_txt(path, None))
    else:
        size = check_sensor_size(sensor_size, path)
    return Source(path, "txt", size, lambda n, tally: iter_txt(path, size))


def reads_as_events(path) -> bool:
    """Whether the first line of ``path`` that is not blank or a ``#`` comment is an event
    (a ``.txt`` that is not is something else: a list of recordings, a calibration...)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(1 << 16)
    except OSError:
        return False
    for m in _LINE.finditer(head):
        if m.group(1) is not None:
            return True
        if m.group(6) is not None and m.group(6).strip():
            return False
    return False


def iter_txt(path, sensor_size, read_bytes: int = READ_BYTES):
    """Decode the events of a ``t x y p`` text file, ``read_bytes`` at a time
    (``sensor_size`` ``None``: coordinates not checked)."""
    line, at, prev_t, carry = 1, 0, None, b""  # (line and byte offset of ``carry``'s start)
    with open(path, "rb") as fh:
        while True:
            raw = fh.read(read_bytes)
            buf = carry + raw
            cut = len(buf) if not raw else buf.rfind(b"\n") + 1
            if not raw and not buf:
                return
            if cut == 0:
                if len(buf) > _LONGEST_LINE:
                    raise InputError(path, f"line is longer than {_LONGEST_LINE} bytes: not {LAYOUT}", _where(line, at))
                carry = buf
                continue
            block, carry = buf[:cut], buf[cut:]
            rows = np.array(_LINE.findall(block[:-1] if block.endswith(b"\n") else block), dtype=bytes)
            bad = np.flatnonzero(rows[:, 5] != b"")
            event = np.flatnonzero(rows[:, 0] != b"")
            if len(bad):
                event = event[event < bad[0]]
            x, y, t, p = _columns(rows[event])
            n, problem = first_fault(x, y, t, sensor_size, prev_t)
            yield pack_events(x[:n], y[:n], t[:n], p[:n])
            if problem or len(bad):
                r = int(event[n]) if problem else int(bad[0])
                text = rows[r, 5].decode("utf-8", "replace")[:60]
                problem = problem or f"line does not read as {LAYOUT}: {text!r}"
                raise InputError(path, problem, _where(line + r, at + _row_offset(block, r)))
            prev_t = int(t[-1]) if len(t) else prev_t
            line, at = line + len(rows), at + cut
            if not raw:
                return


def _columns(rows: np.ndarray):
    """x, y, t (us, rounded) and p (0, 1) of event rows (seconds, fraction, x, y, p as digits)."""
    if not len(rows):
        return (np.zeros(0, np.int64),) * 4
    digits = rows[:, 1]
    n = np.char.str_len(digits)
    value = np.where(n > 0, digits, b"0").astype(np.int64)
    fraction = np.where(n <= _DIGITS, value * _TEN[_DIGITS - np.minimum(n, _DIGITS)], value // _TEN[n - _DIGITS])
    t = rows[:, 0].astype(np.int64) * 1_000_000 + (fraction + 5) // 10
    return rows[:, 2].astype(np.int64), rows[:, 3].astype(np.int64), t, rows[:, 4].astype(np.int64) > 0


def _row_offset(block: bytes, r: int) -> int:
    """The byte offset in ``block`` of its line ``r`` (0-based)."""
    at = 0
    for _ in range(r):
        at = block.index(b"\n", at) + 1
    return at


def _where(line: int, at: int) -> str:
    return f"line {line}, byte offset {at}"
