"""What a PyNN run of the export costs on NEST, from measurement, and its progress lines.

STANDALONE (standard library only; copied into every PyNN export as
``fg_memory.py``). The figures are measured by
``experiments.bench.export_memory`` (``experiments/results/export_memory.md``):
``run.py`` on NEST 3.10 (PyNN 0.13, one thread) for exports of several sizes,
peak resident memory against the cells and synapses built, and the time to
build and to simulate against the synapses.
"""

from __future__ import annotations

import sys
import time

#: peak memory of run.py on NEST: a fixed part (Python, numpy, PyNN, NEST) ...
NEST_BASE_BYTES = 0.144e9
#: ... plus this much per cell or spike source (NEST's node, the cell's spike counter and its share of the
#: recorder, run.py's arrays) ...
NEST_BYTES_PER_CELL = 9_640.0
#: ... plus this much per synapse (the fit, and how well it predicts larger exports: snn-fg's
#: docs/performance.md, "NEST")
NEST_BYTES_PER_SYNAPSE = 41.7
#: building: synapses connected per second, one thread ...
NEST_SYNAPSES_PER_S = 1.2e6
#: ... and simulating: seconds per simulated ms per synapse, one thread, at the input rate the export's
#: gains are set for (a run's spike deliveries grow with its synapses at given rates)
NEST_S_PER_MS_PER_SYNAPSE = 2.0e-8
#: where and when the two time figures were measured (a busier machine is slower)
TIMES_MEASURED = "on a shared 2-core machine on 27 Nov 2026 at load 0.6-0.9"
_last = [0.0]


def progress(message: str, every_s: float = 5.0, last: bool = False):
    """Print ``message`` to stderr, at most once every ``every_s`` seconds; the ``last`` one always."""
    now = time.monotonic()
    if last or now - _last[0] >= every_s:
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


def short_of(need: float, available: float | None = None) -> float | None:
    """The bytes available (``available``, else :func:`available_bytes`) when ``need`` bytes are
    more than that; None when they fit, or when what is available is not known."""
    have = available_bytes() if available is None else available
    return None if have is None or need <= have else have


def duration_text(seconds: float) -> str:
    """``seconds`` in words a person reads at a glance: s below 2 min, min below 2 h, else h."""
    if seconds < 120:
        return f"{seconds:.2g} s" if seconds < 10 else f"{seconds:.0f} s"
    return f"{seconds / 60:.0f} min" if seconds < 7200 else f"{seconds / 3600:.1f} h"


def check_memory(meta: dict, memory_gb: float | None = None, duration_ms: float = 400.0) -> float:
    """Say what the NEST run of ``duration_ms`` of the export ``meta``
    (network.json) will take, and stop with one line if its memory will not
    fit (``memory_gb``, else what the machine has available). Returns the
    predicted bytes."""
    cells = sum(p["size"] for p in meta["populations"])
    synapses = sum(pr.get("synapses", 0) for pr in meta["projections"])
    need = nest_memory_bytes(cells, synapses)
    have = short_of(need, None if memory_gb is None else memory_gb * 1e9)
    if have is not None:
        sys.exit(
            f"run.py: error: the network ({cells:,} cells, {synapses:,} synapses) needs about "
            f"{need / 1e9:.1f} GB on NEST, more than the {have / 1e9:.1f} GB "
            f"{'given (--memory-gb)' if memory_gb is not None else 'available'}: use a smaller export "
            "(--sensor-size, --levels) or a larger machine"
        )
    per_ms = synapses * NEST_S_PER_MS_PER_SYNAPSE
    print(
        f"run.py: {cells:,} cells, {synapses:,} synapses: expect about {need / 1e9:.1f} GB on NEST, "
        f"{duration_text(synapses / NEST_SYNAPSES_PER_S)} to build and {per_ms:.2g} s per simulated ms "
        f"({duration_text(per_ms * duration_ms)} for {duration_ms:g} ms) on one thread, as measured "
        f"{TIMES_MEASURED} (fg_memory.py)",
        flush=True,
    )
    return need
