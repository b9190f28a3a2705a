"""Spiking (Brian2) form of the event-driven figure-ground model.

* :func:`run_spiking` - event frame or timed events -> :class:`~snn_fg.maps.Maps`
  decoded from spike counts (``run_spiking_result`` returns the internals too);
* :func:`save_spiking_figures` - spike raster and per-population rate histograms;
* :mod:`.unroll` - the network description unrolled for one input (numpy only);
* :mod:`.inputs` - events / frames -> input spike trains;
* :mod:`.brian` - the Brian2 network;
* :mod:`.decode` - spike counts -> the rate model's readout.

The network itself is described declaratively in
:mod:`snn_fg.network.description`.
"""
from ..network.description import NetworkParams, build_network
from .api import SpikingResult, run_spiking, run_spiking_result, save_spiking_figures

__all__ = ["NetworkParams", "SpikingResult", "build_network", "run_spiking", "run_spiking_result",
           "save_spiking_figures"]
