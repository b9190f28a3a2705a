"""What a PyNN run of the export costs on NEST, from measurement, and its progress lines.

STANDALONE (standard library only; copied into every PyNN export as
``fg_memory.py``). The figures are measured by
``experiments.bench.export_memory`` (``experiments/results/export_memory.md``):
``run.py`` on NEST 3.10 (PyNN 0.13, one thread) for exports of several sizes,
peak resident memory and wall times against the cells and synapses built.
"""
from __future__ import annotations

import sys
import time

#: peak memory of run.py on NEST: a fixed part (Python, numpy, PyNN, NEST) ...
NEST_BASE_BYTES = 0.14e9
#: ... plus this much per cell or spike source (NEST's node, the cell's spike counter and its share of the
#: recorder, run.py's arrays) ...
NEST_BYTES_PER_CELL = 10_100.0
#: ... plus this much per synapse. Fitted on exports of 24x24 (1 level), 32x24 (2) and 48x36 (3); predicts
#: 64x48 with 3 levels at 6.47 GB (measured 6.47) and with 4 at 6.92 GB (measured 7.16, -3 %)
NEST_BYTES_PER_SYNAPSE = 35.3
#: building: synapses connected per second, one thread: 0.8-2.1 x 10^5 measured at those sizes on a
#: shared 2-core machine at load 15-17 (an idle machine is faster)
NEST_SYNAPSES_PER_S = 1.0e5
_last = [0.0]


def progress(message: str, every_s: float = 5.0):
    """Print ``message`` to stderr, at most once every ``every_s`` seconds."""
    now = time.monotonic()
    if now - _last[0] >= every_s:
        _last[0] = now
        print(f"run.py: {message}", file=sys.stderr, flush=True)


def nest_memory_bytes(cells: int, synapses: int) -> float:
    """Predicted peak memory (bytes) of ``run.py`` on NEST."""
    return NEST_BASE_BYTES + NEST_BYTES_PER_CELL * cells + NEST_BYTES_PER_SYNAPSE * synapses


def available_bytes() -> float | None:
    """Memory the machine has available now (Linux ``MemAvailable``; None elsewhere)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except OSError:
        return None
    return None


def check_memory(meta: dict, memory_gb: float | None = None) -> float:
    """Say what the NEST run of the export ``meta`` (network.json) will take,
    and stop with one line if its memory will not fit (``memory_gb``, else
    what the machine has available). Returns the predicted bytes."""
    cells = sum(p["size"] for p in meta["populations"])
    synapses = sum(pr.get("synapses", 0) for pr in meta["projections"])
    need = nest_memory_bytes(cells, synapses)
    have = memory_gb * 1e9 if memory_gb is not None else available_bytes()
    if have is not None and need > have:
        sys.exit(f"run.py: error: the network ({cells:,} cells, {synapses:,} synapses) needs about "
                 f"{need / 1e9:.1f} GB on NEST, more than the {have / 1e9:.1f} GB "
                 f"{'given (--memory-gb)' if memory_gb is not None else 'available'}: use a smaller export "
                 "(--sensor-size, --levels) or a larger machine")
    print(f"run.py: {cells:,} cells, {synapses:,} synapses: expect about {need / 1e9:.1f} GB and up to "
          f"{synapses / NEST_SYNAPSES_PER_S / 60:.0f} min to build on NEST, one thread (measured figures in "
          "fg_memory.py); simulating takes 1-6 s per simulated ms at those sizes", flush=True)
    return need
