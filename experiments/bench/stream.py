"""The benchmark's ``stream`` section: ``snn-fg run REC --start-ms 100 --no-figures`` as a user runs
it, per network, model and core count, with the fast engine's cost per synaptic event against the
machine's floor measured in the same run (:mod:`.floor`).

After a warm-up run per network (numba compiles what it has not cached), every configuration runs
in its own process pinned to its cores, in ``--stream-rounds`` rounds that
alternate all of them (this machine's speed moves by a third between runs minutes apart); each round
also measures the floor (pinned to one core), and, on request, the peer (``--peer nest``: the same
network on NEST, ``--peer-windows`` windows, beside the fast engine on the same windows) and a BSDS
image end to end (``--bsds-image ID``). REC is ``dvs.es`` or, with ``--stream-copies K``, ``dvs.es``
played K times in a row (the marginal time per window over a long recording).

Per network the summary gives the synaptic events per window and the CPU time per event
(``whole_run.backend_stats.synaptic_events_total`` and ``whole_run.timings_s.run_cpu`` of the
run's maps) on one core, as a ratio to the in-cache random floor of the same round (the median over
the rounds), and the time per window on two cores against one.
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

from experiments.common import DVS_FROM_MS

from .inputs import WINDOW_MS, dvs_path, dvs_played
from .processes import measure, run_process, uptime

#: bytes of one cell's state in the fast engine (snn_fg.backends.fast.lif.STATE)
CELL_BYTES = 32


def maps_row(maps_path: Path, model: str) -> dict:
    """Per-window times and the engine's counters from a run's maps (its output folder)."""
    from snn_fg.results.maps import Maps

    p = Maps.load(maps_path).params
    per = [p["timings_s"]] + [w.get("timings_s", p["timings_s"]) for w in p.get("windows", [])[1:]]
    key = "window" if model == "spiking" and "window" in per[-1] else "run"
    times = [t.get(key, 0.0) for t in per]
    row = {"windows": len(times), "window_s": times, "median_window_s": statistics.median(times[1:] or times)}
    if model == "spiking":
        whole = p.get("whole_run", p)  # (a recording's store keeps the whole run's apart)
        st, sim = whole.get("backend_stats", {}), whole["timings_s"]
        events = st.get("synaptic_events_total")
        row.update(cells=st.get("cells"), run_s=sim.get("run"), run_cpu_s=sim.get("run_cpu"))
        if events:
            row.update(
                synaptic_events_total=events,
                synaptic_events_per_window=events / len(times),
                ns_per_synaptic_event=1e9 * sim.get("run", 0.0) / events,
                cpu_ns_per_synaptic_event=1e9 * sim.get("run_cpu", 0.0) / events,
            )
    return row


def cli_run(recording, args: list, cores: int, timeout, model: str = "spiking") -> dict:
    """One ``snn-fg run RECORDING --no-figures ARGS`` on ``cores`` cores: its row."""
    with tempfile.TemporaryDirectory() as tmp:
        res = Path(tmp) / "out"
        cmd = [sys.executable, "-c", "from snn_fg.cli import console; console()", "run", str(recording)]
        cmd += ["--model", model, "--no-figures", "--no-progress", "--out", str(res), *args]
        before = uptime()
        t = time.perf_counter()
        code, _, rss = run_process(cmd, timeout, cores=set(range(cores)))
        wall = time.perf_counter() - t
        row = {"cores": cores, "exit_status": code, "wall_s": wall, "peak_rss_mb": rss}
        row.update(load_before=before, load_after=uptime(), args=args)
        if code == 0:
            row.update(maps_row(res, model))
            row["wall_s_per_window"] = wall / row["windows"]
        return row


def _say(name: str, k: int, rounds: int, what: str) -> None:
    print(f"[{name}] round {k + 1} of {rounds}: {what}", file=sys.stderr, flush=True)


def _median_round(rows: list, key: str) -> dict:
    """The row of the round with the median ``key``, with every round's value beside it."""
    good = sorted((r for r in rows if r.get("exit_status", 0) == 0 and key in r), key=lambda r: r[key])
    if not good:
        return rows[0]
    return {
        **good[(len(good) - 1) // 2],
        "rounds": len(rows),
        f"rounds_{key}": [r[key] for r in good],
        "load_first": rows[0].get("load_before"),
        "load_last": rows[-1].get("load_after"),
    }


def section_stream(args, eng):
    """The section (module docstring); returns its entries by name."""
    from .run import engine_name

    configs = [
        (network, model, backend, cores)
        for network in args.networks
        for model, backend in eng
        if not (model == "spiking" and backend != "fast")
        for cores in args.cores
    ]
    with tempfile.TemporaryDirectory() as tmp:
        rec = dvs_path() if args.stream_copies <= 1 else dvs_played(Path(tmp) / "dvs_x.npy", args.stream_copies)
        sensor = [] if args.stream_copies <= 1 else ["--sensor-size", "320x240"]
        common = ["--window-ms", str(WINDOW_MS), "--start-ms", f"{DVS_FROM_MS:g}", *sensor]
        for network in args.networks:  # (compiles what numba has not cached yet: not measured)
            _say(f"warm-up {network}", 0, 1, "snn-fg run ... --max-windows 1")
            cli_run(rec, common + ["--network", network, "--max-windows", "1"], max(args.cores), args.timeout)
        runs: dict = {}
        for k in range(args.stream_rounds):
            for network, model, backend, cores in configs:
                name = f"{engine_name(model, backend)}@{network} {cores} core{'s' if cores > 1 else ''}"
                _say(name, k, args.stream_rounds, f"snn-fg run {Path(rec).name} --start-ms 100 --no-figures")
                extra = ["--network", network] + (["--backend", backend] if backend else [])
                row = cli_run(rec, common + extra, cores, args.timeout, model)
                runs.setdefault(name, []).append({**row, "network": network, "model": model, "round": k})
            cells = {
                r["network"]: r["cells"]
                for rows in runs.values()
                for r in rows[-1:]
                if r.get("cells") and r.get("model") == "spiking"  # (the peer's and a BSDS image's rows name none)
            }
            _say("floor", k, args.stream_rounds, "state[idx[k]] += w[k], one core")
            state_mb = {n: c * CELL_BYTES / 1e6 for n, c in cells.items()}
            runs.setdefault("floor", []).append(
                {**measure({"task": "floor", "state_mb": state_mb}, args.timeout, cores={0}), "round": k}
            )
            for peer in args.peer:
                _peer_round(runs, peer, args, k, common)
            for image in args.bsds_image:
                _bsds_round(runs, image, args, k)
    out = {name: _median_round(rows, "median_window_s") for name, rows in runs.items() if name != "floor"}
    out["floor"] = {
        "rounds": [r.get("result", r) for r in runs["floor"]],
        "load": [r.get("load_before") for r in runs["floor"]],
    }
    out["summary"] = summary(runs, args)
    return out


def _peer_round(runs: dict, peer: str, args, k: int, common: list) -> None:
    """The peer backend and the fast engine on the same first windows of the compact network."""
    windows = ["--max-windows", str(args.peer_windows), "--network", "compact"]
    for backend in (peer, "fast"):
        name = f"peer: spiking/{backend}@compact {args.peer_windows} windows 1 core"
        _say(name, k, args.stream_rounds, f"snn-fg run ... --backend {backend} --max-windows {args.peer_windows}")
        row = cli_run(
            dvs_path(),
            ["--window-ms", str(WINDOW_MS), "--start-ms", f"{DVS_FROM_MS:g}", "--backend", backend, *windows],
            1,
            args.timeout,
        )
        runs.setdefault(name, []).append({**row, "backend": backend, "round": k})


def _bsds_round(runs: dict, image: str, args, k: int) -> None:
    """A BSDS image end to end (``snn-fg run IMAGE.jpg --model spiking``), on 1 and 2 cores."""
    from experiments.common import dataset

    path = dataset("bsds-edfg", "images", f"{image}.jpg")
    for cores in args.cores:
        name = f"bsds {image}: spiking/fast@default {cores} core{'s' if cores > 1 else ''}"
        _say(name, k, args.stream_rounds, f"snn-fg run {path.name} --model spiking --no-figures")
        runs.setdefault(name, []).append({**cli_run(path, [], cores, args.timeout), "round": k})


def summary(runs: dict, args) -> dict:
    """Per network: events per window, CPU ns per event on one core and its ratio to the floor of the
    same round (medians over the rounds), and the time per window on two cores against one."""
    floors = {r["round"]: r.get("result", {}) for r in runs.get("floor", [])}
    out = {}
    for network in args.networks:
        one, two = runs.get(f"spiking/fast@{network} 1 core", []), runs.get(f"spiking/fast@{network} 2 cores", [])
        ok = [r for r in one if r.get("exit_status") == 0 and r.get("cpu_ns_per_synaptic_event")]
        if not ok:
            continue
        ratio = [
            r["cpu_ns_per_synaptic_event"] / floors[r["round"]]["in_cache_random"] for r in ok if floors.get(r["round"])
        ]
        s = {
            "synaptic_events_per_window": statistics.median(r["synaptic_events_per_window"] for r in ok),
            "cpu_ns_per_event_1_core": statistics.median(r["cpu_ns_per_synaptic_event"] for r in ok),
            "floor_in_cache_ns": statistics.median(f["in_cache_random"] for f in floors.values() if f),
            "ratio_to_floor": statistics.median(ratio) if ratio else None,
            "ratio_to_floor_rounds": ratio,
            "median_window_s_1_core": statistics.median(r["median_window_s"] for r in ok),
        }
        pairs = [(a, b) for a in ok for b in two if b.get("exit_status") == 0 and b["round"] == a["round"]]
        if pairs:
            s["median_window_s_2_cores"] = statistics.median(b["median_window_s"] for _, b in pairs)
            s["speedup_2_cores"] = statistics.median(a["median_window_s"] / b["median_window_s"] for a, b in pairs)
            s["speedup_2_cores_rounds"] = [a["median_window_s"] / b["median_window_s"] for a, b in pairs]
        out[network] = s
    for peer in args.peer:
        a = runs.get(f"peer: spiking/{peer}@compact {args.peer_windows} windows 1 core", [])
        b = runs.get(f"peer: spiking/fast@compact {args.peer_windows} windows 1 core", [])
        pairs = [(x, y) for x in a for y in b if x["round"] == y["round"] and x["exit_status"] == y["exit_status"] == 0]
        if pairs:
            out[f"peer_{peer}"] = {
                "windows": args.peer_windows,
                "wall_s_per_window": statistics.median(x["wall_s_per_window"] for x, _ in pairs),
                "fast_wall_s_per_window": statistics.median(y["wall_s_per_window"] for _, y in pairs),
                "ratio": statistics.median(x["wall_s_per_window"] / y["wall_s_per_window"] for x, y in pairs),
            }
    return out
