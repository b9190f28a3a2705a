"""Measured effect of the spiking network's deviations from the rate model.

Two kinds of deviation, measured separately:

1. Structural (pruned kernels, stride-2 grouping/feedback lattices, linear
   instead of bicubic pooling, binarised coarse levels above ``support_min``,
   the ``edges&drive`` site rule, top-down pooling). Measured with the *rate
   twin* (``snn_fg.models.spiking.twin``): the unrolled network run as the rate
   model's own iteration, compared with the rate reference. One knob at a
   time is set back to the rate model's value on 128 x 160 crops (the exact
   structure does not fit in memory at full size), and the default structure
   is measured on the full frames.
2. Dynamical (spiking LIF cells, gated additive feedback, continuous time
   instead of 10 iterations, excess cells for the first-iteration rule, rate
   decoding). Measured as spiking vs twin on the same frames, and by
   switching mechanisms off: the rival inhibition through the rivals' own
   cells (``rival_inhibition="direct"``) and the feedback (``feedback=False``).

Writes experiments/results/spiking_deviations.json and .md.

    python -m experiments.validation.spiking_deviations
"""

from __future__ import annotations

import time

import numpy as np

from experiments.common import Run, dataset, describe, markdown_table, save_json, save_markdown
from snn_fg.lowering.unroll import unroll
from snn_fg.models.rate.edfg import run_edfg
from snn_fg.models.spiking import run_spiking_result
from snn_fg.models.spiking.twin import run_twin
from snn_fg.network import Connectivity, Input, SpikingParams, build_network
from snn_fg.params import ModelParams
from snn_fg.scoring.metrics import compare_frame

CROP = (slice(60, 188), slice(100, 260))
KNOBS = {
    "defaults": SpikingParams(),
    "no pruning": SpikingParams(connectivity=Connectivity(prune_dog=0.0, prune_vm=0.0)),
    "grouping stride 1": SpikingParams(connectivity=Connectivity(grouping_stride=1)),
    "bicubic pooling + feedback": SpikingParams(
        connectivity=Connectivity(pool_interpolation="cubic", feedback_interpolation="cubic")
    ),
    "support_min 0.1": SpikingParams(input=Input(support_min=0.1)),
    "no drive hint (drive_min 0)": SpikingParams(input=Input(drive_min=0.0)),
}


def _cmp(fx, fy, g, ref):
    c = compare_frame(fx, fy, g, ref["fg_x"], ref["fg_y"], ref["grouping"])
    return {
        "grouping_pearson_r": c["grouping_pearson_r"],
        "angle_diff_median_deg": c["angle_diff_median_deg"],
        "angle_diff_mean_deg": c["angle_diff_mean_deg"],
    }


def twin_row(pos, neg, ref, knobs):
    net = build_network(ModelParams(), pos.shape, knobs)
    t0 = time.perf_counter()
    un = unroll(net, {"input_on_1": pos > 0, "input_off_1": neg > 0})
    fx, fy, g, _ = run_twin(un)
    return {
        **_cmp(fx, fy, g, ref),
        "synapses": int(sum(c.n for c in un.connections)),
        "cells": int(sum(un.n_cells(p.name) for p in net.populations if p.neuron is not None)),
        "seconds": time.perf_counter() - t0,
    }


def full_row(pos, neg, ref) -> dict:
    """The default network on a whole frame: its twin (structure) and its spiking run (structure +
    dynamics) against the reference ``ref``, and the spiking maps against the twin's."""
    tw = twin_row(pos, neg, ref, SpikingParams())
    res = run_spiking_result(pos, neg, progress=False)
    m = res.maps
    # the run freed its unrolled synapses (they would double its peak memory): unroll again for the twin
    tfx, tfy, tg, _ = run_twin(unroll(res.network, {"input_on_1": res.inputs.on, "input_off_1": res.inputs.off}))
    return {
        "twin_vs_ref": tw,
        "spiking_vs_ref": _cmp(m.fg_x, m.fg_y, m.grouping, ref),
        "spiking_vs_twin": _cmp(m.fg_x, m.fg_y, m.grouping, {"fg_x": tfx, "fg_y": tfy, "grouping": tg}),
    }


