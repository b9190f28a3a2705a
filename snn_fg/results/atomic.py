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

from .marks import MARK
from .outputs import (
    BATCH_OR_RUN,
    WORKING_PREFIX,
    FolderKind,
    check_output_folder,
    check_writable,
    writing,
)


@contextlib.contextmanager
def atomic_path(path, suffix: str | None = None):
    """Yield a temporary path next to ``path``; move it onto ``path`` on success.

    On any exception (including KeyboardInterrupt) the temporary file and
    the folders made for it are removed and ``path`` is left untouched; a place that cannot be written
    raises :class:`~snn_fg.errors.InputError` naming ``path``.
    """
    path = Path(path)
    suffix = path.suffix if suffix is None else suffix
    made = []
    try:
        with writing(path):  # (an unwritable place: one line naming it)
            made = _make_parents(path)
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".part{suffix}", dir=path.parent)
    except BaseException:
        _remove_empty(made)
        raise
    os.close(fd)
    os.chmod(tmp, 0o666 & ~_umask())  # (mkstemp creates 0600: give what a plain open() would)
    try:
        yield Path(tmp)
        with writing(path):
            os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        _remove_empty(made)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _write_npy(fh, value):
    np.lib.format.write_array(fh, np.asanyarray(value), allow_pickle=False)


def save_npz(path, **arrays) -> Path:
    """Write an uncompressed ``.npz`` atomically and return its path; it carries the member
    ``written_by`` (:data:`~snn_fg.results.marks.MARK`), so that ``--force`` knows it for ours."""
    path = Path(path)
    with atomic_path(path, suffix=".npz") as tmp:
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
            for name, value in {**arrays, "written_by": np.array(MARK)}.items():
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
    """Save a matplotlib figure atomically (format from ``path``'s suffix); a PNG's ``Software``
    text is :data:`~snn_fg.results.marks.MARK`, so that ``--force`` knows it for ours."""
    path = Path(path)
    kind = path.suffix.lstrip(".").lower() or "png"
    if kind == "png":
        kwargs["metadata"] = {**kwargs.get("metadata", {}), "Software": MARK}
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=kind, **kwargs)
    return path


class OutputFolder:
    """A run's output folder, written whole on success.

    The folder must be new, empty, or hold an earlier output of ``kind``
    and nothing else, which is replaced only with ``force``
    (:func:`~snn_fg.results.outputs.check_output_folder`: a folder holding
    anything else is refused, nothing deleted). ``cancelled`` (a callable)
    is asked once more before committing: a run that was cancelled (an
    interrupt swallowed by a library) leaves nothing. Use as a context
    manager; write into :attr:`dir` inside the block.

    A new folder is written beside its destination and renamed into place;
    an existing one (which may be a mount point or the current folder,
    neither of which can be renamed) is written inside it and its entries
    exchanged on success, the earlier ones first set aside and then
    removed. An error, Ctrl-C or SIGTERM leaves the destination as it was.
    """

    def __init__(self, path, force: bool = False, cancelled=None, kind: FolderKind = BATCH_OR_RUN):
        self.path = Path(path)
        self.cancelled = cancelled or (lambda: False)
        self.kind = kind
        check_output_folder(self.path, kind, force)
        check_writable(self.path)
        self.dir: Path | None = None
        self._made: list[Path] = []

    def __enter__(self) -> OutputFolder:
        with writing(self.path):
            if self.path.is_dir():
                self.dir = Path(tempfile.mkdtemp(prefix=WORKING_PREFIX, suffix=".staging", dir=self.path))
                return self
            self._made = _make_parents(self.path)
            self.dir = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.", suffix=".staging", dir=self.path.parent))
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None and self.cancelled():
            self._clean()
            raise KeyboardInterrupt("cancelled")
        if exc_type is not None:
            self._clean()
            return False
        try:
            with writing(self.path):
                self._commit()
        except BaseException:
            self._clean()
            raise
        return False

    def _commit(self) -> None:
        os.chmod(self.dir, 0o777 & ~_umask())
        if self.dir.parent == self.path:
            exchange_entries(self.dir, self.path, kept=self.kind.keeps)
        else:
            os.replace(self.dir, self.path)

    def _clean(self) -> None:
        shutil.rmtree(self.dir, ignore_errors=True)
        _remove_empty(self._made)


