"""What a command may write over: the rule ``--force`` follows, and the check that a destination can be written.

A command writes its output folder whole (:class:`~snn_fg.results.atomic.OutputFolder`). A folder that
exists is written into only when it is empty or holds an earlier output of the same kind and nothing
else; ``--force`` is what allows the second. A folder that holds anything else (a user's recording,
another program's files) is refused in one line, whatever the options, and nothing in it is touched:
snn-fg never deletes a file it did not write. Each kind of output (:class:`FolderKind`) lists the
names its command writes; :data:`RUN_FOLDER` is ``snn-fg run``'s, :data:`DECODE_FOLDER` ``snn-fg decode``'s.

A single file (:func:`check_output_file`) follows the same rule: ``--force`` replaces only a file of
the kind being written (its suffix and, where cheap, its first bytes), never a user's other file.

:func:`check_writable` tries the destination before the work starts, so that an unwritable one
(read-only file system, no permission, a full disk) ends in one line naming it, not in a traceback
after the work.
"""

from __future__ import annotations

import contextlib
import errno
import fnmatch
import json
import os
import re
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError
from .marks import MARK, MARKED, json_keys, of_kind, signed

#: the prefix of what snn-fg makes inside an output folder while it writes it (a staging folder, the
#: earlier output set aside); a run killed outright may leave one behind, which the next run removes
WORKING_PREFIX = ".snn-fg."


@dataclass(frozen=True)
class FolderKind:
    """The entries an output folder of one kind holds.

    ``what`` names it in messages ("an snn-fg run"); ``names`` are the
    patterns (:mod:`fnmatch`) of every entry its command and the programs
    that run in it write; ``marks``: one of these names is in every earlier
    output (a folder holding only a figure is not a run); ``owns``: further
    entries recognised by their content (a file whose name the user chose); ``kept``: the names of
    what the output's own instructions tell the user to make in it (a Lava export's environment), which
    a later output of the kind leaves where it is: never refused, never replaced, never deleted.
    """

    what: str
    names: tuple[str, ...]
    marks: tuple[str, ...]
    owns: Callable[[Path], bool] | None = None
    kept: tuple[str, ...] = ()
    #: whether an entry with one of ``names`` holds what this output writes there, as far as its
    #: content tells (None: its name is enough); a user's file of that name is then not replaced
    made: Callable[[Path], bool] | None = None

    def keeps(self, entry: Path) -> bool:
        """Whether ``entry`` is one of :attr:`kept`: left where it is when the folder is written again."""
        return entry.name in self.kept

    def written(self, entry: Path) -> bool:
        """Whether ``entry`` is one this kind of output writes."""
        name = entry.name
        if name.startswith(WORKING_PREFIX):
            return True
        if any(fnmatch.fnmatchcase(name, p) for p in self.names) and (self.made is None or self.made(entry)):
            return True
        return self.owns is not None and self.owns(entry)  # (a batch's recording folder may bear a run's name)


#: a per-window figure's file name (``snn-fg plot --windows``: into ``windows/`` or a folder of the user's naming)
WINDOW_FIGURE = "window_{:04d}.png"


def _window_figures(entry: Path) -> bool:
    """Whether ``entry`` is a folder of ``snn-fg plot --windows`` figures and nothing else."""
    if not entry.is_dir() or entry.is_symlink():
        return False
    names = [p.name for p in entry.iterdir()]
    return bool(names) and all(re.fullmatch(r"window_[0-9]{4,}\.png", n) for n in names)  # (window 10000 on: 5 digits)


#: a batch's table beside its runs (``snn-fg run FOLDER|GLOB|LIST``: :mod:`snn_fg.cli.batch`), told by its header
SUMMARY_NAME = "summary.csv"
SUMMARY_COLUMNS = ("recording", "output", "status", "windows", "seconds", "error")


def is_batch_summary(entry: Path) -> bool:
    """Whether ``entry`` is a batch's ``summary.csv``, told by its header."""
    if entry.name != SUMMARY_NAME or not entry.is_file() or entry.is_symlink():
        return False
    with open(entry, encoding="utf-8", errors="replace") as fh:
        return fh.readline().strip() == ",".join(SUMMARY_COLUMNS)


