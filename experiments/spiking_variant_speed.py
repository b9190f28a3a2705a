"""The fast engine's time per dvs.es window: the default network against a
variant of it, side by side.

Each round runs one fresh process per network, alternately, on the same
windows (85 ms of ``dvs.es``, each run as a recording of one window: one
continuous network, every event at its own time, the window clock, the
read-out lag). A process warms up on the first window, then times every
window once and reports its synaptic events and spikes, which do not depend
on the machine; the ratio of the medians is the speed cost of the variant.
The default variant is ``spiking_heldout.EARLIER`` (inhibition with 10 ms
in every kind of cell but the untuned cells, the network before 24 Nov 2026).

    python experiments/spiking_variant_speed.py [--variant NAME=JSON] [--windows 0 1 2]
           [--start-ms 100] [--rounds 2]

Prints one line per window and run and the ratio; writes nothing.
``alternate`` is the side-by-side timing itself, which ``spiking_dt.py``
also uses (the same network at several time steps).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "experiments"))


def _worker(js: str, specs: list[str], dt_ms: float):
    """Time each window with the network ``js`` changes (``{}``: the default),
    stepped at ``dt_ms``; one backend object serves every window, as in
    ``snn-fg run`` and the bench."""
    from bench.inputs import load
    from spiking_heldout import _spiking_params

    from snn_fg.backends import as_backend
    from snn_fg.spiking.continuous import run_spiking_windows

    sp = _spiking_params("variant", js)
    backend = as_backend("fast")
    wins = [load(s).window() for s in specs]
    run_spiking_windows(wins[:1], spiking=sp, backend=backend, dt_ms=dt_ms, progress=False)      # warm-up
    for spec, w in zip(specs, wins):
        t = time.perf_counter()
        (maps,) = run_spiking_windows([w], spiking=sp, backend=backend, dt_ms=dt_ms, progress=False)
        st = maps.params.get("backend_stats", {})
        print(json.dumps({"input": spec, "wall_s": time.perf_counter() - t,
                          "synaptic_events": st.get("synaptic_events_total"), "spikes": st.get("spikes"),
                          "closed_form_advances": st.get("closed_form_advances"),
                          "active_cell_steps": st.get("active_cell_steps")}), flush=True)


def alternate(runs, specs: list[str], rounds: int, log=print) -> list[dict]:
    """Time the windows ``specs`` (``dvs:K@START`` strings) under each of
    ``runs`` (``(label, change JSON, dt_ms)``), one fresh process per run and
    round, the runs alternating within each round. Returns one row per window
    timed, with its round, label, dt and the load when its process started."""
    rows = []
    for r in range(rounds):
        for label, js, dt_ms in runs:
            load = os.getloadavg()[0]
            proc = subprocess.run([sys.executable, __file__, "--worker", js, ",".join(specs), str(dt_ms)],
                                  capture_output=True, text=True)
            if proc.returncode:
                sys.exit(f"timing worker ({label}) failed:\n{proc.stderr[-2000:]}")
            for line in proc.stdout.splitlines():
                if line.startswith("{"):
                    row = {"round": r + 1, "label": label, "dt_ms": dt_ms, "load": load, **json.loads(line)}
                    rows.append(row)
                    log(f"round {r + 1}  {label:>16}  {row['input']:<10} {row['wall_s']:.3f} s  "
                        f"{row['synaptic_events']:,} synaptic events  {row['spikes']:,} spikes  (load {load:.2f})")
    return rows


def main():
    from spiking_heldout import EARLIER

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", default=EARLIER, metavar="NAME=JSON")
    ap.add_argument("--windows", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--start-ms", type=float, default=100.0)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--worker", nargs=3, metavar=("JSON", "SPECS", "DT"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        return _worker(args.worker[0], args.worker[1].split(","), float(args.worker[2]))
    name, _, js = args.variant.partition("=")
    specs = [f"dvs:{k}@{args.start_ms:g}" for k in args.windows]
    rows = alternate((("default", "{}", 0.5), (name, js, 0.5)), specs, args.rounds, lambda m: print(m, flush=True))
    a, b = (statistics.median(x["wall_s"] for x in rows if x["label"] == lab) for lab in ("default", name))
    print(f"median per window: default {a:.3f} s, {name} {b:.3f} s; default / {name} = {a / b:.2f}  "
          f"(load at the end {os.getloadavg()[0]:.2f})")


if __name__ == "__main__":
    main()
