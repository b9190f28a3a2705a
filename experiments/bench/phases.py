"""Where the fast engine's time goes: the processor's cycle counter per phase of a step.

Issue 59 asks the fast engine for a few nanoseconds per synaptic event. This
measures what a step's phases cost, by the work each one does:

* ``active``   - the active cells' update, per active cell-step;
* ``conv``, ``resize`` - spike delivery through Conv and Resize projections
  into the summed input, per synaptic event of the kind;
* ``handover`` - that input added to each cell it reached, the cell brought
  up to the present first, per cell handed input; ``handover_find`` (part
  of it) is finding those cells in the marks;
* ``merge``, ``gather`` - the newly active cells merged into the sorted
  list, and the step's spikes gathered into the log;
* ``other`` - the rest of the run's CPU time (:func:`phase_rows`).

The engine counts them when ``SNN_FG_ENGINE_PHASES=1`` is set before it is
imported (:data:`snn_fg.backends.fast.lif.PHASES`: off, the counting is
compiled away). Each network runs in a process of its own on one core,
``snn-fg run REC --no-figures`` as the bench's ``stream`` section runs it,
with numba's cache in a folder of its own so that the counting code never
replaces the package's cached code; a first run of one window compiles and
is not counted. The counter is ``rdtsc`` (x86-64 only), which ticks at a
constant rate: the ticks are turned into nanoseconds with the rate this
script measures beside a clock. The floor is
:func:`experiments.bench.floor.ns_per_event` in the same run.

    python -m experiments.bench.phases [--networks compact default] [--copies 3] [--default-windows 3]

Writes experiments/results/engine_phases.{json,md,png}.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

from experiments.common import DVS_FROM_MS, Run, describe, fail, markdown_table, save_figure, save_results

#: the phases as the engine names them (snn_fg.backends.fast.deliver.PHASE_NAMES), and the work each is
#: divided by: the run's counter, and what it counts
PER = {
    "active": ("active_cell_steps", "active cell-step"),
    "conv": ("synaptic_events_conv", "synaptic event through a Conv"),
    "resize": ("synaptic_events_resize", "synaptic event through a Resize"),
    "handover": ("cells_handed_input", "cell handed input"),
    "handover_find": ("cells_handed_input", "cell handed input"),
    "merge": ("active_cell_steps", "active cell-step"),
    "gather": ("spikes", "spike"),
}
#: the phases that, with ``handover_find`` inside ``handover``, make up a step
TOP = ("active", "conv", "resize", "handover", "merge", "gather")


def tick_rate(seconds: float = 0.5) -> float:
    """The cycle counter's ticks per second, against ``time.perf_counter``."""
    from numba import njit

    from snn_fg.backends.fast.lif import cycles

    read = njit(lambda: cycles())
    read()
    c0, t0 = read(), time.perf_counter()
    time.sleep(seconds)
    return (read() - c0) / (time.perf_counter() - t0)


def phase_rows(stats: dict, run_cpu_s: float, ticks_per_s: float) -> list[dict]:
    """One row per phase of a run's ``backend_stats`` (with ``cycles_*``): its
    time, its share of the run's CPU time, its work and the time per unit of
    work; then ``other``, the run's CPU time that no phase counted. That is
    mostly a recording's decoding thread, whose CPU time while the engine
    runs beside it is the process's too (on 30 Nov, compact network: 8 % of
    the run outside the step loop, 2.5 % inside it between the phases)."""
    rows, counted = [], 0.0
    for name, (unit, label) in PER.items():
        seconds = stats[f"cycles_{name}"] / ticks_per_s
        work = stats.get(unit) or 0
        if name in TOP:
            counted += seconds
        rows.append(
            {
                "phase": name,
                "seconds": seconds,
                "share": seconds / run_cpu_s,
                "per": label,
                "work": work,
                "ns_per_unit": 1e9 * seconds / work if work else None,
            }
        )
    rows.append({"phase": "other", "seconds": run_cpu_s - counted, "share": 1 - counted / run_cpu_s})
    return rows


def without_delivery(rows: list[dict], events: int) -> float:
    """Nanoseconds a synaptic event of the run's CPU time less the delivery's
    (``conv`` and ``resize``): what the run would cost an event if spikes
    were delivered for nothing."""
    by = {r["phase"]: r["seconds"] for r in rows}
    total = sum(by[p] for p in TOP) + by["other"]
    return 1e9 * (total - by["conv"] - by["resize"]) / events


