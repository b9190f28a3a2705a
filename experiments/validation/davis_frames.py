"""The frame-based reference on a DAVIS camera's own frames: every model on the same windows.

    python -m experiments.validation.davis_frames [--max-windows N] [--fresh]

A DAVIS camera's grey-level (APS) frames come from the same pixels as its
events, so the frame-based model can read the scene the event models read.
Each recording runs through ``snn-fg run`` as a user runs it, in 85 ms
windows: the rate model, the spiking network (default and compact networks,
the fast engine) and the frame-based model (``--model fbfg``, each window on
the last APS frame before its end). Recordings:

* ``disc``: ``tests/data/davis346_disc.aedat4``, made with dv-processing's
  writer from :func:`snn_fg.frames.scenes.davis_disc_recording` (a light disc
  seen through the iCub's microsaccade, 400 ms, 5 windows): its truth is
  known, the disc's rim owned inward;
* ``street``: the ``davis`` dataset, a real DAVIS346 recording (a street
  seen from a still camera, cars passing, 2.4 s, 28 windows): no truth.

Every pair of models is compared window by window
(:func:`snn_fg.scoring.metrics.compare_maps`, as ``snn-fg compare``) and
pooled over the windows: within 45° and the mean absolute angle difference
on the pixels where both have a vector, coverage (the share of the second
model's vectors the first has at all) and grouping r (median and range over
the windows); and again on the outline of each window's largest filled
event region (``snn-fg compare --outline 3``), where an object that fills
with events has its border. On the disc each model is also scored against the truth
(:func:`~snn_fg.scoring.metrics.truth_scores`, pooled). Runs are kept in
``experiments/results/cache/davis_frames/`` and read back (``--fresh`` runs
them again). Writes ``davis_frames.{json,md}`` and per recording
``davis_frames_<recording>.png`` (APS frame, event frame, spiking network's
map, frame model's map and their difference, for up to four windows).
"""

from __future__ import annotations

import argparse
import itertools
import json
import shutil
import time

import numpy as np

from experiments.common import CACHE, ROOT, Run, dataset, describe, load, markdown_table, save_figure, save_results

#: name -> the ``snn-fg run`` options of the model
MODELS = {
    "rate": ["--model", "rate"],
    "spiking": ["--model", "spiking"],
    "compact": ["--model", "spiking", "--network", "compact"],
    "fbfg": ["--model", "fbfg"],
}
#: name -> what it is, for the tables
RECORDINGS = {
    "disc": "made disc (dv-processing's writer), 400 ms",
    "street": "DAVIS346 street (aedat package's test data), 2.4 s",
}


#: the band compared on the outline of each window's largest event region (px), as snn-fg compare --outline 3
OUTLINE_PX = 3


def _path(recording: str):
    if recording == "disc":
        return ROOT / "tests" / "data" / "davis346_disc.aedat4"
    return dataset("davis", "aedat_davis346_street.aedat4")


def _run(recording: str, model: str, max_windows, fresh: bool) -> tuple:
    """The model's maps on the recording (run, or read back from the cache) and how long its run took
    (``{"seconds", "load"}``: the load average before it)."""
    from snn_fg.cli import main
    from snn_fg.results.maps import Maps
    from snn_fg.results.store import STORE_NAME, read_attrs

    out = CACHE / "davis_frames" / f"{recording}{'' if max_windows is None else f'_{max_windows}w'}" / model
    timing = out / "timing.json"
    done = out.is_dir() and timing.is_file() and read_attrs(out / STORE_NAME)["snn_fg"]["complete"]
    if fresh or not done:
        shutil.rmtree(out, ignore_errors=True)
        argv = ["run", str(_path(recording)), *MODELS[model], "--out", str(out), "--no-progress", "--no-figures"]
        t, before = time.perf_counter(), load()
        if main(argv + ([] if max_windows is None else ["--max-windows", str(max_windows)])) != 0:
            raise SystemExit(f"snn-fg {' '.join(argv)} failed")
        timing.write_text(json.dumps({"seconds": round(time.perf_counter() - t, 1), "load": before[0]}))
    return Maps.load(out), json.loads(timing.read_text())


