"""A recording's or a live stream's input to the spiking network, read once and causally.

A stream can be read once. The events reach the network as they arrive
(:func:`arrivals`: each chunk's events that some window holds, and the
windows the chunk completes, cut by a :class:`~snn_fg.events.cutter.WindowCutter`
on the stream's own clock), and :class:`StreamFeed` turns them into input
spikes as the backend asks for the next segment of steps
(:class:`~snn_fg.lowering.input_stream.SegmentedInput`), holding each
window's event frame until its maps are decoded. Nothing the run needs is
taken from events that have not arrived yet:

* the network is made for the sensor's frame, and its input gains are
  calibrated before the first event (:func:`stream_rate_hz`);
* window ``k`` is read out over its whole span
  ``[start_k + lag, start_k + window + lag)`` on the stream's grid, also
  when the stream ends inside it (a recording's last window), so that the
  read-out spans, the counting bins and the window clock are laid out
  before the run starts. A backend that streams its input is laid out for
  :data:`HORIZON_MS` of windows and stopped once the stream's last window is
  read (:class:`StreamEnded`); one that takes its input whole
  (:attr:`~snn_fg.backends.base.Backend.streams_input` false) gets it once
  the stream has ended (``drain``).

So a recording run and a live run of the same events give the same maps.
Each event is fed once: where windows overlap, the shared events are fed by
the first window that holds them.

:class:`StreamLayout` owns that layout, fixed before the run starts (made
by :func:`~snn_fg.models.spiking.continuous.lay_out`): the network, each
window's read-out span (the backend's counting bins are their edges), and
when the window clock fires and the ``window`` coding's holds end
(:meth:`StreamLayout.clock_steps`, :meth:`StreamLayout.resets`; its
docstring states the clock's rule, ``docs/spiking-network.md`` explains it).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ...errors import InputError, ParameterError
from ...frames.pool import pool_events, pooled_shape
from ...lowering.held_input import HeldStream
from ...lowering.input_stream import SegmentedInput, SpikeStream
from ...network.graph import HELD_CODINGS

#: simulated time per segment of input handed to a backend that streams it (ms); a live
#: run hands it over in shorter segments, so that the network follows the events closely
SEGMENT_MS = 100.0
#: how far ahead a run over a stream of unknown length is laid out (ms of the stream):
#: its counting bins, one step table of 8 bytes a step (29 MB an hour at 1 ms). A
#: stream that goes on longer ends there, said in one line
HORIZON_MS = 3_600_000.0


class StreamEnded(Exception):
    """Raised through a streaming backend's run once the stream's last window is read:
    the run was laid out for longer (:data:`HORIZON_MS`) and has nothing more to do."""


def stream_rate_hz(net, first_window) -> float:
    """The input rate per active source that ``net``'s gains are calibrated to for
    a stream, known before the network needs it (the gains of a run cannot
    change while it runs).

    A network with an input adapter's refractory period ``R`` (the compact
    network: 60 ms) gets the rate of a source that passes events as often as
    its adapter lets it, ``1000 / R`` Hz, known before any event: every active
    source fires at most that often (on the shared recordings a window's
    active sources fire at 74-94 % of it, ``docs/live.md``). A network without
    one gets the rate of an active source in the stream's first window
    (``first_window()`` gives it: its events on the input grid, one spike per
    source and step), so that its run starts once that window is complete.
    The held input codings (``window``, ``sliding``) need none (their held
    sources fire at the network's own rate, :attr:`~snn_fg.network.Network.input_rate_hz`)."""
    if net.input_coding in HELD_CODINGS:
        return net.input_rate_hz
    if net.input_refractory_ms > 0:
        return 1000.0 / net.input_refractory_ms
    w = first_window()
    pool = net.params.input_pool
    dt_ms = net.dt_ms
    spikes = SpikeStream(pooled_shape(w.pos.shape, pool), dt_ms, w.t_start_us)
    spikes.add(pool_events(w.events, pool))
    idx, _ = spikes.take_until(np.iinfo(np.int64).max // (4 * spikes.h * spikes.w + 4))
    if not idx.size:
        return net.input_rate_hz
    span_s = max((w.t_end_us - w.t_start_us) / 1e6, dt_ms / 1000.0)
    return idx.size / np.unique(idx).size / span_s


def read_out_spans(t_start_us, t_end_us, t0_us: float, lag_ms: float, dt_ms: float) -> list:
    """Windows' read-out spans ``(start, end)`` (ms from ``t0_us``, lag included)
    on the step grid, each at least one step long (arrays of the windows'
    times in, a list of pairs out)."""
    a = np.round(((np.asarray(t_start_us) - t0_us) / 1000.0 + lag_ms) / dt_ms).astype(np.int64)
    b = np.round(((np.asarray(t_end_us) - t0_us) / 1000.0 + lag_ms) / dt_ms).astype(np.int64)
    return list(zip((a * dt_ms).tolist(), (np.maximum(b, a + 1) * dt_ms).tolist(), strict=True))


def window_steps(t_start_us, t_end_us, t0_us: float, dt_ms: float):
    """The steps ``a .. b - 1`` windows' input spikes fall on (at least one each):
    ``(a, b)`` as arrays of the windows' times."""
    a = np.floor((np.asarray(t_start_us) - t0_us) / (dt_ms * 1000.0)).astype(np.int64)
    b = np.floor((np.asarray(t_end_us) - t0_us) / (dt_ms * 1000.0)).astype(np.int64)
    return np.stack([a, np.maximum(b, a + 1)])


@dataclasses.dataclass(frozen=True)
class Arrival:
    """What one chunk of a stream brings: the ``events`` the network is fed
    (those some window holds, each once; or None), the ``windows`` it
    completes, ``known_until_us`` (every event before that time has arrived;
    infinite once the stream has ended) and ``origin_us``, the first window's
    start (None until an event has come)."""

    events: np.ndarray | None
    windows: list
    known_until_us: float
    origin_us: float | None


def arrivals(chunks, cut):
    """The :class:`Arrival` of each chunk of events (in time order) cut by
    ``cut`` (a :class:`~snn_fg.events.cutter.WindowCutter`), and a last one
    once the stream has ended. Windows whose events are filtered
    (``denoise_us``, ``refractory_us``: each window's own) feed their events
    as they complete, the others as they arrive."""
    fed_to = None  # (filtered) events before this time have been fed
    known = -np.inf
    for chunk in chunks:
        done = cut.add(chunk)
        if cut.filtered:
            events, fed_to = _new_events(done, fed_to)
            known = done[-1].t_end_us if done else known
        elif len(chunk):
            events, known = cut.held_events(chunk), cut.prev_t
        else:  # (no event; the clock may have passed dropped ones: events.cutter.TimePassed)
            events, known = None, known if cut.prev_t is None else cut.prev_t
        yield Arrival(events, done, known, cut.origin)
        if cut.done:
            break
    last = cut.finish()
    yield Arrival(_new_events(last, fed_to)[0] if cut.filtered else None, last, np.inf, cut.origin)


def window_arrivals(windows):
    """The :class:`Arrival` of each window of an iterable of windows (a list, say):
    its events not in the window before."""
    fed_to = origin = None
    for w in windows:
        events, fed_to = _new_events([w], fed_to)
        origin = w.t_start_us if origin is None else origin
        yield Arrival(events, [w], w.t_end_us, origin)
    yield Arrival(None, [], np.inf, origin)


def _new_events(windows, fed_to):
    """The events of ``windows`` (in order) from ``fed_to`` on, and the time fed to after them."""
    parts = []
    for w in windows:
        ev = w.events if fed_to is None or w.t_start_us >= fed_to else w.events[w.events["t"] >= fed_to]
        parts.append(ev)
        fed_to = w.t_end_us if fed_to is None else max(fed_to, w.t_end_us)
    return (np.concatenate(parts) if parts else None), fed_to


@dataclasses.dataclass
class StreamLayout:
    """What a run over a stream is laid out with before it starts: the network
    (and its ``origin``), the sensor's frame ``shape``, the step ``dt_ms``, the
    calibration rate ``rate_hz``, each window's read-out ``spans`` (ms from the
    first window's start, step 0) and the steps at which each starts and ends
    (``steps``, 2 x windows), whether the window clock fires (``clock``), the read-out lag ``lag_ms``,
    a window's length in steps (``window_length``: how long the ``sliding``
    coding holds a pixel) and, where windows overlap (a hop shorter than the
    window), the window's length in us (``period_us``; 0 where they do not).

    The window clock fires (with ``clock``: a network with one, the clock
    not turned off) as each window starts; where windows overlap, once every
    window length from the first window's start instead, at every such
    period that starts before the last window ends (:meth:`_periods`). The
    ``window`` coding's holds end where those periods start or end
    (:meth:`resets`). So a hop changes what is read out, not how
    the network runs: the windows that start on the clock are those of a run
    without the hop, spike for spike (fired at every start, 10 ms apart, the
    clock held the grouping silent for good: its onset is 15 ms)."""

    network: object
    origin: dict
    shape: tuple
    dt_ms: float
    rate_hz: float
    spans: list
    steps: np.ndarray
    clock: bool
    seed: int = 0
    lag_ms: float = 0.0
    window_length: int = 1
    period_us: int = 0

    @property
    def held(self) -> bool:
        """Whether the events are held as the window's frame (the ``window`` and ``sliding`` input codings)."""
        return self.network.input_coding in HELD_CODINGS

    def _periods(self, n: int | None) -> np.ndarray:
        """The steps at which the first ``n`` windows' periods start and end (2 x periods): each
        window's span, or where windows overlap, every window length that starts before the last window ends."""
        steps = self.steps[:, :n]
        if not self.period_us or not steps.size:
            return steps
        # (every period that starts within the windows, the last one's end excluded: the windows a run
        # without the hop cuts from the same events; up to the last window's start, the clock of a hop
        # run missed the period its last windows' read-out reached near a stream's end)
        j = np.arange(int(steps[1, -1] * self.dt_ms * 1000.0 // self.period_us) + 2, dtype=np.int64)
        starts = window_steps(j * self.period_us, (j + 1) * self.period_us, 0, self.dt_ms)
        return starts[:, starts[0] < steps[1, -1]]

    def clock_steps(self, n: int | None = None) -> np.ndarray:
        """The steps the window clock fires at (none without a clock), for the first ``n`` windows (all)."""
        return np.unique(self._periods(n)[0]) if self.clock else np.zeros(0, np.int64)

    def resets(self, n: int | None = None) -> np.ndarray:
        """The steps at which a held source's hold ends (a period starts or ends), for the first ``n`` windows."""
        return np.unique(self._periods(n))


def input_stream(net, shape, dt_ms: float, t0_us: float, resets, seed: int = 0, window_length: int = 1):
    """The stream that turns events into ``net``'s input spikes on its (pooled)
    input grid of ``shape``: each event a spike
    (:class:`~snn_fg.lowering.input_stream.SpikeStream`, through the input
    adapter's refractory period), or the window's frame held as it is built
    (:class:`~snn_fg.lowering.held_input.HeldStream`: ``window``, every hold
    ending at the steps ``resets``; ``sliding``, every hold ending
    ``window_length`` steps after its event)."""
    if net.input_coding == "window":
        return HeldStream(shape, dt_ms, t0_us, net.input_rate_hz, resets, seed)
    if net.input_coding == "sliding":
        return HeldStream(shape, dt_ms, t0_us, net.input_rate_hz, (), seed, hold_steps=window_length)
    return SpikeStream(shape, dt_ms, t0_us, net.input_refractory_ms)


class StreamFeed:
    """The single pass over a stream's :class:`Arrival` s: the input spikes of
    their events, made as the backend asks for them (:attr:`input`, a
    :class:`~snn_fg.lowering.input_stream.SegmentedInput`), and each window
    held until :meth:`window` gives it out (``keep``: to the end).

    ``lay_out(feed)`` returns the run's :class:`StreamLayout` before any
    event is read, or once the whole stream is (:attr:`ended`) where
    ``drain`` asks for it (a backend that takes its input whole). The first
    event fixes step 0 at the first window's start (:attr:`origin`).

    ``drops``: a live stream that drops windows when the model falls behind
    (:class:`~snn_fg.events.live.LiveStream`): the backend is told which
    steps it may skip (its ``resume_at``), and a dropped window is not
    decoded (:meth:`dropped`, :meth:`passed`)."""

    def __init__(
        self,
        source,
        lay_out,
        *,
        name: str = "<stream>",
        drain: bool = False,
        keep: bool = False,
        segment_ms=SEGMENT_MS,
        drops=None,
    ):
        self.it, self.keep, self.held, self.ended, self.name = iter(source), keep, {}, False, name
        self.drops = drops
        self.n = 0  # windows arrived
        self.pending: list = []  # events arrived before step 0 was known
        self.known_until, self.origin, self.stream = -np.inf, None, None
        while drain and not self.ended:
            self._pull()
        if self.ended and self.origin is None:
            raise InputError(name, "no window to process")
        self.layout = lay = lay_out(self)
        if drops is not None and drops.lag_us != round(lay.lag_ms * 1000):  # (it drops by where read-outs end)
            raise ParameterError(
                f"the live stream {name} was cut for read-outs {drops.lag_us / 1000:g} ms late; "
                f"the network reads them {lay.lag_ms:g} ms late (LiveStream's lag_ms)"
            )
        self.pool, self.step_us = lay.network.params.input_pool, lay.dt_ms * 1000.0
        h, w = pooled_shape(lay.shape, self.pool)
        every = np.ones((h, w), bool)  # (which sources fire is not known ahead)
        self.input = SegmentedInput(
            (h, w),
            every,
            every.copy(),
            lay.rate_hz,
            0,
            max(1, int(round(segment_ms / lay.dt_ms))),
            self._spikes_until,
            lay.clock_steps(),
            resume_at=None if drops is None else self._resume_at,
        )
        if self.origin is not None:
            self._start()

    def first_window(self):
        """Window 0, once it is complete (the stream read that far)."""
        while 0 not in self.held and not self.ended:
            self._pull()
        if 0 not in self.held:
            raise InputError(self.name, "no window to process")
        return self.held[0]

    def _start(self):
        """The spike stream, from step 0 at :attr:`origin` on, with the events that came before."""
        lay = self.layout
        shape = pooled_shape(lay.shape, self.pool)
        self.stream = input_stream(
            lay.network, shape, lay.dt_ms, self.origin, lay.resets(), lay.seed, lay.window_length
        )
        for ev in self.pending:
            self.stream.add(pool_events(ev, self.pool))
        self.pending = None

    def _pull(self) -> bool:
        a = next(self.it, None)
        if a is None:
            self._end()
            return False
        for w in a.windows:
            self.held[self.n] = w
            self.n += 1
        if a.events is not None and len(a.events):
            if self.stream is None:
                self.pending.append(a.events)
            else:
                self.stream.add(pool_events(a.events, self.pool))
        self.known_until, self.origin = a.known_until_us, a.origin_us
        if self.stream is None and self.origin is not None and hasattr(self, "layout"):
            self._start()
        if self.known_until == np.inf:
            self._end()
        return True

    def _end(self):
        """The stream has ended: the windows it did not reach neither fire the clock nor end holds."""
        self.ended = True
        if hasattr(self, "layout"):
            self.input.clock_steps = self.layout.clock_steps(self.n)
            if isinstance(self.stream, HeldStream) and self.stream.hold is None:
                self.stream.resets = self.layout.resets(self.n)

    def _spikes_until(self, end_step: int):
        while not self.ended and (self.origin is None or self.known_until < self.origin + end_step * self.step_us):
            self._pull()
        if self.stream is None:
            raise InputError(self.name, "no window to process")
        return self.stream.take_until(end_step)

    def _resume_at(self, n: int) -> int:
        """The step a run at step ``n`` may go on from (``drops.resume_at``, in the stream's time)."""
        if self.origin is None:
            return n
        t = n * self.step_us
        return max(n, int(self.drops.resume_at(t) // self.step_us))

    def dropped(self, k: int) -> bool:
        """Whether window ``k`` was dropped by the stream (its maps are not wanted)."""
        return self.drops is not None and self.drops.dropped_window(k)

    def stale(self, w) -> bool:
        """Whether window ``w``'s read-out is skipped for a newer one's (a live stream's hops:
        :meth:`~snn_fg.events.live.LiveStream.stale`); the network has taken its events all the same."""
        return self.drops is not None and self.drops.stale(w)

    def passed(self, w) -> None:
        """Window ``w`` is done with (published or dropped): the stream is told."""
        if self.drops is not None:
            self.drops.done(w)

    @property
    def merged(self) -> int:
        """Events that fell in a step their source had fired in already."""
        return 0 if self.stream is None else self.stream.merged

    def window(self, k: int):
        """Window ``k`` (its position in the stream), forgotten unless ``keep``."""
        while k not in self.held and not self.ended:
            self._pull()
        return self.held[k] if self.keep else self.held.pop(k)
