"""The comparison of two runs' maps behind ``snn-fg compare`` (:mod:`.compare`): a pair of maps
files window by window (:func:`compare_pair`), its table (:func:`compare_table`) and ``--json``
record, the reference's own stability beside it (:func:`add_baseline`), the verdict
(:mod:`.compare_verdict`), and the notes on a pair whose settings differ; shared by a single pair
and by runs pooled (:mod:`.compare_pooled`).
"""

from __future__ import annotations

import sys
import textwrap
from pathlib import Path

import numpy as np

from ..errors import InputError, SnnFgError
from ..events.esim import MOTION, THRESHOLD
from ..results.maps import CONFIDENCE, Maps
from ..scoring.align import align_to_export
from ..scoring.baseline import self_agreement
from ..scoring.inputs import differing, other_frames, other_inputs, same_run
from ..scoring.metrics import compare_maps, compared_pixels, flipped_within_45
from ..scoring.outline import event_outlines
from ..scoring.pairing import WindowOutOfRange, pair_windows
from .compare_verdict import axis_flip, over_what, overall, verdict
from .options import blank, cell, nulls
from .run_options import WINDOW_OPTIONS

#: compare's table: (header, row key, width, format spec); at most 100 characters wide. The
#: median angle and the angle MSE are in --json only: a median of angles can look perfect while a
#: third of the pixels are wrong
_COLUMNS = (
    ("A", "number_a", 4, "d"),
    ("B", "number_b", 4, "d"),
    ("t (ms)", "t_start_ms", 8, ".1f"),
    ("pixels", "pixels_compared", 7, "d"),
    ("cover", "coverage_of_b", 6, ".3f"),
    ("mean°", "angle_diff_mean_deg", 6, ".1f"),
    ("<=45°", "angle_within_45_frac", 6, ".3f"),
    ("SSIM", "angle_ssim", 6, ".3f"),
    ("grp r", "grouping_pearson_r", 6, ".3f"),
    ("grp SSIM", "grouping_ssim", 8, ".3f"),
    ("B <=45°", "baseline_within_45", 7, ".3f"),
    ("B grp r", "baseline_grouping_r", 7, ".3f"),
)


def compare_table(rows, outline_px: int | None = None, baseline: str | None = None, named=(), paired=None) -> str:
    """The rows of :func:`~snn_fg.scoring.metrics.compare_maps` as a text
    table; ``baseline``: what the B columns hold, or why they are empty;
    ``named``: lines that say what A and B are, under the table; ``paired``: how
    the windows were paired (:attr:`~snn_fg.scoring.pairing.Pairing.how`)."""
    pooled = any("image" in r for r in rows)  # (runs paired by image: the image in place of the time)
    frames = over_what(rows) == "The frame"  # (one frame each, a still's: no windows to number or time)
    columns = [("image", "image", 8, "") if c[1] == "t_start_ms" and pooled else c for c in _COLUMNS]
    lines = ["  ".join(f"{h:>{w}}" for h, _, w, _ in columns)]
    lines += ["  ".join(cell(r.get(k), w, spec) for _, k, w, spec in columns) for r in rows]
    lines += named
    if paired and not frames:
        lines += textwrap.wrap(f"A, B: {paired}", 95)
    where = "" if outline_px is None else f" within {outline_px} px of the event region's outline"
    if pooled:
        when = "A, B: compared windows; image: the pair's input image"
    elif frames:
        when = "A, B, t: - (each map is one frame)"
    else:
        when = (
            "A, B: the compared windows' numbers in their recording or stream; t: B's window start after B's "
            "first event"
        )
    lines += textwrap.wrap(
        f"{when}; angle columns on pixels{where} where both maps have a figure-ground vector (SSIM: where "
        "either has one); mean°: the mean absolute difference of their directions (chance 90°), <=45°: the "
        "share within 45° (chance 0.25); cover: the share of B's vectors that A has there; grouping r and "
        "SSIM on the whole map, SSIM with each map scaled to 1",
        95,
    )
    if baseline is not None:
        lines += textwrap.wrap(baseline, 95)
    lines += textwrap.wrap(verdict(rows), 95)
    confident = [r["confident_a"] for r in rows if "confident_a" in r]
    if confident:
        lines.append(
            f"A's vectors above the confidence threshold: {min(confident):.1%} to {max(confident):.1%} per window"
        )
    for side in ("a", "b"):
        empty = [r[f"number_{side}"] for r in rows if r.get(f"pixels_{side}") == 0]
        sure = " at the confidence threshold" if any(f"confident_{side}" in r for r in rows) else ""
        if empty and frames:
            lines.append(f"{side.upper()} has no figure-ground vector{sure}: nothing to compare (-)")
        elif empty:
            shown = ", ".join("-" if k is None else str(k) for k in empty[:8]) + (", ..." if len(empty) > 8 else "")
            lines.append(
                f"{side.upper()} has no figure-ground vector{sure} in {len(empty)} of {len(rows)} compared "
                f"window{'s' if len(rows) > 1 else ''} ({shown}): nothing to compare there (-)"
            )
    return "\n".join(lines)


