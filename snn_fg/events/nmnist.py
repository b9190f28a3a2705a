"""N-MNIST / N-Caltech101 binary files (``.bin``): 5-byte records, decoded by tonic.

A record is x, y, ``p << 7 | t[22:16]``, ``t[15:8]``, ``t[7:0]``; a record
with y = 240 marks a timer overflow.  Coordinates are checked here so that
bad records are reported with their byte offset.
"""

from __future__ import annotations

import numpy as np

from snn_fg.errors import InputError
from snn_fg.events._core import EVENT_DTYPE, check_sensor_size
from snn_fg.events.source import Source

SENSOR_SIZE = (34, 34)
RECORD_BYTES = 5
_OVERFLOW_Y = 240


def open_nmnist(path, sensor_size, chunk_events) -> Source:
    """Open an N-MNIST / N-Caltech101 ``.bin`` file (read whole by tonic)."""
    from tonic.io import read_mnist_file  # (tonic takes over a second to import: only for a .bin file)

    nbytes = path.stat().st_size
    if nbytes % RECORD_BYTES:
        whole = nbytes - nbytes % RECORD_BYTES
        raise InputError(
            path,
            f"N-MNIST files hold {RECORD_BYTES}-byte events; {nbytes} bytes leaves {nbytes - whole} trailing",
            f"byte offset {whole}",
        )
    size = check_sensor_size(sensor_size or SENSOR_SIZE, path)

    def chunks(n, tally):
        raw = np.fromfile(path, dtype=np.uint8).reshape(-1, RECORD_BYTES)
        bad = (raw[:, 1] != _OVERFLOW_Y) & ((raw[:, 0] >= size[0]) | (raw[:, 1] >= size[1]))
        if bad.any():
            i = int(np.argmax(bad))
            ev = raw[raw[:, 1] != _OVERFLOW_Y]
            span = f"{int(ev[:, 0].max()) + 1}x{int(ev[:, 1].max()) + 1}"
            raise InputError(
                path,
                f"event at (x={int(raw[i, 0])}, y={int(raw[i, 1])}) lies outside the {size[0]} x {size[1]} sensor "
                f"(the file's events span {span}: --sensor-size {span} or the camera's size)",
                f"byte offset {RECORD_BYTES * i}",
            )
        yield read_mnist_file(str(path), dtype=EVENT_DTYPE)

    return Source(path, "nmnist", size, chunks)
