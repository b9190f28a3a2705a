"""Live event sources read with ``dv-processing`` (the live extra): ``dv://HOST:PORT``, the event
stream a DV server serves over TCP (:class:`DvSource`), and ``camera://``, an iniVation camera on
this machine's USB (:class:`CameraSource`); opened by :func:`~snn_fg.events.live_sources.open_source`,
whose module says what a source's :meth:`packets` gives.
"""

from __future__ import annotations

import threading
import time
import warnings

import numpy as np

from snn_fg.errors import InputError, InputWarning
from snn_fg.events.clock import SENDER
from snn_fg.events.core import EVENT_DTYPE
from snn_fg.events.live_screen import BATCH
from snn_fg.events.watchdog import ends_process_after

#: how long a live stream waits for its first packet once ready (s; ``--wait-s``)
WAIT_S = 30.0

#: how a camera on USB is named (``camera://``, or ``camera://SERIAL``)
CAMERA = "camera://"
#: how long a DV stream's reader is left before it is asked again, when it had no batch (dv-processing's
#: reader cannot be waited on). Every 0.5 ms, with a batch passed on as it came, the receiving thread took
#: about a fifth of one core beside the compact network (30 Nov): 2 ms bounds what it adds to a latency
DV_POLL_S = 0.002
#: events a DV stream's reader is emptied of, at most, before the model asks for the stream (while it
#: warms up): about 260 MB; the rest is left to the reader, and said
EARLY_EVENTS = 20_000_000
#: packets in a row a DV reader cannot read before its stream is taken for broken (until then each is
#: counted and skipped): a reader that raises at every ask held the run there, a core busy, without end
UNREADABLE_IN_A_ROW = 100


def dv_reason(exc: RuntimeError) -> str:
    """What a ``dv-processing`` network error says, without the Boost source location it appends
    (``connect: Connection refused``)."""
    return str(exc).split(" [")[0]


#: how long a server that accepted the connection may take to send a DV stream's header past
#: ``wait_s`` before the run is ended (:func:`~snn_fg.events.watchdog.ends_process_after`)
HEADER_GRACE_S = 2.0


def not_served(wait_s: float, reason: str) -> str:
    """Why no DV stream came within ``wait_s``: nothing listening (a refused or timed-out
    connection), or something that answered and sent no DV stream (a web server, a UDP
    sender's port, a stream of another kind), which is not the same fault."""
    if reason.startswith("connect:"):
        return f"no DV server answered within {wait_s:g} s ({reason})"
    return (
        f"a server answered but sent no DV event stream within {wait_s:g} s ({reason}): is it a DV "
        "network writer (DV software's output, snn-fg stream --to dv://)?"
    )