def compare_pair(args, path_a, path_b, say=print):
    """Maps ``path_a`` against ``path_b`` as ``args`` (compare's options) ask: ``(a, b, rows, where,
    baseline, paired)``, each row of :func:`~snn_fg.scoring.metrics.compare_maps`, ``paired`` how
    their windows were paired; notes on the pair said by ``say``, a bad pair or option one
    :class:`InputError`."""
    a, b = Maps.load(path_a), Maps.load(path_b)
    if args.min_confidence is not None and not any(CONFIDENCE in m.extra for m in (a, b)):  # (as against labels)
        raise InputError(
            "--min-confidence", f"neither {path_a} nor {path_b} holds fg_confidence (no spike counts): leave it out"
        )
    a, b, notes = align_to_export(a, b, args.window, (path_a, path_b))  # (a board's maps against the reference)
    one = _run_dir(path_a) == _run_dir(path_b)
    for note in notes + expectations(a, b):
        say(f"snn-fg: note: {note}")
    window = None if notes else args.window
    try:
        pairing = pair_windows(a, b, window)
        for note in mismatches(a, b, pairing, same_folder=one):
            say(f"snn-fg: note: {note}")
        where = None if args.outline is None else event_outlines(a, b, args.outline)
        rows = compare_maps(a, b, window, where=where, min_confidence=args.min_confidence, pairing=pairing)
    except WindowOutOfRange as exc:  # (compare_maps checks it; said by the option's name and the file)
        raise InputError(
            f"--window {exc.window}", f"{path_a if exc.side == 'a' else path_b} holds windows 0 to {exc.n - 1}"
        ) from None
    except SnnFgError as exc:
        raise InputError(path_b, str(exc).removeprefix("compare_maps: ")) from None
    # (not for a board's maps against a run cut to its crop: a small network against a whole one can agree
    # better flipped by chance, and a new user read the guess as a coordinate bug; decode --reference checks it)
    flip = None if notes else axis_flip(rows, flipped_within_45(a, b, pairing, where, args.min_confidence))
    if flip:
        say(f"snn-fg: note: {flip}")
    baseline = None if args.no_baseline else add_baseline(rows, a, b, where, args.min_confidence)
    return a, b, rows, where, baseline, pairing.how


def _record(args, rows, baseline: str | None, paired: str | None = None) -> dict:
    """What ``--json`` keeps: the inputs, the options that chose the pixels compared, the pooled
    figures the printed verdict gives (:func:`overall`), the verdict and baseline lines as printed, and
    the snn-fg that measured them: a table made from the file alone says what it is."""
    from .. import __version__

    r = [x["grouping_pearson_r"] for x in rows if not blank(x.get("grouping_pearson_r"))]
    pooled = {
        **overall(rows),
        "grouping_pearson_r_min": min(r, default=None),
        "grouping_pearson_r_median": float(np.median(r)) if r else None,
        "verdict": verdict(rows),
        "baseline": baseline,
    }
    options = {"window": args.window, "outline_px": args.outline, "min_confidence": args.min_confidence}
    if paired:
        options["paired"] = paired
    return {
        "a": str(args.a),
        "b": str(args.b),
        "options": options,
        "all_windows": pooled,
        "snn_fg_version": __version__,
        "windows": [nulls(r) for r in rows],  # (null where there was nothing to measure)
    }


def _run_dir(path) -> Path:
    """The output folder of the run a maps argument belongs to (``out/a``, ``out/a/maps.npz`` and
    ``out/a/maps.zarr`` are all run ``a``)."""
    p = Path(path).resolve()
    return p.parent if p.is_file() or p.suffix in (".npz", ".zarr") else p


def _run_name(path) -> str:
    """The name of the run a maps argument belongs to: its output folder's (:func:`_run_dir`)."""
    return _run_dir(path).name


