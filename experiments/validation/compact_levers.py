"""What each of the compact network's levers saves and costs, one after the other (issue 36, item 1).

From the default network, the levers of ``snn_fg.network.recipes.COMPACT_LEVERS``
are added one at a time (the last row is the compact network), plus
alternatives that were measured and not taken (``--alternatives``). For each:

* size at the iCub's 304 x 240 (``snn_fg.export.report.resource_report``):
  neurons, synapses, Loihi 2 cores and chips, SpiNNaker chips;
* ``dvs.es`` from 100 ms in 85 ms windows, one continuous run on the fast
  engine: synaptic events per window, the median time of a window beyond the
  first (``timings_s.window``), whether the grouping peak is on the plane and
  the share of outline vectors pointing inward (least and median over windows);
* discs of radius 16-64 px, both polarities (event frames): the least share
  of scored boundary pixels within 45 degrees, grouping peaks inside;
* a synthetic recording whose disc flips polarity every window
  (``snn_fg.frames.scenes.flipping_disc_recording``, radius 16 and 32, 6 windows):
  the least share within 45 degrees over its windows, the test of the window
  clock on input the project did not record.

    python -m experiments.validation.compact_levers [--alternatives] [--table]

Writes experiments/results/compact_levers.{json,md}. Timings are of one process
on a shared machine: the load is recorded, and the bench (``python -m
experiments.bench --sections stream``) is the measurement of speed.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys

import numpy as np

from experiments.common import DVS_FROM_MS, RESULTS, Run, dataset, describe, markdown_table, save_json, save_markdown
from snn_fg.events.cutter import WINDOW_MS

ICUB = (240, 304)
RADII = (16, 24, 32, 48, 64)


def ladder(alternatives: bool):
    """``(label, Recipe)`` rows: the default, each lever added in turn, alternatives."""
    from snn_fg.network.recipes import COMPACT_LEVERS, RECIPES, Lever

    rows = [("default", RECIPES["default"])]
    r = RECIPES["default"]
    for lever in COMPACT_LEVERS:
        r = lever.apply(r)
        rows.append((f"+ {lever.name}", r))
    if alternatives:

        def refractory(ms):
            return Lever(name="", does="", spiking=lambda s: s.replace(input=s.input.replace(input_refractory_ms=ms)))

        def pruned(**taps):
            return Lever(name="", does="", spiking=lambda s: s.replace(connectivity=s.connectivity.replace(**taps)))

        four = Lever(name="", does="", params=lambda p: p.replace(n_ori=4))
        rows.append(("compact with 4 orientations", four.apply(r)))
        rows.append(("compact without the input refractory period", refractory(0.0).apply(r)))
        rows.append(("compact with the input refractory period at 80 ms", refractory(80.0).apply(r)))
        # the two levers taken last, each undone on its own
        half_ms = Lever(name="", does="", spiking=lambda s: s.replace(time=s.time.replace(dt_ms=0.5)))
        rows.append(("compact at a 0.5 ms time step", half_ms.apply(r)))
        rows.append(("compact with kernels pruned at 5 %", pruned(prune_dog=0.05, prune_vm=0.05).apply(r)))
        rows.append(("compact with von Mises taps pruned at 40 %", pruned(prune_vm=0.4).apply(r)))
    return rows


def size(recipe) -> dict:
    from snn_fg.export.report import resource_report

    rep = resource_report(recipe.build(ICUB))
    t, tg = rep["totals"], rep["targets"]
    return {
        "neurons": t["neurons"],
        "synapses": t["synapses"],
        "loihi2_cores": tg["loihi2"]["cores"],
        "loihi2_chips": tg["loihi2"]["chips"],
        "spinnaker1_chips": tg["spinnaker1"]["chips"],
        "violations": {k: [v["constraint"] for v in x["violations"]] for k, x in tg.items()},
    }


def dvs(recipe) -> dict:
    from snn_fg.backends import get_backend
    from snn_fg.events import iter_windows
    from snn_fg.models.spiking.continuous import run_spiking_windows
    from snn_fg.scoring.metrics import grouping_peak
    from snn_fg.scoring.outline import filled_outline, outline_scores

    windows = list(iter_windows(dataset("events", "dvs.es"), window_ms=WINDOW_MS, start_ms=DVS_FROM_MS))
    maps = run_spiking_windows(
        windows, network=recipe.build(windows[0].pos.shape), backend=get_backend("fast"), progress=False
    )
    inward, found = [], []
    for w, m in zip(windows, maps):
        region = filled_outline(w.pos | w.neg)
        r, c = grouping_peak(m.grouping)
        inward.append(outline_scores(m.fg_x, m.fg_y, region)["inward"])
        found.append(bool(region[r, c]))
    p = maps[-1].params
    per = [m.params["timings_s"]["window"] for m in maps]
    return {
        "inward": inward,
        "plane_found": found,
        "window_s": per,
        "median_window_s": statistics.median(per[1:]),
        "synaptic_events_per_window": p["backend_stats"]["synaptic_events_total"] / len(maps),
    }


def discs(recipe) -> dict:
    from snn_fg.events import image_to_frame
    from snn_fg.frames.scenes import disc
    from snn_fg.models.spiking import run_spiking
    from snn_fg.scoring.metrics import grouping_peak_inside, truth_scores

    within, inside = [], 0
    for radius in RADII:
        for light in (True, False):
            scene = disc(radius=radius, light_on_dark=light)
            pos, neg = image_to_frame(scene.image)
            m = run_spiking(pos, neg, network=recipe.build(pos.shape), progress=False)
            within.append(truth_scores(m.fg_x, m.fg_y, scene)["frac_within_45"])
            inside += bool(grouping_peak_inside(m.grouping, scene))
    return {"within45": within, "peaks_inside": inside}


def flipping(recipe) -> dict:
    from snn_fg.events import iter_windows
    from snn_fg.frames.scenes import flipping_disc_recording
    from snn_fg.models.spiking.continuous import run_spiking_windows
    from snn_fg.scoring.metrics import truth_scores

    out = {}
    for radius in (16, 32):
        scenes, rec = flipping_disc_recording(radius, 6, 85.0)
        windows = list(iter_windows(rec.events, window_ms=85.0, sensor_size=rec.sensor_size[:2]))
        maps = run_spiking_windows(windows, network=recipe.build(windows[0].pos.shape), progress=False)
        out[str(radius)] = [truth_scores(m.fg_x, m.fg_y, s)["frac_within_45"] for m, s in zip(maps, scenes)]
    return out


def _row(row) -> list:
    s, d, c, f = row["size"], row["dvs"], row["discs"], row["flipping"]
    flips = [x for v in f.values() for x in v]
    blank = sum(x != x for x in flips)  # windows without a vector (nan)
    flip = f"{np.nanmin(flips):.2f}" if blank < len(flips) else "-"
    flip += f", {blank} of {len(flips)} windows without a vector" if blank else ""
    return [
        row["label"],
        f"{s['neurons']:,}",
        f"{s['synapses']:,}",
        f"{s['loihi2_cores']} ({s['loihi2_chips']})",
        s["spinnaker1_chips"],
        f"{d['synaptic_events_per_window']:.3g}",
        f"{d['median_window_s']:.3f}",
        f"{sum(d['plane_found'])} of {len(d['plane_found'])}",
        f"{min(d['inward']):.2f} / {np.median(d['inward']):.2f}",
        f"{min(c['within45']):.2f}",
        flip,
    ]


def table(record) -> list[str]:
    # (a record written before the run records carried its date, time and load at the top level)
    run = record.get("run") or {
        "command": "python -m experiments.validation.compact_levers",
        "commit": "unknown",
        "date": record["date"],
        "seconds": record["runtime_s"],
        "load_before": record["load_before"],
        "load_after": record["load_after"],
    }
    return [
        f"# The compact network's levers, one after the other ({run['date']})",
        "",
        f"{describe(run)} Sizes at 304 x 240; dvs.es from 100 ms, 85 ms windows, one continuous run (fast "
        "engine); discs r 16-64 both polarities; the flipping disc: r 16 and 32, 6 windows, polarity flipping "
        "every window. A missing vector scores nan.",
        "",
    ] + markdown_table(
        [
            "network",
            "neurons",
            "synapses",
            "Loihi 2 cores (chips)",
            "SpiNNaker chips",
            "synaptic events per dvs.es window",
            "s per window",
            "plane found",
            "inward: least / median",
            "discs: least within 45 deg",
            "flipping disc: least within 45 deg",
        ],
        map(_row, record["rows"]),
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--alternatives", action="store_true", help="also the alternatives measured and not taken")
    ap.add_argument("--name", default="compact_levers")
    ap.add_argument("--table", action="store_true", help="rewrite the markdown from the stored JSON; measure nothing")
    a = ap.parse_args()
    if a.table:
        save_markdown(a.name, table(json.loads((RESULTS / f"{a.name}.json").read_text())))
        return
    dataset("events", "dvs.es")
    run = Run()
    rows = []
    for label, recipe in ladder(a.alternatives):
        print(f"[{label}]", file=sys.stderr, flush=True)
        rows.append(
            {
                "label": label,
                "params": recipe.params.to_dict(),
                "spiking": recipe.spiking.to_dict(),
                "size": size(recipe),
                "dvs": dvs(recipe),
                "discs": discs(recipe),
                "flipping": flipping(recipe),
            }
        )
    record = {"rows": rows, "run": run.record()}
    save_json(a.name, record)
    save_markdown(a.name, table(record))
    print("\n".join(table(record)))


if __name__ == "__main__":
    main()
