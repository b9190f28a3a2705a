"""The fast backend: an event-driven engine of our own, verified against Brian2.

Why this design
---------------
The network is a few weight-shared kernels applied on pyramid grids of
millions of cells, and at any moment only a small part of it is doing
anything. Brian2 (and any simulator that wants explicit synapses) must
first unroll the kernels into per-synapse arrays (1e8-1e9 at full scale)
and then update every instantiated cell at every step. This engine does
neither:

* **Weight-shared propagation.** A spike adds its projection's *stencil* to
  the summed input of its target when it is delivered: a Conv's kept taps
  (pruned exactly as :func:`~snn_fg.lowering.connect.kernel_taps` prunes
  them) as rows of the target's lattice, each one short loop, and a
  Resize's interpolation weights (:func:`~snn_fg.lowering.connect.resize_factors`).
  Which cells received input is kept as bits, so that the hand-over to the
  cells walks them in memory order and the synaptic events are counted
  with ``popcount`` (:mod:`.deliver`). Memory is proportional to cells
  (about 40 bytes each), not synapses, so the whole network
  (``instantiate="all"``) of a 320 x 240 sensor over ten levels, 9 million
  cells, fits in a few hundred megabytes.
* **Active cells only.** A cell is updated step by step only while it might
  fire (or is refractory); otherwise it is *parked* and brought up to date
  in closed form when input next reaches it (:mod:`~snn_fg.backends.fast.core`). Cost then
  follows synaptic events and active cells, not network size times steps.
* **Brian2's step, bit for bit where it can be.** Each step runs the slots of
  Brian2's schedule as our Brian2 backend uses them (state update, then
  threshold with refractoriness by time steps, then synaptic delivery
  after the projection's delay rounded to steps, then reset), with the same
  update expression, potentials and weights in volts, the same decay
  factors, delays, refractory periods and spike and counting times. What
  may differ is the order in which simultaneous synaptic inputs are summed
  and the rounding of the closed-form advance: a spike train can only
  differ where the potential comes within rounding error of threshold.
  ``tests/test_fast_engine.py`` checks identical spike trains on small
  networks.
* **Compiled with numba**, a maintained JIT compiler for numerical Python:
  the inner loops are plain loops over integers, which numpy cannot
  vectorise (every event depends on the state the previous one left).
* **Two threads** on a network large enough to share
  (:data:`~.backend.PARALLEL_FROM` cells): each target population is owned
  by one thread, which alone adds its projections' spikes to it and updates
  its cells, so the other thread skips those projections whole (neither
  their spikes nor their stencil rows walked); a population too costly for
  one thread's share can be *banded* instead, its rows dealt out in bands
  and every thread walking its spikes. The table is dealt from the work the
  run measures per population (synaptic events, spikes walked, cells handed
  input, active cell-steps) and dealt again as it grows (:mod:`.share`). A
  cell's input is summed by one thread in the order of the spikes, so the
  spikes depend neither on the number of threads nor on the table. Two
  threads pinned to one core do one thread's work (the banded split of
  every population, before 29 Nov, did part of it twice); on the default
  network over 2 ``dvs.es`` windows two cores took 7.1 s against one
  thread's 8.9 s and the banded split's 8.2 s (29 Nov, 1-minute load
  1.6-1.7, the machine shared); the compact network's gain on two cores was
  not shown on that machine, so it runs on one (``docs/performance.md``,
  "Two threads").

The engine honours the instantiation hints like Brian2 (``instantiate=
"input"`` marks the cells the hints leave out as absent) so that both
backends simulate the same cells; with ``instantiate="all"`` it needs no
per-input preparation beyond the edge masks.

The package: :mod:`.backend` (:class:`FastBackend`, the backend interface),
:mod:`.tables`, :mod:`.neurons` and :mod:`.stencils` (the description as
the engine's arrays), :mod:`.run` (one simulation's state), the compiled
loops (:mod:`~snn_fg.backends.fast.core`, the step; :mod:`.deliver`, the delivery; :mod:`.lif`,
one cell; :mod:`.lists`, the sorted cell lists; :mod:`.counting`, spike
counts; :mod:`.compiled`, numba's cache), :mod:`.share` (who owns which
population), :mod:`.results` (spike trains and counts handed back).

Example
-------
>>> from snn_fg.backends import get_backend
>>> get_backend("fast").name
'fast'
"""

from .backend import FastBackend

__all__ = ["FastBackend"]
