"""Runs first (by name): the simulator compiles the network's code here, once
per machine, so that no behavioural test's time is a cold compile."""
import numpy as np

from snn_fg.backends import RunSettings, get_backend
from snn_fg.events import image_to_frame
from snn_fg.network import build_network
from snn_fg.params import ModelParams
from snn_fg.scenes import disc
from snn_fg.lowering.input_spikes import frame_spikes


def test_brian2_compiles_and_runs_every_kind_of_projection_of_the_default_network():
    try:
        from brian2.codegen.runtime.cython_rt import CythonCodeObject
        want = "cython" if CythonCodeObject.is_available() else "numpy"
    except ImportError:
        want = "numpy"
    pos, neg = image_to_frame(disc(8).image)
    net = build_network(ModelParams(levels=1), pos.shape)        # level 1 has every delay and receptor
    backend = get_backend("brian2")
    res = backend.simulate(net, frame_spikes(pos, neg, 200.0, 0.5, 40.0), RunSettings(duration_ms=40.0))
    assert backend.describe()["codegen"] == want
    delays = {round(p.delay_ms, 6) for p in net.projections}
    assert len(res.stats["brian2_synapse_objects"]) >= len(delays)
    assert res.counts["simple_1"].sum() > 0 and np.all(res.counts["group_L_1"] >= 0)


def test_the_fast_engine_compiles_and_counts_the_spikes_brian2_counts():
    """numba compiles the fast engine's loops here (once per checkout: cached
    beside the module), on a network with every delay and receptor."""
    pos, neg = image_to_frame(disc(8).image)
    net = build_network(ModelParams(levels=1), pos.shape)
    inp = frame_spikes(pos, neg, 200.0, 0.5, 40.0)
    settings = RunSettings(duration_ms=40.0, record_spikes=False)
    fast = get_backend("fast").simulate(net, inp, settings)
    ref = get_backend("brian2").simulate(net, inp, settings)
    assert fast.counts["simple_1"].sum() > 0
    for name in ref.counts:
        np.testing.assert_array_equal(fast.counts[name], ref.counts[name], err_msg=name)