def _batch_part(entry: Path) -> bool:
    """Whether ``entry`` is part of an earlier batch: its ``summary.csv`` (:func:`is_batch_summary`), or one
    recording's run folder in it (holding a run's maps, and only what a run writes)."""
    if entry.name == SUMMARY_NAME:
        return is_batch_summary(entry)
    if not entry.is_dir() or entry.is_symlink():
        return False
    inside = list(entry.iterdir())
    return any(p.name in RUN_FOLDER.marks for p in inside) and all(RUN_FOLDER.written(p) for p in inside)


def _zarr_store(entry: Path) -> bool:
    """Whether ``entry`` is a maps store snn-fg wrote: its attributes say so (``snn_fg``'s
    ``format``, :data:`MARK` ...), and it holds a store's entries only (its group and
    attributes, arrays, and the parts an interrupted write left)."""
    if not entry.is_dir() or entry.is_symlink():
        return False
    if not (entry / ".zattrs").exists():  # (killed between making the folder and writing its attributes)
        return _left_by_a_write(entry)
    try:
        attrs = json.loads((entry / ".zattrs").read_text())
    except (OSError, ValueError):
        return False
    ours = isinstance(attrs, dict) and str((attrs.get("snn_fg") or {}).get("format", "")).startswith(MARK)
    return ours and all(
        p.name in (".zgroup", ".zattrs")
        or _part(p)
        or (p.is_dir() and not p.is_symlink() and ((p / ".zarray").is_file() or _left_by_a_write(p)))
        for p in entry.iterdir()
    )


def _part(p: Path) -> bool:
    """A file an interrupted write left (``.NAME.XXXX.part``, :func:`~snn_fg.results.atomic.write_bytes`)."""
    return p.name.startswith(".") and p.name.endswith(".part") and p.is_file()


def _left_by_a_write(folder: Path) -> bool:
    """A folder a write was killed in before it wrote anything of its own: empty, or parts only."""
    return not folder.is_symlink() and all(_part(p) for p in folder.iterdir())


#: the first line of a recording's ``windows.csv`` (:data:`snn_fg.results.timeline.COLUMNS`) starts so
WINDOWS_TABLE_HEAD = "window,t_start_ms,t_end_ms,"


#: the keys of a live run's record (``live.json``) that tell one written before it carried its mark
LIVE_RECORD_KEYS = ("windows", "latency_ms", "ended")


def _run_entry(entry: Path) -> bool:
    """Whether an entry named as a run's is what a run writes there: a maps store by
    :func:`_zarr_store`, window figures by :func:`_window_figures`, the table by its header, the
    other files by :func:`~.marks.of_kind` (a figure or ``maps.npz`` by its mark, ``live.json``
    by its record's, or its keys). Beside a run's own maps (its store, or a marked ``maps.npz``),
    an animation is told by its first bytes, and a figure that matplotlib drew is the run's: one
    snn-fg drew before figures carried a mark (30 Nov 2026); a user's photo of that name is not."""
    if entry.is_symlink():
        return False
    if entry.name == "maps.zarr":
        return _zarr_store(entry)
    if entry.name == "windows":
        return _window_figures(entry)
    if not entry.is_file():
        return False
    suffix = entry.suffix.lower()
    if entry.name == "windows.csv":
        with open(entry, encoding="utf-8", errors="replace") as fh:
            return fh.readline().startswith(WINDOWS_TABLE_HEAD)
    if of_kind(entry, suffix):
        return True
    if entry.name == "live.json":
        return json_keys(entry, LIVE_RECORD_KEYS)
    if suffix in (".png", ".gif", ".mp4") and _anchored(entry.parent):
        # (a PNG snn-fg drew before its mark says matplotlib drew it: a user's photo of the name does not)
        return signed(entry, suffix) and (suffix != ".png" or _drawn_by_matplotlib(entry))
    return False


def _drawn_by_matplotlib(path: Path) -> bool:
    """Whether a PNG's text says matplotlib wrote it (as every figure snn-fg drew before its own mark)."""
    try:
        with open(path, "rb") as fh:
            return b"Software\x00Matplotlib" in fh.read(8192)
    except OSError:
        return False


def _anchored(folder: Path) -> bool:
    """Whether ``folder`` holds a run's own maps: its store, or a marked ``maps.npz``."""
    npz = folder / "maps.npz"
    return _zarr_store(folder / "maps.zarr") or (npz.is_file() and of_kind(npz, ".npz"))


