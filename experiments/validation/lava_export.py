"""Lava runs the compact network's export in Loihi 2's fixed point (issue 60, items 1 and 3).

The compact network exported with ``snn-fg export --format lava`` for a
64 x 48 sensor (22 x 16 blocks), its input written by ``snn-fg events
--write-spikes`` and the export re-made for the input's rate as that
command advises (``--input-rate-hz``, ``--force``: the input stays). Then
``run.py`` in the export's own Python 3.10 environment
(:func:`snn_fg.export.lava_env.lava_python`): Lava's ``fixed_pt``, Lava's
``floating_pt`` on the same numbers, and the numpy reference of the same
fixed point; each decoded with ``snn-fg decode``. Against them the fast
engine on the exported (board) network, same input file, with the 8-bit
weights of ``--weight-bits 8`` and in float. 150 ms, counted from 75 ms.

Inputs: a disc of radius 11 (a 64 x 64 image, its event frame as regular
trains; the crop with the most event blocks) and the ``dvs.es`` window from
100 ms (85 ms) cropped at block x=22, y=12 (the 64 x 48 crop centred on the
window's mean event position, as ``experiments.validation.nir_consumer``
takes it). For the disc also the share of its rim's vectors (blocks within
1.5 blocks of the rim) that point inward. And ``run.py --count-only``:
processes, neurons and synapses as Lava holds them, beside our report.

Writes experiments/results/lava_export.{json,md,png}.
Usage: python -m experiments.validation.lava_export [--inputs disc dvs]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from experiments.common import DVS_FROM_MS, Run, dataset, describe, fail, markdown_table, save_figure, save_results
from snn_fg.events.cutter import WINDOW_MS

DURATION_MS, COUNT_FROM_MS = 150.0, 75.0
DISC_RADIUS = 11.0
DVS_CROP_BLOCKS = "22,12"


def _cli(*argv):
    from snn_fg.cli import main

    if main(list(argv)) != 0:
        fail(f"snn-fg {' '.join(argv)} failed")


def make_export(folder: Path, source: str, extra: list) -> dict:
    """The compact export for a 64 x 48 sensor with its input, re-made for the input's rate."""
    from snn_fg.export.pynn import read_input

    base = ["export", "--format", "lava", "--network", "compact", "--sensor-size", "64x48", "--out", str(folder)]
    _cli(*base)
    _cli(
        "events", source, "--write-spikes", str(folder / "input.npz"), "--export", str(folder), "--no-progress", *extra
    )
    rate = read_input(folder / "input.npz").rate_hz
    _cli(*base, "--input-rate-hz", f"{rate:.3g}", "--force")
    return {"rate_hz": round(rate, 2)}


def lava_env():
    """The Python of the exports' Lava environment (made once, cached), or end with one line."""
    from snn_fg.export.lava_env import LavaEnvMissing, lava_python

    try:
        return lava_python()
    except LavaEnvMissing as e:
        fail(f"no Lava environment: {e}")


def run_py(python, folder: Path, out: str, *args) -> float:
    t0 = time.perf_counter()
    done = subprocess.run(
        [
            str(python),
            "run.py",
            "--input",
            "input.npz",
            "--out",
            out,
            "--force",
            "--duration-ms",
            f"{DURATION_MS:g}",
            *args,
        ],
        cwd=folder,
        capture_output=True,
        text=True,
    )
    if done.returncode != 0:
        fail(f"run.py {' '.join(args)} in {folder}: {done.stderr.strip().splitlines()[-1:]}")
    return time.perf_counter() - t0


def decoded(folder: Path, counts: str):
    from snn_fg.export.loop import decode_counts, export_network

    return decode_counts(export_network(folder)[0], folder / counts)


def fast_maps(folder: Path, bits):
    from snn_fg.backends import RunSettings, get_backend
    from snn_fg.export.loop import export_network
    from snn_fg.export.pynn import read_input
    from snn_fg.models.spiking.decode import decode
    from snn_fg.results.maps import Maps

    net, _ = export_network(folder)
    settings = RunSettings(duration_ms=DURATION_MS, dt_ms=net.dt_ms, count_from_ms=COUNT_FROM_MS, instantiate="all")
    res = get_backend("fast", **({"weight_bits": bits} if bits else {})).simulate(
        net, read_input(folder / "input.npz"), settings
    )
    fx, fy, g, _ = decode(res)
    return Maps(fx, fy, g, {}), int(sum(v.sum() for v in res.counts.values()))


