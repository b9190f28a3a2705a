"""How many cores this process may use: its CPU affinity (``taskset``, a
batch system's cgroup) where the system says, else the machine's count."""

from __future__ import annotations

import os


def usable_cores() -> int:
    """How many cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # (not Linux)
        return os.cpu_count() or 1
