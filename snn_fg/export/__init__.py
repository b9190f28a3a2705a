"""Exports of the network description for neuromorphic boards and other simulators.

* :mod:`.board` - the whole, input-independent network a board holds, and its
  weight-shared synapse tables;
* :mod:`.pynn` - ``snn-fg export --format pynn``: a self-contained PyNN model
  (the standalone program of :mod:`snn_fg.pynn`, which the NEST backend
  also runs, with the network's tables);
* :mod:`.lava` - ``--format lava``: the network as Lava processes in Loihi 2's
  fixed point (the standalone program of :mod:`snn_fg.lava`, registers from
  :mod:`snn_fg.lowering.loihi2`), run in its own Python 3.10 environment
  (:mod:`.lava_env`);
* :mod:`.folder` - what every export folder holds (``network.json``, tables);
* :mod:`.nir` - ``--format nir``: a NIR graph, written node by node; :mod:`.nir_import`
  reads one back into a Network;
* :mod:`.nir_snntorch` - ``--nir-profile snntorch``: the graph in the node kinds
  snnTorch imports; :mod:`.nir_folder` puts it in a folder with its own loop
  (the standalone program of :mod:`.snntorch_loop`), and :mod:`.snntorch_run`
  runs it in snnTorch itself, as an independent consumer;
* :mod:`.spinnaker` - which projections sPyNNaker's convolution connector
  carries; :mod:`.spinn5` - how many SpiNN-5 boards a network needs;
* :mod:`.synapses` - synapse counts, fan-in and fan-out without unrolling;
* :mod:`.artefacts` - the exported artefacts kept in ``networks/`` (the iCub-size
  NIR graph and its resource report);
* :mod:`.report` - ``--format report``: neurons, synapses, delays, weights and
  the hardware each target needs (:mod:`.hardware` holds the documented limits);
* :mod:`.loop` - both ends of a board run: where the export's frame is cut from an
  input, and maps from ``run.py``'s counts.
* :mod:`.edits` - whether an export's ``network.json`` still says what the
  description it embeds says (``snn-fg decode`` checks it).

The commands over them (``snn-fg export``, ``snn-fg decode``, ``snn-fg events
--write-spikes``) are in :mod:`snn_fg.cli`.

Weights are quantised by :mod:`snn_fg.lowering.quantise`.

Nothing here is imported with :mod:`snn_fg`; optional dependencies (``nir``)
are imported when used.
"""
