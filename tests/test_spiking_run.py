"""The spiking model end to end on small synthetic scenes (fast), its inputs,
its Python API, determinism, and its errors."""
import numpy as np
import pytest

from snn_fg.errors import InputError, ParameterError
from snn_fg.events import image_to_events, image_to_frame
from snn_fg.maps import Maps
from snn_fg.metrics import compare_frame, grouping_peak_inside, truth_scores
from snn_fg.rate.edfg import run_edfg
from snn_fg.scenes import disc
from snn_fg.spiking import run_spiking, run_spiking_result, save_spiking_figures
from snn_fg.spiking.api import ROLE_ORDER
from snn_fg.spiking.inputs import event_spikes, frame_spikes


@pytest.fixture(scope="module", params=[True, False], ids=["light", "dark"])
def disc_run(request):
    sc = disc(16, light_on_dark=request.param)
    pos, neg = image_to_frame(sc.image)
    res = run_spiking_result(pos, neg, progress=False)
    return sc, pos, neg, res


def test_disc_matches_the_rate_reference(disc_run):
    sc, pos, neg, res = disc_run
    ref = run_edfg(pos, neg)
    c = compare_frame(res.maps.fg_x, res.maps.fg_y, res.maps.grouping, ref.fg_x, ref.fg_y, ref.grouping)
    assert c["pixels_compared"] > 100
    assert c["angle_diff_median_deg"] <= 20
    assert c["grouping_pearson_r"] >= 0.8


def test_disc_figure_ground_and_grouping_are_right(disc_run):
    sc, _, _, res = disc_run
    t = truth_scores(res.maps.fg_x, res.maps.fg_y, sc)
    assert t["coverage"] > 0.5
    assert t["frac_within_45"] >= 0.75
    assert grouping_peak_inside(res.maps.grouping, sc)


def test_every_population_role_fires_below_its_ceiling(disc_run):
    _, _, _, res = disc_run
    pops = res.maps.params["populations"]
    seen = set()
    for role in ROLE_ORDER:
        ps = [p for p in pops.values() if p["role"] == role and p["cells"] > 0]
        if not ps:
            continue
        seen.add(role)
        cells = sum(p["cells"] for p in ps)
        mean = sum(p["mean_rate_hz"] * p["cells"] for p in ps) / cells
        assert mean > 0.5, role
        assert mean < 0.5 * ps[0]["refractory_max_hz"], role
    assert {"simple", "untuned", "bo_L1", "bo_D2", "group_L", "group_D", "fb_z1p", "fb_z1n"} <= seen


def test_maps_record_counts_rates_and_parameters(disc_run, tmp_path):
    _, pos, _, res = disc_run
    m = res.maps
    assert m.fg_x.shape == pos.shape and m.fg_x.dtype == np.float32
    names = [str(n) for n in m.extra["population_names"]]
    assert "S_1" in names and "GL_1" in names
    for n in names:
        spikes, sites = m.extra[f"spikes_{n}"], m.extra[f"sites_{n}"]
        assert spikes.shape == sites.shape and spikes.dtype == np.int32
        # the decoded rates are these counts over the counting window
        np.testing.assert_allclose(res.rates[n], spikes / (m.params["simulation"]["count_window_ms"] / 1000))
    sim = m.params["simulation"]
    for key in ("duration_ms", "dt_ms", "settle_ms", "seed", "rate_hz_used", "codegen"):
        assert key in sim
    assert m.params["model"] == "spiking" and m.params["levels"] == 10
    assert m.params["counts"]["total_synapses"] == sum(m.params["counts"]["synapses_in"].values())
    assert all(0 < v <= 1 + 1e-9 for v in m.params["kept_kernel_mass"].values())
    back = Maps.load(m.save(tmp_path / "spk.npz"))
    np.testing.assert_array_equal(back.extra["spikes_GL_1"], m.extra["spikes_GL_1"])
    assert back.params["simulation"] == sim
    files = save_spiking_figures(back, tmp_path / "figs")
    assert [f.name for f in files] == ["spike_raster.png", "rate_histograms.png"]
    assert all(f.stat().st_size > 10_000 for f in files)


def test_same_seed_same_spikes_other_seed_other_spikes():
    pos, neg = image_to_frame(disc(16).image)
    runs = [run_spiking_result(pos, neg, duration_ms=120, settle_ms=20, seed=s, progress=False) for s in (5, 5, 6)]
    a, b, c = (r.sim for r in runs)
    assert a.spike_i.size > 1000
    np.testing.assert_array_equal(a.spike_i, b.spike_i)
    np.testing.assert_array_equal(a.spike_t, b.spike_t)
    assert a.spike_i.size != c.spike_i.size or not np.array_equal(a.spike_t, c.spike_t)