def _make_parents(path: Path) -> list[Path]:
    """Make the missing folders above ``path``; the ones made, outermost first."""
    missing = []
    parent = path.parent
    while not parent.exists():
        missing.append(parent)
        parent = parent.parent
    made = []
    try:
        for p in reversed(missing):
            p.mkdir()
            made.append(p)
    except BaseException:
        _remove_empty(made)
        raise
    return made


def _remove_empty(made: list[Path]) -> None:
    """Remove the folders :func:`_make_parents` made, innermost first, as far as they are empty."""
    for p in reversed(made):
        with contextlib.suppress(OSError):
            p.rmdir()


def _entries(folder: Path, kept=None) -> list[Path]:
    """``folder``'s entries but snn-fg's own working folders in it and those ``kept(entry)`` keeps."""
    return [p for p in folder.iterdir() if not (p.name.startswith(WORKING_PREFIX) or (kept and kept(p)))]


def set_aside(folder: Path, kept=None) -> Path:
    """Move ``folder``'s entries (but those ``kept(entry)`` keeps where they are) into a hidden folder
    inside it, and return that folder (:func:`put_back` undoes it, :func:`shutil.rmtree` of it drops them)."""
    aside = Path(tempfile.mkdtemp(prefix=WORKING_PREFIX, suffix=".previous", dir=folder))
    moved = []
    try:
        for p in _entries(folder, kept):
            os.replace(p, aside / p.name)
            moved.append(p.name)
    except BaseException:
        for name in moved:
            os.replace(aside / name, folder / name)
        aside.rmdir()
        raise
    return aside


def put_back(aside: Path, folder: Path, kept=None) -> None:
    """Remove what ``folder`` holds now (but what ``kept(entry)`` keeps) and move back the entries
    :func:`set_aside` put in ``aside``."""
    for p in _entries(folder, kept):
        shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink()
    for p in list(aside.iterdir()):
        os.replace(p, folder / p.name)
    aside.rmdir()


def exchange_entries(staging: Path, folder: Path, kept=None) -> None:
    """Replace ``folder``'s entries (but those ``kept(entry)`` keeps where they are) by those of
    ``staging`` (a folder inside it), which is removed: the earlier entries are set aside first, and
    put back if a move fails."""
    aside = set_aside(folder, kept)
    moved = []
    try:
        for p in list(staging.iterdir()):
            os.replace(p, folder / p.name)
            moved.append(p.name)
    except BaseException:
        for name in moved:
            os.replace(folder / name, staging / name)
        put_back(aside, folder, kept)
        raise
    staging.rmdir()
    shutil.rmtree(aside, ignore_errors=True)


def growing_folder(path, force: bool = False, resume: bool | None = False) -> tuple[Path, Path | None]:
    """A recording's output folder, written in place as windows complete
    (:mod:`snn_fg.results.store`): made when new; an earlier run in it is refused,
    set aside to be replaced (``force``) or continued (``resume``; None: a run that
    cannot continue one, whose refusal offers ``--force`` only); a folder that
    holds anything else is refused (:func:`~snn_fg.results.outputs.check_output_folder`).

    Returns ``(folder, previous)``: ``previous``, for a folder that existed and is
    not continued, is where its entries (an earlier run, or none) wait in a hidden
    folder inside it (:func:`set_aside`) until the new run has a window to show;
    give it to :func:`settle_folder`, which drops them or puts them back.
    """
    path = Path(path)
    earlier = check_output_folder(path, BATCH_OR_RUN, force, resume=resume)
    check_writable(path)
    with writing(path):
        previous = set_aside(path) if path.is_dir() and not (earlier and resume) else None
        path.mkdir(parents=True, exist_ok=True)
    return path, previous


def settle_folder(path, previous: Path | None, keep_new: bool) -> None:
    """After a recording's run into :func:`growing_folder` ``path``: keep what it
    wrote (``keep_new``) and drop what was set aside, if anything; or remove what it
    wrote and put back what was set aside (a folder the run made is removed)."""
    path = Path(path)
    if keep_new:
        if previous is not None:
            shutil.rmtree(previous, ignore_errors=True)
    elif previous is not None:
        put_back(previous, path)
    else:
        shutil.rmtree(path, ignore_errors=True)
