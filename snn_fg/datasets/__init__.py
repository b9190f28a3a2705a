"""The datasets snn-fg is checked on: where they live, what they are, how to get them.

Each dataset is a folder under one data folder, chosen in this order:

1. ``$SNN_FG_DATA``, when set;
2. ``../shared/data`` beside a source checkout of snn-fg, when it exists: the
   read-only reference copy this project's developers keep next to the
   repository, so that tests, experiments and the notebook find it with no
   setting (an installed package has no such sibling);
3. the user data folder: ``$XDG_DATA_HOME/snn-fg`` (``~/.local/share/snn-fg``),
   ``~/Library/Application Support/snn-fg`` on macOS,
   ``%LOCALAPPDATA%\\snn-fg`` on Windows.

:data:`DATASETS` describes each one (files, checksums, source, licence);
``snn-fg data list`` shows them and ``snn-fg data fetch NAME`` downloads one
from its public source, verified by checksum.

Examples
--------
>>> from snn_fg import datasets
>>> sorted(datasets.DATASETS)
['bsds-edfg', 'bsds-fg', 'davis', 'events']
>>> rec = datasets.find("events", "dvs.es")      # None when absent
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from snn_fg.datasets.catalogue import DATASETS, DataFile, Dataset
from snn_fg.datasets.transfer import DatasetError, file_sha256, npz_sha256

__all__ = [
    "DATASETS",
    "DataFile",
    "Dataset",
    "DatasetError",
    "ENV_VAR",
    "data_root",
    "fetch",
    "find",
    "get",
    "how_to_get",
    "missing",
    "require",
    "root_and_origin",
    "user_data_dir",
    "verify",
]

#: the environment variable that names the data folder
ENV_VAR = "SNN_FG_DATA"


def user_data_dir() -> Path:
    """The platform's folder for a user's application data, ``.../snn-fg``."""
    if sys.platform == "win32":
        base = Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
    elif sys.platform == "darwin":
        base = Path.home() / "Library" / "Application Support"
    else:
        base = Path(os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share")
    return base / "snn-fg"


def root_and_origin() -> tuple[Path, str]:
    """The data folder and why it is that one (see the module docstring)."""
    env = os.environ.get(ENV_VAR)
    if env:
        return Path(env).expanduser(), f"set by ${ENV_VAR}"
    checkout = Path(__file__).resolve().parents[2]
    shared = checkout.parent / "shared" / "data"
    if (checkout / "pyproject.toml").is_file() and shared.is_dir():
        return shared, "the shared data beside this source checkout"
    return user_data_dir(), "the user data folder"


def data_root() -> Path:
    """The data folder every dataset lives under."""
    return root_and_origin()[0]


def get(name: str) -> Dataset:
    """The dataset called ``name``; :class:`DatasetError` names the known ones otherwise."""
    try:
        return DATASETS[name]
    except KeyError:
        raise DatasetError(f"no dataset called {name!r}; known: {', '.join(sorted(DATASETS))}") from None


def _folder(name: str, root) -> Path:
    return Path(root if root is not None else data_root()) / get(name).name


def missing(name: str, root=None) -> list[DataFile]:
    """Files of the dataset that are absent (or, for a file checked by its bytes, of the wrong size)."""
    folder = _folder(name, root)
    gone = []
    for f in get(name).files:
        p = folder / f.path
        if not p.is_file() or (f.digest == "bytes" and p.stat().st_size != f.size):
            gone.append(f)
    return gone


def _matches(path: Path, f: DataFile) -> bool:
    if not path.is_file():
        return False
    return (npz_sha256(path) if f.digest == "arrays" else file_sha256(path)) == f.sha256


def verify(name: str, root=None) -> list[DataFile]:
    """Files of the dataset that are absent or differ from their checksum."""
    folder = _folder(name, root)
    return [f for f in get(name).files if not _matches(folder / f.path, f)]


def find(name: str, *parts, root=None) -> Path | None:
    """Path of a dataset (or of a file in it) when the dataset is complete, else ``None``."""
    if missing(name, root):
        return None
    return _folder(name, root).joinpath(*parts)


def how_to_get(name: str) -> str:
    """The command that gets the dataset, or says how to (when no fetch is offered)."""
    return f"snn-fg data {'fetch' if get(name).fetch else 'info'} {name}"


def require(name: str, *parts, root=None) -> Path:
    """As :func:`find`, but an absent dataset raises :class:`DatasetError` saying how to get it."""
    path = find(name, *parts, root=root)
    if path is None:
        folder = _folder(name, root)
        raise DatasetError(
            f"needs the {name} dataset, {_what_is_missing(name, folder)}: "
            f"run `{how_to_get(name)}` (or set ${ENV_VAR} to the folder that holds it)"
        )
    return path


def _what_is_missing(name: str, folder: Path) -> str:
    """Where the dataset falls short, in words: its folder, a sub-folder of it, or some files. A user
    whose folder is there but lacks ``labels/`` would otherwise be told the dataset is not there."""
    if not folder.is_dir():
        return f"which is not in {folder}"
    gone = missing(name, folder.parent)
    subdirs = sorted({f.path.split("/")[0] for f in gone if "/" in f.path})
    absent = [d for d in subdirs if not (folder / d).is_dir()]
    if absent:
        return f"but {folder} has no {' and no '.join(d + '/' for d in absent)} folder"
    n = len(get(name).files)
    return f"but {folder} lacks {len(gone)} of its {n} files (or holds them cut short), {gone[0].path} first"


def fetch(name: str, *, root=None, progress: bool = True) -> list[DataFile]:
    """Make every absent or damaged file of the dataset from its public source; the files made.

    Files already present and matching their checksum are kept, so an
    interrupted fetch resumes. Each file is written atomically after its
    checksum matched.
    """
    ds = get(name)
    folder = _folder(name, root)
    todo = verify(name, root)
    if todo and ds.fetch is None:
        raise DatasetError(f"{name}: fetch not available: {ds.unavailable}")
    if todo:
        try:
            ds.fetch(folder, todo, progress)
        except OSError as exc:  # the folder cannot be written (network errors arrive as DatasetError)
            raise DatasetError(f"{folder}: cannot write the {name} dataset ({exc.strerror or exc})") from None
    return todo
