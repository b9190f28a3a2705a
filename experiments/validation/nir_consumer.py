"""An independent NIR consumer (snnTorch 1.0.0 through nirtorch 2.6) executes the exported graph.

The exact graph (``snn-fg export --format nir``) is refused by snnTorch at
its first LIF node (``v_leak`` must be 0) and has LI, Delay and several
Input nodes it cannot map; the ``snntorch`` profile
(``snn_fg.export.nir_snntorch``) writes what it imports. On each input:

* **consumer**: snnTorch running the profile's graph (read back from its
  file), decoded with our decoder, against the fast engine running the
  exported network (the board network) on the same input spikes;
* **encoding**: the fast engine running the profile's network (no delays
  beyond one step, no refractoriness, zero padding; what the graph holds)
  against the same reference: the cost of the encoding alone;
* **consumer vs encoding**: snnTorch against the fast engine on the
  profile's network: what snnTorch's own arithmetic changes;
* **encoding choices** (fast engine only, against the same reference): the
  profile's network with each way of standing in for the refractory period
  (one step; a deeper reset, ``--nir-refractory-as-deeper-reset``, for
  drives 1 to 16, :func:`~snn_fg.export.nir_snntorch.reset_depth_mv`), and
  with the exported network's own delays and/or refractory periods, which
  no NIR consumer tried can run (what they would be worth).

``--refractory deeper-reset`` runs snnTorch on the graph written with the
deeper reset (drive ``RESET_DRIVE``) instead of the one-step default.

Inputs: a disc of radius 16 (regular trains, 200 Hz) and a 64 x 48 crop of a
``dvs.es`` window (the window from 100 ms, 85 ms, as the compact network's
accuracy run starts; the crop centred on the window's mean event position,
:func:`~snn_fg.export.loop.centroid_crop`, so the plane is in view; its
events each a spike in its time step through the network's input refractory
period, the ``events`` coding, the window replayed).
The network is calibrated to the input's rate as ``snn-fg run`` calibrates
it (the disc's 200 Hz is the default; the crop's events are some 20 Hz per
active block, and uncalibrated the compact network's simple cells stay
silent on them). The default network with one level (the profile cannot
interpolate between pyramid levels), or with ``--network compact`` the
compact network's three octave levels on one grid (``--nir-one-grid``), its
input the sensor's 3 x 3 blocks behind its input refractory period per
block (``Network.input_refractory_ms``: 60 ms since 27 Nov 12:53 UTC, 40 ms
before); 400 ms, counting from 200 ms, in steps of the network's own time
step (0.5 ms; the compact network 1 ms) in every engine.

Writes experiments/results/nir_consumer.{json,md}.
Usage: python -m experiments.validation.nir_consumer [--inputs disc dvs] [--duration-ms 400] [--radius 16]
       [--network default|compact] [--refractory one-step|deeper-reset [--reset-drive 4]]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from experiments.common import DVS_FROM_MS, RESULTS, Run, dataset, markdown_table, save_json, save_markdown
from snn_fg.backends import RunSettings, get_backend
from snn_fg.events.cutter import WINDOW_MS
from snn_fg.export.board import board_network
from snn_fg.export.nir_snntorch import RESET_DRIVE, snntorch_network, to_nir_snntorch
from snn_fg.export.snntorch_run import run_snntorch
from snn_fg.models.spiking.decode import decode, decode_rates
from snn_fg.network import build_network
from snn_fg.network.recipes import RECIPES
from snn_fg.params import ModelParams
from snn_fg.scoring.metrics import agreement


def disc_input(radius: float, duration_ms: float, pool: int, dt_ms: float):
    from snn_fg.events import image_to_frame
    from snn_fg.frames.pool import pool_frame
    from snn_fg.frames.scenes import disc
    from snn_fg.lowering.input_spikes import frame_spikes

    pos, neg = pool_frame(*image_to_frame(disc(radius).image), pool)
    what = f"disc r{radius:g} ({pos.shape[1] * pool} x {pos.shape[0] * pool}" + (
        f", {pool} x {pool} blocks)" if pool > 1 else ")"
    )
    return frame_spikes(pos, neg, 200.0, dt_ms, duration_ms), what, disc(radius).image.shape


def dvs_input(
    dt_ms: float, shape=(48, 64), start_ms=DVS_FROM_MS, window_ms=WINDOW_MS, pool: int = 1, refractory_ms: float = 0.0
):
    """The sensor's ``shape`` crop (rows, cols) centred on the window's mean
    event position, its events pooled into ``pool`` x ``pool`` blocks as the
    network's input adapter does."""
    from snn_fg.events import iter_recording, iter_windows
    from snn_fg.export.loop import centroid_crop, crop_events
    from snn_fg.frames.pool import pool_events, pooled_shape
    from snn_fg.lowering.input_spikes import event_spikes

    path = dataset("events", "dvs.es")
    win = next(iter(iter_windows(iter_recording(path), window_ms=window_ms, start_ms=start_ms, max_windows=1)))
    r0, c0 = centroid_crop(win.events, shape, win.pos.shape)
    ev = pool_events(crop_events(win.events, (r0, c0), shape), pool)
    h, w = pooled_shape(shape, pool)
    inp = event_spikes(ev, (w, h), dt_ms, replay=True, t0_us=win.t_start_us, refractory_ms=refractory_ms)
    return (
        inp,
        (
            f"dvs.es {win.t_start_us}..{win.t_end_us} us, {shape[1]} x {shape[0]} crop at x={c0}, y={r0}"
            + (f", {pool} x {pool} blocks" if pool > 1 else "")
        ),
        shape,
    )


