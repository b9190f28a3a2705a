"""The Examples sections of the public entry points' docstrings run and give
what they show."""

import doctest
import importlib

import pytest

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)

MODULES = [
    "snn_fg.backends",
    "snn_fg.events.io",
    "snn_fg.scoring.metrics",
    "snn_fg.network.builder",
    "snn_fg.network.spiking_params",
    "snn_fg.models.rate.edfg",
    "snn_fg.models.spiking.api",
    "snn_fg.events.paper_motion",
    "snn_fg.scoring.groundtruth",
    "snn_fg.models.rate.corf",
    "snn_fg.models.rate.fbfg",
    "snn_fg.export.pynn",
    "snn_fg.export.nir",
    "snn_fg.export.nir_folder",
    "snn_fg.export.report",
    "snn_fg.backends.cancel",
    "snn_fg.datasets",
]
#: examples that build and export whole networks (several seconds each)
SLOW = {"snn_fg.export.pynn", "snn_fg.export.nir", "snn_fg.export.nir_folder", "snn_fg.export.report"}


@pytest.mark.parametrize("name", [pytest.param(m, marks=pytest.mark.slow) if m in SLOW else m for m in MODULES])
def test_docstring_examples(name):
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0, f"{name} has no examples"
    assert result.failed == 0
