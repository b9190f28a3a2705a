"""``snn-fg compare RUN LABELS``: a run's figure-ground maps against human figure/ground labels.

LABELS is a ``bsds-fg`` folder (the run's image found by its input file's name, ``labels/<id>.npz``)
or one labels file in that format (:mod:`snn_fg.scoring.groundtruth`). RUN is a run's output (its
folder or ``maps.npz``) or a folder of runs made by ``snn-fg run`` on several images (its
``summary.csv`` lists them), or several of either (runs made one at a time: ``RUN1 RUN2 LABELS``),
scored image by image and pooled. Every number is
:mod:`snn_fg.scoring.label_scores`', the one the BSDS experiments report. Everything is read and
checked before anything is printed or written, so a bad input ends in one line, nothing written.
"""

from __future__ import annotations

import csv
import json
import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..results.atomic import save_text
from ..results.figures import rows_shown
from ..results.maps import CONFIDENCE, Maps, made_by
from ..scoring.bootstrap import RESAMPLES, bootstrap_scores
from ..scoring.groundtruth import GroundTruth, boundary_directions, load_labels
from ..scoring.label_scores import labeller_errors, pool_stats
from ..scoring.metrics import confident
from .options import cell, nulls

#: the images --plot draws at most (evenly spaced: :func:`~snn_fg.results.figures.rows_shown`)
FIGURE_ROWS = 6
#: the options of compare that choose windows or pixels of two maps files, and have no meaning here
_MAPS_ONLY = (("window", "--window"), ("outline", "--outline"), ("no_baseline", "--no-baseline"))

#: the table: (header, score key of pool_stats, width, format); words in _KEY below
_COLUMNS = (
    ("labelled", "n_truth", 8, ","),
    ("cover", "coverage", 6, ".3f"),
    ("side", "side_accuracy", 6, ".3f"),
    ("<=45°", "within45", 6, ".3f"),
    ("mean°", "mean_abs_deg", 6, ".1f"),
    ("signed°", "mean_signed_deg", 7, ".1f"),
)
_KEY = (
    "labelled: a labeller's figure-side boundary pixels that got a direction; cover (coverage): the share "
    "of them where the run's map has a vector; on those pixels: side (side accuracy): the vector within "
    "90° of the labelled direction, so on the figure's side (chance 0.5); <=45°: within 45° (chance "
    "0.25); mean°: the mean absolute difference (chance 90°); signed°: the mean signed difference, the "
    "number the paper reports (signs cancel in it: near 0 says nothing alone); both: the labellers' "
    "pixels pooled, as experiments/paper/table1.py counts them; all N: every image's pixels pooled "
    "(labeller k: each image's k-th labelling)"
)


def names_labels(spec) -> bool:
    """Whether compare's B names human labels rather than maps: a folder holding ``labels/`` (or that
    ``labels/`` folder itself), or a
    ``.npz`` file with ``fg`` and no ``fg_x``. A ``.npz`` numpy cannot read is refused here, in
    words for either kind (the maps reader would call it a bad maps file)."""
    path = Path(spec)
    if path.is_dir():
        runs = any((path / n).exists() for n in ("maps.npz", "maps.zarr", ".zattrs"))
        return ((path / "labels").is_dir() or path.name == "labels") and not runs
    if path.suffix.lower() != ".npz" or not path.is_file():
        return False
    try:
        with np.load(path, allow_pickle=False) as d:
            keys = list(d.files)
    except Exception as exc:  # (zip, pickle and format errors from numpy)
        raise InputError(
            path, f"cannot read the .npz archive ({type(exc).__name__}: {exc}); B is a run's maps or human labels"
        ) from None
    if "fg" not in keys and "fg_x" not in keys:  # (neither kind: say both, not only what maps lack)
        raise InputError(
            path,
            "holds neither a run's maps (fg_x, fg_y, grouping) nor human labels (fg); "
            f"found {', '.join(keys) or 'nothing'}",
        )
    return "fg" in keys and "fg_x" not in keys


@dataclass
class Scored:
    """One image of the run scored: its maps' path and run provenance, the labels' path and what
    they hold, each labeller's :func:`~snn_fg.scoring.label_scores.error_stats` part and, for an
    image the figure draws, the labelled directions and the run's field scored (``truths``,
    ``fields``; None otherwise: a folder of 160 runs would hold 1.5 GB of them)."""

    image_id: str
    maps_path: Path
    labels_path: Path
    params: dict
    labels: GroundTruth
    parts: list
    truths: list | None = None
    fields: tuple | None = None