def timing_kept(profile, board, *, delays: bool, refractory: bool):
    """``profile`` (the network the graph holds) with ``board``'s own delays and/or refractory periods."""
    t_ref = {p.name: p.neuron.t_ref_ms for p in board.populations if p.neuron is not None}
    delay = {pr.name: pr.delay_ms for pr in board.projections}
    pops = tuple(
        p
        if p.neuron is None or not refractory
        else dataclasses.replace(p, neuron=dataclasses.replace(p.neuron, t_ref_ms=t_ref[p.name]))
        for p in profile.populations
    )
    prjs = tuple(dataclasses.replace(pr, delay_ms=delay[pr.name]) if delays else pr for pr in profile.projections)
    return dataclasses.replace(profile, populations=pops, projections=prjs)


#: the drives of the deeper reset the encoding choices try
DRIVES = (1.0, 2.0, 4.0, 8.0, 16.0)


def _reference(net, inp, duration_ms: float):
    """The run settings (counting the second half) and the fast engine's maps of the exported network."""
    settings = RunSettings(duration_ms=duration_ms, dt_ms=net.dt_ms, count_from_ms=duration_ms / 2, instantiate="all")
    return settings, decode(get_backend("fast").simulate(board_network(net), inp, settings))[:3]


def encoding_choices(net, inp, settings, ref, one_grid: bool) -> dict:
    """Label -> agreement with ``ref`` of the fast engine on the profile's
    network for each way of standing in for the refractory period, and with
    the exported network's own timing (which the graph cannot hold)."""
    fast, board = get_backend("fast"), board_network(net)
    one_step = snntorch_network(net, one_grid=one_grid)
    nets = {"one step (default)": one_step}
    nets.update(
        {
            f"deeper reset, drive {k:g}": snntorch_network(net, one_grid=one_grid, deeper_reset=True, reset_drive=k)
            for k in DRIVES
        }
    )
    for label, d, r in (
        ("own delays (no NIR consumer runs them)", True, False),
        ("own refractory periods (no NIR node has them)", False, True),
        ("own delays and refractory periods", True, True),
    ):
        nets[label] = timing_kept(one_step, board, delays=d, refractory=r)
    return {label: agreement(decode(fast.simulate(n, inp, settings))[:3], ref) for label, n in nets.items()}


