"""What a model runs on, checked where it comes in: one check of an event
frame (:func:`event_frame`) and one of an image (:func:`image`), used by
:class:`~snn_fg.frames.still.Still` and by every function that takes the arrays
itself (``run_edfg``, ``run_spiking``, ``run_fbfg``). Each problem is one
:class:`~snn_fg.errors.InputError` naming the function, the argument and what
is wrong, before the arrays reach numpy deep inside a model (a broadcast or
unpack error that names neither).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

#: what an event frame is, said with each problem
EVENT_FRAME = "an event frame is H x W, 1 where the pixel's last event was ON (pos) or OFF (neg), 0 elsewhere"


def _numbers(owner: str, name: str, a, what: str) -> np.ndarray:
    if a is None:
        raise InputError(owner, f"{name} is None; {what}")
    arr = np.asarray(a)
    if arr.dtype.kind not in "biuf":
        raise InputError(owner, f"{name} has dtype {arr.dtype}, not numbers; {what}")
    return arr


def _in_unit_range(owner: str, name: str, arr: np.ndarray, what: str) -> None:
    """Refuse values outside [0, 1] (an 8-bit image's 0-255, a count, a negative
    value would run silently, and wrong: the models scale nothing)."""
    if arr.size and arr.dtype.kind != "b":
        lo, hi = arr.min(), arr.max()
        if not (np.isfinite(lo) and np.isfinite(hi)) or lo < 0 or hi > 1:
            raise InputError(owner, f"{name} holds values outside [0, 1] (min {lo:g}, max {hi:g}); {what}")


def event_frame(owner: str, pos, neg) -> None:
    """Refuse an event frame ``pos``, ``neg`` that is not two 2-D arrays of one
    shape with values in [0, 1] (uint8 or bool 0/1 as :func:`~snn_fg.events.events_to_frame` makes)."""
    arrays = {name: _numbers(owner, name, a, EVENT_FRAME) for name, a in (("pos", pos), ("neg", neg))}
    for name, arr in arrays.items():
        if arr.ndim != 2:
            raise InputError(owner, f"{name} has shape {arr.shape}, not 2-D (one value per pixel); {EVENT_FRAME}")
        _in_unit_range(owner, name, arr, EVENT_FRAME)
    if arrays["pos"].shape != arrays["neg"].shape:
        raise InputError(owner, f"pos and neg differ in shape: {arrays['pos'].shape} vs {arrays['neg'].shape}")


#: what an image is, said with each problem
IMAGE = "an image is grey H x W or RGB H x W x 3, floats in [0, 1] (an 8-bit image divided by 255)"


def image(owner: str, img, name: str = "image") -> None:
    """Refuse an image that is not grey ``H x W`` or RGB ``H x W x 3`` with values in [0, 1]."""
    arr = _numbers(owner, name, img, IMAGE)
    if not (arr.ndim == 2 or (arr.ndim == 3 and arr.shape[2] == 3)):
        raise InputError(owner, f"{name} has shape {arr.shape}; {IMAGE}")
    _in_unit_range(owner, name, arr, IMAGE)