def at_every_floor(stats: dict, floor: float, visit: float, step: float) -> float:
    """Nanoseconds a synaptic event of an engine that made the run's visits to
    cells (its hand-overs and active cell-steps, which a spike-for-spike exact
    engine cannot leave out) and did nothing else, each at its least cost on
    this machine with the whole state in cache (:func:`.floor.visit_ns`,
    :func:`.floor.step_ns`), and delivered every event at the floor."""
    events = stats["synaptic_events_total"]
    return floor + (stats["cells_handed_input"] * visit + stats["active_cell_steps"] * step) / events


def run_network(rec: Path, network: str, args: list, cache: str, out: Path) -> dict:
    """``snn-fg run`` of ``network`` on one core with the phases counted; its whole run's record."""
    import subprocess

    from snn_fg.results.maps import Maps

    env = {**os.environ, "SNN_FG_ENGINE_PHASES": "1", "NUMBA_CACHE_DIR": cache}
    cmd = [sys.executable, "-c", "from snn_fg.cli import console; console()", "run", str(rec), "--model", "spiking"]
    cmd += ["--network", network, "--no-figures", "--no-progress", "--force", "--out", str(out), *args]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, preexec_fn=lambda: os.sched_setaffinity(0, {0}))
    if proc.returncode:
        err = proc.stderr.strip().splitlines()
        fail(f"snn-fg run --network {network} failed: {err[-1] if err else proc.returncode}")
    params = Maps.load(out).params
    return {**params.get("whole_run", params), "windows": len(params.get("windows", [])) or 1}


