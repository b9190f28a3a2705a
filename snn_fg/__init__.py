"""snn-fg: event-driven figure-ground organisation (D'Angelo et al. 2025) as a
spiking neural network.

The data flow is the package layout: :mod:`snn_fg.events` (recordings,
windows, event-camera simulation) -> :mod:`snn_fg.frames` (event frames, input
pooling, the pyramid) -> :mod:`snn_fg.network` (the network description) ->
:mod:`snn_fg.lowering` (input spikes and synapses) -> a simulator of
:mod:`snn_fg.backends` (with :mod:`snn_fg.backends.cancel`, which stops a long
run, a simulation's or a rate model's, at its next check) -> :mod:`snn_fg.models` (the spiking model's front end
and read-out, beside the rate models, behind one interface) ->
:mod:`snn_fg.results` (decoded maps, their store and figures) ->
:mod:`snn_fg.scoring` (metrics, ground truth). :mod:`snn_fg.export` writes the
description for boards and other simulators (with the standalone PyNN
program of :mod:`snn_fg.pynn`, which the NEST backend runs too, and the
standalone Lava program of :mod:`snn_fg.lava` for Loihi 2),
:mod:`snn_fg.datasets` fetches the data, and :mod:`snn_fg.cli` is the
command line. Beneath them all: :mod:`snn_fg.errors`, :mod:`snn_fg.validate`
(argument checks) and :mod:`snn_fg.params` (the model's parameters). Each layer imports only those
below it, with one exception: every layer writes files and shows progress with
:mod:`snn_fg.results`' helpers (``atomic``, ``outputs``, ``marks``, ``progress``
and ``activity``), which import nothing of snn_fg's but :mod:`snn_fg.errors`.

``snn_fg.Maps`` is :class:`snn_fg.results.maps.Maps`, what every run writes and
``Maps.load(folder)`` reads back.

From Python, every model runs as ``snn-fg run`` runs it through
:func:`snn_fg.models.get_model` (``get_model("spiking", network="compact")``, then its
``run_windows`` or ``run_still``); :func:`snn_fg.events.iter_windows` cuts a recording
into windows, and :func:`snn_fg.scoring.metrics.compare_maps` compares two runs' maps as
``snn-fg compare`` does (``docs/usage.md``, "From Python").
"""

__all__ = ["Maps", "__version__"]


def __getattr__(name):  # (imported when first asked for: ``import snn_fg`` stays light)
    if name == "Maps":
        from .results.maps import Maps

        return Maps
    if name == "__version__":  # (importlib.metadata takes a tenth of a second: the command line's start waits for it)
        from importlib.metadata import PackageNotFoundError, version

        try:
            return version("snn-fg")
        except PackageNotFoundError:  # running from a source tree that was not installed
            return "0+unknown"
    raise AttributeError(f"module 'snn_fg' has no attribute {name!r}")
