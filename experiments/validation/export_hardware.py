"""Hardware figures of the export: resource reports, the largest configuration
that fits one SpiNN-5 board and one Loihi 2 chip (and its fidelity), and
weight quantisation at 8 and 16 bits.

* ``reports``: resource reports for 304 x 240 (iCub ATIS) and 321 x 481 (BSDS).
* ``fit``: sensor crops of the iCub sensor (304 x 240 scaled down), 8 then 4
  orientations, as many levels as the crop allows; the first (largest) whose
  report needs <= 48 SpiNNaker chips (one SpiNN-5 board) and <= 1 Loihi 2
  chip. Its fidelity: maps of the dvs.es window (100-185 ms) cropped to that
  size, against the full network's maps of the whole window inside the crop
  (what a board of that size loses) and against the default network run on
  the same crop (what the fewer levels and orientations alone lose).
* ``fidelity``: only the fidelity of the configurations ``fit`` stored.
* ``quant``: Brian2 runs with every projection's weights rounded to 8 and 16
  bits (one scale per projection, snn_fg.lowering.quantise) against float, on
  discs (radius 16-48, both polarities), the occlusion scene, the demo scene
  and (``--bsds``) the six BSDS reference frames (dataset ``bsds-edfg``).

Writes experiments/results/export_hardware.json and .md.
Usage: python -m experiments.validation.export_hardware [reports] [fit] [fidelity] [quant] [--bsds]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from experiments.common import DVS_FROM_MS, RESULTS, Run, dataset, describe, markdown_table, save_json, save_markdown
from snn_fg.backends import RunSettings
from snn_fg.backends.brian2 import Brian2Backend
from snn_fg.events.cutter import WINDOW_MS
from snn_fg.export.report import report_table, resource_report
from snn_fg.frames.pyramid import max_levels
from snn_fg.lowering.quantise import quantise_unrolled
from snn_fg.models.spiking.decode import decode
from snn_fg.network import SpikingParams, build_network
from snn_fg.params import ModelParams
from snn_fg.scoring.metrics import compare_frame

#: the quantisation table's row of the float network on input trains of seed 1
SEED_1 = "float, input seed 1"
#: what one board holds, per target: the key of a ``fit`` row's chip count and the most chips
ONE_BOARD = {"spinn5": ("spinnaker_chips", 48), "loihi2": ("loihi2_chips", 1)}
#: the parts, in the page's order, and what each stores in the results
PARTS = {"reports": "report_304x240", "fit": "fit", "fidelity": "fit", "quant": "quantisation"}
CROPS = ((160, 120), (128, 96), (112, 84), (96, 72), (80, 60), (64, 48), (56, 42), (48, 36), (40, 30))


class QuantisedBrian2(Brian2Backend):
    """Brian2 on the unrolled network with quantised weights."""

    def __init__(self, bits, **kw):
        super().__init__(**kw)
        self.bits = bits

    def _run(self, un, inputs, settings, timings):
        quantise_unrolled(un, self.bits)
        return super()._run(un, inputs, settings, timings)


def reports(out):
    for w, h in ((304, 240), (481, 321)):
        t0 = time.perf_counter()
        rep = resource_report(build_network(ModelParams(), (h, w), SpikingParams()))
        print(report_table(rep), f"\n({time.perf_counter() - t0:.0f} s)", flush=True)
        out[f"report_{w}x{h}"] = {k: rep[k] for k in ("totals", "targets", "frame_shape")}


def _config(w, h, n_ori, levels):
    rep = resource_report(build_network(ModelParams(levels=levels, n_ori=n_ori), (h, w), SpikingParams()))
    t = rep["totals"]
    row = {
        "sensor": [w, h],
        "levels": levels,
        "n_ori": n_ori,
        "neurons": t["neurons"],
        "synapses": t["synapses"],
        "spinnaker_chips": rep["targets"]["spinnaker1"]["chips"],
        "loihi2_chips": rep["targets"]["loihi2"]["chips"],
        "loihi2_cores": rep["targets"]["loihi2"]["cores"],
    }
    row.update({t: row[key] <= most for t, (key, most) in ONE_BOARD.items()})
    print(json.dumps(row), flush=True)
    return row


def fit(out):
    """Per target, crops from small to large; for each crop and orientation
    count the most levels that fit (every population takes at least one
    core, so fewer levels can fit where more do not); the largest fitting
    configuration (by neurons) wins; stop at the first crop where none fits."""
    found, tried = {}, []
    for target in ("spinn5", "loihi2"):
        for w, h in sorted(CROPS):
            fits_here = []
            for n_ori in (8, 4):
                for levels in range(min(10, max_levels((h, w))), 3, -1):
                    row = _config(w, h, n_ori, levels)
                    tried.append(row)
                    if row[target]:
                        fits_here.append(row)
                        break
            if not fits_here:
                break
            best = max(fits_here, key=lambda r: r["neurons"])
            if target not in found or best["neurons"] > found[target]["neurons"]:
                found[target] = best
    out["fit"] = {"tried": tried, "largest": found}
    out["fit"]["fidelity"] = {t: _crop_fidelity(c) for t, c in found.items()}


def _dvs_window():
    from snn_fg.events import iter_windows

    return next(iter_windows(dataset("events", "dvs.es"), window_ms=WINDOW_MS, start_ms=DVS_FROM_MS))


def _crop_fidelity(cfg):
    """The fitting configuration on a crop of the dvs.es window against the
    full default network on the whole window, compared inside the crop."""
    from snn_fg.models.spiking import run_spiking

    win = _dvs_window()
    H, W = win.pos.shape
    w, h = cfg["sensor"]
    ys, xs = np.nonzero(win.pos | win.neg)
    r0 = int(np.clip(ys.mean() - h / 2, 0, H - h))
    c0 = int(np.clip(xs.mean() - w / 2, 0, W - w))
    ev = win.events
    keep = (ev["x"] >= c0) & (ev["x"] < c0 + w) & (ev["y"] >= r0) & (ev["y"] < r0 + h)
    crop = ev[keep].copy()
    crop["x"] -= c0
    crop["y"] -= r0
    full = run_spiking(events=ev, sensor_size=(W, H, 2), progress=False)
    small = run_spiking(
        events=crop, sensor_size=(w, h, 2), progress=False, params=ModelParams(levels=cfg["levels"], n_ori=cfg["n_ori"])
    )
    same_crop = run_spiking(events=crop, sensor_size=(w, h, 2), progress=False)
    sl = (slice(r0, r0 + h), slice(c0, c0 + w))
    keys = ("grouping_pearson_r", "angle_within_45_frac", "angle_diff_mean_deg", "pixels_compared")
    c = compare_frame(small.fg_x, small.fg_y, small.grouping, full.fg_x[sl], full.fg_y[sl], full.grouping[sl])
    d = compare_frame(small.fg_x, small.fg_y, small.grouping, same_crop.fg_x, same_crop.fg_y, same_crop.grouping)
    return {"crop_origin": [c0, r0], **{k: c[k] for k in keys}, "against_default_on_crop": {k: d[k] for k in keys}}


def fidelity(out):
    """The fidelity of the configurations a previous ``fit`` stored."""
    old = json.loads((RESULTS / "export_hardware.json").read_text())["fit"]
    out["fit"] = {**old, "fidelity": {t: _crop_fidelity(c) for t, c in old["largest"].items()}}


def _scenes(bsds: bool):
    from snn_fg.events import image_to_frame
    from snn_fg.frames import scenes

    for r in (16, 32, 48):
        for light in (True, False):
            yield f"disc r{r} {'light' if light else 'dark'}", image_to_frame(scenes.disc(r, light_on_dark=light).image)
    yield "occlusion", image_to_frame(scenes.occlusion().image)
    yield "demo", image_to_frame(scenes.demo().image)
    if bsds:
        for f in sorted(dataset("bsds-edfg").glob("*.npz")):
            d = np.load(f)
            yield f"bsds {f.stem}", (d["pos"], d["neg"])


def quant(out, bsds: bool):
    from snn_fg.lowering.input_spikes import frame_spikes

    rows = []
    for name, (pos, neg) in _scenes(bsds):
        net = build_network(ModelParams(), pos.shape, SpikingParams())
        inp = frame_spikes(pos, neg, 200.0, 0.5, 400.0)
        net = net.calibrated(inp.rate_hz)
        s = RunSettings(duration_ms=400.0, dt_ms=net.dt_ms, count_from_ms=200.0, record_spikes=False)
        maps = {}
        for bits in (None, 16, 8):
            backend = Brian2Backend() if bits is None else QuantisedBrian2(bits)
            maps[bits] = decode(backend.simulate(net, inp, s))[:3]
        # the float network on input trains of another phase: how far the maps
        # move with no quantisation at all, the scale the rows above are read on
        other = frame_spikes(pos, neg, 200.0, 0.5, 400.0, seed=1)
        maps[SEED_1] = decode(Brian2Backend().simulate(net, other, s))[:3]
        for bits in (16, 8, SEED_1):
            c = compare_frame(*maps[bits], *maps[None])
            rows.append(
                {
                    "input": name,
                    "bits": bits,
                    **{
                        k: c[k]
                        for k in (
                            "grouping_pearson_r",
                            "angle_within_45_frac",
                            "angle_diff_mean_deg",
                            "pixels_compared",
                        )
                    },
                }
            )
            print(json.dumps(rows[-1]), flush=True)
    out["quantisation"] = rows
    out["quantisation_bsds"] = bool(bsds)


def write(out, run, part):
    """Merge ``out`` into the stored results (each part keeps what it last measured, and the
    record of the run that measured it) and rewrite the page."""
    old = RESULTS / "export_hardware.json"
    merged = json.loads(old.read_text()) if old.exists() else {}
    merged.update(out)
    merged["runs"] = {**merged.get("runs", {}), part: run.record()}
    if part == "fit":
        merged["runs"].pop("fidelity", None)  # fit measures the fidelity again
    merged.pop("run", None)  # the latest part's run alone, before each part kept its own
    save_json("export_hardware", merged)
    save_markdown("export_hardware", _markdown(merged))


def _target_row(name, x) -> list:
    v = "; ".join(f"{a['constraint']} {a['value']} > {a['limit']}" for a in x["violations"][:3])
    more = len(x["violations"]) - 3
    return [name, f"{x['cores']:,}", f"{x['chips']:,}", v + (f" (+{more} more)" if more > 0 else "")]


def _fit_rows(fit) -> list:
    nan, rows = float("nan"), []
    for t, c in fit["largest"].items():
        f = fit["fidelity"].get(t, {})
        for label, x in (("(a) whole window", f), ("(b) same crop", f.get("against_default_on_crop", {}))):
            rows.append(
                [
                    t,
                    f"{c['sensor'][0]}x{c['sensor'][1]}",
                    c["levels"],
                    c["n_ori"],
                    f"{c['neurons']:,}",
                    f"{c['synapses']:,}",
                    label,
                    f"{x.get('grouping_pearson_r', nan):.3f}",
                    f"{x.get('angle_within_45_frac', nan):.3f}",
                    f"{x.get('angle_diff_mean_deg', nan):.1f}",
                    f"{x.get('pixels_compared', 0):,}",
                ]
            )
    return rows


def _no_fit_lines(fit) -> list[str]:
    """A line for each target none of the tried configurations fits, with the one nearest to fitting."""
    lines = []
    for target, (key, most) in ONE_BOARD.items():
        if target not in fit["largest"] and fit["tried"]:
            c = min(fit["tried"], key=lambda r: r[key])
            lines.append(
                f"{target}: none of the {len(fit['tried'])} configurations tried fits ({most} chips at most); "
                f"the fewest chips, {c[key]}, are {c['sensor'][0]}x{c['sensor'][1]}'s with {c['levels']} levels "
                f"and {c['n_ori']} orientations."
            )
    return lines


def _runs_lines(merged) -> list[str]:
    """Which run measured each part on the page (2 shared cores)."""
    runs = merged.get("runs", {})
    lines = [
        f"- `{part}`: " + (describe(runs[part]) if part in runs else "run before each part kept its own record.")
        for part, key in PARTS.items()
        if part in runs or (part != "fidelity" and key in merged)
    ]
    return ["Each part as its last run left it (2 shared cores):", "", *lines, ""]


def _markdown(merged) -> list[str]:
    lines = ["# Export: hardware resources, fitting configurations, quantisation", "", *_runs_lines(merged)]
    for key in ("report_304x240", "report_481x321"):
        if key in merged:
            t = merged[key]["totals"]
            lines += [
                f"## {key}",
                "",
                f"neurons {t['neurons']:,}, synapses {t['synapses']:,}, max fan-in "
                f"{t['max_fan_in']:,}, max fan-out {t['max_fan_out']:,}, delays (steps) {t['delay_steps']}",
                "",
            ]
            lines += markdown_table(
                ["target", "cores", "chips", "violations"],
                [_target_row(name, x) for name, x in merged[key]["targets"].items()],
            )
            lines.append("")
    if "fit" in merged:
        lines += [
            "## Largest configuration that fits",
            "",
            "Its maps on the crop of the dvs.es window against "
            "(a) the default network's maps of the whole window inside the crop, (b) the default network run "
            "on the same crop (only the fewer levels and orientations differ).",
            "",
        ]
        lines += markdown_table(
            [
                "target",
                "sensor",
                "levels",
                "n_ori",
                "neurons",
                "synapses",
                "against",
                "grouping r",
                "within 45°",
                "mean angle °",
                "pixels",
            ],
            _fit_rows(merged["fit"]),
        )
        lines += ["", *_no_fit_lines(merged["fit"])]
        lines.append("")
    if "quantisation" in merged:
        scope = (
            "synthetic scenes and the six BSDS frames"
            if merged.get("quantisation_bsds")
            else "synthetic scenes only; the BSDS frames need `quant --bsds`"
        )
        lines += [
            "## Weight quantisation (Brian2, against float)",
            "",
            f"Inputs: {scope}.",
            f"Each input's row `{SEED_1}` is no quantisation at all: the float network on input trains of "
            "another random phase (seed 1 against 0). It is the network's own seed-to-seed spread, the scale "
            "on which the quantised rows are to be read."
            if any(r["bits"] == SEED_1 for r in merged["quantisation"])
            else "Rows without the seed-to-seed spread: re-run `quant` to add it.",
            "",
        ]
        lines += markdown_table(
            ["input", "bits", "grouping r", "within 45°", "mean angle °"],
            [
                [
                    r["input"],
                    r["bits"],
                    f"{r['grouping_pearson_r']:.3f}",
                    f"{r['angle_within_45_frac']:.3f}",
                    f"{r['angle_diff_mean_deg']:.1f}",
                ]
                for r in merged["quantisation"]
            ],
        )
    return lines


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("parts", nargs="*", choices=PARTS, default=["reports", "fit", "quant"])
    ap.add_argument("--bsds", action="store_true")
    args = ap.parse_args()
    # the commit is taken once, before the first part rewrites the page's own tracked results
    commit = Run().commit
    for part in args.parts:
        run, out = Run(), {}
        run.commit = commit
        if part == "quant":
            quant(out, args.bsds)
        else:
            {"reports": reports, "fit": fit, "fidelity": fidelity}[part](out)
        write(out, run, part)


if __name__ == "__main__":
    main()
