"""The declarative network description: built from ModelParams, faithful to
the model's wiring, round-trips through dict/JSON, and names what is wrong."""
import json
from pathlib import Path

import numpy as np
import pytest

from snn_fg.frames.pyramid import level_shape
from snn_fg.network.description import (FAMILIES, ZPAIRS, Conv, DescriptionError, Kernel, Network, NetworkParams,
                                        Neuron, Population, Resize, build_network)
from snn_fg.network.kernels import dog_kernels, von_mises_masks
from snn_fg.params import ModelParams

ROOT = Path(__file__).resolve().parents[1]


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


# ---- further checks (spiking form) ----
@pytest.fixture(scope="module")
def small():
    return build_network(ModelParams(levels=3), (40, 52))


def test_round_trip_dict_and_json(small):
    d = small.to_dict()
    assert Network.from_dict(d) == small
    text = small.to_json()
    again = Network.from_json(text)
    assert again == small
    # the JSON is plain data: kernels stay references, not unrolled arrays
    assert len(text) < 200_000
    assert all(p["kernel"]["ref"] in ("dog", "von_mises", "channel_map") for p in json.loads(text)["projections"]
               if p["type"] == "conv")


def test_every_level_has_every_stage(small):
    for level in (1, 2, 3):
        roles = {p.role for p in small.populations if p.level == level}
        want = {"simple", "untuned", "group_L", "group_D"} | {f"bo_{f}" for f in FAMILIES} | \
            {f"fb_z{k}" for k in ZPAIRS}
        assert want <= roles, want - roles
        assert {"relay_on", "relay_off"} <= roles if level > 1 else {"input_on", "input_off"} <= roles
        for p in small.populations:
            if p.level == level:
                assert p.level_shape == level_shape((40, 52), level)


def test_simple_cell_threshold_is_the_edge_threshold():
    # A DoG response of exactly edge_threshold at the nominal input rate gives a
    # mean current of exactly one threshold (the gain calibration of stage 3).
    for thr, rate in ((0.3, 200.0), (0.5, 100.0)):
        net = build_network(ModelParams(levels=1, edge_threshold=thr), (32, 32), NetworkParams(input_rate_hz=rate))
        pr = next(p for p in net.projections if p.name == "on_to_S_1")
        s = net.population("S_1").neuron
        current = pr.gain_mv * thr * rate * s.tau_exc_ms / 1000.0
        assert current == pytest.approx(s.v_th_mv - s.v_rest_mv)


def test_kernel_references_materialise_the_model_kernels():
    p = ModelParams()
    k = Kernel("dog", {"directions": [3, None, 12]}).array(p)
    assert k.shape == (3, 1, 31, 31)
    np.testing.assert_array_equal(k[0, 0], dog_kernels(p)[3])
    assert not k[1].any()
    np.testing.assert_array_equal(k[2, 0], dog_kernels(p)[12])
    m1, m2 = von_mises_masks(p)
    g = Kernel("von_mises", {"half": 2, "layout": "gather"}).array(p)
    s = Kernel("von_mises", {"half": 1, "layout": "scatter"}).array(p)
    assert g.shape == (1, 8, 49, 49) and s.shape == (8, 1, 49, 49)
    np.testing.assert_array_equal(g[0], m2)
    np.testing.assert_array_equal(s[:, 0], m1)
    c = Kernel("channel_map", {"n_out": 2, "n_in": 3, "entries": [[1, 2, 0.5], [0, 0, -1]]}).array(p)
    assert c[1, 2, 0, 0] == 0.5 and c[0, 0, 0, 0] == -1 and np.count_nonzero(c) == 2


