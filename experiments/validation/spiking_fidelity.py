"""Fidelity of the spiking network to the rate reference, and its own scores
on synthetic scenes.

Rows:
* the six BSDS frames of the dataset ``bsds-edfg`` (321 x 481; the stored
  fg_x / fg_y / grouping are the rate reference's output on pos / neg);
* synthetic discs (radius 16-64, light-on-dark and dark-on-light; event frame
  from ``image_to_frame``), a square, the occlusion scene and the demo scene,
  each compared with ``run_edfg`` on the same frame and scored against the
  scene's analytic ground truth;
* two discs fed as timed events (``image_to_events``), same comparisons.

Acceptance (issue 3): median |angle difference| <= 20 deg on pixels where both
maps are non-zero, grouping Pearson r >= 0.8; on discs >= 75 % of boundary
pixels within 45 deg and the grouping maximum inside the disc.

With several ``--backend`` s every input runs on each, and the maps and spike
counts of every backend after the first are compared with the first's
(issue 13: a second engine must be statistically the same as Brian2).

With several ``--seeds`` every input runs once per seed of the input trains'
random phase; the main table keeps the first seed, and a second table gives
the range of every score over the seeds and how far each seed's maps lie from
the first seed's (the network's own seed-to-seed spread, against which a
difference between two variants of the network has to be read).

Writes experiments/results/spiking_fidelity.json and .md.
Usage: python -m experiments.validation.spiking_fidelity [--quick] [--only NAME ...] [--backend NAME ...]
       [--seeds N ...]
"""

from __future__ import annotations

import argparse
import json
import re
import resource
import time
from pathlib import Path

import numpy as np

from experiments.common import RESULTS, Run, describe, markdown_table
from snn_fg import datasets
from snn_fg.backends import DEFAULT_BACKEND, backend_names
from snn_fg.events import events_to_frame, image_to_events, image_to_frame
from snn_fg.frames import scenes
from snn_fg.models.rate.edfg import run_edfg
from snn_fg.models.spiking import run_spiking_result
from snn_fg.models.spiking.record import ROLE_ORDER
from snn_fg.results.atomic import save_text
from snn_fg.scoring.metrics import agreement, compare_frame, grouping_peak_inside, truth_scores


def _roles(maps):
    """Mean rate per role over all levels (cells of every level pooled) and
    the highest per-level population mean, with the refractory ceiling."""
    pops = maps.params["populations"]
    out = {}
    for role in ROLE_ORDER:
        ps = [p for p in pops.values() if p["role"] == role and p["cells"] > 0]
        if not ps:
            continue
        cells = sum(p["cells"] for p in ps)
        out[role] = {
            "mean_rate_hz": sum(p["mean_rate_hz"] * p["cells"] for p in ps) / cells,
            "active_frac": sum(p["active_frac"] * p["cells"] for p in ps) / cells,
            "max_level_mean_hz": max(p["mean_rate_hz"] for p in ps),
            "refractory_max_hz": ps[0]["refractory_max_hz"],
            "silent_levels": sorted(p["level"] for p in ps if p["mean_rate_hz"] == 0),
        }
    return out


