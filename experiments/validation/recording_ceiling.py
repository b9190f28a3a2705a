"""The still-frame ceiling on recordings: each window's event frame handed to the network as a still input.

    python -m experiments.validation.recording_ceiling [--windows 6] [--only person] [--networks compact]

The rate model reads each window's event frame; the network, handed that
same frame as a still input for 400 ms (counted over 200-400 ms, as
``snn-fg run F.npz --model spiking`` does), has no input coding left between
it and the reference. Its agreement with the rate model on the same recipe
(``--model rate [--network compact]``) is then the most any input coding of
a recording can give the network as it stands: the ceiling. Scored as in
``recording_fidelity`` (pixels where both have a vector: within 45 degrees,
mean absolute difference, grouping r, coverage), per window.

Writes ``recording_ceiling.{json,md,png}`` (the figure: per recording, one
window's events, the rate model's map and the still-frame maps).

``--stages`` asks where the two part on those still frames, stage by stage
at level 1, on each recording's windows and on BSDS frames (where the
network agrees): the simple cells' winning direction against the rate
model's (pixels where both have a simple-cell response), the side each
border-ownership pair chooses (``B2 - B1`` per orientation, where both
chose), the grouping maps (Pearson r per level), the map; and which of the
rate model's iterations (1 to 40) the network's map sits nearest, beside
the rate model's own 10 against 20 iterations. Writes
``recording_stages.{json,md}``.

``--pruning`` measures the stage the compact network parts at: its DoG
kernels keep only the taps over 30 % of their peak, which keeps 1.35 of
their positive mass and 0.60 of their negative (the whole kernel sums to
0; the pruned one to +0.75, above the 0.3 edge threshold), so a simple cell
answers inside a uniform region of events where the rate model has no
response. The compact network's still ceiling on both recordings and on the
six BSDS frames with the DoG pruned at 30, 10 and 5 % of its peak, each
as it is and balanced (the kept negative taps scaled so that the kernel
sums to 0 again, the taps unchanged). Writes ``recording_pruning.{json,md}``.
"""

from __future__ import annotations

import argparse
import contextlib
import time

import numpy as np

from experiments.common import Run, describe, markdown_table, save_figure, save_results
from experiments.validation.recording_fidelity import NETWORKS, rate_maps, score_cells, scores, show_row, windows_of

#: how long a still frame is presented and where counting starts (``run_spiking``'s defaults)
STILL_MS, COUNT_FROM_MS = 400.0, 200.0


def still_maps(wins, network: str, still_ms: float = STILL_MS, count_from_ms: float = COUNT_FROM_MS, **options):
    """Each window's event frame through the network as a still input, and the seconds a window."""
    from snn_fg.backends import get_backend
    from snn_fg.models.spiking import run_spiking

    backend, maps = get_backend("fast"), []  # (one backend object: what it prepares for a network is kept)
    t = time.perf_counter()
    for w in wins:
        maps.append(
            run_spiking(
                pos=w.pos,
                neg=w.neg,
                network=network,
                duration_ms=still_ms,
                settle_ms=count_from_ms,
                backend=backend,
                progress=False,
                **options,
            )
        )
    return maps, (time.perf_counter() - t) / len(wins)


def measure(name: str, n: int, networks, still_ms: float, count_from_ms: float) -> tuple[dict, dict]:
    wins = windows_of(name, n)
    rows, shown = [], {}
    for network in networks:
        ref = rate_maps(wins, network)
        maps, per_window_s = still_maps(wins, network, still_ms, count_from_ms)
        row = {
            "network": network,
            "map": f"still {still_ms:g} ms, counted from {count_from_ms:g}",
            "s_per_window": per_window_s,
        }
        row.update(scores(maps, ref))
        rows.append(row)
        shown[network] = (ref, maps)
        print(f"{name} {network}: {row['within_45']:.3f} within 45 deg, {per_window_s:.1f} s a window", flush=True)
    return {"windows": len(wins), "rows": rows}, {"wins": wins, "maps": shown}


def table(results: dict) -> list[str]:
    rows = [
        [name, r["network"], *score_cells(r)[:4], f"{r['s_per_window']:.1f}"]
        for name, res in results.items()
        for r in res["rows"]
    ]
    header = ["recording", "network", "within 45° (pooled; per window)", "mean abs °", "grouping r", "coverage"]
    return markdown_table([*header, "s a window"], rows)