def test_simple_cells_feed_border_ownership_after_a_quarter_turn(small):
    # stage 4: direction k -> index (k + n/2) mod 2n; BL1[o] = S[o], BL2[o] = S[o+n]
    n = small.params.n_ori
    for fam, off in (("L1", 0), ("D2", 0), ("L2", n), ("D1", n)):
        pr = next(p for p in small.projections if p.name == f"S_1_to_B{fam}_1")
        k = pr.kernel.array(small.params)[:, :, 0, 0]
        for o in range(n):
            assert np.flatnonzero(k[o]).tolist() == [(o + off - n // 2) % (2 * n)]


@pytest.mark.parametrize("make, fragment", [
    (lambda: Neuron(tau_m_ms=-1), "Neuron"),
    (lambda: Neuron(v_th_mv=-5), "v_th_mv"),
    (lambda: Population("S 1", "simple", 1, (4, 4), neuron=Neuron()), "Population('S 1')"),
    (lambda: Population("S1", "nonsense", 1, (4, 4), neuron=Neuron()), "Population 'S1'"),
    (lambda: Population("S1", "simple", 1, (4, 4)), "needs a Neuron"),
    (lambda: Population("inp", "input_on", 1, (4, 4), neuron=Neuron()), "Population 'inp'"),
    (lambda: Kernel("dog", {"directions": []}), "Kernel(ref='dog')"),
    (lambda: Kernel("von_mises", {"half": 3, "layout": "gather"}), "half=3"),
    (lambda: Kernel("channel_map", {"n_out": 1, "n_in": 1, "entries": [[0, 5, 1.0]]}), "entry"),
    (lambda: Kernel("bogus", {}), "Kernel(ref='bogus')"),
    (lambda: Conv("c1", "a", "b", Kernel("channel_map", {"n_out": 1, "n_in": 1, "entries": []}), mode="x"),
     "Conv 'c1'"),
    (lambda: Resize("r1", "a", "b", interpolation="nearest"), "Resize 'r1'"),
    (lambda: Conv("c2", "a", "b", Kernel("channel_map", {"n_out": 1, "n_in": 1, "entries": []}), prune=1.5),
     "prune"),
    (lambda: NetworkParams(grouping_stride=0), "grouping_stride"),
    (lambda: NetworkParams(tau_m_group_ms=0), "NetworkParams.tau_m_group_ms"),
    (lambda: NetworkParams(pool_interpolation="area"), "NetworkParams.pool_interpolation"),
])
def test_invalid_nodes_name_the_object_at_fault(make, fragment):
    with pytest.raises(DescriptionError) as err:
        make()
    assert fragment in str(err.value)


def _two_pop_network(kernel, src_channels=1, tgt_channels=1, tgt_level=1):
    p = ModelParams(levels=2)
    pops = (Population("on", "input_on", 1, (20, 20)),
            Population("T", "simple", tgt_level, level_shape((20, 20), tgt_level), tgt_channels, 1, Neuron()))
    return Network(p, (20, 20), pops, (Conv("on_to_T", "on", "T", kernel),))


def test_network_checks_name_the_projection():
    cmap = Kernel("channel_map", {"n_out": 2, "n_in": 1, "entries": [[0, 0, 1.0]]})
    with pytest.raises(DescriptionError, match="Conv 'on_to_T'.*output channels"):
        _two_pop_network(cmap, tgt_channels=3)
    with pytest.raises(DescriptionError, match="Conv 'on_to_T'.*share a level"):
        _two_pop_network(Kernel("channel_map", {"n_out": 1, "n_in": 1, "entries": [[0, 0, 1.0]]}), tgt_level=2)
    ok = _two_pop_network(Kernel("channel_map", {"n_out": 1, "n_in": 1, "entries": [[0, 0, 1.0]]}))
    d = ok.to_dict()
    d["projections"][0]["target"] = "nowhere"
    with pytest.raises(DescriptionError, match="Conv 'on_to_T'.*target 'nowhere'"):
        Network.from_dict(d)
    d = ok.to_dict()
    d["populations"][1]["level_shape"] = [5, 5]
    with pytest.raises(DescriptionError, match="Population 'T'.*level_shape"):
        Network.from_dict(d)
    d = ok.to_dict()
    d["schema"] = "other/9"
    with pytest.raises(DescriptionError, match="schema"):
        Network.from_dict(d)


def test_network_params_round_trip():
    p = NetworkParams(bg_gain=1.5, grouping_stride=3, pool_interpolation="cubic")
    assert NetworkParams.from_dict(p.to_dict()) == p
    with pytest.raises(DescriptionError, match="unknown field"):
        NetworkParams.from_dict({"bogus": 1})


def test_stored_default_network_is_current():
    """networks/default_321x481.json is the default network for the BSDS frame
    size; it must load, validate and equal what the code builds today."""
    path = ROOT / "networks" / "default_321x481.json"
    net = Network.from_json(path.read_text())
    assert net.params == ModelParams()
    assert net == build_network(ModelParams(), (321, 481), NetworkParams(**json.loads(
        (ROOT / "networks" / "default_321x481.network_params.json").read_text())))
