"""The fast engine behind the backend interface: :class:`FastBackend`
(its design: :mod:`snn_fg.backends.fast`)."""

from __future__ import annotations

import os
import threading
import time

from ...errors import InputError
from ...lowering.unroll import choose_sites
from ...network.graph import Network
from ..base import Backend, RunSettings, SimulationResult, source_masks
from . import tables as ft
from .results import BinStream, simulation_result
from .run import Pool, Run

#: seconds the engine's first run on a machine spends compiling (numba), as said while it does
#: (the measured first runs: docs/performance.md, Installing and testing)
COMPILE_S = 10
#: seconds between the lines that say the engine's code is still compiling (a first run)
STILL_COMPILING_S = 15.0
#: simulated time per call of the compiled loop (progress, Ctrl-C in between)
CHUNK_MS = 25.0
#: threads a run uses at most (the target populations are dealt out between them, :mod:`.share`)
MAX_THREADS = 2
#: a run on fewer cells than this uses one thread unless told otherwise: the
#: threads meet at every time step, and a small network's step is too short to
#: share. With populations dealt whole (:mod:`.share`) the compact network on
#: dvs.es (0.75 M cells) does no work twice on two threads, but measured on the
#: 2-core machine shared with other jobs (29 Nov, 1-minute load 3.0-3.5) two
#: cores gave 0.81-1.19x one core's engine time, and compact networks on disc
#: frames of 0.37-1.9 M cells 0.60-0.64x: a gain below 1 M cells is not shown
PARALLEL_FROM = 1_000_000
#: how OpenMP's threads (numba's threading layer here) wait for each other, unless the
#: user says otherwise: asleep, not spinning. The threads meet at every time step, and on
#: a machine shared with other work a spinning thread holds the core its partner needs: the
#: compact network on dvs.es on two threads took 6.7-7.3 s spinning against 1.1-2.5 s asleep
#: (1.6-2.4 s on one thread; 29 Nov, 1-minute load 3.0-3.6). Read when OpenMP starts, so set
#: on import, before numba starts its threads
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


