"""The arguments of :func:`~snn_fg.models.get_model` and of a model's
``run_windows``, checked at the door: a mistyped option, a path or a list of
stills given for windows is one error naming the argument and what to give,
not a ``TypeError`` or ``AttributeError`` from inside the run.
"""

from __future__ import annotations

import os

import numpy as np

from .. import validate as check
from ..errors import InputError
from ..events.frame import EventWindow
from ..frames.still import Still


def model_options(name: str, options: dict, takes: tuple) -> None:
    """Refuse keyword ``options`` that model ``name`` does not take (``takes``: its options)."""
    unknown = sorted(set(options) - set(takes))
    if unknown:
        known = ", ".join(("params", "progress", *takes))
        check.fail(
            "get_model",
            None,
            None,
            f"model {name!r} takes no option {', '.join(unknown)} (it takes {known}, and the model parameters "
            "snn-fg run takes as options, as keywords: r0=4, levels=7, ...)",
        )


_HOW = "give the windows of iter_windows(RECORDING, window_ms=..., max_windows=...)"


def windows(owner: str, given):
    """``given`` as a model runs it: windows cut as read (``iter_windows``' iterator,
    a :class:`~snn_fg.events.RecordingWindows`, a live source: their own reader checks
    them) pass as they are; a list is checked whole, another iterable as it is read."""
    if hasattr(given, "cut"):
        return given
    if isinstance(given, (str, bytes, os.PathLike)):
        raise InputError(given, f"{owner} takes windows, not a path: {_HOW}")
    if isinstance(given, np.ndarray):
        raise InputError("<array>", f"{owner} takes windows, not an events array: {_HOW} (with sensor_size=(W, H))")
    if isinstance(given, EventWindow) or not hasattr(given, "__iter__"):
        raise InputError(f"<{type(given).__name__}>", f"{owner} takes an iterable of windows; {_HOW}")
    if isinstance(given, (list, tuple)):
        for k, w in enumerate(given):
            _window(owner, k, w)
        return given
    return (_window(owner, k, w) for k, w in enumerate(given))


def _window(owner: str, k: int, w) -> EventWindow:
    if not isinstance(w, EventWindow):
        hint = " (a Still runs with run_still)" if isinstance(w, Still) else ""
        raise InputError("<windows>", f"{owner}: item {k} is a {type(w).__name__}, not an EventWindow{hint}; {_HOW}")
    return w


def still(owner: str, given, model) -> Still:
    """``given`` if it is a :class:`~snn_fg.frames.still.Still` holding what ``model`` runs on (its
    ``needs``: an event frame, or an image); else one line saying what to give (a tuple ``(pos, neg)``
    or an image array was an AttributeError from inside the model, and an image given to an event
    model 'run_edfg: pos is None')."""
    if not isinstance(given, Still):
        raise InputError(
            f"<{type(given).__name__}>",
            f"{owner} takes a Still: Still(pos, neg) for an event frame, Still(image=...) for an image "
            "(from snn_fg.frames.still import Still); a recording's windows go to run_windows",
        )
    if model.needs == "image" and given.image is None:
        raise InputError(
            "<Still>", f"the {model.name} model runs on an image, and this Still holds an event frame only: "
            "give Still(image=...) (grey or RGB, floats in [0, 1])",
        )  # fmt: skip
    if model.needs != "image" and given.pos is None:
        raise InputError(
            "<Still>", f"the {model.name} model runs on an event frame, and this Still holds an image only: "
            "pos, neg = image_to_frame(image) makes one as the simulated camera sees it (from snn_fg.events "
            "import image_to_frame), then Still(pos, neg)",
        )  # fmt: skip
    return given
