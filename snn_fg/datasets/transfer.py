"""Downloads and checksums: a fetched file is complete and verified, or absent.

:func:`download` streams a URL into a temporary file beside the destination,
hashing as it goes, and moves it into place only when every byte arrived and
the SHA-256 matches; a checksum mismatch, a dropped connection or Ctrl-C
leaves nothing behind (:func:`snn_fg.results.atomic.atomic_path`) and raises
:class:`DatasetError` with one line naming the URL and what went wrong.
"""

from __future__ import annotations

import hashlib
import http.client
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np

from snn_fg.errors import SnnFgError
from snn_fg.results.atomic import atomic_path
from snn_fg.results.progress import bar

#: bytes read per step of a download or a checksum
CHUNK_BYTES = 1 << 20
#: seconds a stalled connection may stay silent before the download fails
TIMEOUT_S = 60.0


class DatasetError(SnnFgError):
    """A dataset is absent, cannot be fetched, or a download failed; one line."""


def file_sha256(path) -> str:
    """SHA-256 of a file's bytes, hex."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while chunk := fh.read(CHUNK_BYTES):
            h.update(chunk)
    return h.hexdigest()


def arrays_sha256(arrays) -> str:
    """SHA-256 of named arrays: each name, dtype, shape and C-order bytes, by name.

    It identifies an ``.npz``'s content whatever the zip container around it
    (compression, timestamps), so a converted file can be checked against the
    reference copy it must equal.
    """
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}\0{a.dtype.str}\0{a.shape}\0".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def npz_sha256(path) -> str:
    """:func:`arrays_sha256` of the arrays stored in an ``.npz`` file."""
    with np.load(path, allow_pickle=False) as z:
        return arrays_sha256({k: z[k] for k in z.files})


def _progress(total, label, show):
    return bar(label, "B", total, disable=not show, unit_scale=True, unit_divisor=1024)


def _why(exc) -> str:
    if isinstance(exc, urllib.error.URLError) and not isinstance(exc, urllib.error.HTTPError):
        return str(exc.reason)
    return str(exc) or type(exc).__name__


def _stream(url: str, out: Path, *, label: str, progress: bool) -> str:
    """Copy ``url`` into ``out``; return the SHA-256 of what arrived."""
    h, done, total = hashlib.sha256(), 0, None
    try:
        with urllib.request.urlopen(url, timeout=TIMEOUT_S) as resp, open(out, "wb") as fh:
            total = resp.length
            with _progress(total, label, progress) as bar:
                while chunk := resp.read(CHUNK_BYTES):
                    fh.write(chunk)
                    h.update(chunk)
                    done += len(chunk)
                    bar.update(len(chunk))
    except urllib.error.HTTPError as exc:
        raise DatasetError(f"{url}: HTTP {exc.code} {exc.reason}; nothing was written") from None
    except (OSError, http.client.HTTPException) as exc:
        raise DatasetError(
            f"{url}: download failed after {done:,}{f' of {total:,}' if total else ''} bytes "
            f"({_why(exc)}); nothing was written"
        ) from None
    if total is not None and done != total:
        raise DatasetError(f"{url}: the connection closed after {done:,} of {total:,} bytes; nothing was written")
    return h.hexdigest()


def download(url: str, dest, *, sha256: str | None, progress: bool = True) -> Path:
    """Download ``url`` to ``dest`` atomically and return ``dest``.

    ``sha256``: the expected SHA-256 of the file's bytes; ``None`` only for an
    intermediate download whose product is checked instead (a converted file).
    """
    dest = Path(dest)
    with atomic_path(dest) as tmp:
        got = _stream(url, tmp, label=dest.name, progress=progress)
        if sha256 is not None and got != sha256:
            raise DatasetError(
                f"{url}: checksum mismatch (sha256 {got[:16]}..., expected {sha256[:16]}...); nothing was written"
            )
    return dest