def figure(shown: dict):
    import matplotlib

    matplotlib.use("Agg")  # (an experiment script, never imported by the package)
    import matplotlib.pyplot as plt

    from snn_fg.results.figures import event_frame_rgb, fg_rgb
    from snn_fg.scoring.metrics import agreement

    names = list(shown)
    networks = list(shown[names[0]]["maps"])
    ncols = 1 + 2 * len(networks)
    fig, axes = plt.subplots(len(names), ncols, figsize=(4 * ncols, 3.4 * len(names)), squeeze=False)
    for row, name in zip(axes, names):
        wins, maps = shown[name]["wins"], shown[name]["maps"]
        k = min(3, len(wins) - 1)
        panels = [("events", event_frame_rgb(wins[k].pos, wins[k].neg))]
        for network in networks:
            ref, spk = maps[network][0][k], maps[network][1][k]
            a = agreement(spk, ref)
            panels += [
                (f"rate model, {network}", fg_rgb(ref.fg_x, ref.fg_y)),
                (f"spiking {network}, still: {a['within_45']:.0%} within 45°", fg_rgb(spk.fg_x, spk.fg_y)),
            ]
        show_row(row, f"{name} window {k}", panels)
    fig.tight_layout()
    return fig


#: (DoG taps kept over this fraction of the peak, balanced) of ``--pruning``; (0.3, False): the compact network
PRUNINGS = ((0.3, False), (0.3, True), (0.1, False), (0.1, True), (0.05, False))


@contextlib.contextmanager
def balanced_dog(prune: float):
    """The network's DoG kernels (``Kernel(ref="dog")``, not the rate model's) with the taps under
    ``prune`` of each kernel's peak set to 0 and the kept negative taps scaled to a zero sum; pruning
    them with the projection's ``prune_dog`` 0 keeps the same taps."""
    import snn_fg.network.nodes as nodes

    full = nodes.dog_kernels

    def balanced(params):
        k = full(params).copy()
        for kd in k:
            kd[np.abs(kd) < prune * np.abs(kd).max()] = 0.0
            kd[kd < 0] *= kd[kd > 0].sum() / -kd[kd < 0].sum()
        return k

    nodes.dog_kernels = balanced
    try:
        yield
    finally:
        nodes.dog_kernels = full


def compact_dog(prune: float, balance: bool):
    """The compact network with its DoG pruned at ``prune`` of each kernel's peak (``balance``: as
    :func:`balanced_dog`): the context to run it in and its run options (``params``, ``spiking``)."""
    from snn_fg.network.recipes import RECIPES

    recipe = RECIPES["compact"]
    # (a balanced kernel carries its pruning: the projection keeps its non-zero taps)
    kept = 0.0 if balance else prune
    sp = recipe.spiking.replace(connectivity=recipe.spiking.connectivity.replace(prune_dog=kept))
    context = balanced_dog(prune) if balance else contextlib.nullcontext()
    return context, {"params": recipe.params, "spiking": sp}


def still_sets(n: int, bsds: bool = True) -> dict:
    """The still frames ``--pruning`` scores on: ``n`` windows of each recording (``dvs_biplane``,
    ``person``) and, with ``bsds``, the six BSDS frames (``BSDS (six frames)``), each with ``pos``, ``neg``."""
    from types import SimpleNamespace

    from experiments.common import dataset

    sets = {name: windows_of(name, n) for name in ("dvs_biplane", "person")}
    if bsds:
        frames = [np.load(p) for p in sorted(dataset("bsds-edfg").glob("*.npz"))]
        sets["BSDS (six frames)"] = [SimpleNamespace(pos=d["pos"], neg=d["neg"]) for d in frames]
    return sets


def rate_refs(sets: dict, params) -> dict:
    """The rate model's maps on each of :func:`still_sets`' frames, with the model parameters ``params``."""
    from snn_fg.models.rate.edfg import run_edfg

    return {name: [run_edfg(w.pos, w.neg, params) for w in wins] for name, wins in sets.items()}