def _pooled(rows) -> dict:
    """Rows of compare_maps pooled over windows (weighted by the pixels each compares)."""
    n = np.array([r["pixels_compared"] for r in rows], float)
    has = n > 0
    within = np.array([r["angle_within_45_frac"] for r in rows])[has]
    mean = np.array([r["angle_diff_mean_deg"] for r in rows])[has]
    grp = np.array([r["grouping_pearson_r"] for r in rows], float)
    grp = grp[np.isfinite(grp)]
    b = sum(r["pixels_b"] for r in rows)
    return {
        "windows": len(rows),
        "pixels_compared": int(n.sum()),
        "within_45": float(np.sum(within * n[has]) / n.sum()) if n.sum() else float("nan"),
        "mean_deg": float(np.sum(mean * n[has]) / n.sum()) if n.sum() else float("nan"),
        "coverage": float(n.sum() / b) if b else float("nan"),
        "grouping_r_median": float(np.median(grp)) if grp.size else float("nan"),
        "grouping_r_range": [float(grp.min()), float(grp.max())] if grp.size else None,
    }


def _truth(maps, scene) -> dict:
    """The disc's truth scores of every window, pooled (weighted by the pixels each scores)."""
    from snn_fg.scoring.metrics import truth_scores

    s = [truth_scores(maps.fg_x[i], maps.fg_y[i], scene) for i in range(maps.fg_x.shape[0])]
    n = np.array([x["scored_pixels"] for x in s], float)
    has = n > 0
    return {
        "windows": len(s),
        "within_45": float(np.sum(np.array([x["frac_within_45"] for x in s])[has] * n[has]) / n.sum()),
        "within_45_per_window": [round(x["frac_within_45"], 4) for x in s],
        "mean_deg": float(np.sum(np.array([x["mean_err_deg"] for x in s])[has] * n[has]) / n.sum()),
        "coverage": float(n.sum() / sum(x["boundary_pixels"] for x in s)),
    }


def _inward(maps) -> dict:
    """How each window's vectors on the outline of its largest filled event region point (the region
    as the figure: a car that moves, the disc), pooled over the windows by their outline vectors."""
    from snn_fg.scoring.outline import filled_outline, outline_scores

    frames = maps.extra["event_frame"]
    s = [
        outline_scores(maps.fg_x[i], maps.fg_y[i], filled_outline(np.asarray(frames[i]) != 0))
        for i in range(len(frames))
    ]
    n = np.array([x["vectors"] for x in s], float)
    has = n > 0
    pool = lambda k: float(np.sum(np.array([x[k] for x in s])[has] * n[has]) / n.sum()) if n.sum() else float("nan")  # noqa: E731
    return {
        "vectors": int(n.sum()),
        "inward": pool("inward"),
        "within_45": pool("within45"),
        "mean_deg": pool("mean_deg"),
    }


def _figure(recording, maps):
    from snn_fg.scoring.compare_figure import aps_inputs, compare_figure
    from snn_fg.scoring.metrics import compare_maps

    a, b = maps["spiking"], maps["fbfg"]
    fig = compare_figure(
        a, b, compare_maps(a, b), names=("spiking network", "frame model (fbfg)"), max_rows=4, inputs=aps_inputs(a, b)
    )
    return save_figure(fig, f"davis_frames_{recording}", dpi=80)  # (five panels a row: 1.8 MB at 110 dpi)


def _f(v, spec=".1%"):
    return "-" if v is None or not np.isfinite(v) else format(v, spec)


