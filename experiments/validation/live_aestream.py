"""aestream sending an AEDAT4 file over UDP into snn-fg live: events received against
events sent, and the maps against snn-fg run on the same file.

    python -m experiments.validation.live_aestream [--ms 300] [--start-ms 100]

``dvs.es`` from ``--start-ms``, ``--ms`` long, is written as AEDAT4 with dv-processing's
``MonoCameraWriter``; ``snn-fg live udp://... --network compact --model spiking
--max-behind 1000`` (one core) binds and warms up, then ``aestream input file F.aedat4
output udp HOST PORT --include-timestamp true`` (the other core) sends the file, as fast
as it reads it: aestream does not pace its packets by their timestamps (``snn-fg stream``
does), so ``--max-behind`` keeps every window, late. The live run's counts (events
received, malformed packets, events outside the sensor and back in time) are set against
the events in the file and aestream's own count ("Sent a total of N events"), and each
window's maps against ``snn-fg run`` on the file (bit for bit where the same events came).
Needs the live extra (``pip install -e '.[live]'``: dv-processing, aestream). Writes
``live_aestream.{json,md}``.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from experiments.common import DVS_FROM_MS, Run, dataset, describe, fail, load, markdown_table, save_results

SNN_FG = [sys.executable, "-m", "snn_fg.cli"]


def aestream_command() -> str | None:
    """aestream's command line tool: beside this Python (a virtual environment's), else on the PATH."""
    beside = Path(sys.executable).with_name("aestream")
    return str(beside) if beside.exists() else shutil.which("aestream")


def write_aedat4(path: Path, events, sensor_size) -> None:
    """``events`` as an AEDAT4 file of events only (dv-processing's writer)."""
    import dv_processing as dv

    store = dv.EventStore()
    for t, x, y, p in zip(*(events[k].tolist() for k in ("t", "x", "y", "p")), strict=True):
        store.push_back(int(t), int(x), int(y), bool(p))
    writer = dv.io.MonoCameraWriter(str(path), dv.io.MonoCameraWriter.EventOnlyConfig("snn-fg", sensor_size))
    writer.writeEvents(store)
    del writer  # (the file is complete once the writer is gone)


def _port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def live_from_aestream(aestream: str, aedat4: Path, out: Path, size) -> dict:
    """snn-fg live on one core, aestream on the other (the same core where there is one)."""
    cpus = sorted(os.sched_getaffinity(0))
    mine, theirs = str(cpus[0]), str(cpus[-1])
    url = f"udp://127.0.0.1:{_port()}"
    cmd = ["taskset", "-c", mine, *SNN_FG, "live", url, "--out", str(out), "--sensor-size", f"{size[0]}x{size[1]}"]
    cmd += ["--model", "spiking", "--network", "compact", "--max-behind", "1000", "--no-figures", "--no-progress"]
    live = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for line in live.stdout:
        if "ready" in line:
            break
    time.sleep(1.0)
    host, port = url.removeprefix("udp://").split(":")
    send = ["taskset", "-c", theirs, aestream, "input", "file", str(aedat4), "output", "udp", host, port]
    said = subprocess.run([*send, "--include-timestamp", "true"], capture_output=True, text=True, check=True).stdout
    _, err = live.communicate(timeout=120)
    if live.returncode:
        fail(f"snn-fg live ended with {live.returncode}: {err.strip()}")
    counted = re.search(r"Sent a total of (\d+) events", said)
    record = json.loads((out / "live.json").read_text())
    record["aestream_sent"] = int(counted.group(1)) if counted else None
    record["stderr"] = [x for x in err.splitlines() if x.startswith("snn-fg")]
    return record


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ms", type=float, default=300.0, help="how much of dvs.es (ms, 300)")
    ap.add_argument("--start-ms", type=float, default=DVS_FROM_MS, help=f"from where in dvs.es (ms, {DVS_FROM_MS:g})")
    args = ap.parse_args(argv)
    aestream = aestream_command()
    if aestream is None:
        fail("no aestream command here: pip install -e '.[live]'")
    from snn_fg.events.replay import recording_from_ms
    from snn_fg.results.store import read_maps

    run = Run()
    events = np.concatenate(list(recording_from_ms(dataset("events", "dvs.es"), args.start_ms)))
    events = events[events["t"] < events["t"][0] + args.ms * 1000]
    size = (320, 240)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        clip = tmp / "clip.aedat4"
        write_aedat4(clip, events, size)
        load_at_start = load()
        live = live_from_aestream(aestream, clip, tmp / "live", size)
        options = ["--model", "spiking", "--network", "compact", "--no-figures", "--no-progress"]
        cmd = [*SNN_FG, "run", str(clip), "--out", str(tmp / "run"), *options]
        subprocess.run(cmd, check=True, capture_output=True)
        a, b = read_maps(tmp / "live" / "maps.zarr"), read_maps(tmp / "run" / "maps.zarr")
        equal = [all(np.array_equal(x[k], y[k]) for x, y in zip(a[:3], b[:3], strict=True)) for k in range(len(a[0]))]
    keys = ("windows", "windows_dropped", "events_received", "packets_malformed", "events_outside", "events_backwards")
    record = {
        "events_in_file": len(events),
        "aestream_sent": live["aestream_sent"],
        **{k: live[k] for k in keys},
        "windows_run": len(b[0]),
        "windows_equal_to_run": int(sum(equal)),
        "latency_ms": live["latency_ms"],
        "load_at_start": load_at_start,
        "stderr": live["stderr"],
        "run": run.record(),
    }
    row = [
        f"{len(events):,}",
        f"{live['aestream_sent']:,}" if live["aestream_sent"] is not None else "-",
        f"{live['events_received']:,}",
        live["packets_malformed"],
        f"{live['events_outside']} / {live['events_backwards']}",
        f"{live['windows']} / {live['windows_dropped']}",
        f"{sum(equal)} of {len(b[0])}",
        " / ".join(f"{live['latency_ms'][k]:.0f}" for k in ("median", "p95", "max")),
        " / ".join(f"{x:.1f}" for x in load_at_start),
    ]
    lines = [
        "# aestream sending an AEDAT4 file over UDP into snn-fg live",
        "",
        describe(record["run"]),
        "",
        f"`dvs.es` from {args.start_ms:g} ms, {args.ms:g} ms of it, written as AEDAT4 and sent by `aestream ... "
        "output udp HOST PORT --include-timestamp true` (as fast as it reads it) into `snn-fg live udp://... "
        "--network compact --model spiking --max-behind 1000` on one core; its maps against `snn-fg run` on the file.",
        "",
        *markdown_table(
            [
                "events in the file",
                "aestream's count sent",
                "events received",
                "malformed packets",
                "outside the sensor / back in time (dropped)",
                "windows published / dropped",
                "windows equal to snn-fg run",
                "latency ms (median / p95 / max)",
                "load at start",
            ],
            [row],
        ),
    ]
    save_results("live_aestream", record, lines)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
