"""The network description: what the spiking model is, independent of any
simulator or exporter.

* :mod:`.nodes` - neurons, populations, kernels; :mod:`.projections` - the
  projections, :class:`Conv` (a weight-shared kernel) and :class:`Resize`;
* :mod:`.roles` - what each population's cells compute;
* :mod:`.graph` - :class:`Network`, the validated graph (JSON in and out);
* :mod:`.spiking_params` - :class:`SpikingParams`, the spiking constants, in
  parts (neurons, input, connectivity, gains, time); :mod:`.gains` - a
  spike's weight on each kind of projection;
* :mod:`.builder` - :func:`build_network`, the figure-ground network, one
  stage at a time (:mod:`.stages`), wired as the model's stages say
  (:mod:`.wiring`), with the side cue's cells (:mod:`.side_cells`);
* :mod:`.kernels` - the model's DoG and von Mises kernels;
* :mod:`.recipes` - networks by name (``--network default``, ``compact``) and
  stored descriptions, checked at load.
"""

from .builder import build_network
from .graph import Network
from .nodes import SITE_RULES, Kernel, Neuron, Population
from .projections import Conv, Projection, Resize
from .roles import ROLES
from .spiking_params import Connectivity, Gains, Input, Neurons, SpikingParams, Timing

__all__ = [
    "ROLES",
    "SITE_RULES",
    "Connectivity",
    "Conv",
    "Gains",
    "Input",
    "Kernel",
    "Network",
    "Neuron",
    "Neurons",
    "Population",
    "Projection",
    "Resize",
    "SpikingParams",
    "Timing",
    "build_network",
]
