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

from experiments.common import CACHE, RESULTS, dataset, fail

#: The paper's Table 1 thresholds.
THRESHOLDS = (0.10, 0.15, 0.20, 0.30, 0.40)
#: Images of --quick (evenly spaced over the sorted ids).
QUICK_IMAGES = 12
#: The per-image settings every BSDS experiment uses.
SETTINGS = {
    "thresholds": THRESHOLDS,
    "shift4_thresholds": (0.10,),
    "event_models": ("rate",),
    "fbfg_operators": ("gaussian", "corf"),
    "fig6": True,
}


def parser(description: str) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=description)
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="Dask scheduler of a running cluster (default: local worker processes, one per core)",
    )
    p.add_argument("--workers", type=int, help="local worker processes (default: one per core)")
    p.add_argument("--images", type=int, metavar="N", help="evaluate N images evenly spaced over the 160 (all)")
    p.add_argument("--quick", action="store_true", help=f"the --images {QUICK_IMAGES} subset")
    p.add_argument("--ids", nargs="+", metavar="ID", help="evaluate these image ids")
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


def sweep(func, ids, settings: dict, args, spiking: bool = False) -> dict:
    """``func(root=..., image_id=..., **settings)`` for every image id, on Dask, cached per image."""
    from experiments.sweep import SweepTask, run_sweep
    from snn_fg.errors import SnnFgError

    tasks = [SweepTask(i, {"root": str(dataset("bsds-fg")), "image_id": i, **settings}) for i in ids]
    try:
        return run_sweep(
            func,
            tasks,
            CACHE / settings_key(settings, spiking),
            scheduler=args.scheduler,
            workers=args.workers,
            progress=not args.no_progress,
            preload=("brian2",) if spiking else (),
        )
    except SnnFgError as exc:
        fail(str(exc))


def evaluate_settings(*, root: str, image_id: str, **settings) -> dict:
    """The sweep's unit of work: :func:`experiments.evaluation.evaluate_image` with the flat settings the cache is
    keyed on (:func:`settings_key`)."""
    from experiments.evaluation import ImageEvaluation, evaluate_image

    return evaluate_image(root=root, image_id=image_id, settings=ImageEvaluation(**settings))


def evaluate(args, settings: dict | None = None) -> dict:
    """Per-image results ``{image_id: dict}`` of :func:`experiments.evaluation.evaluate_image` on the selected
    images (cached)."""
    settings = dict(SETTINGS if settings is None else settings)
    ids = args.ids or select_ids(QUICK_IMAGES if args.quick and args.images is None else args.images)
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
