"""The recording formats: which extension is which format, checked against the
file's first bytes (:func:`detect_format`), the opener of each, and the
format options (:func:`check_format_options`, :func:`check_read_options`).

=================  ============================  ==========================  =========
extension          format                        decoder (module)            streams
=================  ============================  ==========================  =========
``.es``            Event Stream 2.x, DVS         ours (``eventstream``)      yes
``.es``            Event Stream 2.x, ATIS        ours (``eventstream``)      yes
``.raw``           Prophesee EVT 2.0             expelliarmus (+ our check)  yes
``.raw``           Prophesee EVT 3.0             ours (``prophesee``;        yes
                                                 expelliarmus 1.1 drifts
                                                 by 4096 us steps)
``.dat``           Prophesee DAT (CD events)     expelliarmus (+ our check)  yes
``.aedat``         jAER AEDAT 2.0 (DVS128,       ours (``aedat23``)          yes
                   DAVIS)
``.aedat``         cAER AEDAT 3.1                ours (``aedat23``)          yes (per packet)
``.aedat4``        iniVation AEDAT 4             ``aedat`` package           yes (per packet)
``.bin``           N-MNIST / N-Caltech101        tonic ``read_mnist_file``   no
``.log``           iCub YARP ``data.log`` (AE)   ours (``yarp``)             yes
``.txt``           ``t x y p`` lines, t in s     ours (``text_events``)      yes
                   (Event Camera Dataset)
``.npy``           structured array x, y, t, p   numpy (memory-mapped)       yes
``.npz``           structured array x, y, t, p   numpy                       no
``.h5``/``.hdf5``  DSEC, MVSEC, Prophesee HDF5   h5py (``hdf5``)             yes
(array)            structured array x, y, t, p   --                          yes
=================  ============================  ==========================  =========

The extension picks the format; the file's leading bytes must agree (an
Event Stream file renamed ``.raw`` is refused with a clear message instead of
being decoded into garbage).

Format options apply to one format each, and giving one for a file of another
format is a :class:`~snn_fg.errors.ParameterError`:

* ``encoding`` (``.raw``): ``"evt2"`` or ``"evt3"``, for files whose header
  does not say (default: the header's, else EVT2);
* ``codec`` (``.log``): address codec, ``"auto"`` (default), ``"24"`` or ``"20"``;
* ``channel`` (``.log``, MVSEC's ``.hdf5``): camera, 0 (left, default), 1 (right) or, for
  a ``.log``, ``"both"``;
* ``timer_bits`` (``.log``): bits of the timestamp counter (default 30);
* ``chip`` (``.aedat``): the camera of an AEDAT 2.0 file whose header names
  none (no ``# AEChip:`` line): ``"dvs128"``, ``"davis240"``, ``"davis346"``,
  ``"davis640"``, ``"davis128"``, ``"davis208"`` or ``"davis"`` (a DAVIS of the
  sensor size given).

Neither an events ``.txt`` nor an AEDAT 3.1 file from an unknown camera
states its sensor: without a sensor size given, it is the events' extent,
with a warning, as for ``.npy`` arrays.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from snn_fg import validate
from snn_fg.errors import InputError
from snn_fg.events import aedat4, aedat23, eventstream, hdf5, nmnist, numpy_files, prophesee, text_events, yarp
from snn_fg.events.core import sensor_size_parameter
from snn_fg.events.source import Source

SUFFIX_FORMAT = {
    ".es": "es",
    ".raw": "raw",
    ".dat": "dat",
    ".aedat": "aedat",
    ".aedat4": "aedat4",
    ".bin": "nmnist",
    ".log": "yarp",
    ".txt": "txt",
    ".npy": "npy",
    ".npz": "npz",
    ".h5": "h5",
    ".hdf5": "h5",
}
#: the recordings' names as the commands' help lists them (a YARP log is a folder's ``data.log``)
SUFFIXES_TEXT = " ".join("data.log" if s == ".log" else s for s in SUFFIX_FORMAT)


@dataclass(frozen=True)
class Format:
    label: str  # what a file of this format is, for messages
    opener: Callable[..., Source]  # (path, sensor_size, chunk_events, *, its options) -> Source
    looks_like: tuple  # what _sniff may call a file of this format (None: nothing known)

    @property
    def options(self) -> tuple[str, ...]:
        """The format options this format takes: its opener's keyword-only parameters."""
        return tuple(name for name, p in inspect.signature(self.opener).parameters.items() if p.kind is p.KEYWORD_ONLY)


FORMATS = {
    "es": Format("an Event Stream file", eventstream.open_es, ("an Event Stream (.es) file",)),
    "raw": Format("a Prophesee RAW file", prophesee.open_raw, ("a Prophesee RAW/DAT file", None)),
    "dat": Format("a Prophesee DAT file", prophesee.open_dat, ("a Prophesee RAW/DAT file", None)),
    "aedat": Format(
        "an AEDAT 2.0 or 3.1 file", aedat23.open_aedat, ("an AEDAT 2.0 or 3.1 file", "an AEDAT 1.0 or 3.0 file")
    ),
    "aedat4": Format("an AEDAT 4 file", aedat4.open_aedat4, ("an AEDAT 4 (.aedat4) file",)),
    "nmnist": Format("an N-MNIST binary file", nmnist.open_nmnist, (None,)),
    "yarp": Format("a YARP data.log text file", yarp.open_yarp, ("a YARP data.log text file",)),
    "txt": Format("a text file of events", text_events.open_txt, ("a text file",)),
    "npy": Format("a .npy file", numpy_files.open_npy, ("a numpy .npy file",)),
    "npz": Format("an .npz archive", numpy_files.open_npz, ("a zip/.npz file",)),
    "h5": Format("an HDF5 file", hdf5.open_h5, ("an HDF5 file",)),
}