def rim_inward(maps, folder: Path) -> dict:
    """Share of the disc's rim vectors (blocks within 1.5 blocks of the rim) within 90 degrees of the
    direction to its centre (the scene's own ``inward``, x right and y up)."""
    from snn_fg.export.pynn import input_origin
    from snn_fg.frames.scenes import disc

    shape = disc(DISC_RADIUS).shapes[0]
    o = input_origin(folder / "input.npz")
    pool = o["pool"]
    h, w = maps.fg_x.shape
    rows, cols = np.mgrid[0:h, 0:w]
    r = o["crop_y_px"] + pool * rows + (pool - 1) / 2  # block centres in image pixels
    c = o["crop_x_px"] + pool * cols + (pool - 1) / 2
    tx, ty = shape.inward(r.astype(float), c.astype(float))
    has = np.hypot(maps.fg_x, maps.fg_y) > 0
    rim = has & (np.abs(np.hypot(r - shape.row, c - shape.col) - shape.radius) <= 1.5 * pool)
    inward = (maps.fg_x * tx + maps.fg_y * ty) > 0
    return {"inward": float(inward[rim].mean()) if rim.any() else float("nan"), "vectors": int(rim.sum())}


def counts_equal(folder: Path, a: str, b: str) -> dict:
    x, y = np.load(folder / a), np.load(folder / b)
    names = [k for k in y.files if k.startswith("count_") and k != "count_from_ms"]
    return {
        "cells_differing": int(sum((x[k] != y[k]).sum() for k in names)),
        "spikes": [int(sum(x[k].sum() for k in names)), int(sum(y[k].sum() for k in names))],
    }


def one_input(python, folder: Path, name: str) -> dict:
    from snn_fg.events import image_to_frame
    from snn_fg.frames.scenes import disc
    from snn_fg.scoring.metrics import agreement

    folder.parent.mkdir(parents=True, exist_ok=True)
    if name == "disc":
        pos, neg = image_to_frame(disc(DISC_RADIUS).image)
        np.savez(folder.parent / "disc.npz", pos=pos, neg=neg)
        r = make_export(folder, str(folder.parent / "disc.npz"), [])
        r["what"] = f"disc r{DISC_RADIUS:g} (64 x 64 image, its event frame at 200 Hz)"
    else:
        extra = ["--start-ms", f"{DVS_FROM_MS:g}", "--window-ms", f"{WINDOW_MS:g}", "--crop-at", DVS_CROP_BLOCKS]
        r = make_export(folder, str(dataset("events", "dvs.es")), extra)
        r["what"] = f"dvs.es 100..185 ms, crop at block {DVS_CROP_BLOCKS}"
    run = Run()
    r["seconds"] = {
        "lava_fixed": run_py(python, folder, "lava_fixed.npz"),
        "lava_float": run_py(python, folder, "lava_float.npz", "--arithmetic", "float"),
        "reference_fixed": run_py(python, folder, "reference_fixed.npz", "--simulator", "reference"),
    }
    maps = {k: decoded(folder, f"{k}.npz") for k in ("lava_fixed", "lava_float", "reference_fixed")}
    (maps["fast_8bit"], s8), (maps["fast_float"], sf) = fast_maps(folder, 8), fast_maps(folder, None)
    r["spikes_fast"] = {"8bit": s8, "float": sf}
    r["lava_vs_reference_counts"] = counts_equal(folder, "lava_fixed.npz", "reference_fixed.npz")
    pairs = (
        ("lava_fixed", "fast_8bit"),
        ("lava_float", "fast_8bit"),
        ("lava_fixed", "lava_float"),
        ("fast_8bit", "fast_float"),
    )
    r["agreement"] = {f"{a} vs {b}": agreement(maps[a], maps[b]) for a, b in pairs}
    if name == "disc":
        r["rim_inward"] = {k: rim_inward(m, folder) for k, m in maps.items()}
    subprocess.run([str(python), "run.py", "--count-only"], cwd=folder, capture_output=True, check=True)
    r["resources"] = json.loads((folder / "resources.json").read_text())
    r["limits"] = {k: float(np.load(folder / "reference_fixed.npz")[k]) for k in ("max_a_in", "u_wraps", "v_saturated")}
    r["run"] = run.record()
    r["_maps"] = maps
    return r


