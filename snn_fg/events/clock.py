"""The clock a run's times are on, kept in its ``params["source"]`` (``clock``), so that two runs
of the same events can be paired by the events' own times (``snn-fg compare``,
:mod:`snn_fg.scoring.pairing`).

A run stores its windows' times from its first event (``t_start_us``) and that event's time on
the input's own clock (``first_event_us``); ``clock`` says which clock that is. A ``udp://``
stream's times are 32 bits (:mod:`snn_fg.events.spif`): they are its sender's to within a
multiple of ``clock_span_us``, which the run keeps beside ``clock``. A run stored without
``clock`` (before snn-fg kept it) has its times from its own first event only: a replay then
began its clock at 0 wherever the recording's first event lay.
"""

from __future__ import annotations

#: a recording's own timestamps (``snn-fg run``)
RECORDING = "recording"
#: a live stream's timestamps as its sender stamped them (``snn-fg stream`` sends the recording's)
SENDER = "sender"
#: times stamped by the receiver as the events came (a ``udp://`` stream sent without timestamps):
#: no other run's times are on this clock
ARRIVAL = "arrival"
#: the clocks whose times two runs can share
SHARED = (RECORDING, SENDER)


def clock_keys(live_source=None) -> dict:
    """The keys ``params["source"]`` keeps about the clock of a run on a recording (``None``) or on
    the live source ``live_source`` (its ``clock`` and ``clock_span_us``, read at the run's end: a
    ``udp://`` stream's may turn to :data:`ARRIVAL` as it comes)."""
    if live_source is None:
        return {"clock": RECORDING}
    clock, span = getattr(live_source, "clock", SENDER), getattr(live_source, "clock_span_us", None)
    return {"clock": clock, **({"clock_span_us": int(span)} if span and clock == SENDER else {})}
