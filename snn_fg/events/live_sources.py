"""Live event sources: ``udp://HOST:PORT`` (SPIF packets, :mod:`snn_fg.events.spif`),
``dv://HOST:PORT`` and ``camera://`` (iniVation's DV network stream and cameras, read with
``dv-processing``: :mod:`snn_fg.events.live_dv`), and from Python any iterable of event
chunks that your own code makes (:class:`ChunkSource`); :func:`open_source` opens the one named.

A source's :meth:`packets` runs on the receiving thread and yields the
events of each packet, or of the packets that came together, with the time
the last of them arrived (``time.perf_counter()``), and
ends when the sender has gone: a DV stream when its server closes the
connection, a UDP stream (which has no end) once no packet has come for
``idle_s`` seconds after the first. No packet within ``wait_s`` of
:meth:`packets` starting (the model is ready then) is an error. Malformed
packets are counted (:attr:`malformed`) and skipped.
"""

from __future__ import annotations

import os
import select
import socket
import time
import warnings

import numpy as np

from snn_fg.errors import InputError, InputWarning, Remedy
from snn_fg.events import spif
from snn_fg.events.clock import ARRIVAL, SENDER
from snn_fg.events.core import SENSOR_SIZE, as_events, check_sensor_size
from snn_fg.events.live_dv import CAMERA, WAIT_S, CameraSource, DvSource
from snn_fg.events.live_screen import BATCH
from snn_fg.validate import address

#: the schemes a live source is named by (HOST:PORT after them; a camera on USB: live_dv.CAMERA)
SCHEMES = ("udp", "dv")
#: a UDP socket's receive buffer asked for (the kernel may give less: net.core.rmem_max)
UDP_BUFFER = 8 << 20


#: how long a UDP stream may be idle before it counts as ended (s; ``--idle-s``)
IDLE_S = 1.0


def parse_address(url: str, owner: str = "source") -> tuple[str, str, int]:
    """``(scheme, host, port)`` of ``udp://HOST:PORT`` or ``dv://HOST:PORT`` (an InputError naming ``url``)."""
    return address(url, SCHEMES, owner, others=(f"{CAMERA}[SERIAL]",) if owner == "source" else ())


def open_source(url, sensor_size=None, *, wait_s: float = WAIT_S, idle_s: float = IDLE_S, found: bool = False):
    """The live source ``url`` names; ``sensor_size`` ``(W, H)``: a UDP stream's (it
    has none of its own), a DV stream's if given (it must agree with the stream's).
    Anything else than a string is taken for chunks of events (:class:`ChunkSource`). ``found``:
    a ``camera://`` found on USB already (:func:`~snn_fg.events.live_dv.camera_found`), not looked for again."""
    if not isinstance(url, str):
        if sensor_size is None:
            raise InputError("<events>", "events handed over chunk by chunk have no sensor size of their own: give it")
        return ChunkSource(url, sensor_size)
    if url.startswith(CAMERA):
        return CameraSource(url, sensor_size, found=found)
    scheme, host, port = parse_address(url)
    if scheme == "udp":
        if sensor_size is None:
            raise InputError(url, "a UDP (SPIF) stream has no sensor size of its own", remedy=SENSOR_SIZE)
        return UdpSource(url, host, port, sensor_size, wait_s=wait_s, idle_s=idle_s)
    return DvSource(url, host, port, sensor_size, wait_s=wait_s)


class ChunkSource:
    """A live stream that your own code hands over: ``chunks``, any iterable of event
    arrays (fields ``x``, ``y``, ``t`` in microseconds, ``p``; :func:`~snn_fg.events.core.as_events`),
    such as a generator reading a camera's SDK or a YARP port, read on the receiving
    thread. A chunk has arrived when the iterable gives it; the stream ends with the
    iterable. Its times are the chunks' own (``clock`` :data:`~snn_fg.events.clock.SENDER`).
    A chunk that is not events is an error naming the event's place in the stream."""

    clock, clock_span_us = SENDER, None

    def __init__(self, chunks, sensor_size, name: str = "<events>"):
        if isinstance(chunks, np.ndarray):  # (one array is a recording, not a stream of chunks)
            raise InputError(name, "give the live stream as an iterable of event arrays (one array: snn-fg run)")
        self.chunks, self.name = chunks, name
        self.sensor_size = check_sensor_size(sensor_size, name)[:2]
        self.malformed, self.closed, self.given = 0, False, 0

    def packets(self):
        for k, chunk in enumerate(self.chunks):
            if self.closed:  # (the iterable is left as it is: it may be blocked in another thread's read)
                return
            ev = as_events(chunk, self.name, self.given, what=f"chunk {k}")
            self.given += len(ev)
            if len(ev):
                yield ev, time.perf_counter()

    def close(self):
        self.closed = True