def main():
    frames = sorted(dataset("bsds-edfg").glob("*.npz"))
    run = Run()
    record = {"crops": [], "full": [], "dynamics": []}
    # 1a. one knob at a time, crops
    for path in frames[:3]:
        d = np.load(path)
        pos, neg = d["pos"][CROP], d["neg"][CROP]
        r = run_edfg(pos, neg)
        ref = {"fg_x": r.fg_x, "fg_y": r.fg_y, "grouping": r.grouping}
        for label, knobs in KNOBS.items():
            row = {"frame": path.stem, "variant": label, **twin_row(pos, neg, ref, knobs)}
            record["crops"].append(row)
            print(
                f"crop {path.stem:7s} {label:28s} r {row['grouping_pearson_r']:.3f} "
                f"mean dAngle {row['angle_diff_mean_deg']:5.1f}  {row['synapses']:,} synapses",
                flush=True,
            )
    # 1b + 2. full frames: twin (structure) and spiking (structure + dynamics)
    for path in frames:
        d = np.load(path)
        row = {"frame": path.stem, **full_row(d["pos"], d["neg"], {k: d[k] for k in ("fg_x", "fg_y", "grouping")})}
        record["full"].append(row)
        print(
            f"full {path.stem:7s} twin r {row['twin_vs_ref']['grouping_pearson_r']:.3f}  "
            f"spiking r {row['spiking_vs_ref']['grouping_pearson_r']:.3f}  "
            f"spiking vs twin r {row['spiking_vs_twin']['grouping_pearson_r']:.3f}",
            flush=True,
        )
    # 2b. mechanisms switched off one at a time
    for path in frames[:2]:
        d = np.load(path)
        ref = {k: d[k] for k in ("fg_x", "fg_y", "grouping")}
        for label, knobs, feedback in (
            ("default (excess cells, feedback on)", SpikingParams(), True),
            (
                "rival inhibition direct (no excess cells)",
                SpikingParams(connectivity=Connectivity(rival_inhibition="direct")),
                True,
            ),
            ("feedback off", SpikingParams(), False),
        ):
            res = run_spiking_result(d["pos"], d["neg"], progress=False, spiking=knobs, feedback=feedback)
            m = res.maps
            row = {
                "frame": path.stem,
                "variant": label,
                **_cmp(m.fg_x, m.fg_y, m.grouping, ref),
                "group_mean_rate_hz": float(
                    np.mean(
                        [s["mean_rate_hz"] for s in m.params["populations"].values() if s["role"].startswith("group")]
                    )
                ),
            }
            record["dynamics"].append(row)
            print(
                f"dyn  {path.stem:7s} {label:42s} r {row['grouping_pearson_r']:.3f} "
                f"mean dAngle {row['angle_diff_mean_deg']:5.1f} grouping cells {row['group_mean_rate_hz']:.1f} Hz",
                flush=True,
            )
    record["run"] = run.record()
    save_json("spiking_deviations", record)
    save_markdown("spiking_deviations", _markdown(record))
    print("wrote experiments/results/spiking_deviations.md")


def _markdown(rec) -> list[str]:
    def mean_deg(r):
        mean = r["angle_diff_mean_deg"]
        return "no vectors" if mean != mean else f"{mean:.1f}"  # NaN: the figure-ground map is zero

    return (
        [
            "# Deviations of the spiking network from the rate model, measured",
            "",
            f"{describe(rec['run'])} *Twin* = the unrolled network run as the rate model's iteration (structure "
            "only); *spiking* = the network simulated (fast engine; structure + dynamics). Grouping cells' rate: "
            "the mean over the grouping populations of each one's mean rate over the cells the frame creates.",
            "",
            "## Structural knobs, one at a time (twin vs reference, 128 x 160 crops)",
            "",
        ]
        + markdown_table(
            ["frame", "variant", "grouping r", "median dAngle", "mean dAngle", "synapses"],
            [
                [
                    r["frame"],
                    r["variant"],
                    f"{r['grouping_pearson_r']:.3f}",
                    f"{r['angle_diff_median_deg']:.1f}",
                    f"{r['angle_diff_mean_deg']:.1f}",
                    f"{r['synapses']:,}",
                ]
                for r in rec["crops"]
            ],
        )
        + ["", "## Full frames: structure vs dynamics", ""]
        + markdown_table(
            [
                "frame",
                "twin vs ref r",
                "twin mean dAngle",
                "spiking vs ref r",
                "spiking mean dAngle",
                "spiking vs twin r",
            ],
            [
                [
                    r["frame"],
                    f"{r['twin_vs_ref']['grouping_pearson_r']:.3f}",
                    f"{r['twin_vs_ref']['angle_diff_mean_deg']:.1f}",
                    f"{r['spiking_vs_ref']['grouping_pearson_r']:.3f}",
                    f"{r['spiking_vs_ref']['angle_diff_mean_deg']:.1f}",
                    f"{r['spiking_vs_twin']['grouping_pearson_r']:.3f}",
                ]
                for r in rec["full"]
            ],
        )
        + ["", "## Mechanisms switched off (spiking vs reference)", ""]
        + markdown_table(
            ["frame", "variant", "grouping r", "mean dAngle", "grouping cells mean rate (Hz)"],
            [
                [
                    r["frame"],
                    r["variant"],
                    f"{r['grouping_pearson_r']:.3f}",
                    mean_deg(r),
                    f"{r['group_mean_rate_hz']:.1f}",
                ]
                for r in rec["dynamics"]
            ],
        )
    )


if __name__ == "__main__":
    main()
