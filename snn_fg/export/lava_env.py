"""The Python 3.10 environment a Lava export's ``run.py`` runs in, made once and kept.

``lava-nc`` 0.10 installs on Python 3.8-3.10 only, beside this package's
3.11. :func:`lava_python` finds a Python 3.10 (on ``PATH`` or pyenv's), makes
a virtual environment with the export's ``requirements.txt`` in a cache
folder keyed by the requirements' hash (``~/.cache/snn-fg/lava-<hash>``, or
under ``$SNN_FG_CACHE``), and returns its interpreter; the tests and
experiments that run an export in Lava use it. Making it takes about half a
minute (pip, from the package index); later calls reuse it.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from .lava import REQUIREMENTS

#: the interpreter versions lava-nc 0.10 installs on
LAVA_PYTHONS = ("3.10", "3.9", "3.8")


class LavaEnvMissing(RuntimeError):
    """No Lava environment can be made here (the message says what is missing)."""


def cache_root() -> Path:
    return Path(os.environ.get("SNN_FG_CACHE") or Path.home() / ".cache" / "snn-fg")


def find_python() -> Path | None:
    """A Python that lava-nc 0.10 installs on and that runs: pyenv's (``~/.pyenv/versions/3.10.*``),
    or ``python3.10`` (3.9, 3.8) on PATH (a pyenv shim on PATH may not run: each is tried)."""
    for v in LAVA_PYTHONS:
        pyenv = sorted((Path.home() / ".pyenv" / "versions").glob(f"{v}.*/bin/python{v}"), reverse=True)
        for candidate in [*pyenv, shutil.which(f"python{v}")]:
            if candidate and _runs(Path(candidate), v):
                return Path(candidate)
    return None


def _runs(python: Path, version: str) -> bool:
    try:
        done = subprocess.run(
            [str(python), "-c", "import sys, venv; print('%d.%d' % sys.version_info[:2])"],
            capture_output=True,
            text=True,
            timeout=60,
        )
    except (OSError, subprocess.SubprocessError):
        return False
    return done.returncode == 0 and done.stdout.strip() == version


def env_dir(requirements: str = REQUIREMENTS) -> Path:
    """Where the environment for ``requirements`` lives (made or not)."""
    return cache_root() / f"lava-{hashlib.sha256(requirements.encode()).hexdigest()[:12]}"


def lava_python(requirements: str = REQUIREMENTS, timeout_s: float = 900.0) -> Path:
    """The interpreter of the environment for ``requirements``, made first if
    it is not there yet (in a staging folder, moved into place when pip has
    finished: an interrupted make leaves nothing half-made). Raises
    :class:`LavaEnvMissing` naming what is missing."""
    target = env_dir(requirements)
    python = target / "bin" / "python"
    if python.exists():
        return python
    base = find_python()
    if base is None:
        raise LavaEnvMissing(
            f"no Python {'/'.join(LAVA_PYTHONS)} (lava-nc 0.10 needs one): none on PATH nor in ~/.pyenv/versions"
        )
    target.parent.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=target.name + ".", dir=target.parent))
    try:
        subprocess.run([str(base), "-m", "venv", str(stage)], check=True, capture_output=True, timeout=timeout_s)
        req = stage / "requirements.txt"
        req.write_text(requirements)
        done = subprocess.run(
            [str(stage / "bin" / "python"), "-m", "pip", "install", "-q", "-r", str(req)],
            capture_output=True,
            text=True,
            timeout=timeout_s,
        )
        if done.returncode != 0:
            tail = (done.stderr or done.stdout).strip().splitlines()[-1:] or ["?"]
            raise LavaEnvMissing(f"pip could not install the export's requirements with {base}: {tail[0]}")
        # (its console scripts name the staging folder; the interpreter, all that is used, does not)
        try:
            stage.rename(target)
        except OSError:  # another process made it meanwhile
            shutil.rmtree(stage, ignore_errors=True)
    finally:
        if stage.exists() and stage != target:
            shutil.rmtree(stage, ignore_errors=True)
    return python