def figure(results: dict):
    from matplotlib.figure import Figure

    from snn_fg.results.figures import fg_rgb

    keys = ("lava_fixed", "fast_8bit", "fast_float")
    fig = Figure(figsize=(3.2 * len(keys), 2.6 * len(results)))
    for i, (name, r) in enumerate(results.items()):
        for j, k in enumerate(keys):
            ax = fig.add_subplot(len(results), len(keys), i * len(keys) + j + 1)
            m = r["_maps"][k]
            ax.imshow(fg_rgb(m.fg_x, m.fg_y))
            ax.set_title(f"{name}: {k.replace('_', ' ')}", fontsize=8)
            ax.set_axis_off()
    return fig


def markdown(results: dict, load: str) -> list[str]:
    rows, rims, res = [], [], []
    for name, r in results.items():
        for pair, a in r["agreement"].items():
            rows.append([name, pair, f"{a['grouping_r']:.3f}", f"{a['within_45']:.3f}", f"{a['mean_deg']:.1f}"])
        for k, v in r.get("rim_inward", {}).items():
            rims.append([k, f"{v['inward']:.3f}", v["vectors"]])
        lv, ours = r["resources"]["lava"], r["resources"]["snn_fg_report"]
        res.append(
            [
                name,
                lv["processes"]["total"],
                f"{lv['neurons']:,} / {ours['neurons']:,}",
                f"{lv['synapses']:,} / {ours['synapses']:,}",
                f"{lv['weight_exp'][0]}..{lv['weight_exp'][1]}",
                ours["loihi2_cores"],
            ]
        )
    lines = [
        "# Lava runs the compact network's export in Loihi 2's fixed point",
        "",
        "`snn-fg export --format lava --network compact --sensor-size 64x48` (22 x 16 blocks), re-made for "
        "each input's rate; `run.py` in Lava 0.10's CPU simulation (`Loihi2SimCfg(select_tag='fixed_pt')` and "
        "`'floating_pt'`) and the numpy reference, decoded with `snn-fg decode`; the fast engine on the "
        "exported network, same input file, 8-bit weights (`weight_bits=8`) and float. 150 ms, counted "
        f"from 75 ms. Load: {load}.",
        "",
    ]
    for name, r in results.items():
        c = r["lava_vs_reference_counts"]
        lines.append(
            f"- {name} ({r['what']}, {r['rate_hz']} Hz per active block): Lava fixed_pt {c['spikes'][0]:,} spikes, "
            f"the numpy reference {c['spikes'][1]:,}, cells that differ: {c['cells_differing']}; "
            f"Lava {r['seconds']['lava_fixed']:.0f} s (fixed) and {r['seconds']['lava_float']:.0f} s (float), "
            f"the reference {r['seconds']['reference_fixed']:.0f} s; the largest a_in {r['limits']['max_a_in']:.0f} "
            f"(the chip's accumulator: 32768), currents wrapped {r['limits']['u_wraps']:.0f}, voltages saturated "
            f"{r['limits']['v_saturated']:.0f} cell-steps. {describe(r['run'])}"
        )
    lines += ["", *markdown_table(["input", "maps", "grouping r", "within 45°", "mean angle °"], rows)]
    if rims:
        lines += ["", "The disc's rim (blocks within 1.5 blocks of it): share of vectors pointing inward.", ""]
        lines += markdown_table(["run", "inward", "vectors"], rims)
    lines += [
        "",
        "Resources: Lava's count (`run.py --count-only`: its processes, the neurons of its LIF processes, the "
        "synapses of its DelaySparse processes, whose 8-bit mantissa is not 0) beside snn-fg's report "
        "(`snn-fg export --format report --target loihi2`).",
        "",
        *markdown_table(
            [
                "input",
                "Lava processes",
                "neurons (Lava / report)",
                "synapses (Lava / report)",
                "weight_exp",
                "report: cores",
            ],
            res,
        ),
    ]
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--inputs", nargs="+", default=["disc", "dvs"], choices=["disc", "dvs"])
    args = ap.parse_args(argv)
    python = lava_env()
    run = Run()
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.inputs:
            results[name] = one_input(python, Path(tmp) / name / "model", name)
    rec = run.record()
    load = f"{rec['load_before'][0]:.1f} before, {rec['load_after'][0]:.1f} after"
    save_figure(figure(results), "lava_export")
    plain = {k: {kk: vv for kk, vv in r.items() if kk != "_maps"} for k, r in results.items()}
    save_results("lava_export", {"run": rec, "inputs": plain}, markdown(results, load))


if __name__ == "__main__":
    main()