def add_baseline(rows, a: Maps, b: Maps, where=None, min_confidence=None) -> str:
    """B's model run again at twice its iterations on B's own frames
    (:func:`~snn_fg.scoring.baseline.self_agreement`), on the pixels the
    rows compared A and B on (``where`` and ``min_confidence``, as given to
    :func:`~snn_fg.scoring.metrics.compare_maps`:
    :func:`~snn_fg.scoring.metrics.compared_pixels`): its agreement with B
    goes into each row (``baseline_*``); returns the line that says so, or
    why there is no baseline."""
    crop = b.params.get("export_crop")
    if crop is not None:  # (the model run on the crop alone is another run than the whole frame's, cut)
        again = "" if crop["window"] is None else f" --window {crop['window']}"
        return (
            "B <=45°, B grp r: no baseline for B cut to the export's crop; for its whole window, compare B's run "
            f"with itself, which prints its baseline: snn-fg compare B B{again} (B: the run's folder)"
        )
    windows = [r["window_b"] for r in rows]
    print(f"snn-fg: baseline: running B's model again on {len(windows)} frame(s)...", file=sys.stderr)
    masks = [compared_pixels(a, b, r["window_a"], r["window_b"], where, min_confidence) for r in rows]
    got = self_agreement(b, windows, masks=masks)
    if isinstance(got, str):
        spiking = "spiking" in str(b.params.get("model", ""))  # (a spiking run's spread: its input seed's)
        seeds = (
            "; two runs with another --seed show a spiking run's spread (on a recording: with --input-coding window)"
        )
        return f"B <=45°, B grp r: no baseline: {got}{seeds if spiking else ''}"
    for row, base in zip(rows, got):
        for k, v in (base or {}).items():
            row[f"baseline_{k}"] = v
    its = next((x for x in got if x), {})
    return (
        f"B <=45°, B grp r: B against its own model at {its.get('against_iterations', '?')} iterations instead "
        f"of {its.get('iterations', '?')}, on the same frame{'' if windows == [None] else 's'}: how far B moves on "
        "its own; A's agreement "
        "with B means little where it is near these"
    )


#: the model parameters that make the network's stages (two maps made with others are not one model's)
_STAGE_PARAMS = ("levels", "levels_per_octave", "n_ori", "r0", "input_pool")


def mismatches(a: Maps, b: Maps, pairing=None, same_folder: bool = False) -> list[str]:
    """Notes for a pair that is not one input through two models (:mod:`snn_fg.scoring.inputs`):
    one run twice, other inputs, other event frames (their windows, ``pairing``, hold other
    events), other stage parameters."""
    one = same_run(a, b, same_folder)
    if one is not None:
        what = "the same run" if one == "the same run" else "identical runs (the same maps and parameters: a copy?)"
        return [f"A and B are {what}: they agree by construction, which says nothing of a model"]
    out = []
    differ = other_inputs(a, b, pairing)
    if differ is not None:
        out.append(f"A and B come from different inputs ({differ})")
    frames = other_frames(a, b, pairing)
    if frames:
        out.append(
            f"A and B were made from other event frames ({', '.join(frames)}): the windows compared hold other "
            "events, so the maps part by more than the models do; make both with the same options"
        )
    stages = differing(a.params, b.params, _STAGE_PARAMS)
    if stages:
        out.append(
            f"A and B were made with other model parameters ({', '.join(stages)}): B is not A's reference; "
            f"run B's model with A's --network{rerun(a, b)}"
        )
    return out


#: the run options a still image was turned into events with, and their defaults (snn-fg run's)
_STILL_OPTIONS = (("image_scale", None), ("threshold", THRESHOLD), ("motion", MOTION))


def rerun(a: Maps, b: Maps) -> str:
    """``": snn-fg run ..."``, the command that makes B's reference again on A's network: B's model on
    B's input with the options that cut it (a still image's scale, contrast threshold and motion; a
    recording's windows), A's network by its name or file; ``""`` where A's network has neither."""
    net = a.params.get("network") or {}
    network = net.get("recipe") if net.get("origin") == "recipe" else net.get("origin")
    if not isinstance(network, str) or network in ("given", "built") or network.endswith("-export"):
        return ""
    source = b.params.get("source") or {}
    if source.get("kind") == "image":
        given = [(k, source.get(k)) for k, default in _STILL_OPTIONS if source.get(k, default) != default]
    else:
        given = [(k, source.get(k)) for k in WINDOW_OPTIONS if source.get(k) is not None and source.get(k) != 0]
    options = "".join(
        f" --{k.replace('_', '-')} {v:g}" if isinstance(v, float) else f" --{k.replace('_', '-')} {v}" for k, v in given
    )
    model = b.params.get("model", "rate")
    # (with an output folder to name: until 30 Nov the command lacked --out and could not run as printed)
    return f": snn-fg run {source.get('input', 'INPUT')} --out DIR --model {model} --network {network}{options}"


def expectations(a: Maps, b: Maps) -> list[str]:
    """A note for a pair whose models are known to part: the spiking network on a recording's events
    against the rate model on its windows' frames."""
    continuous = [m.params.get("simulation", {}).get("mode") == "continuous" for m in (a, b)]
    models = [m.params.get("model") for m in (a, b)]
    if set(models) != {"rate", "spiking"} or not continuous[models.index("spiking")]:
        return []
    return [
        "the spiking network on a recording's events and the rate model on its windows' frames part there: "
        "the network answers the events in their order and takes about 60 ms for each of the rate model's "
        "iterations; docs/validation.md (on recordings) measures how far, and what a window's frame as a still "
        "input gives (snn-fg events REC --start-ms S --window-ms W --write-frame F.npz, then snn-fg run F.npz)"
    ]
