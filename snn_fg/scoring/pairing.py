"""Which windows of two maps :func:`~snn_fg.scoring.metrics.compare_maps` sets side by side
(:func:`pair_windows`), and the line that says how they were paired.

Two runs of one recording, or a live run of its replay (``snn-fg stream`` sends the recording's
own timestamps), are paired by the events their windows hold: by each window's start on the
events' own clock, ``first_event_us + t_start_us`` (:mod:`snn_fg.events.clock`; a ``udp://``
stream's modulo its 32-bit span). A run's windows start at ``--start-ms`` exactly, a live run's
at the first event it received, a few microseconds later where no event lay at the start
itself: starts less than :data:`PAIR_WITHIN_US` apart are the same window's, and the line says
how far apart the paired starts lay. Two such runs that share no start are refused in one line,
as is a run whose events were stamped on arrival (no other run's clock).

A run stored before snn-fg kept its clock has its starts from its own first event only: it is
paired as then, by equal starts after each run's first event, else a single frame (or a
one-window recording) against every window of the other, else window by window in order; the
line says so.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .. import validate as check
from ..errors import ParameterError
from ..events.clock import ARRIVAL, SHARED
from ..results.maps import Maps
from ..results.timeline import window_numbers
from .inputs import other_inputs

#: how far apart (us) two windows' starts on the events' clock may lie and still be paired: a live run's
#: first window starts at the first event it received, not at --start-ms itself (in dvs.es, 100 ms in,
#: a few us later); far below any window's length, so that a window pairs with one window at most
PAIR_WITHIN_US = 1000


class WindowOutOfRange(ParameterError):
    """:func:`compare_maps`' ``window`` is not among a map's windows. It carries what a caller
    needs to say so in its own words: the window asked, which map (``side``: "a" or "b") and
    how many windows it holds (``n``); the command line names the option and the file."""

    def __init__(self, window: int, side: str, n: int):
        self.window, self.side, self.n = window, side, n
        super().__init__(f"compare_maps: window={window!r} is not among the {n} windows of {side} (0 to {n - 1})")


def _check_window(a: Maps, b: Maps, window: int | None) -> None:
    """``window`` is among the windows of each map that has several (:class:`WindowOutOfRange`)."""
    for side, m in (("a", a), ("b", b)):
        n = 1 if m.fg_x.ndim == 2 else m.fg_x.shape[0]
        if window is not None and n > 1 and not 0 <= window < n:
            raise WindowOutOfRange(window, side, n)


@dataclass(frozen=True)
class Pairing:
    """The windows paired: ``pairs`` of positions in ``a`` and ``b`` (``None``: that map is one
    frame), ``numbers`` the windows' own numbers in their recording or stream
    (:func:`~snn_fg.results.timeline.window_numbers`), ``t_us`` B's window start after B's first
    event (None: unknown), ``how``, the line that says how they were paired, and ``by_start``
    whether each pair's windows start together (on the events' clock, or after each run's first
    event), not only at one place in their runs."""

    pairs: list
    numbers: list
    t_us: list
    how: str
    by_start: bool = False


def _side(m: Maps):
    """Positions, numbers and starts after the first event (us; None) of ``m``'s windows
    (one frame: one window, position None)."""
    if m.fg_x.ndim == 2:
        return [None], [None], [None]
    n = m.fg_x.shape[0]
    t = m.extra.get("t_start_us")
    starts = [None] * n if t is None else [int(v) for v in np.asarray(t)]
    return list(range(n)), [int(k) for k in window_numbers(m)], starts


def _clock(m: Maps) -> tuple[str, int | None, int | None] | None:
    """``(clock, first event's time on it, span)`` of a recording's run stored with its clock, else None."""
    src = m.params.get("source")
    if m.fg_x.ndim == 2 or not isinstance(src, dict) or "clock" not in src or "first_event_us" not in src:
        return None
    return src["clock"], int(src["first_event_us"]), src.get("clock_span_us")


def pair_windows(a: Maps, b: Maps, window: int | None = None) -> Pairing:
    """The windows of ``a`` and ``b`` to compare (the module docstring says how); ``window``: that
    position of each map with several, whatever their starts. A pair that cannot be paired fails
    with one :class:`~snn_fg.errors.ParameterError` line (``compare_maps: ...``)."""
    _check_window(a, b, window)
    (ia, na, ta), (ib, nb, tb) = _side(a), _side(b)
    if window is not None:
        ia, ib = (i if len(i) == 1 else [i[window]] for i in (ia, ib))  # (positions: na, nb, tb read at them)
        how = f"window at place {window} of each run stored (counted from 0), whatever its start"
        return _pairing([(x, y) for x in ia for y in ib], na, nb, tb, how)
    ca, cb = _clock(a), _clock(b)
    if ca is not None and cb is not None:
        return _unpaired(_by_clock(ca, cb, (ia, na, ta), (ib, nb, tb), other_inputs(a, b)), len(ia), len(ib))
    if None not in ta + tb:
        starts = {t: i for i, t in zip(ib, tb)}
        pairs = [(i, starts[t]) for i, t in zip(ia, ta) if t in starts]
        if not pairs:
            differ = other_inputs(a, b)
            said = "" if differ is None else f": they are runs of different inputs ({differ})"
            check.fail("compare_maps", None, None, f"the two recordings share no window start time{said}")
        old = " and ".join(name for name, c in (("A", ca), ("B", cb)) if c is None)
        how = (
            f"windows paired by their start after each run's own first event ({old} "
            f"{'was' if len(old) == 1 else 'were'} stored without the events' clock, as before snn-fg kept it: "
            "a replay's then began at 0 wherever the recording's lay)"
        )
        return _unpaired(_pairing(pairs, na, nb, tb, how, by_start=True), len(ia), len(ib))
    if ia == ib == [None]:
        return _pairing([(None, None)], na, nb, tb, "one frame each")
    if len(ia) == 1 or len(ib) == 1:
        what = "the frame" if ia == [None] or ib == [None] else "the one window"
        return _pairing([(x, y) for x in ia for y in ib], na, nb, tb, f"{what} against every window of the other")
    if len(ia) != len(ib):
        check.fail(
            "compare_maps",
            None,
            None,
            f"the maps hold {len(ia)} and {len(ib)} windows and no start times to pair them by; pick one with window=",
        )
    return _pairing(list(zip(ia, ib)), na, nb, tb, "windows paired in the order stored (no start times)")


def _unpaired(p: Pairing, n_a: int, n_b: int) -> Pairing:
    """``p`` with its line saying how many of each run's windows found no partner (a live run's dropped
    windows: ``live.json`` says which, and which kept windows came after a drop, ``drop_before``)."""
    paired = [len(set(side)) for side in zip(*p.pairs)]  # (windows of A, of B, with a partner)
    left = [f"{n - m} of {side}'s {n} windows" for side, n, m in zip("AB", (n_a, n_b), paired) if n > m]
    if not left:
        return p
    return replace(p, how=f"{p.how}; left out, with no partner in the other run: {' and '.join(left)}")


def _pairing(pairs, na, nb, tb, how, by_start: bool = False) -> Pairing:
    numbers = [(na[0] if x is None else na[x], nb[0] if y is None else nb[y]) for x, y in pairs]
    return Pairing(pairs, numbers, [tb[0] if y is None else tb[y] for _, y in pairs], how, by_start)


def _by_clock(ca, cb, side_a, side_b, differ: str | None = None) -> Pairing:
    """The windows of two runs stored with their clocks, paired by start on the events' clock;
    ``differ``: how the runs' inputs differ (:func:`~.inputs.other_inputs`), said if none pair."""
    for name, (clock, _, _) in (("A", ca), ("B", cb)):
        if clock not in SHARED:
            said = "stamped as they arrived (a stream sent without timestamps)" if clock == ARRIVAL else f"on {clock!r}"
            check.fail(
                "compare_maps",
                None,
                None,
                f"{name}'s events were {said}: no other run's windows share that clock; "
                "compare one window of each: --window I (window=I in Python)",
            )
    (ia, na, ta), (ib, nb, tb) = side_a, side_b
    span = ca[2] or cb[2]  # (a udp:// stream's times: its sender's modulo 2**32 us)
    abs_a = np.array([ca[1] + t for t in ta], np.int64)
    abs_b = np.array([cb[1] + t for t in tb], np.int64)
    order = np.argsort(abs_b % span if span else abs_b, kind="stable")
    pairs, apart = [], []
    for i, t in zip(ia, abs_a):
        d = _apart(t, abs_b[order], span)
        j = int(np.argmin(np.abs(d)))  # (the nearest start of B's)
        if abs(int(d[j])) < PAIR_WITHIN_US:
            pairs.append((i, ib[int(order[j])]))
            apart.append(abs(int(d[j])))
    if not pairs and differ is not None:
        check.fail(
            "compare_maps",
            None,
            None,
            f"A and B are runs of different inputs ({differ}): their events share no clock, so no window of "
            "one pairs with a window of the other; compare one window of each: --window I (window=I in Python)",
        )
    if not pairs:
        first_a, first_b = (_apart(x, np.array([cb[1]]), span)[0] / 1000 for x in (abs_a[0], abs_b[0]))
        check.fail(
            "compare_maps",
            None,
            None,
            f"A and B share no window start on the events' own clock: A's first window starts {_after(first_a)} "
            f"B's first event, B's {_after(first_b)} it, and none of A's starts lies within "
            f"{PAIR_WITHIN_US / 1000:g} ms of one of B's: run one again with the other's --start-ms "
            f"({first_b:g} for B's, from its first event) and --window-ms/--stride-ms, or compare one window of "
            "each with --window I (a live run: docs/live.md, 'Comparing a live run with snn-fg run')",
        )
    far = max(apart)
    how = "windows paired by their start on the events' own clock (their timestamps), " + (
        f"starts up to {far} us apart" if far else "starts equal"
    )
    return _pairing(pairs, na, nb, tb, how, by_start=True)


def _after(ms: float) -> str:
    """``ms`` after (or before) a time, in words a reader takes in: two clocks can lie years apart."""
    when = "after" if ms >= 0 else "before"
    ms = abs(ms)
    for unit, size in (("days", 86_400_000), ("h", 3_600_000), ("s", 1000)):
        if ms >= 10 * size:
            return f"{ms / size:,.0f} {unit} {when}"
    return f"{ms:g} ms {when}"


def _apart(t, starts: np.ndarray, span: int | None) -> np.ndarray:
    """``t`` less each of ``starts`` (us), modulo ``span`` (then the nearest way round) if given."""
    d = int(t) - starts
    return (d + span // 2) % span - span // 2 if span else d