class FastBackend(Backend):
    """Event-driven engine over weight-shared kernels (numba).

    Parameters
    ----------
    chunk_ms : float
        Simulated time per call of the compiled loop; between calls the
        progress bar moves and Ctrl-C is honoured.
    weight_bits : int, optional
        Run with every weight as the ``weight_bits``-bit integer times one
        scale per projection that a board holds (as ``snn-fg export
        --weight-bits`` writes them; weights that round to 0 are dropped).
    threads : int, optional
        Threads a run uses (default: the cores this process may use, at
        most :data:`MAX_THREADS`). The spikes do not depend on it.
    """

    name = "fast"
    requires = "numba (a core dependency: reinstall snn-fg)"
    #: every cell, for timed events: the engine needs no per-input preparation
    #: then (choosing the cells a recording's window can use takes seconds of
    #: unrolling in Python, longer than simulating the cells it leaves out), and
    #: no cell that bursts of events can make fire is left out. An event
    #: frame's regular trains get the hinted cells on every backend instead
    #: (:meth:`snn_fg.models.spiking.options.SimulatorOptions.cells_for`)
    default_instantiate = "all"
    #: a recording's input is loaded a segment at a time (:class:`.feed.InputFeed`)
    streams_input = True

    def __init__(self, *, chunk_ms: float = CHUNK_MS, weight_bits: int | None = None, threads: int | None = None):
        from ... import validate as check

        self.chunk_ms = check.number("FastBackend", "chunk_ms", chunk_ms, lo=0, lo_open=True)
        self.weight_bits = (
            None if weight_bits is None else check.integer("FastBackend", "weight_bits", weight_bits, lo=2, hi=32)
        )
        self.threads = None if threads is None else check.integer("FastBackend", "threads", threads, lo=1)
        self._tables: ft.EngineTables | None = None
        self._pool = Pool()

    @classmethod
    def available(cls):
        try:
            import numba  # noqa: F401
        except ImportError:
            return False, "pip install numba"
        return True, ""

    def describe(self) -> dict:
        import numba

        return {
            "name": self.name,
            "engine": "event-driven, weight-shared kernels",
            "numba": numba.__version__,
            "weight_bits": self.weight_bits,
            "threads": self.threads,
        }

    def threads_for_run(self, cells: int) -> int:
        """The threads of a run on ``cells`` cells: :attr:`threads`, else the
        cores this process may use (at most :data:`MAX_THREADS`, and one
        below :data:`PARALLEL_FROM` cells); numba is told so."""
        import numba

        from ..cores import usable_cores

        n = self.threads
        if n is None:
            n = min(usable_cores(), MAX_THREADS) if cells >= PARALLEL_FROM else 1
        n = max(1, min(n, numba.config.NUMBA_NUM_THREADS))
        numba.set_num_threads(n)
        return n

    def tables(self, network: Network, dt_ms: float) -> ft.EngineTables:
        """The engine's arrays for ``network`` at ``dt_ms``, built once and
        kept while the same description is simulated again (or the same
        with other gains: a recording's window, or a frame, calibrated for
        its own input rate)."""
        t = self._tables
        if t is not None and t.network is not network and t.dt_ms == dt_ms and ft.gains_only(t.network, network):
            t = self._tables = t.with_gains(network)  # (e.g. calibrated for the next window's input rate)
        if t is None or t.network is not network or t.dt_ms != dt_ms:
            t = self._tables = ft.build_tables(network, dt_ms, self.weight_bits)
        return t

    def simulate(self, network: Network, inputs, settings: RunSettings) -> SimulationResult:
        from . import core

        compiling = not core.code_is_cached()
        if compiling:
            settings.say(
                f"compiling the fast engine's code as it prepares and simulates: the first run on this "
                f"machine only, about {COMPILE_S} s on an idle machine for an image, up to a minute for a "
                "recording (numba keeps the code beside the package)"
            )
        t0 = time.perf_counter()
        tab = self.tables(network, settings.dt_ms)
        chosen, _, _ = choose_sites(
            network, source_masks(network, inputs.on, inputs.off), settings.sites, settings.instantiate
        )
        n_steps = int(round(settings.duration_ms / settings.dt_ms))
        cells = sum(chosen[p.name].size for p in network.populations)
        check_cells_fit(network, cells)
        run = Run(tab, chosen, inputs, n_steps, self._pool, self.threads_for_run(cells))
        stream = None
        if settings.on_bin is not None and settings.count_bins_ms is not None:
            stream = BinStream(self.name, tab, chosen, run, settings)
        timings = {"build": time.perf_counter() - t0}
        settings.say(
            f"fast engine: {run.n_present:,} cells, {len(network.projections)} weight-shared projections "
            f"(prepared in {timings['build']:.2f} s)"
        )
        t_run, cpu = time.perf_counter(), time.process_time()
        if stream is not None:
            stream.started = (t_run, cpu)
        compiling = still_compiling(settings.say) if compiling else None
        try:
            run.simulate(settings, max(1, int(round(self.chunk_ms / settings.dt_ms))), stream, compiling)
            timings["run"] = time.perf_counter() - t_run
            timings["run_cpu"] = time.process_time() - cpu  # (wall time on a shared machine overstates the work)
            if stream is not None:  # (the caller's reading of the bins, done while the run paused)
                timings["run"] -= stream.seconds
                timings["run_cpu"] -= stream.cpu_seconds
                timings["read_bins"] = stream.seconds
            result = simulation_result(self.name, tab, chosen, run, settings, stream)
            run.release()
        except BaseException:
            self._pool.clear()  # (e.g. interrupted mid-step: the arrays are not at rest)
            raise
        finally:
            if compiling is not None:
                compiling.set()  # (also when the run failed before its first steps were done)
        timings["total"] = time.perf_counter() - t0
        result.timings_s = timings
        return result


def still_compiling(say, every_s: float = STILL_COMPILING_S) -> threading.Event:
    """Say every ``every_s`` seconds how long the engine's code has been compiling, from a thread of
    its own (a first run is otherwise silent for up to a minute), until the event returned is set."""
    done, t0 = threading.Event(), time.perf_counter()

    def beat():
        while not done.wait(every_s):
            say(f"still compiling the fast engine's code ({time.perf_counter() - t0:.0f} s so far)")

    threading.Thread(target=beat, name="snn-fg still compiling", daemon=True).start()
    return done


def check_cells_fit(network: Network, cells: int, available: float | None = None) -> None:
    """An :class:`~snn_fg.errors.InputError` before a run whose cells' state alone (32 bytes a cell,
    :data:`.lif.STATE`; a run's peak is more: 42 bytes a cell for the default network on a 1280 x 720
    sensor, ``docs/performance.md``) is more than the machine has available (``available`` bytes;
    Linux's ``MemAvailable`` if None, no check where that is not known): such a run would swap or be
    ended by the system part way."""
    from ...pynn.memory import short_of  # (the standard library only)
    from .lif import STATE

    need = cells * STATE.itemsize
    have = short_of(need, available)
    if have is None:
        return
    h, w = network.frame_shape
    smaller = "" if network.params.input_pool > 1 else "; --network compact makes about a twentieth of the cells"
    raise InputError(
        f"the network for a {w} x {h} frame",
        f"its {cells:,} cells need at least {need / 1e9:.1f} GB (their state alone), more than the "
        f"{have / 1e9:.1f} GB this machine has available{smaller}",
    )