def test_timed_events_drive_the_network():
    sc = disc(16)
    rec = image_to_events(sc.image)
    res = run_spiking_result(events=rec.events, sensor_size=rec.sensor_size, progress=False)
    assert res.inputs.kind == "events" and res.inputs.period_steps is not None
    t = truth_scores(res.maps.fg_x, res.maps.fg_y, sc)
    assert t["frac_within_45"] >= 0.75
    assert grouping_peak_inside(res.maps.grouping, sc)


def test_event_spike_times_come_from_the_timestamps():
    ev = np.zeros(5, dtype=[("x", "<i2"), ("y", "<i2"), ("t", "<i8"), ("p", "i1")])
    ev["x"] = [1, 2, 1, 3, 1]
    ev["y"] = [0, 0, 0, 2, 0]
    ev["t"] = [1000, 1400, 1100, 3600, 2000]     # us; the first and third share a 0.5 ms step
    ev["p"] = [1, 0, 1, 1, 1]
    inp = event_spikes(ev, (4, 3), dt_ms=0.5)
    w, h = 4, 3
    got = sorted(zip(inp.indices.tolist(), inp.steps.tolist()))
    want = sorted([(0 * w + 1, 0), (h * w + 0 * w + 2, 0), (2 * w + 3, 5), (0 * w + 1, 2)])
    assert got == want
    assert inp.merged == 1
    assert inp.period_steps == 6                 # window 0 .. 2.6 ms, replayed
    assert inp.on[0, 1] and inp.off[0, 2] and inp.on[2, 3] and not inp.off[0, 1]
    idx, st = inp.spike_times_steps(13)
    assert st.max() == 12 and (idx == 1).sum() == 5          # steps 0, 2, 6, 8, 12
    ev["x"][3] = 9
    with pytest.raises(InputError, match="event 3"):
        event_spikes(ev, (4, 3), dt_ms=0.5)


def test_frame_spike_trains_are_regular_or_poisson_and_seeded():
    pos = np.zeros((6, 7), np.uint8)
    neg = np.zeros((6, 7), np.uint8)
    pos[1, 2] = pos[4, 4] = 1
    neg[3, 0] = 1
    reg = frame_spikes(pos, neg, 200.0, 0.5, 100.0, seed=1)
    assert reg.period_steps == 10 and reg.rate_hz == 200.0
    assert sorted(reg.indices.tolist()) == [1 * 7 + 2, 4 * 7 + 4, 42 + 3 * 7]
    idx, st = reg.spike_times_steps(200)
    assert np.all(np.bincount(idx)[np.bincount(idx) > 0] == 20)     # 200 Hz for 100 ms
    again = frame_spikes(pos, neg, 200.0, 0.5, 100.0, seed=1)
    np.testing.assert_array_equal(reg.steps, again.steps)
    poi = frame_spikes(pos, neg, 200.0, 0.5, 2000.0, seed=2, process="poisson")
    np.testing.assert_array_equal(poi.steps, frame_spikes(pos, neg, 200.0, 0.5, 2000.0, seed=2,
                                                          process="poisson").steps)
    assert abs(poi.indices.size / 3 / 2.0 - 200) < 20
    with pytest.raises(ParameterError, match="input_process"):
        frame_spikes(pos, neg, 200.0, 0.5, 100.0, process="burst")


def test_errors_name_what_is_wrong():
    pos, neg = image_to_frame(disc(16).image)
    ev = image_to_events(disc(16).image)
    with pytest.raises(InputError, match="not both"):
        run_spiking(pos, neg, events=ev.events, sensor_size=ev.sensor_size, progress=False)
    with pytest.raises(InputError, match="sensor_size"):
        run_spiking(events=ev.events, progress=False)
    with pytest.raises(InputError, match="no pixel"):
        run_spiking(np.zeros((20, 20), np.uint8), np.zeros((20, 20), np.uint8), progress=False)
    with pytest.raises(ParameterError, match="settle_ms"):
        run_spiking(pos, neg, duration_ms=100, settle_ms=100, progress=False)
    with pytest.raises(ParameterError, match="dt_ms"):
        run_spiking(pos, neg, dt_ms=0, progress=False)
    with pytest.raises(ParameterError, match="codegen"):
        run_spiking(pos, neg, codegen="gpu", duration_ms=10, settle_ms=0, progress=False)
