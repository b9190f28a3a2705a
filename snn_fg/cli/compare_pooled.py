"""``snn-fg compare`` on runs made one at a time (each image to its own ``--out``), one model's
against another's (``A1 A2 … B1 B2 …``), paired by their input image and pooled into one table;
also two folders of runs (``snn-fg run`` on several images: their ``summary.csv``), one a model.

The first half of the runs are A's, the second half B's, in any order within each half: each A run
is paired with the B run of the same input image (its file name without the suffix). Every pair is
checked and compared before anything is printed or written, so runs that do not pair up end in one
line naming the run, nothing written. The table and ``--json`` are compare's, a row per window of
each pair with the image in the time's place, and the verdict pools every pair's pixels.
"""

from __future__ import annotations

import json
from pathlib import Path

from ..errors import InputError
from ..results.atomic import save_text
from ..results.maps import Maps
from .compare_labels import runs_of
from .compare_maps import _record, _run_name, compare_pair, compare_table


def image_of(run) -> str:
    """The input image a run's maps were made from (its file name without the suffix), or an InputError."""
    given = (Maps.load(run).params.get("source") or {}).get("input")
    if not given:
        raise InputError(run, "its maps name no input, so it cannot be paired with another run by image")
    return Path(str(given)).stem


def pairs_of(runs: list) -> list[tuple[str, str, str]]:
    """``(image, A run, B run)`` for the runs given, the first half A's, the second B's (two: a folder of
    runs each, made by ``snn-fg run`` on several images), paired by image in A's order; runs that do not
    pair up are an InputError naming the run."""
    if len(runs) % 2:
        raise InputError(
            runs[-1],
            f"{len(runs)} runs given: pooled runs are as many of A's model as of B's (A1 A2 B1 B2), "
            "paired by input image; an odd count cannot pair up",
        )
    half = len(runs) // 2
    sides = []
    for side, given in (("A", runs[:half]), ("B", runs[half:])):
        by_image: dict = {}
        for run in [r for folder in given for r in runs_of(folder)]:
            image = image_of(run)
            if image in by_image:
                raise InputError(run, f"is a second {side} run of image {image} (also {by_image[image]})")
            by_image[image] = run
        sides.append(by_image)
    a_runs, b_runs = sides
    for image, run in a_runs.items():
        if image not in b_runs:
            theirs = ", ".join(sorted(b_runs))
            raise InputError(run, f"A's run of image {image} has no B run of that image (B's runs are of {theirs})")
    return [(image, run, b_runs[image]) for image, run in a_runs.items()]


def cmd_compare_pooled(args) -> int:
    """Handler of ``snn-fg compare`` with several A runs against maps; prints the table, returns 0."""
    if args.plot:
        raise InputError("--plot", "draws one pair of runs: give one A and one B to draw them")
    runs = [*args.a, args.b]
    pairs = pairs_of(runs)
    rows, notes, models, baselines = [], [], [set(), set()], []
    for image, path_a, path_b in pairs:
        a, b, got, _, baseline, _ = compare_pair(args, path_a, path_b, say=notes.append)
        rows += [{"image": image, **r} for r in got]
        baselines += [] if baseline is None else [baseline]
        for seen, m in zip(models, (a, b)):
            seen.add(str(m.params.get("model", "unknown")))
    for note in dict.fromkeys(notes):  # (once each, all before the table: every pair checked first)
        print(note)
    baseline = baselines[-1] if baselines else None  # (one wording for every pair: B against itself)
    named = [
        f"{side}: {len(pairs)} runs ({', '.join(_run_name(p[i]) for p in pairs[:4])}{', ...' * (len(pairs) > 4)}), "
        f"the {'/'.join(sorted(seen))} model"
        for side, i, seen in (("A", 1, models[0]), ("B", 2, models[1]))
    ]
    print(compare_table(rows, args.outline, baseline, named))
    if args.json:
        record = _record(args, rows, baseline)
        record["a"], record["b"] = [str(p[1]) for p in pairs], [str(p[2]) for p in pairs]
        record["pairs"] = [{"image": i, "a": str(a), "b": str(b)} for i, a, b in pairs]
        save_text(args.json, json.dumps(record, indent=2))
        print(f"snn-fg: metrics saved to {args.json}")
    return 0
