"""Lowering: the network description turned into what a simulator runs.

Below the backends (:mod:`snn_fg.backends`) and the exports
(:mod:`snn_fg.export`), above the description (:mod:`snn_fg.network`);
nothing here knows a simulator.

* :mod:`.input_spikes` - events and event frames -> input spike trains;
* :mod:`.unroll` (with :mod:`.sites`, :mod:`.connect`, :mod:`.interp`) - the
  description unrolled into cells and synapses for one input, for backends
  that need explicit synapses;
* :mod:`.input_stream` - a recording's input spikes made as the simulation needs
  them, and :mod:`.held_input` - the window's event frame built as the events
  arrive (the ``window`` and ``sliding`` input codings);
* :mod:`.kernel_tables` - a projection's weight-shared table, what an export
  stores and a board holds;
* :mod:`.quantise` - weights as signed integers with one scale per projection;
* :mod:`.loihi2` - the network in Loihi 2's integer registers.
"""
