"""What a format opener hands to :class:`~snn_fg.events.io.RecordingStream`.

Every per-format module (:mod:`~snn_fg.events.eventstream`,
:mod:`~snn_fg.events.prophesee`, ...) has an ``open_*`` function that reads
the file's header and returns a :class:`Source`: the sensor size, the decoder
name and a ``chunks(n, tally)`` function that decodes the file from its start.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: Decoder names whose reader yields bounded chunks (see the table in :mod:`snn_fg.events.formats`).
STREAMING_FORMATS = frozenset(
    {
        "es",
        "es-atis",
        "evt2",
        "evt3",
        "dat",
        "aedat2",
        "aedat3",
        "aedat4",
        "yarp",
        "txt",
        "npy",
        "array",
        "dsec",
        "mvsec",
        "prophesee-hdf5",
    }
)
#: Bytes a binary decoder reads at a time: its memory does not grow with the file.
READ_BYTES = 1 << 22


@dataclass
class DecodeTally:
    """What a decoder read but did not return, counted during one pass over the file."""

    #: ATIS exposure-measurement (threshold-crossing) events: not polarity events.
    exposure_events: int = 0
    #: everything else left out, by what it is: ``{"IMU samples": 475, "APS frames": 59}``
    other: dict = field(default_factory=dict)

    def skip(self, what: str, n: int = 1) -> None:
        """Count ``n`` items of ``what`` left out."""
        if n:
            self.other[what] = self.other.get(what, 0) + int(n)

    @property
    def skipped(self) -> dict:
        """Every kind of item left out, with its count (none: an empty dict)."""
        return ({"ATIS exposure events": self.exposure_events} if self.exposure_events else {}) | self.other


@dataclass(frozen=True)
class Skip:
    """Where a reading may begin instead of a recording's start: found by :attr:`Source.skip`."""

    t_first: int  # the recording's first event's time (us)
    index: int  # the events before, left unread
    chunks: Callable[[int, DecodeTally], Iterator[np.ndarray]] = field(repr=False)  # from event ``index`` on


@dataclass(frozen=True)
class Source:
    """An opened recording, ready to decode.

    ``chunks(n, tally)`` yields event arrays (any structured dtype with
    x, y, t, p; roughly ``n`` events each where the decoder can choose) from
    the start of the file, and adds what it skips to ``tally``. ``skip(us)``,
    where the file has an index of its times (DSEC's ``ms_to_idx``), gives a
    :class:`Skip` to the events from ``us`` after the first one (at or before
    the first of them; every event before it is earlier), or None where the
    index cannot say.
    """

    path: Path | None
    format: str
    sensor_size: tuple[int, int, int]
    chunks: Callable[[int, DecodeTally], Iterator[np.ndarray]] = field(repr=False)
    skip: Callable[[int], Skip | None] | None = field(default=None, repr=False)

    @property
    def streams(self) -> bool:
        return self.format in STREAMING_FORMATS
