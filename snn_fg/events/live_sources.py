"""Live event sources: ``udp://HOST:PORT`` (SPIF packets, :mod:`snn_fg.events.spif`),
``dv://HOST:PORT`` (iniVation's DV network stream, read with ``dv-processing``), and
from Python any iterable of event chunks that your own code makes (:class:`ChunkSource`).

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
import threading
import time
import warnings

import numpy as np

from snn_fg.errors import InputError, InputWarning
from snn_fg.events import spif
from snn_fg.events._core import EVENT_DTYPE, as_events, check_sensor_size
from snn_fg.events.clock import ARRIVAL, SENDER
from snn_fg.validate import address

#: the schemes a live source is named by (HOST:PORT after them), and the one of a camera on USB
SCHEMES = ("udp", "dv")
CAMERA = "camera://"
#: a UDP socket's receive buffer asked for (the kernel may give less: net.core.rmem_max)
UDP_BUFFER = 8 << 20
#: packets taken off a UDP socket's buffer at a time, at most, once one has arrived: the events of those
#: already waiting are checked and queued for the model together (per packet, that took a sixth of a
#: core beside the compact network, 29 Nov); none is waited for
BATCH = 64
#: how long a DV stream's reader is left before it is asked again, when it had no batch (dv-processing's
#: reader cannot be waited on). Every 0.5 ms, with a batch passed on as it came, the receiving thread took
#: about a fifth of one core beside the compact network (30 Nov): 2 ms bounds what it adds to a latency
DV_POLL_S = 0.002
#: events a DV stream's reader is emptied of, at most, before the model asks for the stream (while it
#: warms up): about 260 MB; the rest is left to the reader, and said
EARLY_EVENTS = 20_000_000


def parse_address(url: str, owner: str = "source") -> tuple[str, str, int]:
    """``(scheme, host, port)`` of ``udp://HOST:PORT`` or ``dv://HOST:PORT`` (an InputError naming ``url``)."""
    return address(url, SCHEMES, owner)


def open_source(url, sensor_size=None, *, wait_s: float = 30.0, idle_s: float = 1.0, found: bool = False):
    """The live source ``url`` names; ``sensor_size`` ``(W, H)``: a UDP stream's (it
    has none of its own), a DV stream's if given (it must agree with the stream's).
    Anything else than a string is taken for chunks of events (:class:`ChunkSource`).
    ``found``: a ``camera://`` found on USB already (:func:`camera_found`), not looked for again."""
    if not isinstance(url, str):
        if sensor_size is None:
            raise InputError("<events>", "events handed over chunk by chunk have no sensor size of their own: give it")
        return ChunkSource(url, sensor_size)
    if url.startswith(CAMERA):
        return CameraSource(url, sensor_size, found=found)
    scheme, host, port = parse_address(url)
    if scheme == "udp":
        if sensor_size is None:
            raise InputError(
                url, "a UDP (SPIF) stream has no sensor size of its own: give --sensor-size WxH (sensor_size=(W, H))"
            )
        return UdpSource(url, host, port, sensor_size, wait_s=wait_s, idle_s=idle_s)
    return DvSource(url, host, port, sensor_size, wait_s=wait_s)


class ChunkSource:
    """A live stream that your own code hands over: ``chunks``, any iterable of event
    arrays (fields ``x``, ``y``, ``t`` in microseconds, ``p``; :func:`~snn_fg.events._core.as_events`),
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

    def __init__(self, url, host, port, sensor_size, *, wait_s: float = 30.0, idle_s: float = 1.0):
        self.name, self.sensor_size = url, (int(sensor_size[0]), int(sensor_size[1]))
        self.wait_s, self.idle_s, self.malformed, self.closed = wait_s, idle_s, 0, False
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
                raise InputError(self.name, came if n else f"no packet arrived within {self.wait_s:g} s") from None
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


def dv_reason(exc: RuntimeError) -> str:
    """What a ``dv-processing`` network error says, without the Boost source location it appends
    (``connect: Connection refused``)."""
    return str(exc).split(" [")[0]


class DvSource:
    """The event stream a DV server (DV software, ``dv-processing``'s NetworkWriter) serves over TCP
    (its times the sender's: ``clock``)."""

    clock, clock_span_us = SENDER, None

    def __init__(self, url, host, port, sensor_size=None, *, wait_s: float = 30.0):
        dv = _dv_processing(url)
        t0 = time.perf_counter()
        while True:
            try:
                reader = dv.io.NetworkReader(host, port)
                break
            except RuntimeError as exc:
                if time.perf_counter() - t0 > wait_s:
                    raise InputError(url, f"no DV server answered within {wait_s:g} s ({dv_reason(exc)})") from None
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
        self.taking = threading.Thread(target=self._take_early, name="snn-fg dv reader", daemon=True)
        self.taking.start()

    def _take_early(self):
        """Until :meth:`packets` begins: what the reader holds, kept (up to :data:`EARLY_EVENTS`)."""
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
        when it holds none, :data:`_ENDED` once the server has closed."""
        parts = []
        while len(parts) < BATCH:
            try:
                batch = self.reader.getNextEventBatch()
            except RuntimeError:  # (a packet the reader could not decode)
                self.malformed += 1
                continue
            if batch is None:
                break
            parts.append(batch.numpy())
        if not parts:
            return None if self.reader.isRunning() else _ENDED
        arrived = time.perf_counter()
        a = parts[0] if len(parts) == 1 else np.concatenate(parts)
        ev = np.empty(len(a), EVENT_DTYPE)
        ev["t"], ev["x"], ev["y"], ev["p"] = a["timestamp"], a["x"], a["y"], a["polarity"]
        return ev, arrived

    def packets(self):
        """What the reader held before (:meth:`_take_early`), then each batch of events the reader holds
        (those it holds together, up to :data:`BATCH`), and when the last of them was taken; the reader
        is asked every :data:`DV_POLL_S` while it has none."""
        self._hand_over()
        early, self.early = self.early, []
        yield from early
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
