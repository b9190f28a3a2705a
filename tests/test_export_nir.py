"""The NIR file written node by node, and the snnTorch profile of the graph:
what it changes (measured on our own engine), and snnTorch executing it."""
import numpy as np
import pytest

from snn_fg.errors import ParameterError
from snn_fg.network import build_network
from snn_fg.params import ModelParams

nir = pytest.importorskip("nir", reason='needs pip install "snn-fg[nir]"')


def _arrays(node) -> dict:
    return {k: np.asarray(v) for k, v in vars(node).items() if isinstance(v, np.ndarray)}


def test_streamed_file_reads_back_as_the_whole_graph_written_by_nir(tmp_path):
    """write_streaming (one node in memory at a time) against nir.write of the
    whole graph: nir.read gives the same nodes, arrays and edges."""
    from snn_fg.export.nir import to_nir, write_streaming

    net = build_network(ModelParams(levels=2), (24, 28))
    nir.write(tmp_path / "whole.nir", to_nir(net))
    write_streaming(tmp_path / "streamed.nir", net)
    a, b = nir.read(tmp_path / "whole.nir"), nir.read(tmp_path / "streamed.nir")
    assert sorted(map(tuple, a.edges)) == sorted(map(tuple, b.edges)) and a.metadata == b.metadata
    assert set(a.nodes) == set(b.nodes) and len(a.nodes) > 300
    for name, node in a.nodes.items():
        other = b.nodes[name]
        assert type(node) is type(other), name
        got, want = _arrays(other), _arrays(node)
        assert got.keys() == want.keys() and all(np.array_equal(got[k], want[k]) for k in want), name


def test_snntorch_profile_refuses_what_it_cannot_write():
    from snn_fg.export.nir_snntorch import snntorch_network

    with pytest.raises(ParameterError, match="interpolates between pyramid levels"):
        snntorch_network(build_network(ModelParams(levels=2), (24, 28)))
    net = snntorch_network(build_network(ModelParams(levels=1, r0=4), (24, 28)))
    assert all(pr.delay_ms == 0.5 and pr.padding == "zero" for pr in net.projections)
    assert all(p.stride == 1 and p.role != "clock" for p in net.populations)
    assert all(p.neuron.t_ref_ms == 0.5 for p in net.populations if p.neuron is not None)


def test_snntorch_profile_graph_has_only_the_node_kinds_snntorch_imports(tmp_path):
    from snn_fg.export.nir_snntorch import to_nir_snntorch

    net = build_network(ModelParams(levels=1, r0=4), (24, 28))
    g = to_nir_snntorch(net)
    kinds = {type(n).__name__ for n in g.nodes.values()}
    assert kinds == {"Input", "Output", "CubaLIF", "Conv2d"}
    assert [n for n, v in g.nodes.items() if type(v).__name__ == "Input"] == ["input"]
    nir.write(tmp_path / "g.nir", g)
    back = nir.read(tmp_path / "g.nir")
    # the resting potential is a constant current: the bias of one Conv2d into the cells
    simple = net.one("simple", 1)
    into = [n for a, n in back.edges if n == "simple_1"]
    assert into and all(np.all(back.nodes[c].v_leak == 0) for c in ("simple_1", "bo_L1_1"))
    biased = [a for a, b in back.edges if b == "simple_1" and np.any(back.nodes[a].bias != 0)]
    assert len(biased) == (1 if simple.neuron.v_rest_mv != 0 else 0)
