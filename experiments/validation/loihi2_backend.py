"""The Loihi 2 backend against Lava's fixed point, and the whole compact network in it (issue 60, item 2).

1. **Exports**: the compact network's Lava export for a 64 x 48 sensor with
   the inputs of ``experiments.validation.lava_export`` (a disc of radius
   11, and the ``dvs.es`` window from 100 ms cropped at block 22, 12), each
   re-made for its input's rate. The backend (``--backend loihi2``) on the
   export's network and input file against the export's numpy reference
   (``run.py --simulator reference``, which gives Lava 0.10's ``fixed_pt``
   count in every cell: ``lava_export``), 150 ms counted from 75 ms: cells
   whose counts differ, and the limits met. With ``--lava`` also against
   Lava's ``fixed_pt`` itself (``run.py`` in the export's Python 3.10
   environment).
2. **The whole network**: the compact network for the 304 x 240 sensor, as
   ``snn-fg run --network compact`` runs it, on the fast engine (float, and
   with 8-bit weights) and on the backend, one after the other in this process: the discs of
   ``experiments.validation.compact_accuracy`` (radius 16-64, both
   polarities: share within 45 degrees of the analytic direction) and
   ``dvs.es`` from 100 ms in 85 ms windows, one continuous run (per window
   the share of the plane's outline vectors pointing inward), with each
   run's time: the build (once per network) and the simulation per window,
   wall and CPU.

Writes experiments/results/loihi2_backend.{json,md,png}.
Usage: python -m experiments.validation.loihi2_backend [--lava] [--skip-discs]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from experiments.common import DVS_FROM_MS, Run, dataset, describe, markdown_table, save_figure, save_results
from experiments.validation import compact_accuracy, lava_export
from snn_fg.events.cutter import WINDOW_MS

#: label -> (backend, weight bits): the fast engine in float and with the 8-bit weights of ``--weight-bits 8``
BACKENDS = {"fast": ("fast", None), "fast 8-bit": ("fast", 8), "loihi2": ("loihi2", None)}


def export_inputs(folder: Path, name: str) -> dict:
    """The export and input file of ``lava_export`` for input ``name``."""
    from snn_fg.events import image_to_frame
    from snn_fg.frames.scenes import disc

    folder.parent.mkdir(parents=True, exist_ok=True)
    if name == "disc":
        pos, neg = image_to_frame(disc(lava_export.DISC_RADIUS).image)
        np.savez(folder.parent / "disc.npz", pos=pos, neg=neg)
        return lava_export.make_export(folder, str(folder.parent / "disc.npz"), [])
    extra = [
        "--start-ms",
        f"{DVS_FROM_MS:g}",
        "--window-ms",
        f"{WINDOW_MS:g}",
        "--crop-at",
        lava_export.DVS_CROP_BLOCKS,
    ]
    return lava_export.make_export(folder, str(dataset("events", "dvs.es")), extra)


def against_reference(folder: Path, python) -> dict:
    """The backend's counts on an export against the reference's (and Lava's, with ``python``)."""
    import json

    from snn_fg.backends import RunSettings, get_backend
    from snn_fg.export.loop import export_network
    from snn_fg.export.pynn import read_input
    from snn_fg.lava import reference, synapses
    from snn_fg.pynn.inputs import input_steps

    meta = json.loads((folder / "network.json").read_text())
    conns = synapses.connections(meta, np.load(folder / "tables.npz"))
    dt = meta["dt_ms"]
    n_steps, count_from = int(round(lava_export.DURATION_MS / dt)), int(round(lava_export.COUNT_FROM_MS / dt))
    n_src = sum(p["size"] for p in meta["populations"] if p["neuron"] is None)
    steps, _ = input_steps(folder / "input.npz", n_steps, n_src, meta["frame_shape"])
    t = time.perf_counter()
    ref, limits = reference.simulate(meta, conns, steps, n_steps, count_from)
    ref_s = time.perf_counter() - t
    net, _ = export_network(folder)
    settings = RunSettings(
        duration_ms=lava_export.DURATION_MS, dt_ms=dt, count_from_ms=lava_export.COUNT_FROM_MS, instantiate="all"
    )
    res = get_backend("loihi2").simulate(net, read_input(folder / "input.npz"), settings)
    out = {
        "spikes": {
            "reference": int(sum(c.sum() for c in ref.values())),
            "loihi2": int(sum(c.sum() for c in res.counts.values())),
        },
        "cells": int(sum(c.size for c in ref.values())),
        "cells_differing_reference": int(sum((res.counts[k] != ref[k]).sum() for k in ref)),
        "limits": {
            "reference": [limits.max_a_in, limits.u_wraps, limits.v_saturated],
            "loihi2": [res.stats["max_a_in"], res.stats["u_wraps"], res.stats["v_saturated"]],
        },
        "seconds": {"reference": ref_s, "loihi2_build": res.timings_s["build"], "loihi2_run": res.timings_s["run"]},
    }
    if python is not None:
        lava_export.run_py(python, folder, "lava_fixed.npz")
        lava = np.load(folder / "lava_fixed.npz")
        out["cells_differing_lava"] = int(sum((res.counts[k] != lava[f"count_{k}"]).sum() for k in ref))
    return out


def timed(fn, *args):
    """``(fn(*args), wall seconds, CPU seconds)``."""
    t, cpu = time.perf_counter(), time.process_time()
    value = fn(*args)
    return value, time.perf_counter() - t, time.process_time() - cpu


def whole_network(skip_discs: bool) -> dict:
    out = {}
    for label, (backend, bits) in BACKENDS.items():
        r = {}
        if not skip_discs:
            r["discs"], r["discs_s"], r["discs_cpu_s"] = timed(compact_accuracy.discs, "compact", bits, backend)
        (rows, shown), wall, cpu = timed(compact_accuracy.dvs, "compact", bits, backend)
        r["dvs"], r["dvs_s"], r["dvs_cpu_s"] = rows, wall, cpu
        r["dvs_timings"] = dict(shown[0][1].params["timings_s"])
        r["dvs_stats"] = dict(shown[0][1].params.get("backend_stats", {}))
        r["_shown"] = shown[0]
        out[label] = r
        print(f"{label}: dvs.es {len(rows)} windows in {wall:.1f} s ({cpu:.1f} s CPU)", flush=True)
    return out


def figure(whole: dict):
    from matplotlib.figure import Figure

    from snn_fg.results.figures import fg_rgb

    fig = Figure(figsize=(4.2 * len(BACKENDS), 3.4))
    for j, backend in enumerate(BACKENDS):
        w, m = whole[backend]["_shown"]
        ax = fig.add_subplot(1, len(BACKENDS), j + 1)
        ax.imshow(fg_rgb(m.fg_x, m.fg_y))
        ax.set_title(f"dvs.es window 9 ({backend})", fontsize=9)
        ax.set_axis_off()
    return fig


def markdown(exports: dict, whole: dict, rec: dict) -> list[str]:
    lines = [
        "# The Loihi 2 backend: Lava's fixed point at compiled speed",
        "",
        f"`python -m experiments.validation.loihi2_backend`. {describe(rec)}",
        "",
        "## On the 64 x 48 exports, against the reference (= Lava fixed_pt in every cell)",
        "",
    ]
    rows = []
    for name, r in exports.items():
        rows.append(
            [
                name,
                f"{r['spikes']['reference']:,} / {r['spikes']['loihi2']:,}",
                f"{r['cells_differing_reference']} of {r['cells']:,}",
                r.get("cells_differing_lava", "not run"),
                "equal" if r["limits"]["reference"] == r["limits"]["loihi2"] else f"{r['limits']}",
                f"{r['seconds']['reference']:.1f} / {r['seconds']['loihi2_run']:.2f}",
            ]
        )
    head = [
        "input",
        "spikes (reference / loihi2)",
        "cells differing",
        "vs Lava fixed_pt",
        "limits met",
        "s (reference / loihi2 run)",
    ]
    lines += markdown_table(head, rows)
    lines += ["", "## The whole compact network (304 x 240 sensor): the fast engine (float, 8-bit) and loihi2", ""]
    rows = []
    for backend, r in whole.items():
        dvs = r["dvs"]
        t = r["dvs_timings"]
        row = [
            backend,
            f"{min(x['inward'] for x in dvs):.3f}",
            f"{np.mean([x['inward'] for x in dvs]):.3f}",
            f"{sum(x['plane_found'] for x in dvs)} of {len(dvs)}",
            f"{t.get('build', 0):.1f}",
            f"{t['run'] / len(dvs):.2f} ({t.get('run_cpu', 0) / len(dvs):.2f} CPU)",
        ]
        if "discs" in r:
            d = r["discs"]
            row += [
                f"{min(x['within45'] for x in d):.3f}",
                f"{np.mean([x['within45'] for x in d]):.4f}",
                f"{max(x['mean_abs_deg'] for x in d):.1f}",
            ]
        rows.append(row)
    head = [
        "backend",
        "dvs.es: least share inward",
        "mean share inward",
        "plane found",
        "build s",
        "s per window (run)",
    ]
    if any("discs" in r for r in whole.values()):
        head += ["discs: least within 45°", "mean within 45°", "largest mean error °"]
    lines += markdown_table(head, rows)
    lines += ["", "Per dvs.es window (share of the outline's vectors inward):", ""]
    first = next(iter(whole.values()))["dvs"]
    n = len(first)
    lines += markdown_table(
        ["window (ms)", *BACKENDS],
        [
            [
                f"{first[k]['t_start_ms']:.0f}",
                *(f"{whole[b]['dvs'][k]['inward']:.3f}" for b in BACKENDS),
            ]
            for k in range(n)
        ],
    )
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lava", action="store_true", help="also against Lava's fixed_pt (the export's environment)")
    ap.add_argument("--skip-discs", action="store_true")
    args = ap.parse_args(argv)
    python = lava_export.lava_env() if args.lava else None
    run = Run()
    exports = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in ("disc", "dvs"):
            folder = Path(tmp) / name / "model"
            info = export_inputs(folder, name)
            exports[name] = {**info, **against_reference(folder, python)}
            print(f"{name}: {exports[name]['cells_differing_reference']} cells differ from the reference", flush=True)
    whole = whole_network(args.skip_discs)
    rec = run.record()
    save_figure(figure(whole), "loihi2_backend")
    plain = {b: {k: v for k, v in r.items() if k != "_shown"} for b, r in whole.items()}
    save_results("loihi2_backend", {"run": rec, "exports": exports, "whole": plain}, markdown(exports, whole, rec))


if __name__ == "__main__":
    main()
