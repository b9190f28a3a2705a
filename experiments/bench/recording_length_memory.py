"""Peak memory and output size of ``snn-fg run`` over recordings of 1 window to 60 s, both models.

A recording's run keeps a few windows in memory (the spiking model reads
the recording twice, its input calibrated on the first pass, then fed to
the engine a segment at a time) and writes each window to ``maps.zarr`` as
it completes, so peak memory should not grow with the recording. This
plays ``dvs.es`` (1 s, 320 x 240) again and again with shifted timestamps
into ``.npy`` recordings of ``--seconds`` (10 and 60), and runs ``snn-fg run
REC --no-figures`` on the first window of the longest and on each whole
recording: the rate model, and the spiking model with each of
``--networks`` (default, compact). Each run is a fresh process (peak
resident memory: the child's ``VmHWM`` from /proc, Linux), with the load.

    python -m experiments.bench.recording_length_memory [--seconds 10 60] [--networks default compact]
        [--cases rate:default:1w spiking:compact:60s ...]

``--cases`` runs only those (model:network:length, length ``1w`` or ``Ns``)
and keeps the other cases already in the results (long runs can go apart;
each case records its commit).
Writes experiments/results/recording_length_memory.{json,md} after every case.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from experiments.bench.inputs import dvs_played
from experiments.common import (
    RESULTS,
    ROOT,
    Run,
    describe,
    fail,
    git_commit,
    load,
    markdown_table,
    peak_rss_mb,
    save_json,
    save_markdown,
)

NAME = "recording_length_memory"
#: the sensor of dvs.es (and of the recordings made of it, .npy arrays that do not say)
SENSOR = "320x240"


def _child(argv: list[str]) -> dict:
    """``snn-fg run`` with ``argv`` in this process: windows, time, peak memory, output size."""
    from snn_fg.cli import main as cli
    from snn_fg.results.store import windows_complete

    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        rc = cli(["run", *argv, "--out", out, "--no-progress", "--no-figures"])
        wall = time.perf_counter() - t0
        n = windows_complete(out)
        store_kb = sum(p.stat().st_size for p in (Path(out) / "maps.zarr").rglob("*") if p.is_file()) / 1024
    return {
        "exit_code": rc,
        "windows": n,
        "wall_s": round(wall, 1),
        "store_kb_per_window": round(store_kb / n, 1),
        "peak_rss_mb": peak_rss_mb(),
    }


def _cases(a) -> list[tuple[str, str, str]]:
    """``(model, network, length)`` of every case asked for, in the order they run."""
    if a.cases:
        out = [tuple(c.split(":")) for c in a.cases]
        if any(len(c) != 3 for c in out):
            fail("--cases: each is model:network:length, e.g. spiking:compact:60s")
        return out
    lengths = ["1w"] + [f"{s}s" for s in a.seconds]
    return [("rate", "default", n) for n in lengths] + [("spiking", net, n) for net in a.networks for n in lengths]


def _markdown(rec) -> list[str]:
    lines = [
        "# Peak memory and output size over recordings of 1 window to 60 s",
        "",
        describe(rec["run"]),
        "",
        "`dvs.es` (320 x 240, 1 s, 473,225 events) played again and again with shifted timestamps into "
        "`.npy` recordings; `snn-fg run REC --model M [--network N] --no-figures`, 85 ms windows, each run "
        "a fresh process; `1w` is the first window of the longest recording (`--max-windows 1`). Peak "
        "memory is the process's `VmHWM`; output is `maps.zarr` per window. Rows may come from separate `--cases` "
        "runs (the line above names the last): each gives its start and commit.",
        "",
    ]
    rows = [
        [
            c["model"],
            c["network"],
            c["length"],
            c["windows"],
            f"{c['peak_rss_mb']:.0f}",
            f"{c['peak_rss_mb'] / c['one_window_mb']:.3f}" if c.get("one_window_mb") else "",
            f"{c['store_kb_per_window']:.0f}",
            f"{c['wall_s']:.0f}",
            f"{c['load']:.1f}",
            c["date"],
            c.get("commit", ""),
        ]
        for c in rec["cases"]
    ]
    lines += markdown_table(
        [
            "model",
            "network",
            "length",
            "windows",
            "peak memory (MB)",
            "/ 1 window",
            "maps.zarr per window (kB)",
            "time (s)",
            "load before",
            "started (UTC)",
            "commit",
        ],
        rows,
    )
    return lines + [""]


def _with_ratios(cases: list[dict]) -> list[dict]:
    """Each case with its model and network's 1-window peak (``one_window_mb``), where measured."""
    one = {(c["model"], c["network"]): c["peak_rss_mb"] for c in cases if c["length"] == "1w"}
    order = {"1w": 0}
    return sorted(
        [{**c, "one_window_mb": one.get((c["model"], c["network"]))} for c in cases],
        key=lambda c: (c["model"], c["network"], order.get(c["length"], int(c["length"][:-1]))),
    )


def _kept(cases) -> list[dict]:
    """The cases in the results file other than ``cases`` (read anew: another run may have added some)."""
    path = RESULTS / f"{NAME}.json"
    if not path.exists():
        return []
    run = {tuple(c) for c in cases}
    return [
        c
        for c in json.loads(path.read_text()).get("cases", [])
        if "length" in c and (c["model"], c["network"], c["length"]) not in run
    ]  # (older results: none)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=int, nargs="*", default=[10, 60])
    ap.add_argument("--networks", nargs="*", default=["default", "compact"])
    ap.add_argument("--cases", nargs="*", help="model:network:length to run, keeping the other results")
    ap.add_argument("--child", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child is not None:
        print(json.dumps(_child(a.child)))
        return
    run, cases = Run(), _cases(a)
    seconds = sorted({int(n[:-1]) for _, _, n in cases if n != "1w"} or {10})
    with tempfile.TemporaryDirectory() as d:
        paths, size = {}, None
        for s in seconds:
            paths[s] = Path(d) / f"dvs_{s}s.npy"
            dvs_played(paths[s], s)
            size = SENSOR
        measured = []
        for model, network, length in cases:
            rec = paths[max(seconds)] if length == "1w" else paths[int(length[:-1])]
            argv = [str(rec), "--model", model, "--sensor-size", size]
            argv += ["--max-windows", "1"] if length == "1w" else []
            argv += ["--network", network] if model == "spiking" and network != "default" else []
            before, date = load()[0], time.strftime("%H:%M", time.gmtime())
            p = subprocess.run(
                [sys.executable, "-m", __spec__.name, "--child", *argv], capture_output=True, text=True, cwd=ROOT
            )
            if p.returncode:
                fail(f"{model} {network} {length}: {p.stderr.strip().splitlines()[-1] if p.stderr.strip() else '?'}")
            case = {
                "model": model,
                "network": network,
                "length": length,
                "load": before,
                "date": date,
                "commit": git_commit(),
                **json.loads(p.stdout.strip().splitlines()[-1]),
            }
            measured.append(case)
            print(
                f"{model:<8} {network:<8} {length:>4} {case['windows']:4d} windows  {case['peak_rss_mb']:7.0f} MB "
                f"peak  {case['wall_s']:7.1f} s  {case['store_kb_per_window']:6.0f} kB/window  (load {before:.2f})",
                flush=True,
            )
            record = {"cases": _with_ratios((_kept(cases) if a.cases else []) + measured), "run": run.record()}
            save_json(NAME, record)
            save_markdown(NAME, _markdown(record))
    print("\n".join(_markdown(record)))


if __name__ == "__main__":
    main()
