"""Argument checks written once: every parameter of every public object is
checked here, and every failure is a :class:`~snn_fg.errors.ParameterError`
whose message names the object, the parameter and the value at fault::

    ParameterError: Conv 'on_to_S_1': gain_mv=-1.0 must be >= 0

Each checker takes ``owner`` (the object being built or the function being
called, as a user would recognise it: ``"ModelParams"``, ``"Population 'S_1'"``,
``"run_spiking"``), the parameter ``name`` and its ``value``, and returns the
value converted to its canonical type.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from urllib.parse import urlsplit

import numpy as np

from .errors import InputError, ParameterError

#: how every .npz file (a zip archive) starts; an empty archive starts with its end record
_ZIP_STARTS = (b"PK\x03\x04", b"PK\x05\x06")


def fail(owner: str, name: str | None, value, problem: str):
    """Raise the one error type for a bad parameter (``name=None``: the
    problem concerns ``owner`` as a whole)."""
    what = f"{owner}: " if owner else ""
    if name is not None:
        what += f"{name}={value!r} "
    raise ParameterError(f"{what}{problem}")


def number(
    owner: str,
    name: str,
    value,
    *,
    lo: float | None = None,
    lo_open: bool = False,
    hi: float | None = None,
    hi_open: bool = False,
) -> float:
    """A finite real number within optional bounds, as ``float``."""
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float, np.integer, np.floating))
        or not math.isfinite(value)
    ):
        fail(owner, name, value, "must be a finite number")
    v = float(value) + 0.0  # -0.0 as 0.0
    if lo is not None and (v < lo or (lo_open and v == lo)):
        fail(owner, name, value, f"must be {'>' if lo_open else '>='} {lo:g}")
    if hi is not None and (v > hi or (hi_open and v == hi)):
        fail(owner, name, value, f"must be {'<' if hi_open else '<='} {hi:g}")
    return v


def integer(owner: str, name: str, value, *, lo: int | None = None, hi: int | None = None) -> int:
    """An integer (not a bool, not a float) within optional bounds, as ``int``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        fail(owner, name, value, "must be an integer")
    v = int(value)
    if lo is not None and v < lo:
        fail(owner, name, value, f"must be >= {lo}")
    if hi is not None and v > hi:
        fail(owner, name, value, f"must be <= {hi}")
    return v


def seed(owner: str, value, name: str = "seed") -> int:
    """A random seed: an integer >= 0 (numpy's generators take no negative one)."""
    return integer(owner, name, value, lo=0)


def flag(owner: str, name: str, value) -> bool:
    """A bool (not 0 or 1)."""
    if not isinstance(value, bool):
        fail(owner, name, value, "must be true or false")
    return value


def choice(owner: str, name: str, value, choices: Iterable):
    """One of ``choices``."""
    choices = tuple(choices)
    if value not in choices:
        fail(owner, name, value, f"must be one of {', '.join(repr(c) for c in choices)}")
    return value


def shape2(owner: str, name: str, value) -> tuple[int, int]:
    """Two positive integers ``(rows, cols)``."""
    try:
        t = tuple(int(x) for x in value)
        exact = len(t) == 2 and all(float(a) == b for a, b in zip(value, t))
    except (TypeError, ValueError):
        exact = False
    if not exact or min(t) < 1:
        fail(owner, name, value, "must be two positive integers (rows, cols)")
    return t


def known_keys(owner: str, given: Iterable[str], allowed: Iterable[str]) -> None:
    """Refuse keys (keyword options, mapping fields) that ``owner`` does not take."""
    unknown = sorted(set(given) - set(allowed))
    if unknown:
        fail(owner, None, None, f"unknown field(s) {', '.join(unknown)} (known: {', '.join(sorted(allowed))})")


def address(url: str, schemes: tuple[str, ...], owner: str, others: tuple[str, ...] = ()) -> tuple[str, str, int]:
    """``(scheme, host, port)`` of ``SCHEME://HOST:PORT``, the scheme one of
    ``schemes``; else an InputError naming ``url`` and ``owner`` (the option), and the
    ``others`` the option also takes (``camera://[SERIAL]``)."""
    parts = urlsplit(url)
    named = [f"{s}://HOST:PORT" for s in schemes] + list(others)
    expected = f"{owner}: expected " + (
        " or ".join(named) if len(named) < 3 else f"{', '.join(named[:-1])} or {named[-1]}"
    )
    try:
        port = parts.port  # (urllib raises for a port out of 0-65535 or not a number)
    except ValueError:
        raise InputError(url, f"{expected}, with PORT an integer 0 to 65535") from None
    if parts.scheme not in schemes or not parts.hostname or port is None:
        raise InputError(url, expected)
    return parts.scheme, parts.hostname, port


def check_crop(crop, shape, owner: str = "maps_figure") -> tuple[int, int, int, int]:
    """``(x0, y0, x1, y1)`` of a crop of an ``(H, W)`` frame, checked (x1, y1 exclusive)."""
    h, w = shape
    x0, y0, x1, y1 = (int(v) for v in crop)
    if not (0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h):
        fail(
            owner,
            None,
            None,
            f"crop x0,y0,x1,y1 = {x0},{y0},{x1},{y1} must satisfy 0 <= x0 < x1 <= {w} "
            f"and 0 <= y0 < y1 <= {h} (the frame is {w} x {h})",
        )
    return x0, y0, x1, y1


def load_npz(path, expected: str):
    """``np.load`` of an ``.npz`` file, refused with one line naming the file
    when it is not a zip archive: numpy reads anything else as a pickle and
    says so, advice a user should not follow. ``expected`` says what the
    file should be (``"maps.npz or a run's output folder"``)."""
    with open(path, "rb") as fh:
        head = fh.read(4)
    if head not in _ZIP_STARTS:
        raise InputError(path, f"not an .npz file (expected {expected})")
    return np.load(path, allow_pickle=False)