def fidelity_row(name, kind, maps, ref, elapsed, scene=None, extra=None):
    """One input's scores: the spiking ``maps`` against the rate reference ``ref`` (and the scene's truth)."""
    c = compare_frame(
        maps.fg_x,
        maps.fg_y,
        maps.grouping,
        ref.fg_x if hasattr(ref, "fg_x") else ref["fg_x"],
        ref.fg_y if hasattr(ref, "fg_y") else ref["fg_y"],
        ref.grouping if hasattr(ref, "grouping") else ref["grouping"],
    )
    row = {
        "name": name,
        "kind": kind,
        "angle_diff_median_deg": c["angle_diff_median_deg"],
        "angle_diff_mean_deg": c["angle_diff_mean_deg"],
        "angle_within_45_frac": c["angle_within_45_frac"],
        "grouping_pearson_r": c["grouping_pearson_r"],
        "pixels_compared": c["pixels_compared"],
        "pixels_rate": c["pixels_b"],
        "rate_covered_frac": c["coverage_of_b"],
        "rate_within_45_frac": c["within_45_of_b"],
        "seconds": elapsed,
        "cells": maps.params["counts"]["total_cells"],
        "synapses": maps.params["counts"]["total_synapses"],
        "timings_s": maps.params["timings_s"],
        "roles": _roles(maps),
    }
    # issue 11's acceptance against the rate model on the same input
    row["pass_fidelity"] = bool(
        row["angle_diff_mean_deg"] <= 15 and row["angle_within_45_frac"] >= 0.9 and row["grouping_pearson_r"] >= 0.9
    )
    if scene is not None:
        t = truth_scores(maps.fg_x, maps.fg_y, scene)
        tr = truth_scores(ref.fg_x, ref.fg_y, scene)
        row.update(
            {
                "truth_frac_within_45": t["frac_within_45"],
                "truth_coverage": t["coverage"],
                "truth_frac_of_all_boundary": t["frac_within_45"] * t["coverage"],
                "truth_median_err_deg": t["median_err_deg"],
                "peak_inside": grouping_peak_inside(maps.grouping, scene, None),
                "ref_truth_frac_within_45": tr["frac_within_45"],
                "ref_truth_coverage": tr["coverage"],
                "ref_peak_inside": grouping_peak_inside(ref.grouping, scene, None),
            }
        )
        row["pass_truth"] = bool(row["truth_frac_within_45"] >= 0.95 and row["peak_inside"])
    if extra:
        row.update(extra)
    return row


def _agreement(res, first):
    """How the maps and spike counts of run ``res`` agree with run ``first``
    (same input, another backend)."""
    a, b = res.maps, first.maps
    c = compare_frame(a.fg_x, a.fg_y, a.grouping, b.fg_x, b.fg_y, b.grouping)
    same_cells = equal = total_a = total_b = 0
    for name in first.result.populations:
        sa, sb = res.result.sites[name], first.result.sites[name]
        same_cells += int(np.array_equal(sa, sb))
        if np.array_equal(sa, sb):
            equal += int(np.sum(res.result.counts[name] == first.result.counts[name]))
        total_a += int(res.result.counts[name].sum())
        total_b += int(first.result.counts[name].sum())
    cells = sum(s.size for s in first.result.sites.values())
    return {
        "angle_diff_mean_deg": c["angle_diff_mean_deg"],
        "angle_within_45_frac": c["angle_within_45_frac"],
        "grouping_pearson_r": c["grouping_pearson_r"],
        "populations_same_cells": same_cells,
        "cells_same_count_frac": equal / max(cells, 1),
        "spikes": total_a,
        "spikes_first": total_b,
    }


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument(
        "--quick", action="store_true", help="synthetic scenes only (no BSDS frames; writes spiking_fidelity_quick.*)"
    )
    ap.add_argument(
        "--only",
        nargs="*",
        help="run only rows whose name contains one of these (writes spiking_fidelity_only-<NAMES>.*)",
    )
    ap.add_argument(
        "--backend",
        nargs="+",
        default=[DEFAULT_BACKEND],
        choices=backend_names(),
        help=f"simulator(s); the first is the one the others are compared with (default {DEFAULT_BACKEND})",
    )
    ap.add_argument(
        "--instantiate",
        choices=("input", "all"),
        default="input",
        help="cells every backend creates (input: those the input can use, the same on every backend)",
    )
    ap.add_argument(
        "--seeds",
        nargs="+",
        type=int,
        default=[0],
        help="seeds of the input trains' random phase; each input runs once per seed (default 0)",
    )
    ap.add_argument("--out", default=str(RESULTS))
    return ap


