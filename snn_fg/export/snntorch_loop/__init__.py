"""The loop of a NIR export in snnTorch's terms: the standalone program its folder carries.

These modules import only numpy, the standard library and (when a graph is run) torch,
snnTorch and nir, so that ``snn-fg export --format nir --nir-profile snntorch --out DIR``
(:mod:`snn_fg.export.nir_folder`) can copy them verbatim into the folder, where they run on
a machine without snn_fg; inside snn_fg, :func:`snn_fg.export.snntorch_run.run_snntorch`
runs the same code, so the export's loop and the package's are one implementation.

* :mod:`.counting` - the graph run by snnTorch through nirtorch, each population's spikes
  counted (``fg_snntorch.py``);
* ``run`` - the export's ``run.py`` (not importable inside snn_fg, and left out of the API reference).

They share the input reader and the atomic writer of :mod:`snn_fg.pynn` (copied as
``fg_inputs.py`` and ``fg_files.py``).
"""

from pathlib import Path

#: this package's folder, whose modules an export copies
HERE = Path(__file__).resolve().parent
#: module -> its name in an export folder
COPIED = {"counting.py": "fg_snntorch.py", "run.py": "run.py"}
