"""The files an export's ``run.py`` writes, each written whole, and how it ends when
interrupted: with nothing written (``fg_files.py`` in PyNN and Lava export folders).
Standard library only: the folder runs where snn_fg is not installed, so this is the
export's copy of the rules :mod:`snn_fg.results.atomic` and
:mod:`snn_fg.backends.cancel` keep for the package (a file is complete or absent; Ctrl-C
and SIGTERM end a run in one line, exit 130 and 143)."""

from __future__ import annotations

import hashlib
import json
import os
import signal
import sys

#: the counts key naming the export they were made by: a digest of the ``network.json`` run.py ran
#: (``snn-fg decode`` refuses counts of another export of the same size, which it cannot tell by their arrays)
EXPORT_KEY = "export_network_sha256"


def network_digest(path: str = "network.json") -> str:
    """The first 16 hex digits of the SHA-256 of the export's ``network.json`` (run.py runs in its folder)."""
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()[:16]


def save_atomically(path, write):
    """``write(tmp)`` to a temporary file beside ``path``, moved onto it when complete: an
    interrupted or failed write leaves neither a partial file nor the temporary one."""
    base, ext = os.path.splitext(os.path.abspath(path))
    tmp = f"{os.path.dirname(base)}/.{os.path.basename(base)}.part{ext}"
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_json(path, value):
    """``value`` as indented JSON text into ``path`` (whole: :func:`save_atomically`)."""

    def dump(tmp):
        with open(tmp, "w") as fh:
            json.dump(value, fh, indent=1)

    save_atomically(path, dump)


def npz_path(out: str) -> str:
    """The file ``np.savez(out, ...)`` writes: ``out``, with ``.npz`` added unless it ends so."""
    return out if out.endswith(".npz") else f"{out}.npz"


def check_out(out: str, force: bool) -> None:
    """Exit with one line, before anything runs, when run.py's ``--out`` file (:func:`npz_path`)
    exists and ``--force`` was not given: it holds an earlier run's counts, perhaps a longer or
    another simulator's run, which replacing would lose."""
    path = npz_path(out)
    if os.path.exists(path) and not force:
        sys.exit(
            f"run.py: error: {path}: exists (an earlier run's counts?); pass --force to replace it, "
            "or give another --out; nothing was run"
        )


def save_npz(out: str, arrays: dict) -> str:
    """``arrays`` into :func:`npz_path` of ``out`` (whole); returns that path."""
    import numpy as np  # (numpy: an export's run.py has it; this module's other writers need only the library)

    path = npz_path(out)
    save_atomically(path, lambda tmp: np.savez(tmp, **arrays))
    return path


#: the signals that ended the run (SIGTERM; Ctrl-C arrives as KeyboardInterrupt)
_SIGNALLED = []


def _terminated(signum, frame):
    _SIGNALLED.append(signum)
    raise KeyboardInterrupt


def run_main(main):
    """``main()`` as an export's run.py runs it: Ctrl-C (SIGINT, taken even where the run was
    started with it ignored, as a shell starts a command in the background) and SIGTERM end it
    with one line, ``run.py: interrupted (Ctrl-C); nothing written``, exit 130 (SIGTERM: 143);
    what it writes goes through :func:`save_atomically`, so nothing is half-written."""
    signal.signal(signal.SIGTERM, _terminated)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        main()
    except KeyboardInterrupt:
        print(f"run.py: interrupted ({'SIGTERM' if _SIGNALLED else 'Ctrl-C'}); nothing written", file=sys.stderr)
        sys.exit(143 if _SIGNALLED else 130)