class _Table:
    """The rows of the run: each input on every backend and seed, the later
    backends compared with the first and the later seeds with the first seed."""

    def __init__(self, args):
        self.args, self.rows, self.last = args, [], None

    def want(self, name: str) -> bool:
        return not self.args.only or any(o in name for o in self.args.only)

    def run(self, name, kind, simulate, ref, scene=None, extra=None):
        first = None
        seed0 = {}
        for seed in self.args.seeds:
            first_here = None
            for backend in self.args.backend:
                t0 = time.perf_counter()
                res = simulate(backend, seed)
                row = fidelity_row(
                    name, kind, res.maps, ref, time.perf_counter() - t0, scene, extra(res) if extra else None
                )
                row["backend"], row["seed"] = backend, seed
                if first_here is None:
                    first_here = res
                else:
                    row["vs_first"] = _agreement(res, first_here)
                if backend in seed0:
                    row["vs_first_seed"] = agreement(res.maps, seed0[backend].maps)
                else:
                    seed0[backend] = res
                self.rows.append(row)
                print(_fmt(row), flush=True)
            first = first if first is not None else first_here
        self.last = first


def _bsds_rows(table: _Table, instantiate: str) -> None:
    bsds = datasets.find("bsds-edfg")
    if bsds is None:
        print("skipping BSDS frames: the dataset bsds-edfg is absent (snn-fg data fetch bsds-edfg)", flush=True)
        return
    for path in sorted(bsds.glob("*.npz")):
        name = f"bsds-{path.stem}"
        if not table.want(name):
            continue
        d = np.load(path)
        table.run(
            name,
            "bsds",
            lambda b, seed, d=d: run_spiking_result(
                d["pos"], d["neg"], backend=b, seed=seed, instantiate=instantiate, progress=False
            ),
            d,
        )


def _synthetic_rows(table: _Table, instantiate: str) -> None:
    synth = [scenes.disc(r, light) for r in (16, 24, 32, 48, 64) for light in (True, False)]
    synth += [scenes.square(24, True), scenes.occlusion(), scenes.demo()]
    for sc in synth:
        if not table.want(sc.name):
            continue
        pos, neg = image_to_frame(sc.image)
        table.run(
            sc.name,
            "synthetic-frame",
            lambda b, seed, pos=pos, neg=neg: run_spiking_result(
                pos, neg, backend=b, seed=seed, instantiate=instantiate, progress=False
            ),
            run_edfg(pos, neg),
            sc,
        )
    for sc in (scenes.disc(24, True), scenes.disc(40, False)):
        name = sc.name + "-timed-events"
        if not table.want(name):
            continue
        rec = image_to_events(sc.image)
        pos, neg = events_to_frame(rec.events, rec.sensor_size)  # the frame of these very events
        table.run(
            name,
            "synthetic-events",
            lambda b, seed, rec=rec: run_spiking_result(
                events=rec.events,
                sensor_size=rec.sensor_size,
                backend=b,
                seed=seed,
                instantiate=instantiate,
                progress=False,
            ),
            run_edfg(pos, neg),
            sc,
            lambda r, rec=rec: {
                "events": int(len(rec.events)),
                "input_rate_hz": r.inputs.rate_hz,
                "merged_spikes": r.inputs.merged,
            },
        )


def main(argv=None):
    args = _parser().parse_args(argv)
    run_record = Run()
    table = _Table(args)
    if not args.quick:
        _bsds_rows(table, args.instantiate)
    _synthetic_rows(table, args.instantiate)
    rows, res = table.rows, table.last
    out = Path(args.out)
    record = {
        "rows": rows,
        "backends": args.backend,
        "seeds": args.seeds,
        "instantiate": args.instantiate,
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "network_params": res.maps.params["network"] if res else None,
        "simulation": res.maps.params["simulation"] if res else None,
        "run": run_record.record(),
    }
    stem = _stem(args)
    save_text(out / f"{stem}.json", json.dumps(record, indent=1, default=float))
    save_text(out / f"{stem}.md", "\n".join(_markdown(rows, record["run"], args.seeds)) + "\n")
    print(f"wrote {out / stem}.json and .md", flush=True)


def _stem(args) -> str:
    """``spiking_fidelity``, or for part of the inputs (``--quick``, ``--only``) a stem that says which part:
    a part never overwrites the full set's files, the ones docs/ cite."""
    stem = "spiking_fidelity" + ("_quick" if args.quick else "")
    if args.only:
        stem += "_only-" + re.sub(r"[^A-Za-z0-9.=+-]+", "_", "-".join(args.only))[:60]
    return stem