#: what ``snn-fg run``, ``snn-fg live`` and ``snn-fg decode`` write: maps (a frame's ``.npz``, a
#: recording's Zarr store), their figures, a recording's per-window table and animation, a live run's
#: record, the spiking model's figures, and a folder of window figures under another name
RUN_FOLDER = FolderKind(
    "an snn-fg run",
    names=(
        "maps.npz",
        "maps.zarr",
        "maps.png",
        "timeline.png",
        "windows.csv",
        "windows",
        "maps.gif",
        "maps.mp4",
        "live.json",
        "spike_raster.png",
        "rate_histograms.png",
    ),
    marks=("maps.npz", "maps.zarr"),
    owns=_window_figures,
    made=_run_entry,
)
#: an earlier batch of runs is an earlier run too: ``--force`` replaces it with a run, and a batch with
#: another (its summary.csv and its recordings' folders; ``marks``: the summary)
BATCH_OR_RUN = FolderKind(
    "an snn-fg run",
    names=RUN_FOLDER.names,
    marks=(*RUN_FOLDER.marks, SUMMARY_NAME),
    owns=lambda entry: _window_figures(entry) or _batch_part(entry),
    made=_run_entry,
)


#: what ``snn-fg decode --reference`` writes in ``OUT/reference/``: the reference backend's maps and figure
DECODE_REFERENCE = ("maps.npz", "maps.png")


def _decode_reference(entry: Path) -> bool:
    """Whether ``entry`` is the ``reference/`` an earlier ``snn-fg decode --reference`` wrote: told by its
    content (a user's own folder of that name holding anything else is not replaced)."""
    if entry.name != "reference" or not entry.is_dir() or entry.is_symlink():
        return False
    names = {p.name for p in entry.iterdir()}
    return "maps.npz" in names and names <= set(DECODE_REFERENCE)


#: what ``snn-fg decode`` writes: a run's maps and figure and, with ``--reference``, ``reference/``
#: (before, a decode folder holding reference/ was refused with --force as not snn-fg's)
DECODE_FOLDER = FolderKind(
    "an snn-fg decode",
    names=RUN_FOLDER.names,
    marks=RUN_FOLDER.marks,
    owns=lambda entry: _window_figures(entry) or _decode_reference(entry),
    made=_run_entry,
)


def _listed(entries, n: int = 4) -> str:
    names = sorted(p.name for p in entries)
    return ", ".join(names[:n]) + (", ..." if len(names) > n else "")


#: said of a refused entry that bears an output's name: it is told by its content
_NAMED_LIKE = (
    " (an entry of an output's name is told by its content; maps snn-fg wrote before 30 Nov 2026 carry no mark:"
    " remove such an entry by hand if it is one)"
)


