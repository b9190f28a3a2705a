"""A recording replayed as a live stream, in real time or ``speed`` times faster
(``snn-fg stream``): SPIF packets over UDP (:mod:`snn_fg.events.spif`) or a
DV network stream (``dv-processing``'s NetworkWriter, a server a reader connects to).

Events keep the recording's own timestamps (a SPIF packet carries them modulo 2**32 us), so
that a live run of the replay and ``snn-fg run`` on the recording have their windows on one
clock and ``snn-fg compare`` pairs those that hold the same events. ``loop`` plays the
recording that many times, each time after the last (:func:`looped`).
"""

from __future__ import annotations

import os
import socket
import time

import numpy as np

from snn_fg.errors import InputError
from snn_fg.events import spif
from snn_fg.events.io import iter_recording
from snn_fg.events.live_dv import dv_reason
from snn_fg.events.live_sources import parse_address

#: how long a ``dv://`` sender waits for its reader (s; ``snn-fg stream --wait-s``: a first
#: ``snn-fg live`` compiles its model for up to a minute before it connects)
SEND_WAIT_S = 120.0

#: how often the sender wakes to send what is due (s)
TICK_S = 0.001


def looped(chunks, n: int):
    """The event chunks of a recording (``chunks()``: an iterable, made anew for
    each loop) ``n`` times in a row: the first loop at the recording's own
    times, each later one 1 ms after the one before ends."""
    shift = 0  # (added to a loop's times)
    for _ in range(n):
        t0 = last = None
        for chunk in chunks():
            if not len(chunk):
                continue
            t0 = int(chunk["t"][0]) if t0 is None else t0
            out = chunk.copy()  # (a reader may fill its chunks' memory again)
            out["t"] += shift
            last = int(out["t"][-1])
            yield out
        if last is None:
            return
        shift = last + 1000 - t0


def from_ms(chunks, ms: float, t_first: int | None = None):
    """The events of ``chunks`` from ``ms`` after the first on (a recording's start-up burst left out);
    ``t_first``: the recording's first event's time, where ``chunks`` begin past it."""
    t0 = t_first
    for chunk in chunks:
        if len(chunk):
            t0 = int(chunk["t"][0]) if t0 is None else t0
            chunk = chunk[chunk["t"] >= t0 + int(round(ms * 1000))]
        if len(chunk):
            yield chunk


def recording_from_ms(source, ms: float, **read):
    """The events of the recording ``source`` (``read``: :func:`~snn_fg.events.io.iter_recording`'s
    options) from ``ms`` after its first on: read from there where the file indexes its times (DSEC's
    ``ms_to_idx``, :meth:`~snn_fg.events.io.RecordingStream.skip_to`), else from its start."""
    stream = iter_recording(source, **read)
    skipped = stream.skip_to(int(round(ms * 1000))) if ms > 0 else None
    return from_ms(stream, ms, None if skipped is None else skipped[0])


def paced(chunks, speed: float, tick_s: float = TICK_S):
    """The events of ``chunks`` (times in us) in pieces, each yielded once the
    wall clock has reached its last event's time after the first event's (divided
    by ``speed``): what is due every ``tick_s`` (the sender sleeps in between, so
    that a dense stream does not keep a core busy; events are sent at most a tick late)."""
    start = t0 = None
    for chunk in chunks:
        if not len(chunk):
            continue
        if t0 is None:
            start, t0 = time.perf_counter(), int(chunk["t"][0])
        t = np.ascontiguousarray(chunk["t"])  # (a field is strided: searched as it is, it is copied per search)
        i = 0
        while i < len(t):
            now_us = t0 + (time.perf_counter() - start) * 1e6 * speed
            j = int(np.searchsorted(t, t.dtype.type(now_us), side="right"))  # (a float would cast all of t)
            if j > i:
                yield chunk[i:j]
                i = j
            if i < len(t):  # (until the next event is due, at least a tick)
                time.sleep(max(tick_s, (t[i] - now_us) / 1e6 / speed))


class UdpSender:
    """SPIF packets (with timestamps unless ``timestamps=False``) to ``udp://HOST:PORT``."""

    def __init__(self, url: str, timestamps: bool = True):
        _, host, port = parse_address(url, "--to")
        self.address, self.timestamps = (host, port), timestamps
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sent = 0

    def load(self, events):
        """(Nothing to prepare: packets are made as they are sent.)"""

    def send(self, events):
        for i in range(0, len(events), spif.PACKET_EVENTS):
            part = events[i : i + spif.PACKET_EVENTS]
            self.sock.sendto(spif.encode(part, self.timestamps), self.address)
            self.sent += len(part)

    def close(self) -> bool:
        self.sock.close()
        return False


