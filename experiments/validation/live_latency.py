"""snn-fg live on dvs.es replayed in real time: every window published, its latency,
and its maps against snn-fg run on the same events.

    python -m experiments.validation.live_latency [--loops 5] [--cases compact-1,compact-2,hop10-1,x4-1,rate-1]

``dvs.es`` is played ``--loops`` times back to back (``snn-fg stream --loop``,
5 s for 5) over UDP into ``snn-fg live --network compact --model spiking``
(pinned with ``taskset`` to one core or two), once the live command says
it is ready. Each case gives the windows published and dropped, the events
received against those sent, the latency (from a window's last event's
arrival to its maps written and published: median, 95th percentile,
worst), the peak memory, and each window's maps against ``snn-fg run`` on
the same events written to a file (windows bit for bit equal, grouping r
and the share of vectors within 45 degrees), and whether the strongest
published peak lies on the plane (the window's filled event region). Writes
``live_latency.{json,md}``.
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import ndimage

from experiments.common import Run, dataset, describe, load, markdown_table, save_results

SNN_FG = [sys.executable, "-m", "snn_fg.cli"]
#: case -> (live options, cores, speed)
CASES = {
    "compact-1": (["--model", "spiking", "--network", "compact"], 1, 1.0),
    "compact-2": (["--model", "spiking", "--network", "compact"], 2, 1.0),
    "hop10-1": (["--model", "spiking", "--network", "compact", "--hop-ms", "10"], 1, 1.0),
    "x4-1": (["--model", "spiking", "--network", "compact"], 1, 4.0),
    "rate-1": (["--model", "rate", "--network", "compact"], 1, 1.0),
}


def _port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def live_case(rec: Path, options, cores: int, speed: float, out: Path, loops: int) -> dict:
    port, pub = _port(), _port()
    inbox = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    inbox.bind(("127.0.0.1", pub))
    inbox.settimeout(0.2)
    cpus = ",".join(str(c) for c in sorted(os.sched_getaffinity(0))[:cores])
    cmd = ["/usr/bin/time", "-f", "peak_rss_kb=%M", "taskset", "-c", cpus, *SNN_FG, "live", f"udp://127.0.0.1:{port}"]
    cmd += ["--out", str(out), "--sensor-size", "320x240", "--no-figures", "--no-progress"]
    cmd += ["--publish", f"udp://127.0.0.1:{pub}", *options]
    live = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for line in live.stdout:
        if "ready" in line:
            break
    time.sleep(1.0)
    load_at_start = load()
    sent = subprocess.run(
        [*SNN_FG, "stream", str(rec), "--to", f"udp://127.0.0.1:{port}", "--speed", str(speed)],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    lines = []
    while live.poll() is None or True:
        try:
            lines.append(json.loads(inbox.recv(1 << 16)))
        except TimeoutError:
            if live.poll() is not None:
                break
    rest, err = live.communicate()
    record = json.loads((out / "live.json").read_text())
    record["peak_rss_mb"] = int(err.split("peak_rss_kb=")[-1].split()[0]) / 1024
    record["load_at_start"] = load_at_start
    record["sent"] = sent.strip()
    record["published"] = lines
    record["stderr"] = [x for x in err.splitlines() if x.startswith("snn-fg")]
    return record


def against_run(live_dir: Path, run_dir: Path, published) -> dict:
    from snn_fg.results.store import read_maps
    from snn_fg.scoring.metrics import angle_difference_deg, pearson

    lx, ly, lg, _, lextra = read_maps(live_dir / "maps.zarr")
    rx, ry, rg, _, rextra = read_maps(run_dir / "maps.zarr")
    by_start = {int(t): k for k, t in enumerate(rextra["t_start_us"])}
    equal, rs, within, on_plane, plane_windows = 0, [], [], 0, 0
    for i, t in enumerate(lextra["t_start_us"]):
        k = by_start.get(int(t))
        if k is None:
            continue
        same = all(np.array_equal(a[i], b[k]) for a, b in ((lx, rx), (ly, ry), (lg, rg)))
        equal += same
        rs.append(pearson(lg[i], rg[k]))
        both = (np.hypot(lx[i], ly[i]) > 0) & (np.hypot(rx[k], ry[k]) > 0)
        d = angle_difference_deg(lx[i], ly[i], rx[k], ry[k])[both]
        within.append(float(np.mean(d <= 45)) if d.size else float("nan"))
        frame = rextra["event_frame"][k] != 0
        plane = ndimage.binary_fill_holes(ndimage.binary_closing(frame, iterations=3))
        peaks = published[i]["peaks"] if i < len(published) else []
        if plane.mean() < 0.5 and plane.any():  # (not the start-up burst)
            plane_windows += 1
            on_plane += bool(peaks) and bool(plane[peaks[0]["y"], peaks[0]["x"]])
    return {
        "windows_compared": len(rs),
        "bit_equal": equal,
        "grouping_r_min": float(np.nanmin(rs)) if rs else None,
        "within_45_min": float(np.nanmin(within)) if within else None,
        "strongest_peak_on_plane": f"{on_plane} of {plane_windows}",
    }


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--loops", type=int, default=5)
    ap.add_argument("--cases", default=",".join(CASES))
    args = ap.parse_args(argv)
    from snn_fg.events import iter_recording, save_events
    from snn_fg.events.replay import looped

    run = Run()
    src = dataset("events", "dvs.es")
    results, rows = {}, []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        rec = tmp / "dvs_looped.npz"
        events = np.concatenate(list(looped(lambda: iter_recording(src), args.loops)))
        save_events(rec, events, (320, 240, 2))
        runs = {}
        for case in args.cases.split(","):
            options, cores, speed = CASES[case]
            print(f"{case}: live ...", flush=True)
            r = live_case(rec, options, cores, speed, tmp / case, args.loops)
            hop = options[options.index("--hop-ms") + 1] if "--hop-ms" in options else None
            key = tuple(o for o in options)
            if key not in runs:
                runs[key] = tmp / f"run-{case}"
                cmd = [*SNN_FG, "run", str(rec), "--out", str(runs[key]), "--no-figures", "--no-progress"]
                cmd += [o for o in options if o != "--hop-ms" and o != hop] + (["--stride-ms", hop] if hop else [])
                subprocess.run(cmd, check=True, capture_output=True)
            r["against_run"] = against_run(tmp / case, runs[key], r.pop("published"))
            results[case] = r
            lat = r["latency_ms"] or {}
            a = r["against_run"]
            rows.append(
                [
                    case,
                    f"{speed:g}x",
                    cores,
                    f"{r['windows']} / {r['windows_dropped']}",
                    f"{r['events_received']:,} / {len(events):,}",
                    f"{lat.get('median', float('nan')):.0f} / {lat.get('p95', float('nan')):.0f} / "
                    f"{lat.get('max', float('nan')):.0f}",
                    f"{a['bit_equal']} of {a['windows_compared']}",
                    f"{a['grouping_r_min']:.3f}" if a["grouping_r_min"] is not None else "",
                    a["strongest_peak_on_plane"],
                    f"{r['peak_rss_mb']:.0f}",
                    f"{r['load_at_start'][0]:.1f}",
                ]
            )
            print(rows[-1], flush=True)
    record = {"loops": args.loops, "events": len(events), "cases": results, "run": run.record()}
    lines = [
        "# snn-fg live on dvs.es replayed over UDP",
        "",
        describe(record["run"]),
        "",
        f"`dvs.es` played {args.loops} times back to back ({len(events):,} events, "
        f"{(events['t'][-1] - events['t'][0]) / 1e6:.1f} s) by `snn-fg stream` into `snn-fg live` (85 ms windows).",
        "",
        *markdown_table(
            [
                "case",
                "speed",
                "cores",
                "windows published / dropped",
                "events received / sent",
                "latency ms (median / p95 / max)",
                "maps equal to snn-fg run",
                "grouping r (min)",
                "strongest peak on the plane",
                "peak RSS MB",
                "load at start",
            ],
            rows,
        ),
    ]
    save_results("live_latency", record, lines)


if __name__ == "__main__":
    main()
