"""Why a recording's window with events can give no figure-ground vector: what the warning that
some did (``snn-fg run``, :mod:`snn_fg.cli.runner`) says of them, per model."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class BlankWindows:
    """A model's reasons for windows without a vector: ``short``, said where every such window's
    events last less than ``settle_ms`` (the model needs that long of input), and ``sparse``
    otherwise (with the windows' event counts)."""

    settle_ms: float
    short: str
    sparse: str

    def why(self, spans_ms: list, events: list) -> str:
        """The reason for windows whose events last ``spans_ms`` and number ``events``."""
        if max(spans_ms) < self.settle_ms:
            return self.short
        lo, hi = min(events), max(events)
        return self.sparse.format(events=f"{lo:,}" if lo == hi else f"{lo:,}-{hi:,}")


#: the spiking network's (the settling time: dvs_biplane_spiking_fast.md's median window latency)
SPIKING = BlankWindows(
    52.5,
    "the spiking network needs tens of ms of input before its feedback orders the border-ownership cells: "
    "on dvs.es a window's grouping map takes a median 52.5 ms to settle. A clip that short can run as its "
    "event frame, which the network sees for as long as it needs: snn-fg events REC --write-frame F.npz, "
    "then snn-fg run F.npz --model spiking",
    "{events} events a window, and long enough for the network to settle: its border-ownership cells gave "
    "no vector on these events. The rate model on the same windows (--model rate) shows what their frames "
    "give; docs/validation.md (on recordings) measures where the two part",
)

#: the frame-based model's (it runs on a DAVIS recording's APS frames)
FRAMES = BlankWindows(0.0, "", "a window before the recording's first APS frame has no frame to run on")
