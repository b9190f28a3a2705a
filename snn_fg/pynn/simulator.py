"""A PyNN simulator module, imported without the noise that is not about this network.

STANDALONE (standard library only; copied into every PyNN export as
``fg_simulator.py``; the NEST backend imports PyNN's NEST module through it
too). On importing ``pyNN.nest``, PyNN tries to build its optional NEST
extensions (cell and synapse types of its own) with ``nest-config``, cmake
and a C++ compiler whenever NEST cannot load them, and warns, with cmake's
whole output, when that fails ("Cannot find nest-config ...", "--
Configuring incomplete, errors occurred!"). This network uses only PyNN's
standard ``IF_curr_exp`` cells and static synapses, so those warnings are
left out (every other warning still shows), as are NEST's start-up banner
and the deprecation warning NEST 3.10 gives PyNN 0.13's ``set_verbosity``
call.
"""

from __future__ import annotations

import importlib
import os
import warnings

#: the start of PyNN's warnings that it could not build or install its optional NEST extensions
#: (pyNN/nest/simulator.py, build_extensions)
EXTENSION_WARNINGS = (
    "Cannot find nest-config",
    "Cannot create build directory for nest extensions",
    "Problem running cmake",
    "Unable to compile NEST extensions",
    "Unable to install NEST extensions",
)
#: NEST 3.10's warning when PyNN 0.13 sets its verbosity the old way
VERBOSITY_WARNING = r"\s*Provided for backward compatibility only"


def import_simulator(name: str):
    """``pyNN.<name>``; ``pyNN.nest`` without NEST's banner (unless
    ``PYNEST_QUIET`` is set otherwise), without PyNN's warnings about its
    optional extensions and with NEST's own messages from errors up."""
    if name != "nest":
        return importlib.import_module(f"pyNN.{name}")
    os.environ.setdefault("PYNEST_QUIET", "1")
    with warnings.catch_warnings():
        for start in EXTENSION_WARNINGS:
            warnings.filterwarnings("ignore", message=start, category=UserWarning)
        warnings.filterwarnings("ignore", message=VERBOSITY_WARNING, category=UserWarning)
        sim = importlib.import_module("pyNN.nest")
        import nest

        nest.set_verbosity("M_ERROR")
    return sim
