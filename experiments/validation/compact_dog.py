"""The compact network's DoG as it is against the same taps balanced: the issue's truth bar for the change.

The compact network keeps the DoG taps over 30 % of each kernel's peak, and
the kept kernel sums to +0.75; balanced, the kept negative taps are scaled so
that it sums to 0 again (the same taps; ``recording_ceiling --pruning``,
whose kernel patch this runs under). Both kernels, side by side in one run:

* **BSDS**: every ``--every``-th labelled BSDS image (8: the 20 images of
  ``compact_accuracy``, the same events at contrast 0.4), each image through
  both kernels in turn: against both labellers pooled, binary side accuracy
  (within 90 degrees), coverage, within 45 degrees and the mean absolute
  error, and the difference (balanced minus as pruned) with the 95 %
  interval of a paired bootstrap over the images;
* **time a window**: ``dvs.es`` windows of 85 ms from ``--start-ms``, each
  run as a recording of one window after a warm-up one, in a fresh process
  per kernel and round pinned to one core (``taskset -c 0``), the kernels
  alternating (``spiking_variant_speed.alternate``): the CPU and wall seconds
  a window, its spikes and synaptic events (which do not depend on the
  machine).

    python -m experiments.validation.compact_dog [--every 8] [--workers 1] [--windows 0 1 2 3] [--rounds 2]

Writes experiments/results/compact_dog.{json,md,png} (the figure: side
accuracy per image, and CPU seconds per window, for both kernels).
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from experiments.common import (
    Run,
    dataset,
    describe,
    fail,
    load,
    markdown_table,
    positive_int,
    save_figure,
    save_results,
)
from experiments.validation.compact_accuracy import BSDS_THRESHOLD, bsds_scored
from experiments.validation.recording_ceiling import compact_dog

#: the compact network's DoG pruning (of each kernel's peak), and its two kernels: balanced or not
PRUNE = 0.3
KERNELS = {"as pruned": False, "balanced": True}
PIN = ("taskset", "-c", "0")
#: the reference beside them on BSDS: the rate model on the compact recipe's parameters (the full DoG)
RATE = "rate model"


def bsds_image(job) -> dict:
    """One labelled image through the compact network with one of :data:`KERNELS`, or the rate model
    (:data:`RATE`) on the compact recipe's parameters."""
    image_id, model, threshold = job
    if model == RATE:
        from snn_fg.models.rate.edfg import run_edfg
        from snn_fg.network.recipes import RECIPES

        return bsds_scored(image_id, threshold, RATE, lambda pos, neg: run_edfg(pos, neg, RECIPES["compact"].params))
    from snn_fg.models.spiking import run_spiking

    context, options = compact_dog(PRUNE, KERNELS[model])
    with context:
        run = lambda pos, neg: run_spiking(pos, neg, progress=False, **options)  # noqa: E731
        return bsds_scored(image_id, threshold, f"compact, DoG {model}", run)


def bsds(ids, workers: int, threshold: float) -> dict:
    """Both kernels on the images ``ids`` (each image's two runs one after the other)."""
    from experiments.pooled import bootstrap_difference
    from snn_fg.scoring.label_scores import pool_stats

    models = [*KERNELS, RATE]
    jobs = [(i, model, threshold) for i in ids for model in models]
    with ProcessPoolExecutor(workers) as pool:
        done = list(pool.map(bsds_image, jobs))
    images = {model: [r for r, (_, m, _) in zip(done, jobs) if m == model] for model in models}
    parts = {model: [im["parts"] for im in images[model]] for model in models}
    keys = ("side_accuracy", "coverage", "within45", "mean_abs_deg")
    return {
        "images": ids,
        "threshold": threshold,
        "pooled": {m: pool_stats(p for im in parts[m] for p in im) for m in models},
        "difference": bootstrap_difference(parts["as pruned"], parts["balanced"], keys=keys),
        "per_image": {
            m: [{"image_id": im["image_id"], "seconds": im["seconds"], **pool_stats(im["parts"])} for im in images[m]]
            for m in models
        },
    }


