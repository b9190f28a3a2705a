"""The figure-ground models behind one interface (:mod:`.interface`): the
rate model and its variants (:mod:`.rate`) and the spiking network's front
end and read-out (:mod:`.spiking`). The command line and the experiments
pick a model by name from :data:`MODELS`; :func:`~.live.run_live` runs one on
a live stream (:mod:`.live`, which ``snn-fg live`` runs too).
"""

from .interface import MODELS, Model, Still, get_model


def __getattr__(name):  # (the live run's modules, sockets and threads: imported when first asked for)
    if name == "run_live":
        from .live import run_live

        return run_live
    raise AttributeError(f"module 'snn_fg.models' has no attribute {name!r}")


__all__ = ["MODELS", "Model", "Still", "get_model", "run_live"]