_MAGICS = [
    (eventstream.MAGIC, "an Event Stream (.es) file"),
    (b"#!AER-DAT4", "an AEDAT 4 (.aedat4) file"),
    (b"#!AER-DAT2.0", "an AEDAT 2.0 or 3.1 file"),
    (b"#!AER-DAT3.1", "an AEDAT 2.0 or 3.1 file"),
    (b"#!AER-DAT", "an AEDAT 1.0 or 3.0 file"),
    (b"\x93NUMPY", "a numpy .npy file"),
    (b"\x89HDF\r\n\x1a\n", "an HDF5 file"),
    (b"PK\x03\x04", "a zip/.npz file"),
    (b"PK\x05\x06", "a zip/.npz file"),
    (b"\x89PNG", "a PNG image"),
    (b"\xff\xd8\xff", "a JPEG image"),
]


def _sniff(head: bytes):
    for magic, name in _MAGICS:
        # (a file cut inside its signature is still that kind of file: its reader says it ends there)
        if head.startswith(magic) or (len(head) < len(magic) and magic.startswith(head)):
            return name
    if head.startswith(b"%"):
        return "a Prophesee RAW/DAT file"
    if head and all(32 <= c < 127 or c in (9, 10, 13) for c in head[:4096]):
        if yarp.is_yarp_line(head.split(b"\n", 1)[0]):
            return "a YARP data.log text file"
        return "a text file"
    return None


def looks_like(head: bytes) -> tuple[str | None, list[str]]:
    """What a file whose first bytes are ``head`` looks like ("an Event Stream (.es) file", None when
    nothing known), and the suffixes of the recording formats it may be (for a file misnamed)."""
    seen = _sniff(head)
    suffixes = [sfx for sfx, fmt in SUFFIX_FORMAT.items() if seen is not None and seen in FORMATS[fmt].looks_like]
    return seen, suffixes


def detect_format(path) -> str:
    """Format name from the extension, checked against the file's first bytes."""
    path = Path(path)
    fmt = SUFFIX_FORMAT.get(path.suffix.lower())
    if path.is_dir():
        raise InputError(path, "is a folder, not a recording's file")
    if fmt is None:
        raise InputError(
            path,
            f"unknown event file extension '{path.suffix or '(none)'}' (supported: {', '.join(sorted(SUFFIX_FORMAT))})",
        )
    if not path.exists():
        raise InputError(path, "no such file")
    if not path.is_file():
        raise InputError(path, "not a regular file")
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError as exc:
        raise InputError(path, f"cannot read file ({exc.strerror or exc})") from exc
    if not head:
        raise InputError(path, "file is empty", "byte offset 0")
    seen = _sniff(head)
    if seen not in FORMATS[fmt].looks_like:
        raise InputError(
            path,
            f"extension says {FORMATS[fmt].label} but the content looks like "
            f"{seen or 'unrecognised binary data'}; is the file mislabelled?",
            "byte offset 0",
        )
    return fmt


def check_format_options(owner: str, *, encoding=None, codec=None, channel=None, timer_bits=None, chip=None) -> dict:
    """Check the format options passed to ``owner``; return the given ones (not ``None``).

    Values are checked here, for every entry point alike; whether an option
    applies to the file's format is checked once the format is known.
    """
    given = {}
    if encoding is not None:
        enc = encoding.lower() if isinstance(encoding, str) else encoding
        given["encoding"] = validate.choice(owner, "encoding", enc, prophesee.ENCODINGS)
    if codec is not None:
        given["codec"] = validate.choice(owner, "codec", codec, yarp.CODECS)
    if channel is not None:
        whole = isinstance(channel, (int, np.integer)) and not isinstance(channel, bool)
        if not (channel == "both" if isinstance(channel, str) else whole and channel in yarp.CHANNELS):
            validate.fail(owner, "channel", channel, "must be 0 (left camera), 1 (right camera) or 'both'")
        given["channel"] = channel if channel == "both" else int(channel)
    if timer_bits is not None:
        given["timer_bits"] = validate.integer(owner, "timer_bits", timer_bits, lo=1, hi=31)
    if chip is not None:
        given["chip"] = validate.choice(owner, "chip", chip.lower() if isinstance(chip, str) else chip, aedat23.CHIPS)
    return given


#: how a recording is read, besides the source: what :func:`check_read_options` takes
READ_OPTIONS = ("sensor_size", "chunk_events", "encoding", "codec", "channel", "timer_bits", "chip")


def check_read_options(owner: str, options: dict) -> dict:
    """The options of how a recording is read (:data:`READ_OPTIONS`) that
    were passed to ``owner`` as keywords, checked (:func:`check_format_options`,
    the sensor size); any other keyword is a ``TypeError``, as Python's own."""
    for k in options:
        if k not in READ_OPTIONS:
            raise TypeError(f"{owner}() got an unexpected keyword argument {k!r}")
    given = {k: v for k, v in options.items() if k in ("sensor_size", "chunk_events")}
    given.update(check_format_options(owner, **{k: v for k, v in options.items() if k not in given}))
    if given.get("sensor_size") is not None:
        sensor_size_parameter(owner, given["sensor_size"])
    return given


def refuse_options(options: dict, owner: str, label: str) -> None:
    """ParameterError for the first of ``options``, none of which applies to ``label``."""
    for name, value in options.items():
        users = " or ".join(f.label for f in FORMATS.values() if name in f.options)
        validate.fail(owner, name, value, f"does not apply to {label} (it is an option for {users})")
