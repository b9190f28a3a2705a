"""Whether two runs' maps come from one input, cut into the same event frames, and whether they
are one run: what ``snn-fg compare`` notes on a pair (:mod:`snn_fg.cli.compare_maps`) and the
words of a pair whose windows cannot be paired (:mod:`.pairing`).

**Inputs.** A run on a recording keeps in ``params["source"]`` the sensor size and a digest of
the recording's first events (:mod:`snn_fg.events.identity`): two runs that both have them are of
one input when these agree, whatever their files are named (every iCub recording is a
``data.log``) and whatever format holds the events. A run stored before snn-fg kept them is told by
its windows paired at one start and cut alike, whose event counts (``event_count``, stored with
each window) differ only between inputs, else by its input's file name. Runs on the two cameras of
one recording (MVSEC's, an iCub log's) are told by the ``channel`` each kept (``--channel``; none:
the left, 0). A live run's input is a stream's address: its windows' clock tells instead.

**Event frames.** A paired window holds other events when the runs were cut with another window
length or event filter, or a still image was turned into events at another contrast threshold or
under another motion (:data:`FRAME_KEYS`); windows paired by place (``--window``, or in the order
stored) also when the runs started or strode otherwise (:data:`PLACE_KEYS`). Windows paired by
their start on the events' clock start together whatever the runs' ``--start-ms``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: what ``params["source"]`` keeps to tell a recording from another (:mod:`snn_fg.events.identity`)
IDENTITY_KEYS = ("sensor_size", "events_head")
#: the settings in ``params["source"]`` that change which events a window of a given start holds
FRAME_KEYS = ("window_ms", "denoise_us", "refractory_us", "threshold", "motion")
#: the settings that change where a run's windows start: which windows a place pairs
PLACE_KEYS = ("start_ms", "stride_ms")
#: settings whose absence means off (no filter), told against a value
_OFF_WHEN_ABSENT = ("denoise_us", "refractory_us")
#: run provenance that differs between two runs of one command (how long it took)
_NOT_THE_RUN = ("timings_s", "whole_run")


def differing(pa: dict, pb: dict, keys, off_when_absent=()) -> list[str]:
    """``"key A's against B's"`` for each of ``keys`` on which the settings ``pa`` and ``pb``
    disagree; a key only one of them has is told only if it is among ``off_when_absent``
    (its absence, or None: off)."""
    out = []
    for k in keys:
        if (k not in pa or k not in pb) and (k not in off_when_absent or (k not in pa and k not in pb)):
            continue
        va, vb = pa.get(k), pb.get(k)
        if va != vb:
            out.append(f"{k} {'off' if va is None else va} against {'off' if vb is None else vb}")
    return out


def _sources(a, b) -> tuple[dict, dict]:
    return tuple(m.params.get("source") or {} for m in (a, b))


def other_inputs(a, b, pairing=None) -> str | None:
    """How the inputs of the maps ``a`` and ``b`` differ, in words for a parenthesis (``"dvs.es,
    person.aedat4"``, ``"both data.log: their first events differ"``), or None: one input as far as
    the runs tell, or a live run's (the module docstring). ``pairing``
    (:class:`~snn_fg.scoring.pairing.Pairing`): the windows paired, whose event counts tell two
    runs stored without the keys of :data:`IDENTITY_KEYS`."""
    sa, sb = _sources(a, b)
    if "live" in (sa.get("kind"), sb.get("kind")) or None in (sa.get("input"), sb.get("input")):
        return None
    na, nb = (Path(str(s["input"])).name for s in (sa, sb))
    named = f"both {na}" if na == nb else f"{na}, {nb}"
    cameras = [s.get("channel", 0) for s in (sa, sb)]  # (a recording of two cameras: the left one unless told)
    if cameras[0] != cameras[1]:
        return f"{named}: channel {cameras[0]} against {cameras[1]}, other cameras"
    if all(k in sa and k in sb for k in IDENTITY_KEYS):
        if sa["sensor_size"] != sb["sensor_size"]:
            size = [" x ".join(map(str, s["sensor_size"])) for s in (sa, sb)]
            return f"{named}: sensors of {size[0]} and {size[1]} pixels"
        return None if sa["events_head"] == sb["events_head"] else f"{named}: their first events differ"
    counts = _paired_counts(a, b, pairing)
    if counts is not None:
        return None if counts == "" else f"{named}: {counts}"
    return None if na == nb else named


def _paired_counts(a, b, pairing) -> str | None:
    """Of windows paired at one start and cut alike: ``""`` when each pair holds as many events,
    else the first pair that does not, in words; None when no such pair tells."""
    if pairing is None or not pairing.by_start or differing(*_sources(a, b), FRAME_KEYS, _OFF_WHEN_ABSENT):
        return None
    if "event_count" not in a.extra or "event_count" not in b.extra:
        return None
    ca, cb = (np.asarray(m.extra["event_count"]) for m in (a, b))
    told = False
    for (x, y), (ka, kb) in zip(pairing.pairs, pairing.numbers):
        if x is None or y is None:
            continue
        if int(ca[x]) != int(cb[y]):
            return (
                f"A's window {ka} and B's window {kb} start together and hold {int(ca[x]):,} and {int(cb[y]):,} events"
            )
        told = True
    return "" if told else None


def other_frames(a, b, pairing=None) -> list[str]:
    """The settings of ``a`` and ``b`` (``params["source"]``) that put other events in the windows
    paired (``pairing``; :data:`PLACE_KEYS` too unless it paired them by their start), each
    ``"key A's against B's"``."""
    by_start = pairing is not None and pairing.by_start
    return differing(*_sources(a, b), FRAME_KEYS + (() if by_start else PLACE_KEYS), _OFF_WHEN_ABSENT)


def same_run(a, b, same_folder: bool = False) -> str | None:
    """Whether ``a`` and ``b`` are one run, in words: ``"the same run"`` (``same_folder``: both
    were read from one folder or file), ``"identical"`` (the same maps and run provenance, its
    timings aside: a copy, or one command run twice), or None."""
    if same_folder:
        return "the same run"
    pa, pb = ({k: v for k, v in m.params.items() if k not in _NOT_THE_RUN} for m in (a, b))
    if pa != pb or a.fg_x.shape != b.fg_x.shape:
        return None
    same = (np.array_equal(np.asarray(getattr(a, k)), np.asarray(getattr(b, k))) for k in ("fg_x", "fg_y", "grouping"))
    return "identical" if all(same) else None