class UdpSource:
    """SPIF event packets arriving on a UDP port (bound at construction). Their times are the
    sender's, modulo 2**32 us (``clock`` :data:`~snn_fg.events.clock.SENDER`, ``clock_span_us``),
    or, once a packet came whose first event has no timestamp, the arrival's
    (:data:`~snn_fg.events.clock.ARRIVAL`)."""

    clock_span_us = spif.Unwrap.SPAN

    def __init__(self, url, host, port, sensor_size, *, wait_s: float = WAIT_S, idle_s: float = IDLE_S):
        self.name, self.sensor_size = url, (int(sensor_size[0]), int(sensor_size[1]))
        self.wait_s, self.idle_s, self.malformed, self.closed = wait_s, idle_s, 0, False
        # (UDP has no end of its own: the stream ends when it falls silent; live.json's ``ended``)
        self.ended_by = f"the sender stopped: no packet for {idle_s:g} s (--idle-s)"
        self.clock = SENDER
        self.packets_lost = None  # (read as the socket closes: _udp_drops)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, UDP_BUFFER)
        try:
            self.sock.bind((host, port))
        except OSError as exc:
            self.sock.close()
            raise InputError(url, f"cannot listen there: {exc.strerror}") from None
        spif.prepare()  # (compiled now, before the model's warm-up, not at the first packet)
        self.t_start = time.perf_counter()

    def packets(self):
        """Each batch of packets that has come (those waiting in the socket's buffer once one
        has arrived, up to :data:`BATCH`): their events, and when the last of them arrived."""
        unwrap, first = spif.Unwrap(), True
        # (the socket never blocks: a packet is waited for with select, and those waiting behind it are
        # taken without waiting. Until 29 Nov the socket had a timeout, under which Python waits for a
        # packet before every receive, MSG_DONTWAIT or not: a batch grew until 64 packets had come,
        # 160 ms of dvs.es, before any of its events reached the model)
        self.sock.setblocking(False)
        # (the first packet is waited for from here, when the model is ready for it, not from when the
        # port was bound: a first run's warm-up compiles the engine for up to a minute meanwhile)
        last = waiting_since = time.perf_counter()  # (last: the latest packet with events)
        while not self.closed:
            try:
                ready = select.select([self.sock], [], [], 0.1)[0]
            except (OSError, ValueError):
                return  # (closed)
            data = self._waiting() if ready else None
            parts, arrived, taken = [], None, 0
            while data is not None:
                taken += 1
                now = time.perf_counter()
                ev = spif.decode(data, int((now - self.t_start) * 1e6))
                # (a packet without an event, garbage or empty, is counted and is no arrival: it neither
                # begins the idle clock nor holds it back, so a noisy port cannot keep a stream open, and a
                # stray datagram before the sender's first packet cannot end the stream before it begins)
                if ev is None or not len(ev):
                    self._malformed(data)
                else:
                    parts.append(ev)
                    arrived = now
                    if data[3] & 0x80:  # (the first word's bit 31: an event stamped on arrival)
                        self.clock = ARRIVAL
                data = self._waiting() if taken < BATCH else None  # (packets taken: a flood of garbage too)
            if parts:
                first, last = False, arrived
                ev = parts[0] if len(parts) == 1 else np.concatenate(parts)
                ev["t"] = unwrap(ev["t"])
                yield ev, last
                continue
            now = time.perf_counter()  # (no event came: the waits are checked, garbage or silence)
            if first and now - waiting_since > self.wait_s:
                n = self.malformed
                came = f"no event arrived within {self.wait_s:g} s, only {n:,} malformed packet{'s' * (n != 1)}"
                said = came if n else f"no packet arrived within {self.wait_s:g} s"
                # (run_live's keyword, or the command line's option: each front door names its own)
                raise InputError(
                    self.name, said, remedy=Remedy("wait_s=S", "--wait-s S"), note=" to wait longer"
                ) from None
            if not first and now - last > self.idle_s:
                return  # (the sender has gone: UDP has no end of its own)

    def _waiting(self) -> bytes | None:
        """The next packet if one is waiting in the socket's buffer, else None."""
        try:
            return self.sock.recv(1 << 16)
        except OSError:  # (none waiting, interrupted, or closed: the next wait says so)
            return None

    def _malformed(self, data: bytes) -> None:
        self.malformed += 1
        if self.malformed == 1:
            warnings.warn(
                f"{self.name}: a malformed packet ({len(data)} bytes, not whole SPIF events, or none); such packets "
                "are skipped and counted (packets_malformed: live.json, run_live's summary)",
                InputWarning,
                stacklevel=3,
            )

    def close(self):
        if not self.closed:  # (read while the socket is there: the kernel forgets its count with it)
            self.packets_lost = _udp_drops(self.sock)
        self.closed = True
        self.sock.close()


def _udp_drops(sock) -> int | None:
    """The packets the kernel dropped for ``sock`` because its receive buffer was full (Linux's
    ``/proc/net/udp`` ``drops``, matched by the socket's inode); None where that cannot be read."""
    try:
        inode = str(os.fstat(sock.fileno()).st_ino)
        for table in ("/proc/net/udp", "/proc/net/udp6"):
            with open(table) as f:
                for line in f.readlines()[1:]:
                    cols = line.split()
                    if len(cols) > 12 and cols[9] == inode:
                        return int(cols[-1])
    except (OSError, ValueError):
        pass
    return None
