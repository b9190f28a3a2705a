"""What marks a file snn-fg wrote, as far as its format tells (:func:`of_kind`): a mark where the
format has room for one (a PNG's text, an ``.npz`` member, a JSON key), its first bytes or suffix
elsewhere. The output rules of :mod:`.outputs` ask it before ``--force`` replaces anything. Imports
nothing of snn_fg's: every layer's writers use it."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

#: the first bytes of a file of each suffix snn-fg writes, where they tell it cheaply: HDF5 (a NIR graph),
#: PNG, a zip (numpy's .npz), numpy's .npy, GIF; .json begins with { or [, .mp4 has "ftyp" at byte 4; the
#: others (.csv, .es, .raw) are told by their suffix alone
SIGNATURES = {
    ".nir": (b"\x89HDF\r\n\x1a\n",),
    ".png": (b"\x89PNG\r\n\x1a\n",),
    ".npz": (b"PK\x03\x04", b"PK\x05\x06"),
    ".npy": (b"\x93NUMPY",),
    ".gif": (b"GIF87a", b"GIF89a"),
}
#: what marks a file snn-fg wrote, where its format has room for it: a PNG's ``Software`` text
#: (:func:`~snn_fg.results.atomic.save_figure`), an ``.npz``'s member ``written_by``
#: (:func:`~snn_fg.results.atomic.save_npz`, ``save_events``, ``export.pynn.save_input``), a JSON
#: object's ``snn_fg_version`` or ``schema`` ``snn-fg.*`` (compare's and export's records, a network
#: description)
MARK = "snn-fg"
#: the formats whose files carry :data:`MARK`: --force replaces one only when it does
MARKED = (".png", ".npz", ".json")


def of_kind(path: Path, suffix: str) -> bool:
    """Whether the file ``path`` is one snn-fg wrote, as far as its format tells: :data:`MARK` in
    the formats of :data:`MARKED`, its first bytes (:data:`SIGNATURES`) or suffix in the others."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(8192)
    except OSError:
        return False
    if suffix == ".json":
        return _marked_json(path) if head.lstrip()[:1] == b"{" else False
    if suffix == ".mp4":
        return head[4:8] == b"ftyp"
    if not head.startswith(SIGNATURES.get(suffix, (b"",))):
        return False
    if suffix == ".png":  # (matplotlib writes the text chunks before the image data)
        return b"Software\x00" + MARK.encode() in head
    if suffix == ".npz":
        try:
            with zipfile.ZipFile(path) as zf:
                return "written_by.npy" in zf.namelist()
        except (OSError, zipfile.BadZipFile):
            return False
    return True


def made_by_snn_fg(path) -> bool:
    """Whether the file ``path`` is one snn-fg wrote, as far as its format tells (:func:`of_kind`)."""
    path = Path(path)
    return path.is_file() and not path.is_symlink() and of_kind(path, path.suffix.lower())


def _record(path: Path) -> dict | None:
    """The JSON object ``path`` holds, or None (not one, or larger than snn-fg's records: a user's
    data set is not read)."""
    try:
        if path.stat().st_size > 64 << 20:
            return None
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) else None


def _marked_json(path: Path) -> bool:
    record = _record(path)
    return record is not None and ("snn_fg_version" in record or str(record.get("schema")).startswith(MARK + "."))


def signed(path: Path, suffix: str) -> bool:
    """Whether ``path`` begins as a file of ``suffix`` does (:data:`SIGNATURES`; an MP4 its ``ftyp`` box)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(8)
    except OSError:
        return False
    return head[4:8] == b"ftyp" if suffix == ".mp4" else head.startswith(SIGNATURES[suffix])


def json_keys(path: Path, keys) -> bool:
    """Whether ``path`` holds a JSON object with every one of ``keys`` (a small file only)."""
    record = _record(path)
    return record is not None and all(k in record for k in keys)
