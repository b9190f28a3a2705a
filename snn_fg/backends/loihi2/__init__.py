"""The Loihi 2 backend: any network run in the integer arithmetic Lava's
fixed point computes Loihi 2's with, as the chip would run it.

``snn-fg run INPUT --model spiking --backend loihi2`` lowers the network to
Loihi 2's registers and 8-bit weights exactly as ``snn-fg export --format
lava`` does (:mod:`snn_fg.lowering.loihi2`, :mod:`snn_fg.lowering.kernel_tables`,
:mod:`snn_fg.lava.synapses`) and steps it in the arithmetic of
:mod:`snn_fg.lava.fixed`, in the order of the export's numpy reference
(:func:`snn_fg.lava.reference.simulate`, which gives Lava 0.10's
``fixed_pt`` count in every cell): 24-bit currents that wrap around and
voltages that saturate, 12-bit decays truncated toward zero, each
connection's summed weights shifted by its exponent, the refractory
voltage held. The input's spikes reach the export's source populations
as ``run.py`` feeds them: source ``i`` of :class:`~snn_fg.lowering.input_spikes.InputSpikes`
is cell ``i`` of the sources in the network's order (ON pixels, OFF
pixels, the window clock), a spike of step ``n`` sent at step ``n``. So on
an export's own network and input file it gives the reference's (and
Lava's) spikes, and a whole 304 x 240 network runs at compiled speed
(:mod:`.kernel`, numba) where Lava's CPU simulation runs one process per
population and connection.

Where it differs from the chip: every cell is updated at every step (the
chip too), the dendritic accumulator is not limited to 16 bits (Lava's
simulation does not limit it; ``stats["max_a_in"]`` says how far a run
went), and the cells a run leaves out (the populations' site hints, as
every backend honours them) are absent, where a board holds them all.
Spike times are ``n * dt``, in the counting window and bins from step
``round(t / dt)``. ``record_state`` gives ``v`` (mV; Loihi 2's neuron has
one current, not ``I_exc`` and ``I_inh``).

The package: :mod:`.tables` (the network as the loop's arrays, the input
as cell numbers), :mod:`.rest` (one cell's integer update, and when a
cell may be left alone), :mod:`.kernel` (the compiled step loop) and
:mod:`.simulation` (one run: bins, spikes, the result).
"""

from __future__ import annotations

import time

from ...errors import SnnFgError
from ...lowering.unroll import choose_sites
from ...network.graph import Network
from ..base import Backend, RunSettings, SimulationResult, importable, source_masks


class Loihi2Backend(Backend):
    """Loihi 2's fixed-point arithmetic, as Lava 0.10's ``fixed_pt`` computes it (numba).

    Parameters
    ----------
    chunk_ms : float
        How much simulated time the compiled loop runs at a time (25 ms):
        the progress bar and Ctrl-C wait for it.

    Examples
    --------
    >>> from snn_fg.backends import get_backend
    >>> get_backend("loihi2").name
    'loihi2'
    """

    name = "loihi2"
    requires = "numba (a core dependency: reinstall snn-fg)"
    #: every cell, as the fast engine: choosing them per input costs more than they do
    default_instantiate = "all"
    #: a recording's input is taken a segment at a time
    streams_input = True

    def __init__(self, *, chunk_ms: float = 25.0):
        from ... import validate as check

        self.chunk_ms = check.number("Loihi2Backend", "chunk_ms", chunk_ms, lo=0, lo_open=True)
        self._tables = None
        self._key = None

    @classmethod
    def available(cls):
        return importable("numba", install="pip install numba")

    def describe(self) -> dict:
        import numba

        return {"name": self.name, "arithmetic": "Loihi 2 fixed point (Lava 0.10 fixed_pt)", "numba": numba.__version__}

    def tables(self, network: Network, dt_ms: float):
        """The network's arrays at ``dt_ms``, built once and kept while the
        same description (by its JSON) is simulated again."""
        from .tables import build_tables

        key = (network.to_json(indent=None), float(dt_ms))
        if self._key != key:
            self._tables, self._key = None, None  # (let the old arrays go first)
            self._tables, self._key = build_tables(network, dt_ms), key
        return self._tables

    def simulate(self, network: Network, inputs, settings: RunSettings) -> SimulationResult:
        from .simulation import Run

        other = [v for v in settings.record_state if v != "v"]
        if other:
            raise SnnFgError(
                f"backend 'loihi2' records v only: Loihi 2's neuron has one current, not {' and '.join(other)}"
            )
        t0 = time.perf_counter()
        tab = self.tables(network, settings.dt_ms)
        chosen, _, _ = choose_sites(
            network, source_masks(network, inputs.on, inputs.off), settings.sites, settings.instantiate
        )
        run = Run(tab, chosen, inputs, settings)
        timings = {"build": time.perf_counter() - t0}
        settings.say(
            f"loihi2: {run.n_present:,} cells, {int(tab.post.size):,} synapses in Loihi 2's fixed point "
            f"(prepared in {timings['build']:.1f} s)"
        )
        t_run, cpu = time.perf_counter(), time.process_time()
        with _Progress(settings) as bar:
            run.simulate(max(1, int(round(self.chunk_ms / settings.dt_ms))), bar)
        timings["run"] = time.perf_counter() - t_run - run.read_s
        timings["run_cpu"] = time.process_time() - cpu - run.read_cpu_s
        if run.streamed:
            timings["read_bins"] = run.read_s
        result = run.result()
        timings["total"] = time.perf_counter() - t0
        result.timings_s = timings
        return result


class _Progress:
    """A callable advancing a progress bar (:mod:`snn_fg.results.progress`) by simulated steps (or doing nothing)."""

    def __init__(self, settings: RunSettings):
        self.settings, self.bar = settings, None

    def __enter__(self):
        if self.settings.progress:
            from ...results.progress import bar

            self.bar = bar("simulating", "ms", round(self.settings.duration_ms))
        return self

    def __call__(self, steps: int):
        if self.bar is not None:
            self.bar.update(steps * self.settings.dt_ms)

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()
