"""Atomic file writes: a result file is either complete or absent.

Data is written to a temporary file in the destination folder and moved into
place with :func:`os.replace` (atomic on POSIX and Windows), so a crash or
Ctrl-C never leaves a half-written output behind.
"""
from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@contextlib.contextmanager
def atomic_path(path, suffix: str | None = None):
    """Yield a temporary path next to ``path``; move it onto ``path`` on success.

    On any exception (including KeyboardInterrupt) the temporary file is
    removed and ``path`` is left untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    suffix = path.suffix if suffix is None else suffix
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".part{suffix}", dir=path.parent)
    os.close(fd)
    # mkstemp creates 0600; give the result the permissions a plain open() would.
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


@dataclass(frozen=True)
class RawArrayFile:
    """An array stored as raw C-order bytes in a file (no header), for
    :func:`save_npz` to copy into the archive without loading or mapping it."""

    path: Path
    dtype: np.dtype
    shape: tuple


def _write_npy(fh, value):
    if isinstance(value, RawArrayFile):
        header = {"descr": np.lib.format.dtype_to_descr(np.dtype(value.dtype)), "fortran_order": False,
                  "shape": tuple(value.shape)}
        np.lib.format.write_array_header_2_0(fh, header)
        with open(value.path, "rb") as src:
            shutil.copyfileobj(src, fh, 1 << 20)
    else:
        np.lib.format.write_array(fh, np.asanyarray(value), allow_pickle=False)


def save_npz(path, **arrays) -> Path:
    """Write an uncompressed ``.npz`` atomically and return its path.

    Values are arrays or :class:`RawArrayFile` (streamed from disk in 1 MB
    blocks, so writing a recording's maps needs no memory for them).
    """
    path = Path(path)
    with atomic_path(path, suffix=".npz") as tmp:
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
            for name, value in arrays.items():
                with zf.open(f"{name}.npy", "w", force_zip64=True) as fh:
                    _write_npy(fh, value)
    return path


def save_text(path, text: str) -> Path:
    """Write a text file atomically."""
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return path


def save_figure(fig, path, **kwargs) -> Path:
    """Save a matplotlib figure atomically (format from ``path``'s suffix)."""
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=path.suffix.lstrip(".") or "png", **kwargs)
    return path
