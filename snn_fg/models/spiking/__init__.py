"""The spiking form of the figure-ground model.

* :func:`run_spiking` - an event frame or timed events -> :class:`~snn_fg.results.maps.Maps`
  decoded from spike counts (:func:`run_spiking_result` returns the internals);
* :func:`run_spiking_windows` - a recording's windows through one continuous
  network -> one :class:`~snn_fg.results.maps.Maps` per window (:mod:`.continuous`);
* :class:`SpikingOptions` - every option of a run, checked once (:mod:`.options`);
* :mod:`.api` - the entry points above, for an event frame or timed events;
* :mod:`.stream_input` - a recording's or a live stream's input, read once
  and causally; :mod:`.window_reader` - its windows decoded as the run goes;
* :mod:`.decode` - firing rates -> the rate model's readout;
* :mod:`.record` - the spike counts kept beside the maps;
* :mod:`.figures` - the raster and the firing-rate histograms;
* :mod:`.twin` - the unrolled network iterated like the rate model.

The network is described in :mod:`snn_fg.network`, lowered to input spikes
and synapses by :mod:`snn_fg.lowering` and simulated by a backend of
:mod:`snn_fg.backends`.
"""

from ...network import SpikingParams, build_network
from .api import SpikingResult, run_spiking, run_spiking_result
from .continuous import run_spiking_windows
from .options import SpikingOptions
from .record import SpikingRecord

__all__ = [
    "SpikingOptions",
    "SpikingParams",
    "SpikingRecord",
    "SpikingResult",
    "build_network",
    "run_spiking",
    "run_spiking_result",
    "run_spiking_windows",
]
