"""The figure-ground models behind one interface (:mod:`.interface`): the
rate model and its variants (:mod:`.rate`) and the spiking network's front
end and read-out (:mod:`.spiking`). The command line and the experiments
pick a model by name from :data:`MODELS`.
"""

from .interface import MODELS, Model, Still, get_model

__all__ = ["MODELS", "Model", "Still", "get_model"]
