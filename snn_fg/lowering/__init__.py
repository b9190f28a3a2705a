"""Lowering: the network description turned into what a simulator runs.

Below the backends (:mod:`snn_fg.backends`) and the exports
(:mod:`snn_fg.export`), above the description (:mod:`snn_fg.network`);
nothing here knows a simulator.

* :mod:`.input_spikes` - events and event frames -> input spike trains;
* :mod:`.unroll` (with :mod:`.sites`, :mod:`.connect`, :mod:`.interp`) - the
  description unrolled into cells and synapses for one input, for backends
  that need explicit synapses;
* :mod:`.quantise` - weights as signed integers with one scale per projection.
"""
