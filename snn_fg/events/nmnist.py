"""N-MNIST / N-Caltech101 binary files (``.bin``): 5-byte records, decoded by tonic.

A record is x, y, ``p << 7 | t[22:16]``, ``t[15:8]``, ``t[7:0]``; a record
with y = 240 marks a timer overflow.  Coordinates are checked here so that
bad records are reported with their byte offset.
"""

from __future__ import annotations

import io

import numpy as np

from snn_fg.errors import InputError, Remedy
from snn_fg.events.core import EVENT_DTYPE, check_sensor_size
from snn_fg.events.source import Source

SENSOR_SIZE = (34, 34)
RECORD_BYTES = 5
_OVERFLOW_Y = 240


def open_nmnist(path, sensor_size, chunk_events) -> Source:
    """Open an N-MNIST / N-Caltech101 ``.bin`` file (read whole by tonic). A file cut inside a
    record, or holding a record outside the sensor, is read up to it: its events before it are
    handed on, then the error (with the byte offset; the stream adds the event's index)."""
    from tonic.io import read_mnist_file  # (tonic takes over a second to import: only for a .bin file)

    nbytes = path.stat().st_size
    whole = nbytes - nbytes % RECORD_BYTES
    cut = None
    if whole != nbytes:
        cut = InputError(
            path, f"file ends inside an event ({nbytes - whole} of {RECORD_BYTES} bytes)", f"byte offset {whole}"
        )
    size = check_sensor_size(sensor_size or SENSOR_SIZE, path)

    def decoded(raw):
        return read_mnist_file(io.BytesIO(raw.tobytes()), dtype=EVENT_DTYPE, is_stream=True)

    def chunks(n, tally):
        raw = np.fromfile(path, dtype=np.uint8, count=whole).reshape(-1, RECORD_BYTES)
        bad = (raw[:, 1] != _OVERFLOW_Y) & ((raw[:, 0] >= size[0]) | (raw[:, 1] >= size[1]))
        if bad.any():
            i = int(np.argmax(bad))
            ev = raw[raw[:, 1] != _OVERFLOW_Y]
            span = f"{int(ev[:, 0].max()) + 1}x{int(ev[:, 1].max()) + 1}"
            yield decoded(raw[:i])
            raise InputError(
                path,
                f"event at (x={int(raw[i, 0])}, y={int(raw[i, 1])}) lies outside the {size[0]} x {size[1]} sensor "
                f"(the file's events span {span})",
                f"byte offset {RECORD_BYTES * i}",
                remedy=Remedy(f"sensor_size=({span.replace('x', ', ')})", f"--sensor-size {span}"),
                note=" or the camera's size",
            )
        yield decoded(raw)
        if cut is not None:
            raise cut

    return Source(path, "nmnist", size, chunks)