def _fmt(r):
    s = (
        f"{r['name']:28s} {r['backend']:7s} seed {r.get('seed', 0)} "
        f"median dAngle {r['angle_diff_median_deg']:5.1f} deg  mean {r['angle_diff_mean_deg']:5.1f}  "
        f"r {r['grouping_pearson_r']:.3f}  {r['seconds']:6.1f} s"
    )
    if "truth_frac_within_45" in r:
        s += (
            f"  truth<=45: {r['truth_frac_within_45']:.2f} (ref {r['ref_truth_frac_within_45']:.2f})"
            f" peak in {r['peak_inside']}"
        )
    if "vs_first" in r:
        v = r["vs_first"]
        s += (
            f"  vs first backend: r {v['grouping_pearson_r']:.4f}, angle mean {v['angle_diff_mean_deg']:.2f} deg, "
            f"same counts {v['cells_same_count_frac']:.4f}, spikes {v['spikes']} / {v['spikes_first']}"
        )
    return s


def _synapses(row) -> str:
    return f"{row['synapses']:,}" if row["synapses"] else "-"


def _main_row(r) -> list:
    nan = float("nan")
    return [
        r["name"],
        r.get("backend", ""),
        f"{r['angle_diff_median_deg']:.1f}",
        f"{r['angle_diff_mean_deg']:.1f}",
        f"{r.get('angle_within_45_frac', nan):.2f}",
        f"{r.get('rate_covered_frac', nan):.2f} / {r.get('rate_within_45_frac', nan):.2f}",
        f"{r['grouping_pearson_r']:.3f}",
        "yes" if r["pass_fidelity"] else "NO",
        f"{r['truth_frac_within_45']:.2f} / {r['ref_truth_frac_within_45']:.2f}" if "truth_frac_within_45" in r else "",
        f"{r['truth_coverage']:.2f}" if "truth_coverage" in r else "",
        f"{r['peak_inside']} / {r['ref_peak_inside']}" if "peak_inside" in r else "",
        "" if "pass_truth" not in r else "yes" if r["pass_truth"] else "NO",
        f"{r['cells']:,}",
        _synapses(r),
        f"{r['seconds']:.0f}",
    ]


def _versus_row(r) -> list:
    v = r["vs_first"]
    return [
        r["name"],
        r["backend"],
        f"{v['grouping_pearson_r']:.4f}",
        f"{v['angle_diff_mean_deg']:.2f}",
        f"{v['angle_within_45_frac']:.3f}",
        f"{v['cells_same_count_frac']:.4f}",
        f"{v['spikes']:,} / {v['spikes_first']:,}",
    ]


