"""SpikingParams in parts: what earlier releases stored still loads and means
the same constants, the flat keyword form still works (and warns), and the
compact recipe's levers make what they made when they were string keys."""

import dataclasses
import json
import warnings
from pathlib import Path

import pytest

from snn_fg.errors import ParameterError
from snn_fg.network import Connectivity, Gains, Neuron, SpikingParams, Timing
from snn_fg.network.recipes import COMPACT_LEVERS, RECIPES, Recipe
from snn_fg.network.spiking_params import FLAT_FIELDS, PARTS
from snn_fg.params import ModelParams

RESULTS = Path(__file__).resolve().parents[1] / "experiments" / "results"


def _flat(sp: SpikingParams) -> dict:
    """Every constant in one mapping, as earlier releases wrote them."""
    return {name: value for part in sp.to_dict().values() for name, value in part.items()}


def test_every_field_of_the_flat_form_has_one_part():
    assert len(FLAT_FIELDS) == sum(len(dataclasses.fields(kind)) for kind in PARTS.values()) == 42
    assert set(FLAT_FIELDS).isdisjoint(PARTS)


def test_a_run_record_of_an_earlier_release_loads_as_the_same_constants():
    """A run's params as spiking_fidelity.json recorded them (38 fields, flat):
    each stored value is the loaded part's value; the fields it predates take
    their defaults."""
    stored = json.loads((RESULTS / "spiking_fidelity.json").read_text())["network_params"]["spiking_params"]
    assert len(stored) == 38 and "dt_ms" not in stored
    loaded = SpikingParams.from_dict(stored)
    assert {k: v for k, v in _flat(loaded).items() if k in stored} == stored
    assert loaded.time.dt_ms == SpikingParams().time.dt_ms


def test_the_compact_levers_make_what_they_made_as_string_keys():
    """compact_levers.json recorded, lever after lever, the constants each
    step made when the levers were flat string keys (27 Nov): the typed levers
    make the same ones, and the last step is the compact recipe."""
    rows = {r["label"]: r for r in json.loads((RESULTS / "compact_levers.json").read_text())["rows"]}
    recipe = Recipe("compact", "", ModelParams(), SpikingParams())
    for lever in COMPACT_LEVERS:
        recipe = lever.apply(recipe)
        row = rows[f"+ {lever.name}"]
        assert recipe.params == ModelParams.from_dict(row["params"]), lever.name
        assert recipe.spiking == SpikingParams.from_dict(row["spiking"]), lever.name
    assert recipe.spiking == RECIPES["compact"].spiking and recipe.params == RECIPES["compact"].params


def test_the_flat_keyword_form_warns_and_means_the_parts():
    parts = SpikingParams(time=Timing(dt_ms=1.0), connectivity=Connectivity(prune_dog=0.3))
    with pytest.warns(DeprecationWarning, match=r"SpikingParams\(dt_ms, prune_dog=...\).*deprecated"):
        flat = SpikingParams(dt_ms=1.0, prune_dog=0.3)
    assert flat == parts
    with pytest.warns(DeprecationWarning, match="SpikingParams.time.dt_ms"):
        assert flat.dt_ms == 1.0
    with pytest.warns(DeprecationWarning):
        assert flat.replace(clock_inh_group=0.0) == parts.replace(gains=Gains(clock_inh_group=0.0))
    with pytest.warns(DeprecationWarning):
        assert SpikingParams(bo=Neuron(tau_m_ms=7.0)).neurons.bo.tau_m_ms == 7.0


def test_the_parts_form_does_not_warn():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sp = SpikingParams(gains=Gains(clock_inh_group=0.0))
        assert sp.replace(time=sp.time.replace(dt_ms=1.0)).time.dt_ms == 1.0
        assert SpikingParams.from_dict(sp.to_dict()) == sp


def test_what_is_not_a_field_is_refused():
    with pytest.raises(TypeError, match="unexpected keyword argument 'dt'"):
        SpikingParams(dt=1.0)
    with pytest.raises(AttributeError, match="no attribute 'dt'"):
        SpikingParams().dt  # noqa: B018
    with pytest.raises(ParameterError, match="dt_ms=1.0 is given twice"):
        SpikingParams.from_dict({"dt_ms": 1.0, "time": {"dt_ms": 0.5}})
