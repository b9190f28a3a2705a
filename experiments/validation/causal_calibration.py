"""What reading a recording once and causally changes in its spiking maps.

    python -m experiments.validation.causal_calibration [--before main] [--windows 6]

A spiking run over a recording used to read it twice: a first pass for the
mean rate of an active input over every window (the gains' calibration)
and the read-out spans, then the run. It now reads it once, as a live
stream is read (``snn_fg/models/spiking/stream_input.py``): the compact
network's gains are calibrated to its input adapter's ceiling (1000 / R
Hz) before any event, the default network's to the rate of window 0, and a
recording's last window is read out over a whole window's span. This runs
the spiking network on ``dvs.es`` (the windows of
``recording_fidelity``) with the code of ``--before`` (a git ref, taken
with ``git archive`` into a temporary folder) and with this checkout, for
the default and the compact network, and scores each against the rate
model on the same recipe (``recording_fidelity.scores``) and the two
against each other. Writes ``causal_calibration.{json,md,png}``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from experiments.common import Run, dataset, describe, markdown_table, save_figure, save_results
from experiments.validation.recording_fidelity import NETWORKS, inward, rate_maps, scores, windows_of

ROOT = Path(__file__).resolve().parents[2]


#: the maps of whichever ``snn_fg`` comes first on the path, into an npz (run in its own process)
_MAPS = """
import numpy as np
from experiments.validation.recording_fidelity import windows_of
from snn_fg.models.spiking import run_spiking_windows
maps = run_spiking_windows(windows_of("dvs_biplane", {n}), network={network!r}, progress=False)
cal = maps[0].params["network"].get("calibrated", {{}})
np.savez({out!r}, fg_x=np.stack([m.fg_x for m in maps]), fg_y=np.stack([m.fg_y for m in maps]),
         grouping=np.stack([m.grouping for m in maps]), to_hz=cal.get("to_hz", np.nan))
"""


def _maps_of(src: Path | None, network: str, n: int, tmp: str):
    """The spiking maps of the code in ``src`` (None: this checkout), made in a process of its own."""
    out = os.path.join(tmp, f"{network}-{'before' if src else 'after'}.npz")
    env = dict(os.environ, PYTHONPATH=str(src or ROOT), SNN_FG_DATA=str(dataset("events").parent))
    code = _MAPS.format(n=n, network=network, out=out)
    subprocess.run([sys.executable, "-c", code], check=True, env=env, cwd=str(src or ROOT))
    with np.load(out) as z:
        return {k: z[k] for k in z.files}


class _M:
    def __init__(self, d, k):
        self.fg_x, self.fg_y, self.grouping = d["fg_x"][k], d["fg_y"][k], d["grouping"][k]


def _as_maps(d):
    return [_M(d, k) for k in range(len(d["fg_x"]))]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default="main", help="git ref of the two-pass code (main)")
    ap.add_argument("--windows", type=int, default=6)
    args = ap.parse_args(argv)
    run = Run()
    wins = windows_of("dvs_biplane", args.windows)
    rows, shown, record = [], {}, {"windows": len(wins), "before": args.before, "networks": {}}
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp, "before")
        src.mkdir()
        archive = subprocess.run(["git", "archive", args.before], cwd=ROOT, check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(src)], input=archive, check=True)
        for network in NETWORKS:
            ref = rate_maps(wins, network)
            both = {
                "before": _maps_of(src, network, args.windows, tmp),
                "after": _maps_of(None, network, args.windows, tmp),
            }
            rec = {"against_each_other": scores(_as_maps(both["after"]), _as_maps(both["before"]))}
            for when, d in both.items():
                maps = _as_maps(d)
                rec[when] = {**scores(maps, ref), "inward": inward(maps, wins), "to_hz": float(d["to_hz"])}
                r = rec[when]
                rows.append(
                    [
                        network,
                        when,
                        f"{r['to_hz']:.1f}",
                        f"{r['within_45']:.1%}",
                        f"{r['mean_abs_deg']:.1f}",
                        f"{r['grouping_r_mean']:.3f}",
                        f"{r['coverage']:.1%}",
                        f"{np.median(r['inward']):.2f}",
                    ]
                )
            record["networks"][network] = rec
            shown[network] = both
            print(f"{network}: {rec['against_each_other']['within_45']:.3f} within 45 deg of each other", flush=True)
    record["run"] = run.record()
    each = {n: record["networks"][n]["against_each_other"] for n in NETWORKS}
    lines = [
        "# A recording read once and causally: its spiking maps before and after",
        "",
        describe(record["run"]),
        "",
        f"`dvs.es`, {len(wins)} windows of 85 ms from 100 ms; before: `{args.before}` (two passes, gains calibrated "
        "to the mean rate of an active input over every window); after: this checkout (one pass: the compact "
        "network at its adapter's ceiling, the default network at window 0's rate).",
        "",
        *markdown_table(
            [
                "network",
                "code",
                "calibrated to (Hz)",
                "within 45° of the rate model",
                "mean abs °",
                "grouping r",
                "coverage",
                "plane outline inward (median)",
            ],
            rows,
        ),
        "",
        "After against before: "
        + "; ".join(
            f"{n} {e['within_45']:.1%} within 45°, grouping r {e['grouping_r_mean']:.3f}, coverage {e['coverage']:.1%}"
            for n, e in each.items()
        ),
    ]
    save_results("causal_calibration", record, lines)
    figure(wins, shown)


def figure(wins, shown) -> None:
    import matplotlib

    matplotlib.use("Agg")  # (an experiment script, never imported by the package)
    import matplotlib.pyplot as plt

    from snn_fg.results.figures import event_frame_rgb, fg_rgb

    ks = [1, len(wins) - 1]
    fig, axes = plt.subplots(len(ks), 5, figsize=(19, 3.6 * len(ks)), squeeze=False)
    for row, k in zip(axes, ks, strict=True):
        panels = [(event_frame_rgb(wins[k].pos, wins[k].neg), f"window {k}: events")]
        for network in NETWORKS:
            for when in ("before", "after"):
                d = shown[network][when]
                panels.append((fg_rgb(d["fg_x"][k], d["fg_y"][k]), f"{network}, {when} ({float(d['to_hz']):.0f} Hz)"))
        for ax, (img, title) in zip(row, panels, strict=True):
            ax.imshow(img)
            ax.set_title(title, fontsize=9)
            ax.set_xlabel("x (px)")
            ax.set_ylabel("y (px)")
    fig.suptitle("dvs.es: spiking figure-ground maps, two passes (before) and one causal pass (after)")
    save_figure(fig, "causal_calibration")
    plt.close(fig)
    print(json.dumps({"figure": "experiments/results/causal_calibration.png"}))


if __name__ == "__main__":
    main()