def _markdown(rows, run, seeds=(0,)) -> list[str]:
    every_seed, rows = rows, [r for r in rows if r.get("seed", seeds[0]) == seeds[0]]
    lines = [
        "# Spiking network vs the rate reference",
        "",
        f"{describe(run)} Default parameters. Angle difference: "
        "median / mean of |circular difference| on pixels where both figure-ground maps are non-zero. "
        "Truth: fraction of scored boundary pixels within 45 deg of the analytic direction "
        "(scored = the model has a vector there; `coverage` = scored / all boundary pixels). "
        "Rate's vectors: the fraction of the rate model's non-zero vectors that the spiking map has at all "
        "(covered), and has within 45 deg (covered x dAngle <= 45): the angle columns alone are over the "
        "shared pixels and would not show a map that leaves the hard ones blank.",
        "",
        "Pass (vs rate): mean <= 15 deg, >= 90 % within 45 deg, grouping r >= 0.9. Pass (truth): >= 95 % "
        "within 45 deg of the analytic direction and the grouping peak inside an object (any of the scene's "
        "shapes). Synapses: as a backend that unrolls the network makes them (Brian2); - for the fast "
        "engine, which follows the weight-shared kernels and makes none.",
        f"Input trains' seed: {seeds[0]}"
        + (f" (the spread over seeds {', '.join(map(str, seeds))} follows the tables)." if len(seeds) > 1 else "."),
        "",
    ]
    lines += markdown_table(
        [
            "input",
            "backend",
            "median dAngle (deg)",
            "mean dAngle",
            "dAngle <= 45",
            "rate's vectors: covered / within 45",
            "grouping r",
            "pass (vs rate)",
            "truth <= 45 (spk / ref)",
            "coverage",
            "peak inside (spk / ref)",
            "pass (truth)",
            "cells",
            "synapses",
            "time (s)",
        ],
        map(_main_row, rows),
    )
    versus = [r for r in rows if "vs_first" in r]
    if versus:
        lines += [
            "",
            "## Each backend against the first on the same input",
            "",
            "Maps compared as above (the first backend's maps as reference); counts: fraction of cells "
            "with the same spike count in the counting window; spikes: total in the window.",
            "",
        ]
        lines += markdown_table(
            [
                "input",
                "backend",
                "grouping r",
                "mean dAngle (deg)",
                "dAngle <= 45",
                "same counts",
                "spikes (this / first)",
            ],
            map(_versus_row, versus),
        )
    if len(seeds) > 1:
        lines += _spread(every_seed, seeds)
    lines += ["", "## Mean firing rate per population role (Hz; all levels pooled; first row)", ""]
    if rows:
        lines += markdown_table(
            ["role", "mean", "active fraction", "highest level mean", "refractory max"],
            [
                [
                    role,
                    f"{v['mean_rate_hz']:.1f}",
                    f"{v['active_frac']:.2f}",
                    f"{v['max_level_mean_hz']:.1f}",
                    f"{v['refractory_max_hz']:.0f}",
                ]
                for role, v in rows[0]["roles"].items()
            ],
        )
    return lines


def _span(values, fmt):
    return f"{fmt(min(values))} - {fmt(max(values))}" if len(values) > 1 else fmt(values[0])


def _spread(rows, seeds):
    """The range of each score over the input seeds, per input and backend,
    and how far each later seed's maps lie from the first seed's."""
    lines = [
        "",
        f"## Spread over the input trains' seeds ({', '.join(map(str, seeds))})",
        "",
        "Left: each score against the rate model, lowest - highest over the seeds, and on how many seeds "
        "the row passes. Right: each later seed's maps against the first seed's (the same network and "
        "input, only the phase of the input trains changed), lowest - highest.",
        "",
    ]
    deg, frac, corr = (lambda v: f"{v:.1f}"), (lambda v: f"{v:.2f}"), (lambda v: f"{v:.3f}")

    def row(name, backend):
        rs = [r for r in rows if (r["name"], r["backend"]) == (name, backend)]
        vs = [r["vs_first_seed"] for r in rs if "vs_first_seed" in r]
        truth = _span([r["truth_frac_within_45"] for r in rs], frac) if "truth_frac_within_45" in rs[0] else ""
        right = (
            [
                _span([v["mean_deg"] for v in vs], deg),
                _span([v["within_45"] for v in vs], frac),
                _span([v["grouping_r"] for v in vs], corr),
            ]
            if vs
            else ["", "", ""]
        )
        return [
            name,
            backend,
            _span([r["angle_diff_mean_deg"] for r in rs], deg),
            _span([r["angle_within_45_frac"] for r in rs], frac),
            _span([r["grouping_pearson_r"] for r in rs], corr),
            f"{sum(r['pass_fidelity'] for r in rs)} of {len(rs)}",
            truth,
            *right,
        ]

    return lines + markdown_table(
        [
            "input",
            "backend",
            "mean dAngle (deg)",
            "dAngle <= 45",
            "grouping r",
            "pass (vs rate)",
            "truth <= 45",
            "vs first seed: mean dAngle",
            "dAngle <= 45",
            "grouping r",
        ],
        [row(*k) for k in dict.fromkeys((r["name"], r["backend"]) for r in rows)],
    )


if __name__ == "__main__":
    main()
