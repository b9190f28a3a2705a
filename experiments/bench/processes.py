"""Running the benchmark's measurements: each in its own process (pinned to
given cores if asked), with its exit status, output, peak memory and the
machine's load before and after."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading

from experiments.common import ROOT


def uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def run_process(cmd, timeout_s, cores=None) -> tuple[int, str, float]:
    """Run ``cmd`` (on the CPUs ``cores`` only, if given); return ``(exit
    status, stdout, peak RSS in MB)`` of that process alone."""
    pin = None if cores is None else (lambda: os.sched_setaffinity(0, cores))
    p = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, text=True, preexec_fn=pin)
    timer = threading.Timer(timeout_s, p.kill)
    timer.start()
    try:
        out = p.stdout.read()
        _, status, usage = os.wait4(p.pid, 0)
    finally:
        timer.cancel()
    p.returncode = os.waitstatus_to_exitcode(status)
    return p.returncode, out, usage.ru_maxrss / 1024.0


def measure(spec: dict, timeout_s: float, cores=None):
    """Run one :mod:`experiments.bench.child` task (on the CPUs ``cores`` only, if given); its result
    with load and memory."""
    before = uptime()
    code, out, rss = run_process(
        [sys.executable, "-m", "experiments.bench.child", json.dumps(spec)], timeout_s, cores=cores
    )
    if code != 0:
        return {
            "error": f"exit status {code} (timeout {timeout_s:.0f} s?)",
            "load_before": before,
            "load_after": uptime(),
        }
    return {
        "result": json.loads(out.strip().splitlines()[-1]),
        "peak_rss_mb": rss,
        "load_before": before,
        "load_after": uptime(),
    }
