"""The network in PyNN: the standalone program every PyNN export carries.

These modules import only numpy and the standard library (PyNN is passed
in as the ``sim`` module), so that ``snn-fg export --format pynn``
(:mod:`snn_fg.export.pynn`) can copy them verbatim into an export folder,
where they run on a machine without snn_fg; inside snn_fg the NEST backend
(:mod:`snn_fg.backends.nest`) builds its network with the same code, so the
exported model and the backend are one implementation.

* :mod:`.cells` - a cell's and a synapse's PyNN parameters (``fg_cells.py``);
* :mod:`.network` - populations, synapses and input (``fg_network.py``);
* :mod:`.readout` - recording, the run, and spikes, counts and state read back (``fg_readout.py``);
* :mod:`.tables` - explicit synapses from the weight-shared tables (``fg_tables.py``);
* :mod:`.inputs` - the input spike file run.py reads (``fg_inputs.py``);
* :mod:`.spinnaker` - the network on sPyNNaker and its mapping (``fg_spinnaker.py``);
* :mod:`.memory` - what a NEST run of the export costs (``fg_memory.py``);
* :mod:`.files` - the files run.py writes, each whole (``fg_files.py``; Lava exports carry it too);
* :mod:`.simulator` - PyNN's simulator module, imported quietly (``fg_simulator.py``);
* ``run`` - the export's ``run.py`` (not importable inside snn_fg, and left out of the API reference).
"""

from pathlib import Path

#: this package's folder, whose modules an export copies
HERE = Path(__file__).resolve().parent
#: module -> its name in an export folder
COPIED = {
    "cells.py": "fg_cells.py",
    "network.py": "fg_network.py",
    "readout.py": "fg_readout.py",
    "tables.py": "fg_tables.py",
    "inputs.py": "fg_inputs.py",
    "spinnaker.py": "fg_spinnaker.py",
    "memory.py": "fg_memory.py",
    "files.py": "fg_files.py",
    "simulator.py": "fg_simulator.py",
    "run.py": "run.py",
}