def runs_of(spec) -> list[Path]:
    """The maps RUN holds: itself, or each run a dataset folder's ``summary.csv`` lists as done
    (or skipped as done before); a failed one is left out, named by :func:`failed_runs`."""
    path = Path(spec)
    summary = path / "summary.csv"
    if not path.is_dir() or any((path / n).exists() for n in ("maps.npz", "maps.zarr")) or not summary.is_file():
        return [path]
    with open(summary, newline="") as fh:
        rows = list(csv.DictReader(fh))
    runs = [Path(r["output"]) for r in rows if r.get("status") in ("done", "skipped")]
    runs = [p if p.is_absolute() or p.exists() else path / p.name for p in runs]
    if not runs:
        raise InputError(summary, "lists no run that finished: nothing to score")
    return runs


def failed_runs(spec) -> list[str]:
    """The inputs a dataset folder's ``summary.csv`` lists as failed (none for a single run)."""
    summary = Path(spec) / "summary.csv"
    if not summary.is_file() or any((Path(spec) / n).exists() for n in ("maps.npz", "maps.zarr")):
        return []
    with open(summary, newline="") as fh:
        return [r["recording"] for r in csv.DictReader(fh) if r.get("status") == "failed"]


def _labels_path(run: Path, maps: Maps, labels) -> tuple[str, Path, Path | None]:
    """(image id, labels file, the bsds-fg image beside the labels or None) for one run."""
    source = maps.params.get("source") or {}
    given = source.get("input")
    if Path(labels).is_file():  # (one labels file: its name says its image where it is a BSDS id)
        stem, own = Path(labels).stem, Path(given).stem if given else None
        if own is not None and own.isdigit() and stem.isdigit() and own != stem:
            raise InputError(labels, f"labels image {stem}, but the run ({run}) is of image {own}")
        return own or stem, Path(labels), None
    if given is None:
        raise InputError(run, "its maps name no input image, so no labels can be matched to it; give the labels file")
    image_id = Path(given).stem
    root = Path(labels) if Path(labels, "labels").is_dir() else Path(labels).parent  # (bsds-fg, or its labels/)
    found = root / "labels" / f"{image_id}.npz"
    if not found.is_file():
        raise InputError(
            labels, f"holds no labels for the run's image {image_id} (its input {Path(given).name}): no {found}"
        )
    image = root / "images" / f"{image_id}.jpg"
    return image_id, found, image if image.is_file() else None


def score_run(run: Path, labels, min_confidence: float | None = None, keep: bool = False) -> Scored:
    """One run's maps against their labels, checked first: a recording's maps, labels of another
    size or a bad labels file end in an :class:`InputError` naming the file. ``keep``: keep the
    directions and the field for the figure."""
    maps = Maps.load(run)
    if np.ndim(maps.fg_x) != 2:
        raise InputError(
            run, f"holds a recording's maps ({len(maps.fg_x)} windows); human labels score a still image's run"
        )
    image_id, path, image = _labels_path(run, maps, labels)
    if min_confidence is not None and CONFIDENCE not in maps.extra:
        raise InputError(
            "--min-confidence", f"{run} holds no fg_confidence (its model has no spike counts): leave the option out"
        )
    gt = load_labels(path, image, image_id)
    if gt.fg.shape[1:] != maps.fg_x.shape:
        h, w = maps.fg_x.shape
        raise InputError(
            path,
            f"labels are {gt.fg.shape[1]} x {gt.fg.shape[2]} (rows x columns) but the run's maps ({run}) are {h} x {w}",
        )
    fx, fy = maps.fg_x, maps.fg_y
    sure = confident(maps, None, min_confidence)
    if sure is not None:  # (a spiking run's vectors below the threshold count as no vector: coverage drops)
        fx, fy = np.where(sure, fx, 0), np.where(sure, fy, 0)
    truths = [boundary_directions(m) for m in gt.fg]
    if not any(valid.any() for _, _, valid in truths):  # (every cell of the table would be a dash)
        raise InputError(
            path,
            "its labels give no direction: a labelled boundary needs +1 pixels on the figure's side and -1 "
            "pixels on the ground's side beside them (fg), and these have "
            + ("no -1 pixel" if not (gt.fg < 0).any() else "no +1 pixel" if not (gt.fg > 0).any() else "none near"),
        )
    parts = labeller_errors(fx, fy, truths)
    kept = (truths, (fx, fy)) if keep else (None, None)
    return Scored(image_id, Path(run), path, maps.params, gt, parts, *kept)


