"""The network description: what the spiking model is, independent of any
simulator or exporter.

* :mod:`.nodes` - neurons, populations, kernels, projections;
* :mod:`.roles` - what each population's cells compute;
* :mod:`.graph` - :class:`Network`, the validated graph (JSON in and out);
* :mod:`.spiking_params` - :class:`SpikingParams`, the spiking constants, in
  parts (neurons, input, connectivity, gains, time);
* :mod:`.builder` - :func:`build_network`, the figure-ground network;
* :mod:`.kernels` - the model's DoG and von Mises kernels.
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
