"""The spiking network at other time steps: fidelity and cost of dt = 1 ms
(or any other) against the default 0.5 ms, side by side.

The network is described in milliseconds; ``dt_ms`` only says how finely a
simulator steps it. SpiNNaker is usually run in real time at 1 ms steps
(finer steps with a slower time scale), and part of the fast engine's cost
is per step: the active cells' updates, and the closed-form catch-up of a
cell each step that input reaches it. What changes at 1 ms: spike times and
delays land on a 1 ms grid, and a cell fires at most once per step (the
feedback cells, whose refractory period is 0.5 ms, get a 1 kHz ceiling
instead of 2 kHz).

For each ``--dt`` (the first is the one the others are compared with):

1. the six BSDS frames of the dataset ``bsds-edfg`` against the rate reference
   (issue 11's acceptance: mean angle difference <= 15 deg, >= 90 % of shared
   edge pixels within 45 deg, grouping r >= 0.9) and against the first dt's maps;
2. the synthetic discs (radius 16-64, both polarities), the square, the
   occlusion and the demo scene against ``run_edfg`` and their analytic truth;
3. ``dvs.es`` from 100 ms in 85 ms windows as one continuous run: the grouping
   peak on the plane, the outline vectors pointing inwards, and each window's
   maps against the first dt's;
4. the time per ``dvs.es`` window, measured in fresh processes that alternate
   between the time steps, round after round (``--rounds``), each warmed up on
   the first window and keeping one backend object for all its windows, as
   ``snn-fg run`` does (``experiments.bench.spiking_variant_speed.alternate``): the ratio of the
   medians is the speed gain.

Writes experiments/results/spiking_dt.json, .md and .png (``--name``: another
stem). ``--changes JSON`` runs a changed network (``SpikingParams`` to change in
their stored form, as ``experiments.bench.spiking_variant_speed`` takes them) at every dt, to be compared with
the default network's scores in ``spiking_dt.md``.

    python -m experiments.validation.spiking_dt [--dt 0.5 1.0] [--quick] [--rounds 3] [--changes JSON --name STEM]

The stored results come from ``--dt 0.5 1.0 0.25``; ``spiking_dt_pruned``
from ``--dt 1.0 --changes '{"prune_vm": 0.2, "prune_dog": 0.1}' --name
spiking_dt_pruned``.

``--quick`` leaves out the BSDS frames (about 5 of the 8 minutes).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from experiments.common import (
    DVS_FROM_MS,
    RESULTS,
    Run,
    dataset,
    describe,
    load,
    markdown_table,  # noqa: E402
    save_json,
    save_markdown,
)
from experiments.validation.spiking_fidelity import fidelity_row  # noqa: E402
from experiments.validation.spiking_heldout import variant_params  # noqa: E402
from snn_fg import datasets
from snn_fg.events import image_to_frame, iter_windows  # noqa: E402
from snn_fg.frames import scenes  # noqa: E402
from snn_fg.models.rate.edfg import run_edfg  # noqa: E402
from snn_fg.models.spiking import run_spiking_result  # noqa: E402
from snn_fg.results.atomic import save_figure  # noqa: E402
from snn_fg.scoring.metrics import agreement, grouping_peak  # noqa: E402
from snn_fg.scoring.outline import filled_outline, outline_scores  # noqa: E402

START_MS = DVS_FROM_MS
WINDOW_MS = 85.0
TIMED_WINDOWS = (0, 1, 2)


def _frames(dts, quick, sp, log):
    """Sections 1 and 2: one row per input and dt."""
    inputs = []
    bsds = datasets.find("bsds-edfg")
    if not quick and bsds is not None:
        for path in sorted(bsds.glob("*.npz")):
            d = np.load(path)
            inputs.append((f"bsds-{path.stem}", d["pos"], d["neg"], d, None))
    elif not quick:
        log("skipping BSDS frames: the dataset bsds-edfg is absent (snn-fg data fetch bsds-edfg)")
    synth = [scenes.disc(r, light) for r in (16, 24, 32, 48, 64) for light in (True, False)]
    synth += [scenes.square(24, True), scenes.occlusion(), scenes.demo()]
    for sc in synth:
        pos, neg = image_to_frame(sc.image)
        inputs.append((sc.name, pos, neg, run_edfg(pos, neg), sc))
    rows = []
    for name, pos, neg, ref, scene in inputs:
        first = None
        for dt in dts:
            t0 = time.perf_counter()
            res = run_spiking_result(pos, neg, spiking=sp, backend="fast", seed=0, dt_ms=dt, progress=False)
            row = fidelity_row(
                name, "bsds" if scene is None else "synthetic", res.maps, ref, time.perf_counter() - t0, scene
            )
            row.pop("roles")
            row["dt_ms"] = dt
            row["run_s"] = res.maps.params["timings_s"].get("run")
            if first is None:
                first = res.maps
            else:
                row["vs_first_dt"] = agreement(res.maps, first)
            rows.append(row)
            log(
                f"{name:<18} dt {dt:g} ms: {row['angle_diff_mean_deg']:5.1f} deg, "
                f"{row['angle_within_45_frac']:.3f} within 45, r {row['grouping_pearson_r']:.3f}"
                + (f", truth {row['truth_frac_within_45']:.2f}" if scene is not None else "")
                + (f"; vs dt {dts[0]:g}: {row['vs_first_dt']['mean_deg']:.1f} deg" if "vs_first_dt" in row else "")
                + f"  ({row['seconds']:.0f} s)"
            )
    return rows


def _recording(dts, sp, log):
    """Section 3: dvs.es as one continuous run per dt."""
    from snn_fg.models.spiking.continuous import run_spiking_windows

    windows = list(iter_windows(dataset("events", "dvs.es"), window_ms=WINDOW_MS, start_ms=START_MS))
    out, first = {}, None
    for dt in dts:
        t0 = time.perf_counter()
        maps = run_spiking_windows(windows, spiking=sp, backend="fast", dt_ms=dt, progress=False)
        rows = []
        for k, (w, m) in enumerate(zip(windows, maps)):
            region = filled_outline(w.pos | w.neg)
            r, c = grouping_peak(m.grouping)
            o = outline_scores(m.fg_x, m.fg_y, region)
            row = {
                "window": w.index,
                "peak_on_plane": bool(region[r, c]),
                "outline_vectors": o["vectors"],
                "inward": o["inward"],
                "within45": o["within45"],
                "mean_deg": o["mean_deg"],
            }
            if first is not None:
                row["vs_first_dt"] = agreement(m, first[k])
            rows.append(row)
        first = first or maps
        run = maps[-1].params["timings_s"]
        out[str(dt)] = {
            "windows": rows,
            "seconds": time.perf_counter() - t0,
            "run_s": run.get("run"),
            "synaptic_events": maps[0].params.get("backend_stats", {}).get("synaptic_events_total"),
            "spikes": maps[0].params.get("backend_stats", {}).get("spikes"),
            "peak_on_plane": sum(r["peak_on_plane"] for r in rows),
            "inward_min": float(np.nanmin([r["inward"] for r in rows])),
        }
        log(
            f"dvs.es dt {dt:g} ms: peak on the plane in {out[str(dt)]['peak_on_plane']} of {len(rows)} windows, "
            f"inward >= {out[str(dt)]['inward_min']:.2f}, run {run.get('run', 0):.1f} s"
        )
    return out


def _timing(dts, rounds, changes, log):
    """Section 4: alternating fresh processes, one per dt and round
    (``experiments.bench.spiking_variant_speed.alternate``, with the network ``changes``)."""
    from experiments.bench.spiking_variant_speed import alternate

    runs = alternate(
        [(f"dt {dt:g} ms", changes, dt) for dt in dts], [f"dvs:{k}@{START_MS:g}" for k in TIMED_WINDOWS], rounds, log
    )
    med = {str(dt): statistics.median(x["wall_s"] for x in runs if x["dt_ms"] == dt) for dt in dts}
    return {"runs": runs, "median_s": med, "windows": list(TIMED_WINDOWS), "load_end": load()}


def _triple(mean_deg, within45, r) -> str:
    return f"{mean_deg:.1f} / {within45:.2f} / {r:.3f}"


def _timing_table(t, dts, base) -> list[str]:
    m = t["median_s"]

    def row(dt):
        first = next(x for x in t["runs"] if x["dt_ms"] == dt and x["input"].startswith("dvs:0@"))
        return [
            f"{dt:g}",
            f"{m[str(dt)]:.3f}",
            f"{m[str(dt)] / m[str(base)]:.2f}",
            f"{first['synaptic_events']:,}",
            f"{first['closed_form_advances']:,}",
            f"{first['active_cell_steps']:,}",
        ]

    return markdown_table(
        [
            "dt (ms)",
            "median s per window",
            f"relative to dt {base:g}",
            "synaptic events",
            "closed-form catch-ups",
            "active cell-steps",
        ],
        map(row, dts),
    )


def _frame_row(r) -> list:
    v = r.get("vs_first_dt")
    return [
        r["name"],
        f"{r['dt_ms']:g}",
        _triple(r["angle_diff_mean_deg"], r["angle_within_45_frac"], r["grouping_pearson_r"]),
        f"{r['rate_covered_frac']:.2f}",
        "yes" if r["pass_fidelity"] else "NO",
        f"{r['truth_frac_within_45']:.2f} / {r['ref_truth_frac_within_45']:.2f}" if "truth_frac_within_45" in r else "",
        "" if "peak_inside" not in r else ("yes" if r["peak_inside"] else "NO"),
        "" if v is None else _triple(v["mean_deg"], v["within_45"], v["grouping_r"]),
        f"{r['run_s']:.1f}",
    ]


def _dvs_row(dt, d) -> list:
    ws = d["windows"]
    vs = [w["vs_first_dt"] for w in ws if "vs_first_dt" in w]
    versus = (
        [
            f"{np.median([v['mean_deg'] for v in vs]):.1f}",
            f"{min(v['within_45'] for v in vs):.2f}",
            f"{min(v['grouping_r'] for v in vs):.3f}",
        ]
        if vs
        else ["", "", ""]
    )
    return [
        f"{dt:g}",
        f"{d['peak_on_plane']} of {len(ws)}",
        f"{d['inward_min']:.2f}",
        f"{np.nanmedian([w['inward'] for w in ws]):.2f}",
        f"{np.nanmedian([w['within45'] for w in ws]):.2f}",
        *versus,
        f"{d['run_s']:.1f}",
    ]


def _markdown(rec) -> list[str]:
    dts, base = rec["dt_ms"], rec["dt_ms"][0]
    names = [f"{d:g}" for d in dts]
    steps = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    changed = f"; network changes `{json.dumps(rec['changes'])}`" if rec.get("changes") else ""
    lines = [
        "# The spiking network at dt = " + steps + " ms",
        "",
        f"{describe(rec['run'])} Fast engine, input seed 0{changed}. Angles: mean absolute difference (deg) / "
        "fraction of shared edge pixels within 45 deg / grouping Pearson r. Figure: "
        f"`{rec.get('name', 'spiking_dt')}.png`.",
        "",
    ]
    t = rec.get("timing")
    if t:
        lines += [
            "## Time per dvs.es window (side by side)",
            "",
            f"Windows {', '.join(map(str, t['windows']))} from {START_MS:g} ms, each run as a recording of "
            f"one window, in fresh processes alternating between the time steps, {rec['rounds']} rounds "
            f"(load {min(x['load'] for x in t['runs']):.1f}-{max(x['load'] for x in t['runs']):.1f}).",
            "",
            *_timing_table(t, dts, base),
            "",
            "(counters of window 0)",
            "",
        ]
    if rec["frames"]:
        lines += [f"## Frames against the rate model (and against dt {base:g})", ""]
        lines += markdown_table(
            [
                "input",
                "dt (ms)",
                "vs rate",
                "covered",
                "pass (issue 11)",
                "truth within 45 (spk / rate)",
                "peak inside",
                f"vs dt {base:g}",
                "run (s)",
            ],
            map(_frame_row, rec["frames"]),
        )
        lines.append("")
    dvs = rec.get("dvs")
    if dvs:
        lines += [
            "## dvs.es, one continuous run, 85 ms windows from 100 ms",
            "",
            "Outline vectors against the plane's inward normal: inward fraction / within 45 deg / mean "
            f"angle; the last columns compare each window's maps with dt {base:g}'s.",
            "",
        ]
        lines += markdown_table(
            [
                "dt (ms)",
                "peak on plane",
                "inward, lowest window",
                "inward, median",
                "within 45, median",
                f"vs dt {base:g}: mean angle (median over windows)",
                "within 45 (lowest)",
                "grouping r (lowest)",
                "run (s)",
            ],
            [_dvs_row(dt, dvs[str(dt)]) for dt in dts],
        )
        lines.append("")
    return lines


def _figure(rec, path):
    dts = rec["dt_ms"]
    fig, ax = plt.subplots(1, 3, figsize=(14, 4))
    bsds = sorted({r["name"] for r in rec["frames"] if r["kind"] == "bsds"})
    width = 0.8 / len(dts)
    for j, dt in enumerate(dts):
        val = [
            next(r["angle_diff_mean_deg"] for r in rec["frames"] if r["name"] == n and r["dt_ms"] == dt) for n in bsds
        ]
        ax[0].bar(np.arange(len(bsds)) + j * width, val, width, label=f"dt {dt:g} ms")
    ax[0].axhline(15, color="k", ls=":", lw=1)
    ax[0].set_xticks(np.arange(len(bsds)) + width * (len(dts) - 1) / 2, [n[5:] for n in bsds], rotation=30)
    ax[0].set(ylabel="mean |angle difference| to the rate model (deg)", title="BSDS frames (15 deg: issue 11)")
    ax[0].legend(fontsize=8)
    if rec.get("dvs"):
        for dt in dts:
            ws = rec["dvs"][str(dt)]["windows"]
            ax[1].plot([w["window"] for w in ws], [w["inward"] for w in ws], "o-", label=f"dt {dt:g} ms")
        ax[1].axhline(0.6, color="k", ls=":", lw=1)
        ax[1].set(
            xlabel="dvs.es window (85 ms, from 100 ms)",
            ylabel="outline vectors pointing inwards",
            ylim=(0, 1.02),
            title="dvs.es, one continuous run (0.6: issue 11)",
        )
        ax[1].legend(fontsize=8)
    if rec.get("timing"):
        for j, dt in enumerate(dts):
            xs = [x["wall_s"] for x in rec["timing"]["runs"] if x["dt_ms"] == dt]
            ax[2].plot(np.full(len(xs), j) + np.linspace(-0.1, 0.1, len(xs)), xs, "o")
        ax[2].axhline(0.85, color="k", ls=":", lw=1)
        ax[2].set_xticks(range(len(dts)), [f"dt {d:g} ms" for d in dts])
        ax[2].set(ylabel="s per dvs.es window", ylim=(0, None), title="time per window (0.85 s: issue 13)")
    if rec.get("changes"):
        fig.suptitle(f"network changes: {json.dumps(rec['changes'])}", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, dpi=90)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--dt",
        type=float,
        nargs="+",
        default=[0.5, 1.0],
        help="time steps in ms; the first is the one the others are compared with (0.5 1.0)",
    )
    ap.add_argument("--quick", action="store_true", help="leave out the BSDS frames (writes spiking_dt_quick.*)")
    ap.add_argument("--rounds", type=int, default=3, help="timing rounds (3)")
    ap.add_argument("--changes", default="{}", metavar="JSON", help="SpikingParams fields to change ({})")
    ap.add_argument("--name", help="stem of the files written (spiking_dt; with --quick spiking_dt_quick)")
    a = ap.parse_args()
    # without the BSDS frames the results are not the full set's: they never overwrite spiking_dt.*
    a.name = a.name or ("spiking_dt_quick" if a.quick else "spiking_dt")
    sp = variant_params("--changes", a.changes)
    dataset("events", "dvs.es")
    run = Run()
    log = lambda msg: print(msg, flush=True)  # noqa: E731
    rec = {"dt_ms": a.dt, "rounds": a.rounds, "changes": json.loads(a.changes), "name": a.name}
    rec["timing"] = _timing(a.dt, a.rounds, a.changes, log)
    rec["frames"] = _frames(a.dt, a.quick, sp, log)
    rec["dvs"] = _recording(a.dt, sp, log)
    rec["run"] = run.record()
    save_json(a.name, rec)
    save_markdown(a.name, _markdown(rec))
    _figure(rec, RESULTS / f"{a.name}.png")
    log(f"wrote experiments/results/{a.name}.json, .md and .png")


if __name__ == "__main__":
    main()