def _who(s: Scored, k: int) -> str:
    return f"{k + 1}" + (f" (id {s.labels.labellers[k]})" if s.labels.labellers else "")


def _cells(name, who, stats) -> str:
    cells = [f"{name:>10}", f"{who:>12}"]
    cells += [cell(stats.get(key), width, spec) for _, key, width, spec in _COLUMNS]
    return "  ".join(cells)


def table_rows(scored: list[Scored]) -> list[tuple[str, str, dict]]:
    """(image, labeller, pool_stats) per image and labeller and both labellers; pooled over the
    images when there are several (labeller k: each image's k-th labelling)."""
    out = []
    for s in scored:
        out += [(s.image_id, _who(s, k), pool_stats([p])) for k, p in enumerate(s.parts)]
        out.append((s.image_id, "both", pool_stats(s.parts)))
    if len(scored) > 1:
        n = max(len(s.parts) for s in scored)
        out += [
            (f"all {len(scored)}", f"{k + 1}", pool_stats(s.parts[k] for s in scored if k < len(s.parts)))
            for k in range(n)
        ]
        out.append((f"all {len(scored)}", "both", pool_stats(p for s in scored for p in s.parts)))
    return out


def labels_table(rows, notes=()) -> str:
    """The rows of :func:`table_rows` as text, ``notes`` under them, then what each column is."""
    header = "  ".join([f"{'image':>10}", f"{'labeller':>12}"] + [f"{h:>{w}}" for h, _, w, _ in _COLUMNS])
    lines = [header] + [_cells(*r) for r in rows] + list(notes)
    return "\n".join(lines + textwrap.wrap(_KEY, 98))


#: the interval line's scores: (score, word, format), in the table's words
_INTERVAL = (("side_accuracy", "side", ".3f"), ("coverage", "cover", ".3f"), ("within45", "<=45°", ".3f"))
_INTERVAL += (("mean_abs_deg", "mean°", ".1f"),)


def run_settings(params: dict) -> str:
    """What a run's maps say it was made with, in one line: the model, its network (a spiking run's
    recipe, file or the default built from parameters) and backend, the stage parameters and how the
    image was turned into events (the model and its network: :func:`~snn_fg.results.maps.made_by`)."""
    said = made_by(params)
    stages = [f"{k} {params[k]:g}" for k in ("levels", "n_ori", "r0", "iterations", "input_pool") if k in params]
    source = params.get("source") or {}
    events = [f"{k} {source[k]}" for k in ("motion", "threshold") if source.get(k) is not None]
    return "; ".join(
        [said] + ([", ".join(stages)] if stages else []) + ([f"events {', '.join(events)}"] * bool(events))
    )


def pooled_interval(scored: list[Scored]) -> tuple[str, dict | None]:
    """The line under the table that gives the pooled scores of every image and labeller with the 95 %
    interval of a bootstrap over the images, as the experiment pages give them
    (:func:`~snn_fg.scoring.bootstrap.bootstrap_scores`, :data:`~snn_fg.scoring.bootstrap.RESAMPLES`
    resamples), and those numbers; one image allows none (resampling one image gives it back), and the
    line says so."""
    if len(scored) < 2:
        return "interval: none for one image (the experiment pages' 95 % interval resamples images: give several)", None
    boot = bootstrap_scores([s.parts for s in scored], n_resamples=RESAMPLES, keys=tuple(k for k, _, _ in _INTERVAL))
    cells = [
        f"{word} {boot[k]['pooled']:{f}} [{boot[k]['low']:{f}}, {boot[k]['high']:{f}}]" for k, word, f in _INTERVAL
    ]
    head = f"all {len(scored)}, both, with the 95 % interval of {RESAMPLES} bootstrap resamples of the images"
    return f"{head}: {'; '.join(cells)}", {k: nulls(boot[k]) for k, _, _ in _INTERVAL}