def _measure(recording: str, what: str, args) -> dict:
    """Every model on ``recording``, compared pair by pair, against the event region's outline and
    (the disc) against the truth; its figure written."""
    from snn_fg.frames.scenes import davis_disc_recording
    from snn_fg.scoring.metrics import compare_maps
    from snn_fg.scoring.outline import event_outlines

    maps, seconds = {}, {}
    for model in MODELS:
        maps[model], seconds[model] = _run(recording, model, args.max_windows, args.fresh)
    pairs, outline = {}, {}
    for a, b in itertools.combinations(MODELS, 2):
        pairs[f"{a} vs {b}"] = _pooled(compare_maps(maps[a], maps[b]))
        band = event_outlines(maps[a], maps[b], OUTLINE_PX)
        outline[f"{a} vs {b}"] = _pooled(compare_maps(maps[a], maps[b], where=band))
    rec = {"what": what, "windows": int(maps["fbfg"].fg_x.shape[0]), "seconds": seconds, "pairs": pairs}
    rec["outline_pairs"] = outline
    rec["aps_index"] = maps["fbfg"].extra["aps_index"].tolist()
    rec["outline_inward"] = {m: _inward(maps[m]) for m in MODELS}
    if recording == "disc":
        scene = davis_disc_recording().scene
        rec["truth"] = {m: _truth(maps[m], scene) for m in MODELS}
    rec["figure"] = _figure(recording, maps).name
    return rec


def _page(recording: str, rec: dict) -> list[str]:
    """The results page's section of one recording."""
    what, pairs, outline, seconds = rec["what"], rec["pairs"], rec["outline_pairs"], rec["seconds"]
    lines = []
    lines += [f"## {recording}: {what}, {rec['windows']} windows of 85 ms", ""]
    header = (
        "A vs B",
        "windows",
        "pixels",
        "within 45°",
        "mean abs",
        "coverage of B",
        "grouping r (median, range)",
    )
    lines += markdown_table(
        header,
        (
            (
                k,
                v["windows"],
                v["pixels_compared"],
                _f(v["within_45"]),
                _f(v["mean_deg"], ".1f") + "°",
                _f(v["coverage"]),
                f"{_f(v['grouping_r_median'], '.2f')} ({', '.join(_f(x, '.2f') for x in v['grouping_r_range'] or [])})",
            )
            for k, v in pairs.items()
        ),
    )
    lines += ["", f"On the outline ({OUTLINE_PX} px) of each window's largest filled event region only:", ""]
    lines += markdown_table(
        ("A vs B", "pixels", "within 45°", "mean abs", "coverage of B"),
        (
            (k, v["pixels_compared"], _f(v["within_45"]), _f(v["mean_deg"], ".1f") + "°", _f(v["coverage"]))
            for k, v in outline.items()
        ),
    )
    lines += [
        "",
        "Each model's vectors on that outline against its inward normal (the event region as the figure):",
        "",
    ]
    lines += markdown_table(
        ("model", "outline vectors", "inward", "within 45°", "mean abs"),
        (
            (m, v["vectors"], _f(v["inward"]), _f(v["within_45"]), _f(v["mean_deg"], ".1f") + "°")
            for m, v in rec["outline_inward"].items()
        ),
    )
    if "truth" in rec:
        lines += ["", "Against the truth (the disc's rim, owned inward):", ""]
        lines += markdown_table(
            ("model", "within 45°", "per window", "mean abs", "coverage of the rim"),
            (
                (
                    m,
                    _f(t["within_45"]),
                    ", ".join(f"{x:.0%}" for x in t["within_45_per_window"]),
                    _f(t["mean_deg"], ".1f") + "°",
                    _f(t["coverage"]),
                )
                for m, t in rec["truth"].items()
            ),
        )
    took = ", ".join(f"{m} {s['seconds']:.0f} s (load {s['load']:.1f})" for m, s in seconds.items())
    lines += ["", f"Run times (`snn-fg run --no-figures`, as each run was made): {took}.", ""]
    lines += [f"Figure: `{rec['figure']}` (spiking network against the frame model).", ""]
    return lines


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--max-windows", type=int, default=None, help="windows per recording (all)")
    p.add_argument("--fresh", action="store_true", help="run every model again (not from the cache)")
    args = p.parse_args(argv)
    run = Run()
    record = {"recordings": {}}
    lines = ["# The frame-based model on a DAVIS camera's own frames, against the event models", ""]
    for recording, what in RECORDINGS.items():
        record["recordings"][recording] = rec = _measure(recording, what, args)
        lines += _page(recording, rec)
    record["run"] = run.record()
    lines += [describe(record["run"])]
    save_results("davis_frames", record, lines)


if __name__ == "__main__":
    main()