def figure(results: dict):
    """Each network's run as stacked shares of its CPU time by phase."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [*(p for p in TOP if p != "handover"), "handover_find", "handover (rest)", "other"]
    labels = {"other": "other (mostly the decoding thread beside the engine)"}
    fig, ax = plt.subplots(figsize=(8, 1.2 + 0.8 * len(results)))
    colours = plt.get_cmap("tab10")(range(len(names)))
    for y, res in enumerate(results.values()):
        share = {r["phase"]: r["share"] for r in res["phases"]}
        share["handover (rest)"] = share["handover"] - share["handover_find"]
        left = 0.0
        for name, colour in zip(names, colours, strict=True):
            ax.barh(y, share[name], left=left, color=colour, label=labels.get(name, name) if y == 0 else None)
            if share[name] > 0.04:
                ax.text(left + share[name] / 2, y, f"{100 * share[name]:.0f}%", ha="center", va="center", fontsize=8)
            left += share[name]
    ax.set_yticks(range(len(results)), [f"{n}\n{r['ms_per_window']:.0f} ms a window" for n, r in results.items()])
    ax.set_xlim(0, 1)
    ax.set_xlabel("share of the run's CPU time (one core)")
    ax.set_title("The fast engine's time by phase of a step (dvs.es)")
    ax.legend(ncol=4, fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.28))
    return fig


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--networks", nargs="+", default=["compact", "default"])
    ap.add_argument("--copies", type=int, default=3, help="dvs.es played this many times in a row (default 3)")
    ap.add_argument(
        "--default-windows", type=int, default=3, help="windows of the default network (default 3; 2 s each)"
    )
    ap.add_argument("--save", default="engine_phases")
    a = ap.parse_args(argv)
    if platform.machine() not in ("x86_64", "AMD64"):
        fail(f"the phases are counted with x86-64's rdtsc; this machine is {platform.machine()}")
    from experiments.bench.floor import IN_CACHE_MB, lazy_visit_ns, ns_per_event, step_ns, visit_ns
    from experiments.bench.inputs import WINDOW_MS, dvs_played
    from experiments.bench.processes import uptime

    run = Run()
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        rec = dvs_played(Path(tmp) / "dvs_x.npy", a.copies)
        common = ["--window-ms", str(WINDOW_MS), "--start-ms", f"{DVS_FROM_MS:g}", "--sensor-size", "320x240"]
        cache = str(Path(tmp) / "numba")
        for network in a.networks:
            print(f"[{network}] compiling the counting code (one window, not counted)", file=sys.stderr, flush=True)
            run_network(rec, network, [*common, "--max-windows", "1"], cache, Path(tmp) / "warm")
            limit = ["--max-windows", str(a.default_windows)] if network == "default" else []
            print(f"[{network}] counting", file=sys.stderr, flush=True)
            before = uptime()
            whole = run_network(rec, network, [*common, *limit], cache, Path(tmp) / network)
            st, cpu = whole["backend_stats"], whole["timings_s"]["run_cpu"]
            results[network] = {
                "windows": whole["windows"],
                "run_cpu_s": cpu,
                "ms_per_window": 1e3 * cpu / whole["windows"],
                "stats": st,
                "load_before": before,
                "load_after": uptime(),
            }
        rate = tick_rate()
        floor = min(ns_per_event(IN_CACHE_MB) for _ in range(2))
        visit, step, lazy = visit_ns(IN_CACHE_MB), step_ns(IN_CACHE_MB), lazy_visit_ns(IN_CACHE_MB)
    for res in results.values():
        res["phases"] = phase_rows(res["stats"], res["run_cpu_s"], rate)
        res["ns_per_synaptic_event"] = 1e9 * res["run_cpu_s"] / res["stats"]["synaptic_events_total"]
        res["ns_at_every_floor"] = at_every_floor(res["stats"], floor, visit, step)
        res["ns_at_every_floor_lazy"] = at_every_floor(res["stats"], floor, lazy, step)
    record = {"run": run.record(), "ticks_per_s": rate, "floor_in_cache_ns": floor, "networks": results}
    record.update(visit_in_cache_ns=visit, active_step_in_cache_ns=step, lazy_visit_in_cache_ns=lazy)
    lines = ["# The fast engine's time by phase of a step", "", describe(record["run"]), ""]
    lines += [
        f"The cycle counter ticked {rate / 1e9:.3f} G a second; the in-cache floor (random targets in "
        f"{IN_CACHE_MB} MB, `experiments.bench.floor`) was {floor:.2f} ns a synaptic event. In the same "
        f"{IN_CACHE_MB} MB, the least a hand-over's arithmetic costs was {visit:.2f} ns a cell and an active "
        f"cell's step {step:.2f} ns (`floor.visit_ns`, `floor.step_ns`); a visit that only adds input to a "
        f"parked cell's bound and pending sums, {lazy:.2f} ns (`floor.lazy_visit_ns`).",
        "",
    ]
    for network, res in results.items():
        st = res["stats"]
        lines += [
            f"## {network}: {res['windows']} windows of `dvs.es` played {a.copies} times, one core",
            "",
            f"{res['ms_per_window']:.1f} ms of CPU a window; {st['synaptic_events_total']:,} synaptic events, "
            f"{st['cells_handed_input']:,} cells handed input, {st['active_cell_steps']:,} active cell-steps, "
            f"{st['spikes']:,} spikes: {res['ns_per_synaptic_event']:.2f} ns a synaptic event, "
            f"{res['ns_per_synaptic_event'] / floor:.1f}x the floor. Load {res['load_before'].split('average:')[-1]} "
            f"before, {res['load_after'].split('average:')[-1]} after.",
            "",
        ]
        rows = [
            [
                r["phase"],
                f"{1e3 * r['seconds'] / res['windows']:.1f}",
                f"{100 * r['share']:.0f} %",
                f"{r['ns_per_unit']:.2f} ns per {r['per']}" if r.get("ns_per_unit") else "",
            ]
            for r in res["phases"]
        ]
        lines += markdown_table(["phase", "ms a window", "share of CPU", "per unit of work"], rows) + [""]
        rest = without_delivery(res["phases"], st["synaptic_events_total"])
        lines += [
            f"Delivered for nothing, a synaptic event would still cost {rest:.2f} ns, {rest / floor:.1f}x the "
            f"floor: {st['cells_handed_input'] / st['synaptic_events_total']:.2f} cells are handed input and "
            f"{st['active_cell_steps'] / st['synaptic_events_total']:.2f} active cell-steps are made per event.",
            "",
            f"An engine that made those visits at their least cost, with its whole state in cache, and delivered "
            f"every event at the floor would take {res['ns_at_every_floor']:.2f} ns a synaptic event, "
            f"{res['ns_at_every_floor'] / floor:.1f}x the floor. With every hand-over at the cost of a visit that "
            f"only adds to a bound (fewer full visits; a floor no engine reaches, since the cells that might fire "
            f"are still brought up to the present): {res['ns_at_every_floor_lazy']:.2f} ns, "
            f"{res['ns_at_every_floor_lazy'] / floor:.1f}x.",
            "",
        ]
    save_results(a.save, record, lines)
    save_figure(figure(results), a.save)


if __name__ == "__main__":
    main()
