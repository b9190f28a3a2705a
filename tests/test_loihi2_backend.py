"""The Loihi 2 backend (``--backend loihi2``): any network in Lava's
fixed-point arithmetic, against the export's numpy reference (which gives
Lava's ``fixed_pt`` count in every cell, tests/test_export_lava.py) on the
export's own network and input file."""

import dataclasses
import json

import numpy as np
import pytest

from snn_fg.backends import RunSettings, get_backend
from snn_fg.cli import main
from snn_fg.errors import InputError, SnnFgError
from snn_fg.lava import reference, synapses

DURATION_MS, COUNT_FROM_MS = 100.0, 40.0


@pytest.fixture(scope="module")
def export(tmp_path_factory, disc_recording):
    """The compact network's Lava export for a 48 x 36 sensor (16 x 12 blocks),
    with a 40 ms window of the disc's recording (window clock included) as
    ``snn-fg events --write-spikes`` writes it, re-made for its rate."""
    from snn_fg.export.loop import export_network
    from snn_fg.export.pynn import read_input

    out = tmp_path_factory.mktemp("loihi2") / "model"
    base = ["export", "--format", "lava", "--network", "compact", "--sensor-size", "48x36", "--out", str(out)]
    assert main(base) == 0
    spikes = ["events", str(disc_recording), "--write-spikes", str(out / "input.npz"), "--export", str(out)]
    assert main([*spikes, "--window-ms", "40", "--no-progress"]) == 0
    rate = read_input(out / "input.npz").rate_hz
    assert main([*base, "--input-rate-hz", f"{rate:.3g}", "--force"]) == 0
    meta = json.loads((out / "network.json").read_text())
    conns = synapses.connections(meta, np.load(out / "tables.npz"))
    net, _ = export_network(out)
    return out, meta, conns, net, read_input(out / "input.npz")


def reference_counts(out, meta, conns):
    """The numpy reference on the export's input file, as ``run.py --simulator reference`` runs it."""
    from snn_fg.pynn.inputs import input_steps

    n_steps, count_from = int(DURATION_MS / meta["dt_ms"]), int(COUNT_FROM_MS / meta["dt_ms"])
    n_src = sum(p["size"] for p in meta["populations"] if p["neuron"] is None)
    steps, _ = input_steps(out / "input.npz", n_steps, n_src, meta["frame_shape"])
    return reference.simulate(meta, conns, steps, n_steps, count_from)


def settings(**kw):
    return RunSettings(duration_ms=DURATION_MS, dt_ms=1.0, count_from_ms=COUNT_FROM_MS, instantiate="all", **kw)


def test_the_backend_gives_the_references_count_in_every_cell(export):
    """Same network, same input file: the count of every cell and the limits met (the largest a_in, the
    voltages saturated) are the reference's; the cells at rest were left alone most of the time."""
    out, meta, conns, net, inputs = export
    ref, limits = reference_counts(out, meta, conns)
    res = get_backend("loihi2").simulate(net, inputs, settings())
    assert sum(int(c.sum()) for c in ref.values()) > 1000
    assert set(res.counts) == set(ref)
    assert all(np.array_equal(res.counts[k], ref[k]) for k in ref)
    assert (res.stats["max_a_in"], res.stats["u_wraps"], res.stats["v_saturated"]) == (
        limits.max_a_in,
        limits.u_wraps,
        limits.v_saturated,
    )
    assert res.stats["active_cell_steps"] < 0.5 * res.stats["cells"] * DURATION_MS


def test_a_sum_of_odd_weights_is_shifted_after_it_is_summed(export):
    """With weights ``2 m + 1`` (odd) under an exponent of -1, ``(sum W) >> 1`` is not ``sum (W >> 1)``;
    the backend shifts the sum, as Lava and the reference do (and on this input it matters)."""
    from snn_fg.backends.base import lif_populations
    from snn_fg.backends.loihi2.simulation import Run
    from snn_fg.backends.loihi2.tables import tables_from

    out, meta, conns, net, inputs = export
    odd = [
        dataclasses.replace(c, w2m=c.w2m + np.sign(c.w2m)) if c.weight_exp == -1 else c for c in conns
    ]  # (|2 m + 1| <= 255: still 8 bits)
    assert any(c.weight_exp == -1 and c.pre.size for c in conns)
    ref, _ = reference_counts(out, meta, odd)
    each = [dataclasses.replace(c, w2m=c.w2m >> 1, weight_exp=0) if c.weight_exp == -1 else c for c in odd]
    naive, _ = reference_counts(out, meta, each)
    assert any(not np.array_equal(ref[k], naive[k]) for k in ref)
    tab = tables_from(net, 1.0, meta, odd)
    chosen = {p.name: np.arange(p.size) for p in lif_populations(net)}
    run = Run(tab, chosen, inputs, settings())
    run.simulate(25)
    counts = run.result().counts
    assert all(np.array_equal(counts[k], ref[k]) for k in ref)


def test_bins_streamed_or_kept_are_the_same_and_add_up_to_the_counts(export):
    out, meta, conns, net, inputs = export
    edges = (40.0, 60.0, 80.0, 100.0)
    backend = get_backend("loihi2")
    kept = backend.simulate(net, inputs, settings(count_bins_ms=edges))
    handed = []
    streamed = backend.simulate(
        net, inputs, settings(count_bins_ms=edges, on_bin=lambda k, r: handed.append((k, r.counts, r.spikes)))
    )
    assert streamed.binned_counts is None and streamed.spikes is None and [k for k, _, _ in handed] == [0, 1, 2]
    for name, c in kept.counts.items():
        assert np.array_equal(kept.binned_counts[name].sum(0), c) and np.array_equal(streamed.counts[name], c)
        for k, counts, spikes in handed:
            assert np.array_equal(counts[name], kept.binned_counts[name][k])
            cell, t = spikes[name]
            assert np.all((t >= edges[k]) & (t < edges[k + 1]))
            assert np.array_equal(np.bincount(cell, minlength=c.size), counts[name])


def test_a_resting_cells_voltage_is_read_where_its_steps_took_it(export):
    """Without input every cell is left alone from its first step on; reading the state brings each
    voltage to where the steps it missed take it: the populations' resting potentials."""
    from snn_fg.lowering.input_spikes import InputSpikes

    _, _, _, net, inputs = export
    silent = dataclasses.replace(inputs, indices=inputs.indices[:0], steps=inputs.steps[:0], period_steps=None)
    assert isinstance(silent, InputSpikes)
    res = get_backend("loihi2").simulate(net, silent, settings(record_state=("v",)))
    assert res.stats["active_cell_steps"] <= 2 * res.stats["cells"]
    for name, state in res.state.items():
        rest = net.population(name).neuron.v_rest_mv
        assert np.abs(state["v"] - rest).max() < 0.1, name
    with pytest.raises(SnnFgError, match="records v only.*one current, not I_exc$"):
        get_backend("loihi2").simulate(net, silent, settings(record_state=("v", "I_exc")))


def test_a_network_loihi_2_cannot_hold_is_refused_in_one_line(export):
    _, _, _, net, inputs = export
    pops = tuple(
        dataclasses.replace(p, neuron=dataclasses.replace(p.neuron, tau_inh_ms=10.0)) if p.role == "untuned" else p
        for p in net.populations
    )
    with pytest.raises(InputError, match="population 'untuned_1'.*one synaptic current"):
        get_backend("loihi2").simulate(dataclasses.replace(net, populations=pops), inputs, settings())


def test_run_names_the_backend(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    assert "loihi2" in capsys.readouterr().out