def _record(args, scored: list[Scored], rows, interval=None) -> dict:
    """What --json keeps: the inputs and what each run was made with, every row as printed (all scores
    of pool_stats, the median to half a degree), the pooled interval over images (several images),
    the options and the snn-fg that measured them."""
    from .. import __version__

    return {
        "a": str(args.a[0]) if len(args.a) == 1 else [str(a) for a in args.a],
        "b": str(args.b),
        "options": {"min_confidence": args.min_confidence},
        "images": [
            {
                "image_id": s.image_id,
                "maps": str(s.maps_path),
                "labels": str(s.labels_path),
                "labellers": list(s.labels.labellers),
                "settings": run_settings(s.params),
            }
            for s in scored
        ],
        "rows": [{"image": i, "labeller": w, **nulls(st)} for i, w, st in rows],
        "interval": None if interval is None else {"level": 0.95, "resamples": RESAMPLES, **interval},
        "snn_fg_version": __version__,
    }


def cmd_compare_labels(args) -> int:
    """Handler of ``snn-fg compare RUN LABELS`` (``args`` as compare parses them); prints the table, returns 0."""
    for key, flag in _MAPS_ONLY:
        if getattr(args, key) is not None and getattr(args, key) is not False:  # (--window 0 == False)
            raise InputError(flag, f"chooses windows or pixels of two maps files; {args.b} holds human labels")
    runs_given = ", ".join(map(str, args.a))  # (RUN: one run or folder of runs, or several made one at a time)
    runs = [r for a in args.a for r in runs_of(a)]
    if len(runs) > 1 and Path(args.b).is_file():
        raise InputError(
            args.b, f"is one image's labels, but {runs_given} holds {len(runs)} runs: give the labels folder"
        )
    drawn = set(rows_shown(len(runs), FIGURE_ROWS).tolist()) if args.plot else set()
    scored = [score_run(r, args.b, args.min_confidence, keep=i in drawn) for i, r in enumerate(runs)]
    seen: dict = {}
    for s in scored:  # (runs given one by one and pooled: an image given twice would weigh twice)
        if s.image_id in seen and len(args.a) > 1:
            raise InputError(
                s.maps_path, f"is a second run of image {s.image_id} (also {seen[s.image_id]}): give each once"
            )
        seen[s.image_id] = s.maps_path
    notes = []
    failed = [f for a in args.a for f in failed_runs(a)]
    if failed:
        notes.append(
            f"snn-fg: note: {runs_given} lists {len(failed)} failed run(s), not scored: {', '.join(failed[:4])}"
        )
    for s in scored:
        given = (s.params.get("source") or {}).get("input")
        if len(s.labels.fg) > 1 and all(np.array_equal(s.labels.fg[0], f) for f in s.labels.fg[1:]):
            notes.append(f"snn-fg: note: {s.labels_path.name}: its labellers gave the same labels (the same scores)")
        if given and Path(given).stem != s.labels_path.stem:
            notes.append(f"snn-fg: note: the run's input is {Path(given).name} but the labels are {s.labels_path.name}")
    rows = table_rows(scored)
    models = sorted({str(s.params.get("model", "unknown")) for s in scored})
    images = f"{len(scored)} image{'s' if len(scored) > 1 else ''}"
    what = [f"run{'s' * (len(args.a) > 1)}: {runs_given} ({images}, the {'/'.join(models)} model); labels: {args.b}"]
    settings: dict = {}
    for s in scored:  # (one line when every run was made alike, as is usual; else one per kind, counted)
        settings.setdefault(run_settings(s.params), []).append(s.image_id)
    for line, ids in settings.items():
        what.append(f"read: {line}" + (f" ({len(ids)} of {len(scored)} images)" if len(settings) > 1 else ""))
    interval, boot = pooled_interval(scored)
    print(labels_table(rows, what + [interval] + notes))
    if args.json:
        save_text(args.json, json.dumps(_record(args, scored, rows, boot), indent=2))
        print(f"snn-fg: scores saved to {args.json}")
    if args.plot:
        from ..scoring.labels_figure import save_labels_figure

        save_labels_figure(args.plot, scored, FIGURE_ROWS)
        print(f"snn-fg: figure saved to {args.plot}")
    return 0