class DvSender:
    """A DV network stream served on ``dv://HOST:PORT``; waits up to ``wait_s`` for a reader to connect."""

    def __init__(self, url: str, sensor_size, wait_s: float = SEND_WAIT_S):
        try:
            import dv_processing as dv  # (the live extra)
        except ImportError:
            raise InputError(url, "serving dv:// needs dv-processing: pip install -e '.[live]'") from None
        _, host, port = parse_address(url, "--to")
        self.dv, self.sent = dv, 0
        stream = dv.io.Stream.EventStream(0, "events", "snn-fg", (int(sensor_size[0]), int(sensor_size[1])))
        before = _threads()
        try:
            self.writer = dv.io.NetworkWriter(host, port, stream)
        except RuntimeError as exc:  # (the port taken, or an address not of this machine)
            raise InputError(url, f"cannot serve there: {dv_reason(exc).removeprefix('bind: ')}") from None
        self.yielding = _yield_cpu(_threads() - before)
        t0 = time.perf_counter()
        while self.writer.getClientCount() == 0:
            if time.perf_counter() - t0 > wait_s:
                raise InputError(url, f"no reader connected within {wait_s:g} s")
            time.sleep(0.01)

    def load(self, events):
        """The whole replay as one event store before it starts (dv-processing adds an
        event in about 2 us from Python, too slow to keep pace with a camera; a slice of
        a store is taken at once)."""
        self.store = self.dv.EventStore()
        for t, x, y, p in zip(
            events["t"].tolist(), events["x"].tolist(), events["y"].tolist(), events["p"].tolist(), strict=True
        ):
            self.store.push_back(t, x, y, bool(p))

    def send(self, events):
        self.writer.writeEvents(self.store.sliceTime(int(events["t"][0]), int(events["t"][-1]) + 1))
        self.sent += len(events)

    def close(self, linger_s: float = 1.0) -> bool:
        """Waits (up to 5 s) for the queue to be sent, then ``linger_s`` more while
        a reader is connected: a ``dv-processing`` reader throws away what it
        has received but not yet taken when the connection closes. Then the
        server is taken down if no reader is connected; ``True`` if one is:
        the writer cannot be deleted from Python while a reader is connected
        (its destructor waits for its network thread, which waits for the
        interpreter lock the deleting thread holds, to report the reader
        gone). The caller then ends the process without tearing the writer
        down (``os._exit``); the operating system closes the connection,
        which is how a reader learns that the stream ended."""
        t0 = time.perf_counter()
        while self.writer.getQueuedPacketCount() and time.perf_counter() - t0 < 5:
            time.sleep(0.01)
        t0 = time.perf_counter()
        while self.writer.getClientCount() and time.perf_counter() - t0 < linger_s:
            time.sleep(0.01)
        if self.writer.getClientCount():
            return True
        del self.writer
        return False


#: the scheduling priority (``nice``) of dv-processing's network thread: the lowest
WRITER_NICE = 19


def _threads() -> set[int]:
    """This process's thread ids (Linux: ``/proc/self/task``; empty elsewhere)."""
    try:
        return {int(t) for t in os.listdir("/proc/self/task")}
    except OSError:
        return set()


def _yield_cpu(tids) -> int:
    """Threads ``tids`` put at the lowest priority (:data:`WRITER_NICE`); returns how many.

    dv-processing's ``NetworkWriter`` (2.0.4) serves from a thread that polls its
    sockets without pause: 3 s of CPU in 3 s with no reader and nothing to send,
    and as much while it sends. At the lowest priority it takes what other
    programs leave (a live run beside it, which waits for every event), and
    still sends as soon as they wait."""
    done = 0
    for tid in tids:
        try:
            os.setpriority(os.PRIO_PROCESS, tid, WRITER_NICE)
            done += 1
        except OSError:  # (the thread gone, or not ours to change: it keeps its priority)
            pass
    return done


def open_sender(url: str, sensor_size, timestamps: bool = True, wait_s: float = SEND_WAIT_S):
    """The sender of ``snn-fg stream --to url`` (``wait_s``: how long a ``dv://`` server waits for its reader)."""
    scheme, _, _ = parse_address(url, "--to")
    return UdpSender(url, timestamps) if scheme == "udp" else DvSender(url, sensor_size, wait_s)
