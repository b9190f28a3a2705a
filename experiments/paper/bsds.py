"""What the BSDS experiments (table1, fig6, best_worst) share: options, the image
selection, the sweep of :func:`experiments.evaluation.evaluate_image` on Dask, and writing tables.

The three run the same per-image evaluation with the same settings, so they
share one cache (``experiments/results/cache/bsds-<settings>/``): whichever
runs first computes, the others read. The labels are the dataset ``bsds-fg``.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import io
import json
from pathlib import Path

import numpy as np

from experiments.common import CACHE, RESULTS, dataset, fail, positive_int

#: The paper's Table 1 thresholds.
THRESHOLDS = (0.10, 0.15, 0.20, 0.30, 0.40)
#: Images of --quick (evenly spaced over the sorted ids).
QUICK_IMAGES = 12
#: Below this coverage (share of labelled pixels with a vector) or ...
LOW_COVERAGE = 0.02
#: ... this many scored pixels, a result's scores get a warning line: with fewer than 100 pixels the
#: standard error of a side accuracy near 50 % passes 5 points (sqrt(0.25 / 100)), and at a coverage
#: near zero the few pixels left are the strongest edges, not the labelled boundaries at large.
FEW_PIXELS = 100
#: The per-image settings every BSDS experiment uses.
SETTINGS = {
    "thresholds": THRESHOLDS,
    "shift4_thresholds": (0.10,),
    "event_models": ("rate",),
    "fbfg_operators": ("gaussian", "corf"),
    "fig6": True,
}


def contrast_threshold(text: str) -> float:
    """argparse type: an event simulator contrast threshold C, a step of ``log(I + eps)``
    (snn_fg.events.esim). It must be above 0, and below ``log((1 + eps) / eps)`` (6.9), the largest
    step an image in [0, 1] can make: a threshold beyond it gives no events at all."""
    from snn_fg.events.esim import LOG_EPS

    top = float(np.log((1 + LOG_EPS) / LOG_EPS))
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0 < value < top:
        raise argparse.ArgumentTypeError(
            f"contrast threshold must lie in (0, {top:.2f}) (a step of log intensity; the paper uses "
            f"0.10-0.40), not {value:g}"
        )
    return value


def parser(doc: str, images: int | None = None, workers: int | None = None) -> argparse.ArgumentParser:
    """The options every BSDS experiment shares; the help opens with the first paragraph of ``doc`` (the
    script's docstring), whole: its first line alone stops mid-sentence. ``images``, ``workers``: the
    script's defaults where they are not all the images and one worker per core."""
    p = argparse.ArgumentParser(description=" ".join(doc.strip().split("\n\n")[0].split()))
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="Dask scheduler of a running cluster (default: local worker processes, one per core)",
    )
    p.add_argument(
        "--workers",
        type=positive_int,
        default=workers,
        help=f"local worker processes (default: {workers or 'one per core'})",
    )
    p.add_argument(
        "--images",
        type=positive_int,
        default=images,
        metavar="N",
        help=f"evaluate N images evenly spaced over the 160 ({images or 'all'}); other than "
        f"{images or 'all'} write <name>_<N>images.*",
    )
    p.add_argument("--quick", action="store_true", help=f"the --images {QUICK_IMAGES} subset")
    p.add_argument("--ids", nargs="+", metavar="ID", help="evaluate these image ids (writes <name>_ids-<ids>.*)")
    p.add_argument("--no-progress", action="store_true")
    return p


def select_ids(n: int | None) -> list[str]:
    """All image ids, or ``n`` of them evenly spaced (deterministic)."""
    from snn_fg.scoring.groundtruth import bsds_ids

    ids = bsds_ids(dataset("bsds-fg"))
    if n is None or n >= len(ids):
        return ids
    pick = sorted({int(round(i * (len(ids) - 1) / max(n - 1, 1))) for i in range(n)})
    return [ids[i] for i in pick]


def chosen_ids(args) -> list[str]:
    """The image ids a run's options select: ``--ids``, ``--images N`` or ``--quick``, else all."""
    return (
        list(args.ids) if args.ids else select_ids(QUICK_IMAGES if args.quick and args.images is None else args.images)
    )


def subset_name(name: str, args, n: int, default: int | None = None) -> str:
    """The stem a run on ``n`` images writes its results under: ``name`` when it ran on the ``default``
    number of images (all of them unless said) without ``--ids``, else a stem that says which subset,
    as experiments.validation.spiking_groundtruth does: ``<name>_<n>images``, and for ``--ids``
    ``<name>_ids-<id>-<id>...`` (``<name>_<k>ids-<hash>`` past 4 ids). The full-set files are the ones
    docs/ cite, so a quick look at 2 images must never overwrite them."""
    if args.ids:
        ids = sorted(set(args.ids), key=lambda i: (len(i), i))
        if len(ids) <= 4:
            return f"{name}_ids-{'-'.join(ids)}"
        return f"{name}_{len(ids)}ids-{hashlib.sha1(' '.join(ids).encode()).hexdigest()[:8]}"
    full = len(select_ids(None)) if default is None else default
    return name if n == full else f"{name}_{n}images"