def pruning(n: int) -> tuple[dict, list[str]]:
    """The compact network's still ceiling with its DoG pruned as in :data:`PRUNINGS`."""
    from snn_fg.network.kernels import dog_kernels
    from snn_fg.network.recipes import RECIPES

    recipe = RECIPES["compact"]
    sets = still_sets(n)
    refs = rate_refs(sets, recipe.params)
    out, rows = [], []
    for prune, balance in PRUNINGS:
        row = {"prune_dog": prune, "balanced": balance}
        context, options = compact_dog(prune, balance)
        with context:
            for name, wins in sets.items():
                maps, per_window_s = still_maps(wins, None, **options)
                row[name] = {**scores(maps, refs[name]), "s_per_window": per_window_s}
        taps = sum(int((np.abs(k) >= prune * np.abs(k).max()).sum()) for k in dog_kernels(recipe.params))
        row["taps"] = taps
        out.append(row)
        cells = [f"{prune:.0%}", "balanced" if balance else "as pruned", f"{taps / 16:.0f}"]
        for name in sets:
            r = row[name]
            cells.append(f"{r['within_45']:.1%} / {r['mean_abs_deg']:.1f}° / {r['coverage']:.0%}")
        rows.append(cells)
        print(" | ".join(cells), flush=True)
    header = [
        "DoG taps kept over",
        "kernel",
        "taps a direction",
        *(f"{k}: within 45° / mean abs / coverage" for k in sets),
    ]
    return {"rows": out}, markdown_table(header, rows)


ITERATIONS = (1, 3, 5, 10, 20, 40)
#: BSDS frames (dataset bsds-edfg) on which the network agrees with the rate model: the stages' baseline
BSDS_FRAMES = ("105053", "35070")


