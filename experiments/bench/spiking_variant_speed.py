"""The fast engine's time per dvs.es window: the default network against
variants of it, side by side.

Each round runs one fresh process per network, alternately, on the same
windows (85 ms of ``dvs.es``, each run as a recording of one window: one
continuous network, each event a spike in its time step (the default
network's ``events`` input coding: docs/spiking-network.md, "How events
become input spikes"), the window clock, the read-out lag). A process warms
up on the first window, then times every window once and reports its
synaptic events, spikes and cell updates, which do not depend on the
machine; the ratio of the medians is the speed cost of a variant. A
variant is ``NAME=JSON`` (``SpikingParams`` to change, stored form) or
``NAME@DT=JSON`` to step it at ``DT`` ms instead of 0.5 ms; ``--variant``
repeats. Without one, the variant is ``experiments.validation.spiking_heldout.EARLIER``
(inhibition with 10 ms in every kind of cell but the untuned cells, the
network before 24 Nov 2026).

    python -m experiments.bench.spiking_variant_speed [--variant NAME[@DT]=JSON ...] [--windows 0 1 2]
           [--start-ms 100] [--rounds 2] [--save NAME]

Prints one line per window and run and each variant's ratio to the default.
``--save NAME`` also writes experiments/results/NAME.{json,md}: every
timed window, and per run its median, its ratio to the default and the
first window's counters. The stored ``spiking_frontier`` comes from::

    python -m experiments.bench.spiking_variant_speed --rounds 3 --save spiking_frontier \
        --variant 'dt1@1={}' \
        --variant 'prune20/10={"prune_vm": 0.2, "prune_dog": 0.1}' \
        --variant 'dt1+prune20/10@1={"prune_vm": 0.2, "prune_dog": 0.1}' \
        --variant 'dt1+prune30/20@1={"prune_vm": 0.3, "prune_dog": 0.2}'

``alternate`` is the side-by-side timing itself, which
``experiments.validation.spiking_dt`` also uses (the same network at several time steps).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time

from experiments.common import DVS_FROM_MS, ROOT, Run, describe, fail, load, markdown_table, save_json, save_markdown
from experiments.validation.spiking_heldout import EARLIER, variant_params


def _worker(js: str, specs: list[str], dt_ms: float):
    """Time each window with the network ``js`` changes (``{}``: the default),
    stepped at ``dt_ms``; one backend object serves every window, as in
    ``snn-fg run`` and the bench."""
    from experiments.bench import inputs
    from snn_fg.backends import as_backend
    from snn_fg.models.spiking.continuous import run_spiking_windows

    sp = variant_params("variant", js)
    backend = as_backend("fast")
    wins = [inputs.load(s).window() for s in specs]
    run_spiking_windows(wins[:1], spiking=sp, backend=backend, dt_ms=dt_ms, progress=False)  # warm-up
    for spec, w in zip(specs, wins):
        t = time.perf_counter()
        (maps,) = run_spiking_windows([w], spiking=sp, backend=backend, dt_ms=dt_ms, progress=False)
        st = maps.params.get("backend_stats", {})
        print(
            json.dumps(
                {
                    "input": spec,
                    "wall_s": time.perf_counter() - t,
                    "synaptic_events": st.get("synaptic_events_total"),
                    "spikes": st.get("spikes"),
                    "closed_form_advances": st.get("closed_form_advances"),
                    "active_cell_steps": st.get("active_cell_steps"),
                }
            ),
            flush=True,
        )


def alternate(runs, specs: list[str], rounds: int, log=print, worker: str = __spec__.name, pin=()) -> list[dict]:
    """Time the windows ``specs`` (``dvs:K@START`` strings) under each of
    ``runs`` (``(label, change JSON, dt_ms)``), one fresh process per run and
    round, the runs alternating within each round. Returns one row per window
    timed, with its round, label, dt and the load when its process started.
    ``worker``: the module whose ``--worker JSON SPECS DT`` prints the rows
    (this one's: :func:`_worker`); ``pin``: a command it runs under
    (``("taskset", "-c", "0")``: one core)."""
    rows = []
    for r in range(rounds):
        for label, js, dt_ms in runs:
            now = load()[0]
            proc = subprocess.run(
                [*pin, sys.executable, "-m", worker, "--worker", js, ",".join(specs), str(dt_ms)],
                capture_output=True,
                text=True,
                cwd=ROOT,
            )
            if proc.returncode:
                err = proc.stderr.strip().splitlines()
                fail(f"timing worker ({label}) failed: {err[-1] if err else '?'}")
            for line in proc.stdout.splitlines():
                if line.startswith("{"):
                    row = {"round": r + 1, "label": label, "dt_ms": dt_ms, "load": now, **json.loads(line)}
                    rows.append(row)
                    log(
                        f"round {r + 1}  {label:>16}  {row['input']:<10} {row['wall_s']:.3f} s  "
                        f"{row['synaptic_events']:,} synaptic events  {row['spikes']:,} spikes  (load {now:.2f})"
                    )
    return rows


def _variant(text: str):
    """``(label, change JSON, dt_ms)`` of a ``NAME[@DT]=JSON`` argument."""
    name, eq, js = text.partition("=")
    label, at, dt = name.partition("@")
    if not eq or not label:
        fail(f"--variant {text!r}: expected NAME=JSON or NAME@DT=JSON")
    try:
        json.loads(js)
        dt_ms = float(dt) if at else 0.5
    except ValueError as e:
        fail(f"--variant {text!r}: {e}")
    return label, js, dt_ms


def _markdown(rec) -> list[str]:
    def row(v):
        c = v["first_window"]
        return [
            v["label"],
            f"{v['dt_ms']:g}",
            f"`{v['changes']}`",
            f"{v['median_s']:.3f}",
            f"{v['relative']:.2f}",
            f"{c['synaptic_events']:,}",
            f"{c['closed_form_advances']:,}",
            f"{c['active_cell_steps']:,}",
            f"{c['spikes']:,}",
        ]

    return (
        [
            "# The fast engine's time per dvs.es window: variants side by side",
            "",
            f"{describe(rec['run'])} Windows {', '.join(map(str, rec['windows']))} from {rec['start_ms']:g} ms, "
            f"{rec['rounds']} rounds of fresh processes alternating between the runs (load "
            f"{rec['load'][0]:.2f}-{rec['load'][1]:.2f} as each started). The counters are those of the first "
            "window; they do not depend on the machine.",
            "",
        ]
        + markdown_table(
            [
                "run",
                "dt (ms)",
                "changes",
                "median s per window",
                "relative to default",
                "synaptic events",
                "closed-form catch-ups",
                "active cell-steps",
                "spikes",
            ],
            map(row, rec["variants"]),
        )
        + [""]
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", action="append", default=None, metavar="NAME[@DT]=JSON")
    ap.add_argument("--windows", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--start-ms", type=float, default=DVS_FROM_MS)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--save", metavar="NAME", help="also write experiments/results/NAME.{json,md}")
    ap.add_argument("--worker", nargs=3, metavar=("JSON", "SPECS", "DT"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        return _worker(args.worker[0], args.worker[1].split(","), float(args.worker[2]))
    runs = [("default", "{}", 0.5)] + [_variant(v) for v in args.variant or [EARLIER]]
    if len({label for label, _, _ in runs}) < len(runs):
        fail("--variant: every run needs its own name (and 'default' is taken)")
    specs = [f"dvs:{k}@{args.start_ms:g}" for k in args.windows]
    run = Run()
    rows = alternate(runs, specs, args.rounds, lambda m: print(m, flush=True))
    med = {lab: statistics.median(x["wall_s"] for x in rows if x["label"] == lab) for lab, _, _ in runs}
    for lab, _, _ in runs[1:]:
        print(
            f"median per window: default {med['default']:.3f} s, {lab} {med[lab]:.3f} s; "
            f"{lab} / default = {med[lab] / med['default']:.2f}"
        )
    span = [min([run.load_before[0]] + [x["load"] for x in rows]), max([load()[0]] + [x["load"] for x in rows])]
    print(f"load {span[0]:.2f}-{span[1]:.2f}")
    if args.save:
        first = {lab: next(x for x in rows if x["label"] == lab and x["input"] == specs[0]) for lab, _, _ in runs}
        keys = ("synaptic_events", "closed_form_advances", "active_cell_steps", "spikes")
        rec = {
            "windows": args.windows,
            "start_ms": args.start_ms,
            "rounds": args.rounds,
            "load": span,
            "rows": rows,
            "variants": [
                {
                    "label": lab,
                    "changes": js,
                    "dt_ms": dt,
                    "median_s": med[lab],
                    "relative": med[lab] / med["default"],
                    "first_window": {k: first[lab][k] for k in keys},
                }
                for lab, js, dt in runs
            ],
            "run": run.record(),
        }
        save_json(args.save, rec)
        save_markdown(args.save, _markdown(rec))
        print(f"wrote experiments/results/{args.save}.json and .md")


if __name__ == "__main__":
    main()
