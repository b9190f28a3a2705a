"""Both engines on a network with every kind of projection (the session's
warm-up run, ``conftest.warm_simulators``, which compiles their code)."""

import numpy as np


def test_brian2_compiles_and_runs_every_kind_of_projection_of_the_default_network(warm_simulators):
    try:
        from brian2.codegen.runtime.cython_rt import CythonCodeObject

        want = "cython" if CythonCodeObject.is_available() else "numpy"
    except ImportError:
        want = "numpy"
    net, res = warm_simulators.network, warm_simulators.brian2
    assert warm_simulators.brian2_codegen == want
    delays = {round(p.delay_ms, 6) for p in net.projections}
    assert len(res.stats["backend_objects"]) >= len(delays)
    lif = {p.name for p in net.populations if not p.is_source}
    assert set(res.counts) == lif
    for name in lif:
        assert res.counts[name].shape == res.sites[name].shape, name
    assert res.counts["simple_1"].sum() > 0


def test_the_fast_engine_compiles_and_counts_the_spikes_brian2_counts(warm_simulators):
    fast, ref = warm_simulators.fast, warm_simulators.brian2
    assert fast.counts["simple_1"].sum() > 0
    assert set(fast.counts) == set(ref.counts)
    for name in ref.counts:
        np.testing.assert_array_equal(fast.counts[name], ref.counts[name], err_msg=name)