class DvSource:
    """The event stream a DV server (DV software, ``dv-processing``'s NetworkWriter) serves over TCP
    (its times the sender's: ``clock``)."""

    clock, clock_span_us = SENDER, None

    def __init__(self, url, host, port, sensor_size=None, *, wait_s: float = WAIT_S):
        dv = _dv_processing(url)
        t0 = time.perf_counter()
        while True:
            left = max(wait_s - (time.perf_counter() - t0), 0.0) + HEADER_GRACE_S
            try:
                with ends_process_after(left, f"{url}: {not_served(wait_s, 'it never sent a DV stream header')}"):
                    reader = dv.io.NetworkReader(host, port)
                break
            except RuntimeError as exc:
                if time.perf_counter() - t0 > wait_s:
                    raise InputError(url, not_served(wait_s, dv_reason(exc))) from None
                time.sleep(0.1)
        self._begin(url, reader, sensor_size, "the DV server there sends no event stream", "the stream's")

    def _begin(self, url, reader, sensor_size, no_events: str, whose: str):
        """Read ``reader`` (a ``dv-processing`` input) from now on, once it is found to give events
        (``no_events``: what it is said when not) of the size ``sensor_size`` where given (``whose``: its size)."""
        self.name, self.malformed, self.closed, self.reader = url, 0, False, reader
        problem = None
        if not self.reader.isEventStreamAvailable():
            problem = no_events
        else:
            size = tuple(int(v) for v in self.reader.getEventResolution())
            if sensor_size is not None and tuple(int(v) for v in sensor_size[:2]) != size:
                problem = f"--sensor-size {sensor_size[0]}x{sensor_size[1]} disagrees with {whose} {size[0]}x{size[1]}"
        if problem is not None:
            self.reader = None
            raise InputError(url, problem)
        self.sensor_size = size
        # (the reader is emptied from the connection on: dv-processing's reader throws away what it holds
        # untaken when the server closes, and a short stream's server closed before a model that warmed up
        # after connecting, without --sensor-size, asked for the first event: "the stream ended before any event")
        self.early, self.ended, self.handed_over = [], False, threading.Event()
        self.taken, self.failed = 0, None  # (events taken; what stopped the early taking, raised by packets())
        self.broken = None  # (the reader's stream cannot go on: raised once the events before it are given)
        self.taking = threading.Thread(target=self._take_early, name="snn-fg dv reader", daemon=True)
        self.taking.start()

    def _take_early(self):
        """Until :meth:`packets` begins: what the reader holds, kept (up to :data:`EARLY_EVENTS`); an error
        is kept for :meth:`packets` to raise on the receiving thread (on this one it was a traceback of its
        own, and the run went on without the rest of the stream)."""
        try:
            self._keep_early()
        except BaseException as exc:
            self.failed = exc

    def _keep_early(self):
        held = 0
        while not self.handed_over.is_set():
            got = self._take()
            if got is _ENDED:
                self.ended = True
                return
            if got is None:
                time.sleep(DV_POLL_S)
            elif held + len(got[0]) > EARLY_EVENTS:  # (a camera's stream during a long warm-up)
                warnings.warn(
                    f"{self.name}: more than {EARLY_EVENTS:,} events came before the model was ready; "
                    "the stream goes on from where the reader is (--sensor-size warms up before connecting)",
                    InputWarning,
                    stacklevel=1,
                )
                return
            else:
                held += len(got[0])
                self.early.append(got)

    def _take(self):
        """The batches the reader holds (up to :data:`BATCH`) as one, with when they were taken; None
        when it holds none, :data:`_ENDED` once the server has closed. A stream that cannot go on
        (:meth:`_broken`) raises its InputError once the events before it are given."""
        if self.broken is not None:  # (the events before it were given first)
            raise self.broken
        parts, failed = [], 0
        while len(parts) < BATCH:
            try:
                batch = self.reader.getNextEventBatch()
            except RuntimeError as exc:  # (a packet the reader could not decode)
                self.malformed, failed = self.malformed + 1, failed + 1
                self.broken = self._broken(exc, failed, self.taken + sum(len(a) for a in parts))
                if self.broken is not None:
                    break
                continue
            failed = 0
            if batch is None:
                break
            parts.append(batch.numpy())
        if not parts:
            if self.broken is not None:
                raise self.broken
            return None if self.reader.isRunning() else _ENDED
        arrived = time.perf_counter()
        a = parts[0] if len(parts) == 1 else np.concatenate(parts)
        ev = np.empty(len(a), EVENT_DTYPE)
        ev["t"], ev["x"], ev["y"], ev["p"] = a["timestamp"], a["x"], a["y"], a["polarity"]
        self.taken += len(ev)
        return ev, arrived

    def _broken(self, exc: RuntimeError, failed: int, at: int) -> InputError | None:
        """What ends the stream when the reader could not read ``failed`` packets in a row (the last one
        raising ``exc``) at event ``at``: once the reader has stopped, or after :data:`UNREADABLE_IN_A_ROW`
        of them; None while it may go on (the packet counted as malformed, and skipped)."""
        running = self.reader.isRunning()
        if running and failed < UNREADABLE_IN_A_ROW:
            return None
        said = (
            f"{failed} packets in a row could not be read"
            if running
            else "the reader stopped at a packet it could not read"
        )
        return InputError(self.name, f"the stream cannot go on: {said} ({_said(exc)})", f"event {at:,}")

    def packets(self):
        """What the reader held before (:meth:`_take_early`), then each batch of events the reader holds
        (those it holds together, up to :data:`BATCH`), and when the last of them was taken; the reader
        is asked every :data:`DV_POLL_S` while it has none."""
        self._hand_over()
        early, self.early = self.early, []
        yield from early
        if self.failed is not None:
            raise self.failed
        while not (self.closed or self.ended):
            got = self._take()
            if got is _ENDED:
                return
            if got is None:
                time.sleep(DV_POLL_S)
                continue
            yield got

    def _hand_over(self):
        self.handed_over.set()
        self.taking.join()

    def close(self):
        """Disconnects (a DV server waits for its readers to go)."""
        self.closed = True
        self._hand_over()
        self.reader = None


class CameraSource(DvSource):
    """An iniVation camera (DAVIS, DVXplorer, DVS128) on this machine's USB, read with
    ``dv-processing`` as a ``dv://`` stream is read, with no DV software: ``camera://`` the
    first one found, ``camera://SERIAL`` that one (``found``: found already, :func:`camera_found`).
    Its times are the camera's (``clock``)."""

    def __init__(self, url: str, sensor_size=None, *, found: bool = False):
        dv = _dv_processing(url) if found else camera_found(url)
        serial = url.removeprefix(CAMERA)
        try:
            reader = dv.io.camera.open(serial) if serial else dv.io.camera.open()
        except (RuntimeError, IndexError) as exc:  # (a serial not found; a camera gone since it was found)
            raise InputError(url, f"cannot open the camera: {_said(exc)}") from None
        self._begin(url, reader, sensor_size, "the camera there gives no events", "the camera's")


def camera_found(url: str):
    """dv-processing, once it has found the camera ``url`` names on USB (``camera://``: any,
    ``camera://SERIAL``: that serial number); an InputError naming ``url`` if not. Asked before
    a live run's warm-up where that comes first (the size given), and not again as it is opened."""
    dv = _dv_processing(url)
    found, serial = dv.io.camera.discover(), url.removeprefix(CAMERA)
    if not found:
        raise InputError(url, "no iniVation camera found on this machine's USB (dv-processing looked)")
    serials = [str(getattr(d, "serialNumber", "")) for d in found]
    if serial and serial not in serials:
        raise InputError(url, f"no camera with serial number {serial} on USB (found: {', '.join(serials)})")
    return dv


def _dv_processing(url: str):
    try:
        import dv_processing as dv  # (the live extra)
    except ImportError:
        raise InputError(url, f"reading {url.split('//')[0]}// needs dv-processing: pip install -e '.[live]'") from None
    return dv


def _said(exc: Exception) -> str:
    """The message of a ``dv-processing`` error, without the source location and stack it carries."""
    lines = str(exc).splitlines()
    said = [line.split(": ", 1)[1] for line in lines if line.startswith("RuntimeError: ")]
    return said[0] if said else dv_reason(exc)


#: what :meth:`DvSource._take` gives once the server has closed the stream
_ENDED = object()