def _worker(kernel: str, specs: list[str], dt: str):
    """Time each window (``inputs`` specs) through the compact network with ``kernel``; one JSON line each."""
    from experiments.bench import inputs
    from snn_fg.backends import as_backend
    from snn_fg.models.spiking.continuous import run_spiking_windows

    context, options = compact_dog(PRUNE, KERNELS[kernel])
    options.update(backend=as_backend("fast"), dt_ms=None if dt == "None" else float(dt), progress=False)
    wins = [inputs.load(s).window() for s in specs]
    with context:
        run_spiking_windows(wins[:1], **options)  # warm-up
        for spec, w in zip(specs, wins):
            t, c = time.perf_counter(), time.process_time()
            (maps,) = run_spiking_windows([w], **options)
            wall, cpu = time.perf_counter() - t, time.process_time() - c
            st, span_s = maps.params["backend_stats"], maps.params["simulation"]["count_window_ms"] / 1000
            by_role = {}
            for p in maps.params["populations"].values():  # (spikes counted over the window's read-out span)
                by_role[p["role"]] = by_role.get(p["role"], 0) + round(p["mean_rate_hz"] * p["cells"] * span_s)
            row = {"input": spec, "wall_s": wall, "cpu_s": cpu, "synaptic_events": st["synaptic_events_total"]}
            print(json.dumps({**row, "spikes": st["spikes"], "spikes_by_role": by_role}), flush=True)


def timing(windows, start_ms: float, rounds: int) -> dict:
    """The kernels' time a window, alternating in fresh processes on one core."""
    from experiments.bench.spiking_variant_speed import alternate

    if shutil.which(PIN[0]) is None:
        fail(f"{PIN[0]} not found: the timing pins each process to one core (util-linux)")
    specs = [f"dvs:{k}@{start_ms:g}" for k in windows]
    runs = [(kernel, kernel, None) for kernel in KERNELS]
    rows = alternate(runs, specs, rounds, lambda m: print(m, flush=True), worker=__spec__.name, pin=PIN)
    out = {"windows": list(windows), "start_ms": start_ms, "rounds": rounds, "pinned": " ".join(PIN), "rows": rows}
    for kernel in KERNELS:
        mine = [r for r in rows if r["label"] == kernel]
        out[kernel] = {
            "median_cpu_s": statistics.median(r["cpu_s"] for r in mine),
            "median_wall_s": statistics.median(r["wall_s"] for r in mine),
            "spikes": {s: next(r["spikes"] for r in mine if r["input"] == s) for s in specs},
            "simple_spikes": {s: next(r["spikes_by_role"]["simple"] for r in mine if r["input"] == s) for s in specs},
            "synaptic_events": {s: next(r["synaptic_events"] for r in mine if r["input"] == s) for s in specs},
            "load": [min(r["load"] for r in mine), max(r["load"] for r in mine)],
        }
    return out


def lines(record: dict) -> list[str]:
    out = ["# The compact network's DoG: as it is against balanced", "", describe(record["run"]), ""]
    if "bsds" in record:
        b, ks = record["bsds"], [*KERNELS, RATE]
        fmt = {"side_accuracy": "{:.3f}", "coverage": "{:.3f}", "within45": "{:.3f}", "mean_abs_deg": "{:.1f}"}

        def row(key):
            d = b["difference"][key]
            diff = f"{d['difference']:+.3f} ({d['low']:+.3f} to {d['high']:+.3f})"
            return [key, *(fmt[key].format(b["pooled"][k][key]) for k in ks), diff]

        out += [
            f"BSDS: {len(b['images'])} labelled images (every {record['every']}-th by id, events at contrast "
            f"{b['threshold']:g}), both labellers pooled; the compact network with each kernel and the {RATE} on "
            "the compact recipe's parameters (its full DoG); the difference balanced minus as pruned with the 95 % "
            "interval of a paired bootstrap over the images.",
            "",
            *markdown_table(["score", *ks, "balanced - as pruned"], map(row, fmt)),
            "",
        ]
    if "timing" in record:
        t = record["timing"]
        ks, specs = list(KERNELS), [f"dvs:{k}@{t['start_ms']:g}" for k in t["windows"]]
        base = t[ks[0]]

        def trow(k):
            v = t[k]
            return [
                k,
                f"{v['median_cpu_s']:.3f} ({v['median_cpu_s'] / base['median_cpu_s']:.2f})",
                f"{v['median_wall_s']:.3f}",
                " / ".join(f"{v['spikes'][s]:,}" for s in specs),
                " / ".join(f"{v['simple_spikes'][s]:,}" for s in specs),
                " / ".join(f"{v['synaptic_events'][s]:,}" for s in specs),
                f"{v['load'][0]:.2f}-{v['load'][1]:.2f}",
            ]

        out += [
            f"Time a window: `dvs.es` windows {', '.join(map(str, t['windows']))} of 85 ms from {t['start_ms']:g} ms, "
            f"{t['rounds']} rounds of fresh processes pinned to one core (`{t['pinned']}`), the kernels alternating; "
            "medians over windows and rounds (in brackets: relative to as pruned); spikes (all; the simple cells' "
            "counted over the window's read-out span) and synaptic events per window, which do not depend on the "
            "machine.",
            "",
            *markdown_table(
                [
                    "kernel",
                    "CPU s a window",
                    "wall s a window",
                    "spikes",
                    "simple-cell spikes",
                    "synaptic events",
                    "load",
                ],
                map(trow, ks),
            ),
            "",
        ]
    return out


