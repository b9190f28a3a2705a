"""The fast engine's compiled code as numba caches it: whether it is
compiled already (:func:`code_is_cached`, so a first run can say it
compiles first) and the check that drops code cached from older versions
of the engine's files (:func:`drop_stale_caches`)."""

from __future__ import annotations

import hashlib
from pathlib import Path

#: the file, in numba's cache folder, holding the digest of the sources the cache was made from
STAMP = "snn_fg_fast_engine.sources"


def code_is_cached(fn) -> bool:
    """Whether the numba function ``fn`` is compiled already, in this
    process or in numba's cache. Best effort (numba's cache object is not
    public API): ``True`` when it cannot tell."""
    if getattr(fn, "signatures", True):  # (compiled here, or not numba's function at all)
        return True
    try:
        return bool(fn._cache._cache_file._load_index())  # (empty when stale or flushed)
    except Exception:  # noqa: BLE001 - whatever numba's private cache does, we cannot tell
        return True


def drop_stale_caches(anchor, modules, variant: bytes = b"") -> None:
    """Forget compiled code cached from older versions of the engine's files.

    numba checks a cached function against the file that defines it, and no
    other, but the engine's loops compile in functions and constants of
    the package's other modules: after an edit there they kept running the
    old code. So the caches of every compiled function of ``modules`` are
    dropped whenever any source file of the package changes, or
    ``variant`` (a constant compiled in that the sources do not show, such
    as :data:`.lif.PHASES`); the digest is kept beside ``anchor``'s cache. Best effort: numba's cache object is
    not public API, and if it changes this check is skipped.
    """
    here = Path(__file__).parent
    digest = hashlib.sha256(b"".join(f.read_bytes() for f in sorted(here.glob("*.py"))) + variant).hexdigest()
    try:
        stamp = Path(anchor._cache._cache_path) / STAMP
        if stamp.exists() and stamp.read_text() == digest:
            return
        for module in modules:
            for f in vars(module).values():
                if hasattr(f, "_cache") and hasattr(f._cache, "flush"):
                    f._cache.flush()
        stamp.write_text(digest)
    except (AttributeError, OSError):
        pass
