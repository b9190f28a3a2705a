"""Event arrays saved by numpy: ``.npy`` (streamed) and ``.npz`` (read whole)."""

from __future__ import annotations

import numpy as np

from snn_fg.errors import InputError, SnnFgError
from snn_fg.events.core import as_events, check_sensor_size, file_sensor_size, infer_sensor_size
from snn_fg.events.source import Source


def _load_npy(path, mmap=True):
    try:
        arr = np.load(path, mmap_mode="r" if mmap else None, allow_pickle=False)
    except Exception as exc:  # numpy's header parser can raise ValueError, SyntaxError, TokenError...
        raise InputError(path, f"not a readable .npy array ({type(exc).__name__}: {exc})") from None
    return arr


def open_npy(path, sensor_size, chunk_events) -> Source:
    """Open a ``.npy`` structured array; a plain file is read one memory-mapped chunk at a time."""
    arr = _load_npy(path)
    if arr.dtype.names is None or arr.ndim != 1:
        raise InputError(
            path,
            f".npy must hold a 1-D structured array with fields x, y, t, p "
            f"(found dtype {arr.dtype}, shape {arr.shape})",
        )
    as_events(arr[:0], path)  # field check

    total, dtype, base = len(arr), arr.dtype, int(getattr(arr, "offset", 0))
    if not isinstance(arr, np.memmap) or not (arr.flags.c_contiguous or arr.flags.f_contiguous):

        def slices(n, tally=None):
            for i in range(0, total, n):
                yield as_events(np.asarray(arr[i : i + n]), path, offset=i)
    else:

        def slices(n, tally=None):
            # one short-lived mapping per chunk, copied and unmapped, so resident
            # memory stays at one chunk however large the file is
            for i in range(0, total, n):
                m = min(n, total - i)
                view = np.memmap(path, dtype=dtype, mode="r", offset=base + i * dtype.itemsize, shape=(m,))
                chunk = np.array(view)
                del view
                yield as_events(chunk, path, offset=i)

    size = (
        check_sensor_size(sensor_size, path)
        if sensor_size is not None
        else infer_sensor_size(path, slices(chunk_events))
    )
    return Source(path, "npy", size, slices)


def open_npz(path, sensor_size, chunk_events) -> Source:
    """Open an ``.npz``: an ``events`` array or x, y, t, p arrays, and an optional ``sensor_size``."""
    try:
        with np.load(path, allow_pickle=False) as z:
            keys = list(z.files)
            if "events" in keys:
                arr = z["events"]
            elif all(k in keys for k in "xytp"):
                cols = {k: z[k] for k in "xytp"}
                n = len(cols["t"])
                if any(c.ndim != 1 or len(c) != n for c in cols.values()):
                    raise InputError(path, "arrays x, y, t, p in the .npz must be 1-D and of equal length")
                arr = np.empty(n, dtype=[(k, cols[k].dtype) for k in "xytp"])
                for k in "xytp":
                    arr[k] = cols[k]
            else:
                structured = [k for k in keys if z[k].dtype.names]
                if "pos" in keys or "neg" in keys:
                    raise InputError(
                        path, "holds an event frame (pos, neg), not a recording's events: snn-fg run takes it as it is"
                    )
                if len(structured) != 1:
                    raise InputError(
                        path,
                        f".npz needs an 'events' structured array or x, y, t, p arrays "
                        f"(found keys {', '.join(keys) or 'none'})",
                    )
                arr = z[structured[0]]
            file_size = tuple(int(v) for v in z["sensor_size"]) if "sensor_size" in keys else None
    except SnnFgError:
        raise
    except Exception as exc:  # zip, zlib and numpy header errors of every kind
        raise InputError(path, f"not a readable .npz archive ({type(exc).__name__}: {exc})") from None
    ev = as_events(arr, path)
    stated = file_size is not None or sensor_size is not None
    size = file_sensor_size(path, sensor_size, file_size) if stated else infer_sensor_size(path, [ev])
    return Source(path, "npz", size, lambda n, tally: iter([ev]))