def compare(
    net,
    inp,
    duration_ms: float,
    tmp: Path,
    one_grid: bool = False,
    deeper_reset: bool = False,
    reset_drive: float = RESET_DRIVE,
) -> dict:
    import nir
    import torch

    torch.set_num_threads(1)
    profile = snntorch_network(net, one_grid=one_grid, deeper_reset=deeper_reset, reset_drive=reset_drive)
    path = tmp / "graph.nir"
    nir.write(path, to_nir_snntorch(net, one_grid=one_grid, deeper_reset=deeper_reset, reset_drive=reset_drive))
    t0 = time.perf_counter()
    settings, ref = _reference(net, inp, duration_ms)
    enc_run = get_backend("fast").simulate(profile, inp, settings)
    enc = decode(enc_run)[:3]
    choices = encoding_choices(net, inp, settings, ref, one_grid)
    t1 = time.perf_counter()
    counts = run_snntorch(
        nir.read(path),
        net,
        inp,
        step_ms=net.dt_ms,
        duration_ms=duration_ms,
        count_from_ms=duration_ms / 2,
        one_grid=one_grid,
    )
    t2 = time.perf_counter()
    window_s = duration_ms / 2 / 1e3
    ours = decode_rates(
        profile, {k: np.arange(v.size) for k, v in counts.items()}, {k: v / window_s for k, v in counts.items()}
    )[:3]
    spikes = {
        "snntorch": int(sum(v.sum() for v in counts.values())),
        "fast_profile": int(sum(v.sum() for v in enc_run.counts.values())),
    }
    return {
        "consumer": agreement(ours, ref),
        "encoding": agreement(enc, ref),
        "consumer_vs_encoding": agreement(ours, enc),
        "encoding_choices": choices,
        "spikes_counted": spikes,
        "fast_s": t1 - t0,
        "snntorch_s": t2 - t1,
    }


def choices_only(net, inp, duration_ms: float, one_grid: bool) -> dict:
    """:func:`encoding_choices` against the fast engine on the exported network, without snnTorch."""
    return encoding_choices(net, inp, *_reference(net, inp, duration_ms), one_grid)


def _load(r) -> str:
    """The load average when the input ran (a record from before the run records: as stored)."""
    if "run" not in r:
        return r["load"]
    return f"{r['run']['load_before'][0]:.1f} -> {r['run']['load_after'][0]:.1f}"