def figure(record: dict):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [k for k in ("bsds", "timing") if k in record]
    fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 4.2), squeeze=False)
    for ax, panel in zip(axes[0], panels):
        if panel == "bsds":
            side = {m: np.array([im["side_accuracy"] for im in ims]) for m, ims in record["bsds"]["per_image"].items()}
            a = side.pop("as pruned")
            for (model, b), marker in zip(side.items(), "ox"):
                ax.scatter(a, b, s=18, marker=marker, label=model)
            ax.plot([0, 1], [0, 1], color="0.6", lw=0.8)
            ax.axhline(0.5, color="0.8", lw=0.8)
            ax.set(
                xlim=(0, 1), ylim=(0, 1), xlabel="side accuracy, compact network, DoG as pruned", ylabel="side accuracy"
            )
            ax.legend()
            ax.set_title(f"BSDS, {len(a)} images: side accuracy per image")
        else:
            t = record["timing"]
            for kernel, marker in zip(KERNELS, "ox"):
                rows = [r for r in t["rows"] if r["label"] == kernel]
                ax.scatter([r["spikes"] for r in rows], [r["cpu_s"] for r in rows], marker=marker, label=kernel)
            ax.set(xlabel="spikes in the window", ylabel="CPU s (one core)")
            ax.set_title("dvs.es windows, compact network")
            ax.legend()
    fig.tight_layout()
    return fig


def main():
    from snn_fg.scoring.groundtruth import bsds_ids

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--every", type=int, default=8, help="every N-th labelled BSDS image, by sorted id (0: none)")
    ap.add_argument(
        "--images", type=positive_int, default=None, help="only the first N of those (writes <name>_<N>images.*)"
    )
    ap.add_argument("--workers", type=positive_int, default=1)
    ap.add_argument("--threshold", type=float, default=BSDS_THRESHOLD, help="BSDS event conversion contrast")
    ap.add_argument("--windows", type=int, nargs="*", default=[0, 1, 2, 3], help="dvs.es windows to time (none: no)")
    ap.add_argument("--start-ms", type=float, default=85.0)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--name", help="stem of the files written (compact_dog; with --images N compact_dog_<N>images)")
    ap.add_argument("--worker", nargs=3, metavar=("KERNEL", "SPECS", "DT"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker:
        return _worker(a.worker[0], a.worker[1].split(","), a.worker[2])
    run, record = Run(), {"prune_dog": PRUNE, "every": a.every}
    if a.every:
        every = bsds_ids(dataset("bsds-fg"))[:: a.every]
        ids = every[: a.images]
        # a subset of the --every images never overwrites the files of them all (the ones docs/ cite)
        a.name = a.name or ("compact_dog" if len(ids) == len(every) else f"compact_dog_{len(ids)}images")
        print(f"BSDS: {len(ids)} images, both kernels and the {RATE}", file=sys.stderr, flush=True)
        record["bsds"] = bsds(ids, a.workers, a.threshold)
    if a.windows:
        record["timing"] = timing(a.windows, a.start_ms, a.rounds)
    record["run"] = run.record()
    record["load_after"] = load()
    a.name = a.name or "compact_dog"
    save_results(a.name, record, lines(record))
    save_figure(figure(record), a.name)


if __name__ == "__main__":
    main()