def settings_key(settings: dict, spiking: bool | None = None) -> str:
    """Cache directory name of one set of settings. Runs of the spiking model
    (``spiking``; by default: when ``settings["event_models"]`` names it)
    also key on the default network's constants, so that a cache made before a
    change of ``SpikingParams`` is not read back as the new network's; all
    key on the version of what an image's result holds."""
    from experiments.evaluation import RESULT_VERSION

    text = json.dumps(settings, sort_keys=True) + ("" if RESULT_VERSION == 1 else f"v{RESULT_VERSION}")
    if spiking is None:
        spiking = "spiking" in settings.get("event_models", ())
    if spiking:
        from snn_fg.network import SpikingParams

        text += json.dumps(SpikingParams().to_dict(), sort_keys=True)
    return "bsds-" + hashlib.sha1(text.encode()).hexdigest()[:10]


def coverage_warnings(scored) -> list[str]:
    """Warning lines for the ``(label, scores)`` whose coverage or scored pixels are too few to read
    their other scores by (:data:`LOW_COVERAGE`, :data:`FEW_PIXELS`)."""
    return [
        f"Warning: {label}: coverage {100 * s['coverage']:.1f} %, {s['n_pixels']:,} scored pixels: too few for "
        "its other scores to mean much (a higher contrast threshold gives fewer events)."
        for label, s in scored
        if not s["coverage"] >= LOW_COVERAGE or s["n_pixels"] < FEW_PIXELS
    ]


def input_digest(root, image_id: str) -> str:
    """Digest of an image's inputs, its ``images/<id>.jpg`` and ``labels/<id>.npz``, that its cache file is
    named by, so that a changed (or replaced, or damaged) label or image file is computed again instead of
    its old scores being read back. A hash of their bytes rather than size and mtime: the 160 images and
    labels are 14 MB, hashed in about 30 ms, and a content hash also survives a copy of the dataset
    (``cp -r`` gives every file a new mtime, which would throw the whole cache away) while still
    catching an edit that keeps the size and the mtime."""
    h = hashlib.sha1()
    for path in (Path(root, "images", f"{image_id}.jpg"), Path(root, "labels", f"{image_id}.npz")):
        h.update(path.name.encode() + b"\0")
        h.update(path.read_bytes() if path.is_file() else b"absent")
        h.update(b"\0")
    return h.hexdigest()[:10]


def check_inputs(root, ids) -> None:
    """Read every image's labels (checked against its image) before any worker starts, so that a bad
    file ends the run with one line naming it, not with a Dask worker's traceback, and nothing written."""
    from snn_fg.errors import InputError
    from snn_fg.scoring.groundtruth import load_bsds_fg

    for image_id in ids:
        try:
            load_bsds_fg(root, image_id)
        except InputError as exc:
            fail(exc.for_command_line())


def sweep(func, ids, settings: dict, args, spiking: bool = False) -> dict:
    """``func(root=..., image_id=..., **settings)`` for every image id, on Dask, cached per image and
    per digest of its inputs (:func:`input_digest`); ``{image_id: result}``."""
    from experiments.sweep import SweepTask, run_sweep
    from snn_fg.errors import SnnFgError

    root = dataset("bsds-fg")
    check_inputs(root, ids)
    keys = {i: f"{i}-{input_digest(root, i)}" for i in ids}
    tasks = [SweepTask(keys[i], {"root": str(root), "image_id": i, **settings}) for i in ids]
    try:
        done = run_sweep(
            func,
            tasks,
            CACHE / settings_key(settings, spiking),
            scheduler=args.scheduler,
            workers=args.workers,
            progress=not args.no_progress,
            preload=("brian2",) if spiking else (),
        )
    except SnnFgError as exc:
        fail(exc.for_command_line())
    return {i: done[keys[i]] for i in ids}


def evaluate_settings(*, root: str, image_id: str, **settings) -> dict:
    """The sweep's unit of work: :func:`experiments.evaluation.evaluate_image` with the flat settings the cache is
    keyed on (:func:`settings_key`)."""
    from experiments.evaluation import ImageEvaluation, evaluate_image

    return evaluate_image(root=root, image_id=image_id, settings=ImageEvaluation(**settings))


def evaluate(args, settings: dict | None = None) -> dict:
    """Per-image results ``{image_id: dict}`` of :func:`experiments.evaluation.evaluate_image` on the selected
    images (cached)."""
    settings = dict(SETTINGS if settings is None else settings)
    ids = chosen_ids(args)
    return sweep(evaluate_settings, ids, settings, args, "spiking" in settings["event_models"])


def write_table(name: str, rows: list[dict], formats=("json", "csv"), run: dict | None = None) -> list[Path]:
    """``results/<name>.json`` (``{"rows": rows, "run": run}``, or the list of rows without a run record) and/or
    ``results/<name>.csv``."""
    from snn_fg.results.atomic import save_text

    written = []
    if "json" in formats:
        written.append(
            save_text(
                RESULTS / f"{name}.json", json.dumps(rows if run is None else {"rows": rows, "run": run}, indent=1)
            )
        )
    if "csv" in formats:
        buf = io.StringIO()
        if rows:
            w = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
            w.writeheader()
            w.writerows(rows)
        written.append(save_text(RESULTS / f"{name}.csv", buf.getvalue()))
    return written