def stage_agreement(pos, neg, network: str, **options) -> dict:
    """Level-1 stages of the network on a still frame against the rate model's on the same frame."""

    from snn_fg.models.rate.edfg import run_edfg, run_edfg_state
    from snn_fg.models.spiking import run_spiking_result
    from snn_fg.models.spiking.decode import decode
    from snn_fg.network.recipes import RECIPES
    from snn_fg.scoring.metrics import agreement, pearson

    params = RECIPES[network].params
    rate = run_edfg_state(pos, neg, params)
    res = run_spiking_result(
        pos, neg, network=network, duration_ms=STILL_MS, settle_ms=COUNT_FROM_MS, progress=False, record_spikes=False
    )
    gr, gs, n = rate.grouping_result, decode(res.result)[3], params.n_ori
    # simple cells: the rate model's S channel is the direction turned a quarter (n / 2 of 2n)
    s_rate, s_spk = gr.s[0], np.roll(gs.s[0], n // 2, axis=0)
    both = (s_rate.max(0) > 0) & (s_spk.max(0) > 0)
    untuned = both & (rate.resp.max(0) <= 0)  # (no response above threshold: the rate model's default index)
    same = s_rate.argmax(0) == s_spk.argmax(0)
    side_r = (gr.bl2[0] + gr.bd2[0]) - (gr.bl1[0] + gr.bd1[0])
    side_s = (gs.bl2[0] + gs.bd2[0]) - (gs.bl1[0] + gs.bd1[0])
    chose = (side_r != 0) & (side_s != 0)
    ref = rate.maps()
    iterations = {
        k: agreement(res.maps, ref if k == params.iterations else run_edfg(pos, neg, params.replace(iterations=k)))
        for k in ITERATIONS
    }
    ref20 = run_edfg(pos, neg, params.replace(iterations=2 * params.iterations))
    return {
        "simple_same_direction": float(same[both].mean()),
        "simple_same_direction_tuned": float(same[both & ~untuned].mean()),
        "rate_untuned_share": float(untuned.sum() / max(both.sum(), 1)),
        "bo_same_side": float(np.mean(np.sign(side_r[chose]) == np.sign(side_s[chose]))),
        "bo_side_r": pearson(side_r[chose], side_s[chose]),
        "grouping_r": [pearson(np.stack([a, b]), np.stack([c, d])) for a, b, c, d in zip(gr.gl, gr.gd, gs.gl, gs.gd)],
        "map": scores([res.maps], [ref]),
        "vs_iterations": {k: v["within_45"] for k, v in iterations.items()},
        "rate_10_vs_20": scores([ref], [ref20]),
    }


def stages(networks, n: int) -> tuple[dict, list[str]]:
    from experiments.common import dataset

    frames = [
        (f"BSDS {f}", *(np.load(dataset("bsds-edfg", f"{f}.npz"))[k] for k in ("pos", "neg"))) for f in BSDS_FRAMES
    ]
    for name in ("dvs_biplane", "person"):
        frames += [(f"{name} window {k}", w.pos, w.neg) for k, w in enumerate(windows_of(name, n))]
    out, rows = {}, []
    for network in networks:
        for label, pos, neg in frames:
            t = time.perf_counter()
            st = stage_agreement(pos, neg, network)
            out[f"{network}: {label}"] = st
            g, m = np.array(st["grouping_r"]), st["map"]
            rows.append(
                [
                    network,
                    label,
                    f"{st['simple_same_direction']:.0%} ({st['simple_same_direction_tuned']:.0%})",
                    f"{st['rate_untuned_share']:.0%}",
                    f"{st['bo_same_side']:.0%}",
                    f"{np.nanmean(g):.2f} ({np.nanmin(g):.2f})",
                    f"{m['within_45']:.0%} / {m['mean_abs_deg']:.0f}° / {m['coverage']:.0%}",
                    " ".join(f"{st['vs_iterations'][k]:.0%}" for k in ITERATIONS),
                    f"{st['rate_10_vs_20']['within_45']:.0%} / {st['rate_10_vs_20']['mean_abs_deg']:.0f}°",
                ]
            )
            print(" | ".join(rows[-1]), f"({time.perf_counter() - t:.0f} s)", flush=True)
    header = [
        "network",
        "still frame",
        "simple cells: same direction (tuned pixels)",
        "rate model untuned",
        "border ownership: same side",
        "grouping r, mean over levels (min)",
        "map: within 45° / mean abs / coverage",
        "map within 45° of the rate model at " + ", ".join(map(str, ITERATIONS)) + " iterations",
        "rate model 10 vs 20 iterations",
    ]
    return out, markdown_table(header, rows)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--windows", type=int, default=6, help="windows per recording (6)")
    ap.add_argument("--only", nargs="+", choices=["dvs_biplane", "person"], default=["dvs_biplane", "person"])
    ap.add_argument("--networks", nargs="+", choices=NETWORKS, default=list(NETWORKS))
    ap.add_argument("--still-ms", type=float, default=STILL_MS, help=f"presentation (ms, {STILL_MS:g})")
    ap.add_argument("--count-from-ms", type=float, default=COUNT_FROM_MS, help=f"counting start ({COUNT_FROM_MS:g})")
    ap.add_argument("--pruning", action="store_true", help="the compact network's DoG pruning (module docstring)")
    ap.add_argument("--stages", action="store_true", help="where the two part on still frames (module docstring)")
    a = ap.parse_args()
    run = Run()
    if a.pruning:
        record, lines = pruning(a.windows)
        head = ["# The compact network's still ceiling and its DoG pruning", "", describe(run.record()), ""]
        save_results("recording_pruning", {"run": run.record(), **record}, head + lines)
        return
    if a.stages:
        record, lines = stages(a.networks, a.windows)
        head = ["# Where the network and the rate model part on still event frames", "", describe(run.record()), ""]
        save_results("recording_stages", {"run": run.record(), "frames": record}, head + lines)
        return
    results, shown = {}, {}
    for name in a.only:
        results[name], shown[name] = measure(name, a.windows, a.networks, a.still_ms, a.count_from_ms)
    head = [
        "# The still-frame ceiling on recordings",
        "",
        describe(run.record()),
        "",
        f"Each window's event frame presented as a still input for {a.still_ms:g} ms, counted over",
        f"{a.count_from_ms:g}-{a.still_ms:g} ms, against the rate model on the same recipe and frame; pixels where",
        "both have a vector (coverage: the share of the rate model's vectors the spiking map has).",
        "",
    ]
    out = "recording_ceiling" if a.still_ms == STILL_MS else f"recording_ceiling_{a.still_ms:g}ms"
    save_results(out, {"run": run.record(), "recordings": results}, head + table(results))
    save_figure(figure(shown), out)


if __name__ == "__main__":
    main()
