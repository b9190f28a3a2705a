"""Exports of the network description for neuromorphic boards and other simulators.

* :mod:`.board` - the whole, input-independent network a board holds, and its
  weight-shared synapse tables;
* :mod:`.pynn_model` - the network in PyNN (standalone: copied into every PyNN
  export, and what the NEST backend builds);
* :mod:`.pynn_tables` - explicit synapses from the weight-shared tables
  (standalone too: the PyNN export unrolls its projections with it);
* :mod:`.pynn` - ``snn-fg export --format pynn``: a self-contained PyNN model;
* :mod:`.nir` - ``--format nir``: a NIR graph, and the reader back into a Network;
* :mod:`.report` - ``--format report``: neurons, synapses, delays, weights and
  the hardware each target needs (:mod:`.hardware` holds the documented limits);
* :mod:`.quantise` - weights as signed integers with one scale per projection.

Nothing here is imported with :mod:`snn_fg`; optional dependencies (``nir``)
are imported when used.
"""
