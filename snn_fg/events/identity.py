"""What a run keeps about its recording to tell it from another (``params["source"]``), so that
``snn-fg compare`` can say two runs come from different inputs whatever their files are named
(every iCub recording is a ``data.log``; :mod:`snn_fg.scoring.inputs` reads these keys).

``sensor_size`` is the sensor's ``[width, height]``; ``events_head`` a digest of the recording's
first :data:`HEAD_EVENTS` events (coordinates, time from the first event and polarity ON or OFF),
read from the events rather than the file's bytes: the same events converted to another format
(``snn-fg events REC --write-events F.npz``) keep it, and so does a recording whose times were
shifted to begin at 0.
"""

from __future__ import annotations

import hashlib

import numpy as np

from ..errors import InputError
from .core import EVENT_DTYPE
from .io import iter_recording

#: events at the head of a recording that its digest covers: a few ms of a busy scene, read in one
#: chunk (a run reads the recording from its start anyway)
HEAD_EVENTS = 4096


def head_digest(events: np.ndarray) -> str:
    """A digest (16 hex digits) of ``events`` (:data:`~snn_fg.events.EVENT_DTYPE`), with times from
    the first event and polarity as ON or OFF."""
    x, y = (np.ascontiguousarray(events[k], np.int32) for k in ("x", "y"))
    t = np.asarray(events["t"], np.int64)
    t = np.ascontiguousarray(t - (t[0] if len(t) else 0))
    on = np.ascontiguousarray(np.asarray(events["p"]) > 0, np.uint8)
    h = hashlib.sha256()
    for part in (x, y, t, on):
        h.update(part.tobytes())
    return h.hexdigest()[:16]


def input_keys(path, sensor_size=None, **camera) -> dict:
    """The keys ``params["source"]`` keeps about the recording ``path`` (``sensor_size`` and the format
    options ``chip`` and ``channel`` as :func:`~snn_fg.events.iter_recording` takes them) to tell it
    from another: ``sensor_size`` and ``events_head`` (the module docstring)."""
    stream = iter_recording(path, sensor_size=sensor_size, chunk_events=HEAD_EVENTS, **camera)
    stream.warn_no_span = False  # (the run's own reading warns of a stream cut short, once)
    head, n = [], 0
    try:
        for chunk in stream:
            head.append(chunk[: HEAD_EVENTS - n])
            n += len(head[-1])
            if n >= HEAD_EVENTS:
                break
    except InputError:  # (damage within the head: the digest of the events before it; the run says it)
        pass
    events = np.concatenate(head) if head else np.zeros(0, EVENT_DTYPE)
    return {"sensor_size": [int(v) for v in stream.sensor_size[:2]], "events_head": head_digest(events)}