def check_output_folder(path, kind: FolderKind = RUN_FOLDER, force: bool = False, resume: bool | None = None) -> bool:
    """Whether the output folder ``path`` may be written, by :class:`FolderKind` ``kind``'s rule: it
    does not exist, is empty, or holds an earlier output of ``kind`` and nothing else, which only
    ``force`` (replace it) or ``resume`` (continue it; None: the output cannot be continued) allows.
    Returns whether it holds such an earlier output; raises :class:`~snn_fg.errors.InputError` (one
    line, nothing touched) otherwise."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputError(path, "--out must be a folder, but a file of that name exists")
    if not path.is_dir():
        return False
    here = Path.cwd().resolve()
    if path.resolve() != here and path.resolve() in here.parents:
        raise InputError(path, "holds the current folder: choose an output folder outside it")
    entries = [p for p in path.iterdir() if not (p.name.startswith(WORKING_PREFIX) or kind.keeps(p))]
    if not entries:
        return False
    foreign = [p for p in entries if not kind.written(p)]
    if foreign or not any((path / m).exists() for m in kind.marks):
        shown = foreign or entries
        raise InputError(
            path,
            f"holds {_listed(shown)}, which snn-fg did not write"
            + (
                f": --force replaces only a folder holding {kind.what} and nothing else; nothing was deleted"
                if force
                else ""
            )
            + "; choose another output folder"
            + (_NAMED_LIKE if any(fnmatch.fnmatchcase(e.name, n) for e in foreign for n in kind.names) else ""),
        )
    # (an earlier batch: a summary and a run per recording, no run's maps of its own; replaced, never continued)
    batch = kind is BATCH_OR_RUN and not any((path / m).exists() for m in RUN_FOLDER.marks)
    if resume and not force and batch:
        raise InputError(
            path,
            f"holds an earlier batch of runs ({SUMMARY_NAME} and a folder per recording), not one run to continue: "
            "the batch's own command goes on with it, and --force replaces it",
        )
    if not (force or resume):
        how = (
            "pass --force to replace it"
            if resume is None or batch
            else "pass --resume to continue it or --force to replace it"
        )
        what = "an earlier batch of runs" if batch else f"{kind.what} already"
        raise InputError(path, f"holds {what} ({_listed(entries)}); choose another output folder or {how}")
    return True


def check_output_file(out, force: bool, flag: str = "--out", suffixes: tuple[str, ...] = ()) -> Path:
    """A file a command writes (``flag`` names it; ``suffixes``: the names it may have, the first
    the one it is usually given), by the folders' rule: not a folder; a name with another suffix is
    refused (one line saying which); an existing file is replaced only with ``force`` and only when
    snn-fg wrote it, as far as its format tells (:func:`~.marks.of_kind`: a figure, an ``.npz`` or a JSON
    record by the mark it carries, so a user's photo, recording or settings of that name are never
    replaced; the other formats by their first bytes and suffix); and in a place that can be
    written. Checked before the work starts; nothing is touched when refused. Returns it as a Path."""
    out = Path(out)
    if out.is_dir():
        raise InputError(out, f"{flag} names a file to write, but a folder of that name exists")
    suffix = out.suffix.lower()
    if suffixes and suffix not in suffixes:
        ending = suffixes[0] if len(suffixes) == 1 else f"{', '.join(suffixes[:-1])} or {suffixes[-1]}"
        raise InputError(out, f"{flag} writes {' or '.join(suffixes)}: give a file name ending {ending}")
    if out.exists() or out.is_symlink():
        ours = not out.is_symlink() and out.is_file() and of_kind(out, suffix)
        if not force and ours:
            raise InputError(out, "exists; pass --force to replace it")
        if not ours:  # (told before --force too: its hint led a user's photo to a second refusal)
            marked = (
                f" (snn-fg marks each {suffix} file it writes, and this one has no mark; one it wrote before"
                " 30 Nov 2026 has none either: remove it by hand if it is one)"
                if suffix in MARKED
                else ""
            )
            raise InputError(
                out,
                f"is not a {suffix or 'such'} file snn-fg wrote: --force replaces only an earlier output of the "
                f"kind being written; nothing was changed; choose another file name{marked}",
            )
    check_writable(out)
    return out


#: what a failed write's error number means, in the line that names the path
_WHY = {
    errno.EROFS: "read-only file system",
    errno.EACCES: "permission denied",
    errno.EPERM: "permission denied",
    errno.ENOSPC: "no space left on the device",
    errno.EDQUOT: "disk quota exceeded",
    errno.ENOTDIR: "a file stands where a folder must be",
}


def cannot_write(path, exc: OSError) -> InputError:
    """The one-line error of a write to ``path`` that failed with ``exc``."""
    why = _WHY.get(exc.errno, exc.strerror or type(exc).__name__)
    return InputError(path, f"cannot write here ({why})")


@contextlib.contextmanager
def writing(path):
    """Turn an :class:`OSError` raised while the block writes ``path`` into the one line of :func:`cannot_write`."""
    try:
        yield
    except OSError as exc:
        raise cannot_write(path, exc) from None


def check_writable(path) -> None:
    """Raise the one line of :func:`cannot_write` unless ``path`` (a file or folder to write) can be
    made: a file is created and removed in the nearest folder of ``path`` that exists (a real write:
    a read-only file system, permissions and a full disk all show)."""
    path = Path(path)
    place = path if path.is_dir() else path.parent
    while not place.exists():
        place = place.parent
    with writing(path):
        if not place.is_dir():
            raise NotADirectoryError(errno.ENOTDIR, "not a directory", str(place))
        fd, probe = tempfile.mkstemp(prefix=WORKING_PREFIX, suffix=".probe", dir=place)
        os.close(fd)
        os.unlink(probe)