def markdown(out: dict) -> list[str]:
    comparisons = (
        ("consumer", "snnTorch vs fast"),
        ("encoding", "profile network (fast) vs fast"),
        ("consumer_vs_encoding", "snnTorch vs profile network (fast)"),
    )
    rows = [
        [
            r.get("network", "default, 1 level"),
            r["what"],
            label,
            f"{r[key]['grouping_r']:.3f}",
            f"{r[key]['within_45']:.3f}",
            f"{r[key]['mean_deg']:.1f}",
            f"{r[key]['coverage']:.3f}",
            f"{r['snntorch_s']:.0f}",
            _load(r),
        ]
        for r in out["inputs"].values()
        if "consumer" in r
        for key, label in comparisons
    ]
    choices = [
        [r["what"], label, f"{a['grouping_r']:.3f}", f"{a['within_45']:.3f}", f"{a['mean_deg']:.1f}"]
        for key, r in out["inputs"].items()
        if "deeper" not in key
        for label, a in r.get("encoding_choices", {}).items()
    ]
    return (
        [
            "# An independent NIR consumer runs the export (snnTorch 1.0.0, nirtorch 2.6)",
            "",
            "`snn-fg export --format nir --nir-profile snntorch` (the default network with one level; the compact "
            "network with `--nir-one-grid`, its three levels on one grid); decoded with snn-fg's decoder. "
            "Reference: the fast engine on the exported (board) network, same input spikes. Each input's "
            "run (commit, command, date) is in `nir_consumer.json`. An empty comparison (nan): the reference has "
            "no border-ownership vector.",
            "",
        ]
        + markdown_table(
            [
                "network",
                "input",
                "comparison",
                "grouping r",
                "within 45°",
                "mean angle °",
                "coverage",
                "snnTorch s",
                "load",
            ],
            rows,
        )
        + [
            "",
            "## Standing in for the refractory period (fast engine, against the exported network)",
            "",
            "A deeper reset costs no node and no neuron (the CubaLIF's threshold and resting "
            "current change); the exported network's own delays and refractory periods are what "
            "no consumer tried can run.",
            "",
        ]
        + markdown_table(["input", "profile network with", "grouping r", "within 45°", "mean angle °"], choices)
    )


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--inputs", nargs="+", default=["disc", "dvs"], choices=["disc", "dvs"])
    ap.add_argument("--duration-ms", type=float, default=400.0)
    ap.add_argument("--radius", type=float, default=16.0)
    ap.add_argument(
        "--refractory",
        default="one-step",
        choices=["one-step", "deeper-reset"],
        help="one-step: a cell may fire again the step after it spikes (the profile's default); "
        "deeper-reset: its reset stands in for its refractory period (--nir-refractory-as-deeper-reset)",
    )
    ap.add_argument(
        "--reset-drive",
        type=float,
        default=RESET_DRIVE,
        help=f"deeper-reset: the drive it is reckoned for (the export's: {RESET_DRIVE:g})",
    )
    ap.add_argument("--dvs-start-ms", type=float, default=DVS_FROM_MS, help="dvs: where its 85 ms window starts")
    ap.add_argument(
        "--choices-only",
        action="store_true",
        help="only the encoding choices on the fast engine (no snnTorch): a check on other inputs",
    )
    ap.add_argument(
        "--network",
        default="default",
        choices=["default", "compact"],
        help="default: one level; compact: its three levels on one grid (--nir-one-grid)",
    )
    args = ap.parse_args(argv)
    compact = args.network == "compact"
    recipe = RECIPES["compact"]
    pool, refractory = (recipe.params.input_pool, recipe.spiking.input.input_refractory_ms) if compact else (1, 0.0)
    dt_ms = (recipe if compact else RECIPES["default"]).spiking.time.dt_ms
    path = RESULTS / "nir_consumer.json"
    out = json.loads(path.read_text()) if path.exists() else {"inputs": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.inputs:
            inp, what, sensor = (
                disc_input(args.radius, args.duration_ms, pool, dt_ms)
                if name == "disc"
                else dvs_input(dt_ms, start_ms=args.dvs_start_ms, pool=pool, refractory_ms=refractory)
            )
            net = recipe.build(sensor) if compact else build_network(ModelParams(levels=1), inp.shape)
            net = net.calibrated(inp.rate_hz)  # as snn-fg run calibrates it
            run = Run()
            deeper = args.refractory == "deeper-reset"
            if args.choices_only:
                r = {"encoding_choices": choices_only(net, inp, args.duration_ms, compact)}
            else:
                r = compare(
                    net,
                    inp,
                    args.duration_ms,
                    Path(tmp),
                    one_grid=compact,
                    deeper_reset=deeper,
                    reset_drive=args.reset_drive,
                )
            r.update(
                what=what,
                duration_ms=args.duration_ms,
                run=run.record(),
                network=("compact, 3 levels on one grid" if compact else "default, 1 level")
                + f", {net.dt_ms:g} ms steps"
                + (f", refractory as deeper reset (drive {args.reset_drive:g})" if deeper else ""),
            )
            key = (f"compact {name}" if compact else name) + (
                f" from {args.dvs_start_ms:g} ms" if name == "dvs" and args.dvs_start_ms != 100 else ""
            )
            out["inputs"][
                key
                + (" choices only" if args.choices_only else f" deeper reset {args.reset_drive:g}" if deeper else "")
            ] = r
            print(name, json.dumps(r, default=float), flush=True)
            save_json("nir_consumer", out)
    save_markdown("nir_consumer", markdown(out))
    print("\n".join(markdown(out)))


if __name__ == "__main__":
    main()
