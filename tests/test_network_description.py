"""The declarative network description: built from ModelParams, faithful to
the model's wiring, round-trips through dict/JSON, and names what is wrong."""
import numpy as np
import pytest

from snn_fg.network.description import Conv, DescriptionError, Network, Neuron, Population, build_network
from snn_fg.network.kernels import dog_kernels, von_mises_masks
from snn_fg.params import ModelParams


@pytest.fixture(scope="module")
def net():
    return build_network(ModelParams(), (321, 481))


def test_round_trip(net):
    again = Network.from_dict(net.to_dict())
    assert again == net
    assert Network.from_json(net.to_json()) == net


def test_every_level_has_the_model_populations(net):
    for level in range(1, 11):
        roles = {p.role for p in net.populations if p.level == level}
        assert {"simple", "bo_L1", "bo_L2", "bo_D1", "bo_D2", "group_L", "group_D"} <= roles
    assert {p.role for p in net.populations if p.level == 1} >= {"input_on", "input_off"}


def test_simple_cells_get_the_dog_kernels(net):
    k = dog_kernels(net.params)
    on = next(p for p in net.projections if p.source == "on" and p.target == "S_1")
    off = next(p for p in net.projections if p.source == "off" and p.target == "S_1")
    a_on, a_off = on.kernel.array(net.params), off.kernel.array(net.params)
    # directions 0-7 see ON events, 8-15 OFF events (stage 3)
    assert np.array_equal(a_on[:8, 0], k[:8]) and not a_on[8:].any()
    assert np.array_equal(a_off[8:, 0], k[8:]) and not a_off[:8].any()
    assert on.mode == "conv" and on.padding == "wrap"


# Stage 7: gL1 = (BL1 - w BD2) (*) m2, gL2 = (BL2 - w BD1) (*) m1,
#          gD1 = (BD1 - w BL2) (*) m2, gD2 = (BD2 - w BL1) (*) m1.
STAGE7 = {
    "GL": {("BL1", 2, 1), ("BL2", 1, 1), ("BD2", 2, -1), ("BD1", 1, -1)},
    "GD": {("BD1", 2, 1), ("BD2", 1, 1), ("BL2", 2, -1), ("BL1", 1, -1)},
}


@pytest.mark.parametrize("level", [1, 4, 10])
def test_grouping_wiring_follows_stage_7(net, level):
    m1, m2 = von_mises_masks(net.params)
    for g, want in STAGE7.items():
        got = set()
        for p in net.projections:
            if p.target == f"{g}_{level}" and p.source.startswith("B"):
                assert isinstance(p, Conv) and p.mode == "corr" and p.padding == "zero"
                a = p.kernel.array(net.params)[0]                   # (n_ori, 49, 49)
                half = 1 if np.allclose(a, m1) else 2 if np.allclose(a, m2) else None
                got.add((p.source.split("_")[0], half, p.sign))
        assert got == want, g


def test_validation_names_the_object_at_fault():
    with pytest.raises(DescriptionError, match="Population 'S_x'.*role"):
        Population("S_x", "nonsense", 1, (10, 10), neuron=Neuron())
    with pytest.raises(DescriptionError, match="Neuron.*v_th_mv"):
        Neuron(v_th_mv=-5.0)
    with pytest.raises(DescriptionError, match="Population 'B'.*needs a Neuron"):
        Population("B", "bo_L1", 1, (10, 10))


def test_built_from_the_parameter_object():
    small = build_network(ModelParams(levels=3, r0=4), (60, 80))
    assert max(p.level for p in small.populations) == 3
    vm = next(p for p in small.projections if p.target == "GL_1" and p.source == "BL1_1")
    assert vm.kernel.array(small.params).shape[-1] == 2 * 3 * 4 + 1
