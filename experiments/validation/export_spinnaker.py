"""sPyNNaker's own mapping of the PyNN export on virtual SpiNN-5 boards, beside the resource report's estimate.

For each configuration: ``snn-fg export --format pynn`` into a temporary
folder, then, as a user without a board runs it, ``python run.py --simulator
spinnaker --virtual-board --map-only`` (sPyNNaker 1!7.4.1 partitions, places
and routes; its data generation, hours for tens of millions of explicit
synapses, is skipped), once as sPyNNaker chooses its cores and once with
``--combined-cores`` (each population's synapses on the core that updates its
cells, as the report counts). ``mapping.json`` of each run is kept.

Writes experiments/results/export_spinnaker.{json,md}.
Usage: python -m experiments.validation.export_spinnaker [--configs 64x48:4 compact:159x126 NETWORK.json ...]
       [--no-combined] [--keep]
(--keep: the stored rows of other configurations stay in the results, and the runs that made them
are listed)
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from experiments.bench.export_memory import RUN_CHILD
from experiments.common import RESULTS, Run, describe, load, load_change, markdown_table, save_results
from snn_fg.network.recipes import RECIPES


def export_args(config: str) -> list:
    """``snn-fg export`` arguments of a configuration: WxH:levels (the default
    network), NAME:WxH (a named network, e.g. compact:159x126), or a stored network file."""
    if config.endswith(".json") or config.endswith(".nir"):
        return ["--network", config]
    a, b = config.split(":")
    if a in RECIPES:
        return ["--network", a, "--sensor-size", b]
    return ["--sensor-size", a, "--levels", b]


def one(config: str, combined: bool, tmp: Path) -> dict:
    folder = tmp / (Path(config).stem if "." in config else config.replace(":", "_"))
    if not folder.exists():
        subprocess.run(
            [
                sys.executable,
                "-m",
                "snn_fg.cli",
                "export",
                "--format",
                "pynn",
                "--target",
                "spinnaker",
                "--out",
                str(folder),
            ]
            + export_args(config),
            check=True,
            capture_output=True,
            text=True,
        )
    flags = ["--simulator", "spinnaker", "--virtual-board", "--map-only"] + (["--combined-cores"] if combined else [])
    load0, t0 = load(), time.perf_counter()
    done = subprocess.run([sys.executable, "-c", RUN_CHILD] + flags, cwd=folder, capture_output=True, text=True)
    if done.returncode:
        err = done.stderr.strip().splitlines()
        return {
            "config": config,
            "combined_cores": combined,
            "failed": err[-1] if err else "?",
            "load": load_change(load0),
        }
    m = json.loads((folder / "mapping.json").read_text())
    m["estimate_by_population"] = json.loads((folder / "spinnaker.json").read_text())["estimate"]["cores_by_population"]
    m.update(
        config=config,
        wall_s=time.perf_counter() - t0,
        peak_gb=float(done.stdout.split("MAXRSS")[1]) / 1e9,
        load=load_change(load0),
    )
    print(config, combined, {k: m[k] for k in ("chips_used", "cores_used", "fits", "estimate")}, flush=True)
    return m


def _synapse_cores(m) -> int:
    k = m["cores_by_kind"]
    return k.get("PopulationSynapsesMachineVertexLead", 0) + k.get("PopulationSynapsesMachineVertexShared", 0)


def why(m) -> str:
    """Where sPyNNaker's network cores part from the report's estimate, population by population
    (the three that differ most), and the network cores it placed per used chip (the report counts 15)."""
    if "estimate_by_population" not in m:
        return ""
    est = m["estimate_by_population"]
    extra = {n: c - est.get(n, 0) for n, c in m["cores_by_population"].items() if c != est.get(n, 0)}
    most = sorted(extra.items(), key=lambda kv: (-abs(kv[1]), kv[0]))[:3]
    listed = ", ".join(f"{n} {d:+d}" for n, d in most) or "every population as estimated"
    return (
        f"{m['cores_network'] - m['estimate']['cores']:+d} cores ({listed}); "
        f"{m['cores_network'] / m['chips_used']:.1f} network cores per chip (report: 15)"
    )


def _row(m) -> list:
    cores = "combined" if m["combined_cores"] else "sPyNNaker"
    if "failed" in m:
        return [m["config"], cores, f"failed: {m['failed']}", "", "", "", "", "", "", "", m["load"], ""]
    k, est = m["cores_by_kind"], m["estimate"]
    syn = _synapse_cores(m)
    neu = k.get("PopulationNeuronsMachineVertex", 0) + k.get("PopulationMachineVertex", 0)
    return [
        m["config"],
        cores,
        m["chips_used"],
        f"{m['cores_used']} ({m['cores_network']})",
        f"{est['chips']} / {est['cores']}",
        m["fits"],
        f"{neu} / {syn} / {k.get('PopulationMachineLocalOnlyCombinedVertex', 0)}",
        f"{m['machine_chips']} chips",
        f"{m['sPyNNaker_s']['mapping']:.0f}",
        f"{m['peak_gb']:.1f}",
        m["load"],
        why(m),
    ]


def markdown(rows, runs) -> list[str]:
    """The results page: one line for each run whose rows it holds (``runs``, oldest first)."""
    tool = rows[0]["tool"]["version"] if rows and "tool" in rows[0] else "?"
    head = ["# sPyNNaker's mapping of the PyNN export (virtual SpiNN-5 boards)", ""]
    for run in runs:
        head += [
            f"{describe(run)} sPyNNaker {tool}, `run.py --simulator spinnaker --virtual-board --map-only`; "
            "shared 2-core machine.",
            "",
        ]
    return head + markdown_table(
        [
            "export",
            "cores",
            "chips used",
            "cores used (network)",
            "estimate chips / cores",
            "fits one SpiNN-5",
            "neuron / synapse / local-only cores",
            "machine",
            "map s",
            "peak GB",
            "load",
            "against the estimate",
        ],
        map(_row, rows),
    )


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configs", nargs="+", default=["64x48:4"], help="WxH:levels, NAME:WxH or a stored network file")
    ap.add_argument("--no-combined", action="store_true", help="only sPyNNaker's own choice of cores")
    ap.add_argument("--keep", action="store_true", help="keep the stored rows of other configurations")
    args = ap.parse_args(argv)
    run = Run()
    stored = RESULTS / "export_spinnaker.json"
    old = json.loads(stored.read_text()) if args.keep and stored.exists() else {"rows": []}
    rows = [m for m in old["rows"] if m["config"] not in args.configs]
    earlier = old.get("earlier_runs", []) + ([old["run"]] if "run" in old else [])
    with tempfile.TemporaryDirectory() as tmp:
        for config in args.configs:
            for combined in (False,) if args.no_combined else (False, True):
                rows.append(one(config, combined, Path(tmp)))
    record = {"rows": rows, "run": run.record(), "earlier_runs": earlier}
    save_results("export_spinnaker", record, markdown(rows, [*earlier, record["run"]]))


if __name__ == "__main__":
    main()
