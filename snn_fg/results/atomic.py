"""Atomic writes: a result file, or a whole output folder, is either complete or absent.

Data is written to a temporary file in the destination folder and moved into
place with :func:`os.replace` (atomic on POSIX and Windows), so a crash or
Ctrl-C never leaves a half-written output behind. :class:`OutputFolder` does
the same for a folder: files are written into a staging folder beside the
destination, which replaces the destination as a whole only when the run
succeeds; an error, Ctrl-C or SIGTERM leaves the destination exactly as it was.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from ..errors import InputError


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
    os.chmod(tmp, 0o666 & ~_umask())  # (mkstemp creates 0600: give what a plain open() would)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _write_npy(fh, value):
    np.lib.format.write_array(fh, np.asanyarray(value), allow_pickle=False)


def save_npz(path, **arrays) -> Path:
    """Write an uncompressed ``.npz`` atomically and return its path."""
    path = Path(path)
    with atomic_path(path, suffix=".npz") as tmp:
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
            for name, value in arrays.items():
                with zf.open(f"{name}.npy", "w", force_zip64=True) as fh:
                    _write_npy(fh, value)
    return path


def write_bytes(path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically, into a folder that exists: the
    :func:`atomic_path` promise in fewer system calls, for files written
    many times a second (a recording's store writes about 20 a window)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            os.fchmod(fd, 0o666 & ~_umask())
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


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


class OutputFolder:
    """A run's output folder, replaced as a whole on success.

    ``force=False`` refuses a destination that exists and is not empty (so an
    earlier run is never mixed with this one); ``force=True`` replaces it.
    ``cancelled`` (a callable) is asked once more before committing: a run
    that was cancelled (an interrupt swallowed by a library) leaves nothing.
    Use as a context manager; write into :attr:`dir` inside the block.
    """

    def __init__(self, path, force: bool = False, cancelled=None):
        self.path = Path(path)
        self.cancelled = cancelled or (lambda: False)
        if self.path.exists() and not self.path.is_dir():
            raise InputError(self.path, "--out must be a folder, but a file of that name exists")
        if self.path.is_dir() and any(self.path.iterdir()) and not force:
            held = ", ".join(sorted(p.name for p in self.path.iterdir())[:4])
            raise InputError(
                self.path,
                f"output folder is not empty (holds {held}...); choose another folder or pass --force to replace it",
            )
        self.dir: Path | None = None
        self._made: list[Path] = []

    def __enter__(self) -> OutputFolder:
        parent = self.path.parent
        missing = []
        while not parent.exists():
            missing.append(parent)
            parent = parent.parent
        for p in reversed(missing):
            p.mkdir()
            self._made.append(p)
        self.dir = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.", suffix=".staging", dir=self.path.parent))
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None and self.cancelled():
            exc_type = KeyboardInterrupt
        if exc_type is not None:
            shutil.rmtree(self.dir, ignore_errors=True)
            for p in reversed(self._made):
                with contextlib.suppress(OSError):
                    p.rmdir()
            if exc is None:
                raise KeyboardInterrupt("cancelled")
            return False
        os.chmod(self.dir, 0o777 & ~_umask())
        if self.path.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.", suffix=".old", dir=self.path.parent))
            os.replace(self.path, old / "previous")
            os.replace(self.dir, self.path)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(self.dir, self.path)
        return False


def growing_folder(path, force: bool = False, resume: bool = False) -> tuple[Path, Path | None]:
    """A recording's output folder, written in place as windows complete
    (:mod:`snn_fg.results.store`): made when new; an earlier run in it is refused,
    set aside to be replaced (``force``) or continued (``resume``).

    Returns ``(folder, previous)``: ``previous`` is where a replaced run waits
    (a hidden sibling) until the new one has a window to show; give it to
    :func:`settle_folder`, which drops it or puts it back.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputError(path, "--out must be a folder, but a file of that name exists")
    previous = None
    if path.is_dir() and any(path.iterdir()) and not resume:
        if not force:
            held = ", ".join(sorted(p.name for p in path.iterdir())[:4])
            raise InputError(
                path,
                f"output folder is not empty (holds {held}...); choose another folder, pass "
                "--resume to continue its run or --force to replace it",
            )
        previous = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".previous", dir=path.parent))
        os.replace(path, previous / "run")
    path.mkdir(parents=True, exist_ok=True)
    return path, previous


def settle_folder(path, previous: Path | None, keep_new: bool) -> None:
    """After a recording's run into :func:`growing_folder` ``path``: keep what it
    wrote (``keep_new``) and drop the run it replaced, if any; or remove what it
    wrote and put the replaced run back where it was."""
    if not keep_new:
        shutil.rmtree(path, ignore_errors=True)
        if previous is not None:
            os.replace(previous / "run", path)
    if previous is not None:
        shutil.rmtree(previous, ignore_errors=True)
