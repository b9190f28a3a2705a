"""The time step has one owner: the network (``Network.dt_ms``, default
``DEFAULT_DT_MS``); a run or an export takes the step it is given, else the
network's (``Network.time_step``)."""

import json

import pytest

from snn_fg.backends import RunSettings
from snn_fg.errors import ParameterError
from snn_fg.export.lava import export_lava
from snn_fg.export.pynn import pynn_model
from snn_fg.export.report import resource_report, spinnaker_estimate
from snn_fg.export.spinnaker import spinnaker_cores
from snn_fg.network import SpikingParams, Timing, build_network
from snn_fg.network.graph import DEFAULT_DT_MS
from snn_fg.network.recipes import RECIPES
from snn_fg.params import ModelParams

SMALL = ModelParams(levels=1)


@pytest.fixture(scope="module")
def coarse():
    """A network made for a 1 ms step (not the default)."""
    return build_network(SMALL, (16, 20), SpikingParams(time=Timing(dt_ms=1.0)))


def test_a_network_built_with_defaults_has_the_one_default_step():
    assert build_network(SMALL, (16, 20)).dt_ms == SpikingParams().time.dt_ms == DEFAULT_DT_MS


def test_the_given_step_else_the_networks(coarse):
    assert coarse.dt_ms == 1.0
    assert coarse.time_step() == 1.0
    assert coarse.time_step(0.25) == 0.25


@pytest.mark.parametrize("bad", [0, -0.5, float("nan"), "half"])
def test_a_bad_step_names_the_caller(coarse, bad):
    with pytest.raises(ParameterError, match=r"spinnaker_cores: dt_ms="):
        spinnaker_cores(coarse, dt_ms=bad)
    with pytest.raises(ParameterError, match=r"resource_report: dt_ms="):
        spinnaker_estimate(coarse, dt_ms=bad)


def test_exports_take_the_networks_step_unless_told(coarse):
    assert resource_report(coarse)["dt_ms"] == 1.0
    assert resource_report(coarse, dt_ms=0.5)["dt_ms"] == 0.5
    assert pynn_model(coarse)[0]["dt_ms"] == 1.0
    assert pynn_model(coarse, dt_ms=0.25)[0]["dt_ms"] == 0.25


def test_run_settings_have_no_step_of_their_own():
    with pytest.raises(TypeError, match="dt_ms"):
        RunSettings(duration_ms=10.0)
    assert RunSettings(duration_ms=10.0, dt_ms=1.0).dt_ms == 1.0


def test_the_lava_export_takes_the_networks_step_unless_told(tmp_path):
    net = RECIPES["compact"].build((24, 32))
    assert json.loads((export_lava(net, tmp_path / "own") / "network.json").read_text())["dt_ms"] == net.dt_ms
    given = export_lava(net, tmp_path / "given", dt_ms=2 * net.dt_ms)
    assert json.loads((given / "network.json").read_text())["dt_ms"] == 2 * net.dt_ms
    with pytest.raises(ParameterError, match=r"export_lava: dt_ms="):
        export_lava(net, tmp_path / "bad", dt_ms=0)
    assert not (tmp_path / "bad").exists()
