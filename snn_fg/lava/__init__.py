"""The network in Lava: the standalone program every Lava export carries.

These modules import only numpy, the standard library and (where they build
Lava processes) Lava itself, so that ``snn-fg export --format lava``
(:mod:`snn_fg.export.lava`) can copy them verbatim into an export folder,
where they run in a Python 3.10 environment with ``lava-nc`` and without
snn_fg.

* :mod:`.fixed` - Loihi 2's arithmetic as Lava's fixed point computes it
  (``fg_loihi.py``), the rules the lowering and the reference follow;
* :mod:`.reference` - the whole network stepped in that arithmetic with
  numpy alone (``fg_reference.py``; ``run.py --simulator reference``);
* :mod:`snn_fg.lava.network` - the network as Lava processes (``fg_lava.py``);
* ``run`` - the export's ``run.py`` (not importable inside snn_fg, and left out of the API reference).

They share the input reader and the table unroller of :mod:`snn_fg.pynn`
(copied as ``fg_inputs.py`` and ``fg_tables.py``).
"""

from pathlib import Path

#: this package's folder, whose modules an export copies
HERE = Path(__file__).resolve().parent
#: module -> its name in an export folder
COPIED = {
    "fixed.py": "fg_loihi.py",
    "reference.py": "fg_reference.py",
    "synapses.py": "fg_synapses.py",
    "network.py": "fg_lava.py",
    "run.py": "run.py",
}
