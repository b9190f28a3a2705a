"""The spiking model's Python API: inputs, what a run records, running a
stored (and edited) network description, and errors."""

import json

import numpy as np
import pytest

from snn_fg.backends import DEFAULT_BACKEND
from snn_fg.errors import InputError, ParameterError
from snn_fg.events import image_to_events, image_to_frame
from snn_fg.frames.scenes import disc
from snn_fg.lowering.input_spikes import event_spikes, frame_spikes
from snn_fg.models.spiking import SpikingRecord, run_spiking, run_spiking_result
from snn_fg.models.spiking.figures import save_spiking_figures
from snn_fg.network import build_network
from snn_fg.params import ModelParams
from snn_fg.results.maps import Maps

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)

SMALL = ModelParams(levels=2)


@pytest.fixture(scope="module")
def frame():
    return image_to_frame(disc(12).image)


@pytest.fixture(scope="module")
def small_run(frame):
    pos, neg = frame
    return run_spiking_result(pos, neg, params=SMALL, duration_ms=120, progress=False)


@pytest.mark.slow
def test_maps_record_counts_rates_and_parameters(small_run, frame, tmp_path):
    pos, _ = frame
    m = small_run.maps
    assert m.fg_x.shape == pos.shape and m.fg_x.dtype == np.float32
    rec, _ = SpikingRecord.from_maps(m)
    assert "simple_1" in rec.names and "group_L_1" in rec.names
    for n in rec.names:
        assert rec.counts[n].shape == rec.sites[n].shape and rec.counts[n].dtype == np.int32
        res = small_run.result
        fired = res.counts[n] > 0  # only cells that fired are stored; the summary counts all
        assert np.all(rec.counts[n] > 0) and rec.populations[n]["cells"] == res.sites[n].size
        np.testing.assert_array_equal(rec.sites[n], res.sites[n][fired])
        np.testing.assert_allclose(res.rates(n)[fired], rec.rates(n))
    sim = m.params["simulation"]
    for key in ("duration_ms", "dt_ms", "settle_ms", "count_window_ms", "seed", "rate_hz_used", "instantiate"):
        assert key in sim
    assert m.params["backend"]["name"] == DEFAULT_BACKEND == small_run.result.backend
    assert m.params["model"] == "spiking" and m.params["levels"] == 2
    assert m.params["network"]["origin"] == "built"
    assert m.params["counts"]["total_cells"] == sum(m.params["counts"]["cells"].values()) > 0
    # the fast engine makes no synapses (it follows shared kernels): not counted, rather than counted as 0
    assert m.params["counts"]["total_synapses"] is None and set(m.params["counts"]["synapses_in"].values()) == {None}
    assert set(m.params["kept_kernel_mass"]) == {pr.name for pr in small_run.network.projections}
    assert all(0 < v <= 1 + 1e-9 for v in m.params["kept_kernel_mass"].values())
    files = save_spiking_figures(Maps.load(m.save(tmp_path / "spk.npz")), tmp_path / "figs")
    assert [f.name for f in files] == ["maps.png", "spike_raster.png", "rate_histograms.png"]
    assert all(f.read_bytes()[:4] == b"\x89PNG" and f.stat().st_size > 10_000 for f in files)


@pytest.mark.slow
def test_a_frame_gets_the_hinted_cells_by_default_and_every_cell_s_maps(frame):
    """Regular trains keep the nominal rate the site hints assume, so by
    default a frame creates only the cells the hints choose, on the fast
    engine too (whose own default is every cell); the maps are bit for bit
    those of every cell. Timed events keep the backend's default."""
    pos, neg = frame
    params = ModelParams(levels=3)
    runs = {
        inst: run_spiking_result(
            pos,
            neg,
            params=params,
            backend="fast",
            duration_ms=120,
            progress=False,
            **({"instantiate": inst} if inst else {}),
        )
        for inst in (None, "all")
    }
    default, every = runs[None], runs["all"]
    assert default.maps.params["simulation"]["instantiate"] == "input"
    assert default.maps.params["counts"]["total_cells"] < 0.7 * every.maps.params["counts"]["total_cells"]
    assert np.abs(every.maps.fg_x).sum() > 0 and every.maps.grouping.max() > 0
    for key in ("fg_x", "fg_y", "grouping"):
        np.testing.assert_array_equal(getattr(default.maps, key), getattr(every.maps, key), err_msg=key)
    rec = image_to_events(disc(12).image)
    timed = run_spiking_result(
        events=rec.events, sensor_size=rec.sensor_size, params=SMALL, backend="fast", duration_ms=60, progress=False
    )
    assert timed.maps.params["simulation"]["instantiate"] == "all"


@pytest.mark.slow
def test_a_stored_description_runs_and_an_edited_gain_changes_the_result(small_run, frame, tmp_path):
    pos, neg = frame
    path = small_run.network.save(tmp_path / "net.json")
    same = run_spiking(pos, neg, network=path, duration_ms=120, progress=False)
    for k in ("fg_x", "fg_y", "grouping"):
        np.testing.assert_array_equal(getattr(same, k), getattr(small_run.maps, k))
    assert same.params["network"]["origin"] == str(path)
    d = json.loads(path.read_text())
    for pr in d["projections"]:
        if pr["name"] == "bo_L1_1_to_group_L_1":
            pr["gain_mv"] *= 3
    path.write_text(json.dumps(d))
    edited = run_spiking(pos, neg, network=path, duration_ms=120, progress=False)
    assert not np.array_equal(edited.grouping, small_run.maps.grouping)
    # the stored network is for another frame size: it is resized, and says so
    other = build_network(SMALL, (40, 40)).save(tmp_path / "other.json")
    resized = run_spiking(pos, neg, network=other, duration_ms=120, progress=False)
    assert resized.params["network"]["resized_from"] == [40, 40]
    np.testing.assert_array_equal(resized.grouping, small_run.maps.grouping)
    with pytest.raises(ParameterError, match="not both"):
        run_spiking(pos, neg, network=path, params=SMALL, progress=False)


@pytest.mark.slow
def test_the_run_is_silent_unless_asked(frame, capfd):
    pos, neg = frame
    run_spiking(pos, neg, params=ModelParams(levels=1), duration_ms=20, progress=False)
    assert capfd.readouterr().err == ""
    for backend, says in (("brian2", ("unrolling", "compiling")), ("fast", ("cells",))):
        lines = []
        run_spiking(
            pos, neg, params=ModelParams(levels=1), duration_ms=20, progress=False, log=lines.append, backend=backend
        )
        assert all(any(word in m for m in lines) for word in says), lines
        assert len(lines) < 10
    assert capfd.readouterr().err == ""


@pytest.mark.slow
def test_brian2_records_its_code_generation_and_synapses(frame):
    pos, neg = frame
    m = run_spiking(pos, neg, params=ModelParams(levels=1), duration_ms=20, progress=False, backend="brian2")
    assert m.params["backend"]["name"] == "brian2" and m.params["backend"]["codegen"] in ("cython", "numpy")
    assert m.params["counts"]["total_synapses"] == sum(m.params["counts"]["synapses_in"].values()) > 0


def test_event_spike_times_come_from_the_timestamps():
    ev = np.zeros(5, dtype=[("x", "<i2"), ("y", "<i2"), ("t", "<i8"), ("p", "i1")])
    ev["x"] = [1, 2, 1, 3, 1]
    ev["y"] = [0, 0, 0, 2, 0]
    ev["t"] = [1000, 1400, 1100, 3600, 2000]  # us; the first and third share a 0.5 ms step
    ev["p"] = [1, 0, 1, 1, 1]
    inp = event_spikes(ev, (4, 3), dt_ms=0.5)
    w, h = 4, 3
    got = sorted(zip(inp.indices.tolist(), inp.steps.tolist()))
    want = sorted([(0 * w + 1, 0), (h * w + 0 * w + 2, 0), (2 * w + 3, 5), (0 * w + 1, 2)])
    assert got == want
    assert inp.merged == 1
    assert inp.period_steps == 6  # window 0 .. 2.6 ms, replayed
    assert inp.on[0, 1] and inp.off[0, 2] and inp.on[2, 3] and not inp.off[0, 1]
    idx, st = inp.spike_times_steps(13)
    assert st.max() == 12 and (idx == 1).sum() == 5  # steps 0, 2, 6, 8, 12
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
    assert np.all(np.bincount(idx)[np.bincount(idx) > 0] == 20)  # 200 Hz for 100 ms
    again = frame_spikes(pos, neg, 200.0, 0.5, 100.0, seed=1)
    np.testing.assert_array_equal(reg.steps, again.steps)
    poi = frame_spikes(pos, neg, 200.0, 0.5, 2000.0, seed=2, process="poisson")
    np.testing.assert_array_equal(
        poi.steps, frame_spikes(pos, neg, 200.0, 0.5, 2000.0, seed=2, process="poisson").steps
    )
    assert abs(poi.indices.size / 3 / 2.0 - 200) < 20
    with pytest.raises(ParameterError, match="input_process"):
        frame_spikes(pos, neg, 200.0, 0.5, 100.0, process="burst")


def test_errors_name_what_is_wrong(frame):
    pos, neg = frame
    ev = image_to_events(disc(16).image)
    with pytest.raises(InputError, match="not both"):
        run_spiking(pos, neg, events=ev.events, sensor_size=ev.sensor_size, progress=False)
    with pytest.raises(InputError, match="sensor_size"):
        run_spiking(events=ev.events, progress=False)
    with pytest.raises(InputError, match="no pixel"):
        run_spiking(np.zeros_like(pos), np.zeros_like(neg), progress=False)
    with pytest.raises(ParameterError, match="settle_ms"):
        run_spiking(pos, neg, duration_ms=100, settle_ms=100, progress=False)
    with pytest.raises(ParameterError, match="dt_ms"):
        run_spiking(pos, neg, dt_ms=0, progress=False)
    with pytest.raises(ParameterError, match="codegen"):
        run_spiking(
            pos, neg, backend="brian2", backend_options={"codegen": "gpu"}, duration_ms=10, settle_ms=0, progress=False
        )
    with pytest.raises(TypeError, match="codegen"):  # an option the backend does not have
        run_spiking(pos, neg, backend="fast", backend_options={"codegen": "cython"}, progress=False)
    with pytest.raises(ParameterError, match="run_spiking: backend='nest2' must be one of 'brian2', 'fast'"):
        run_spiking(pos, neg, backend="nest2", progress=False)
    with pytest.raises(TypeError, match="durration_ms"):
        run_spiking(pos, neg, durration_ms=10)


@pytest.mark.slow
@pytest.mark.parametrize("light", [True, False], ids=["light", "dark"])
def test_ownership_comes_from_the_feedback(light):
    """The feedback ablation: with feedback the rim of a disc points inwards
    (>= 95 % of the boundary pixels that have a vector); without it the two
    sides of every border stay equal, as in the model with f = 1, and no
    boundary pixel keeps an inward vector."""
    from snn_fg.scoring.metrics import truth_scores

    sc = disc(20, light_on_dark=light)
    pos, neg = image_to_frame(sc.image)
    kw = dict(params=ModelParams(levels=4), duration_ms=200, progress=False)
    on = run_spiking(pos, neg, **kw)
    off = run_spiking(pos, neg, feedback=False, **kw)
    t_on, t_off = truth_scores(on.fg_x, on.fg_y, sc), truth_scores(off.fg_x, off.fg_y, sc)
    assert t_on["coverage"] >= 0.5 and t_on["frac_within_45"] >= 0.95
    inward_off = 0.0 if t_off["coverage"] == 0 else t_off["coverage"] * t_off["frac_within_45"]
    assert inward_off <= 0.1
    assert off.params["network"]["feedback"] is False and on.params["network"]["feedback"] is True
    # the border-ownership cells still fire without feedback: the map is zero because both sides are equal
    rec, _ = SpikingRecord.from_maps(off)
    assert sum(int(rec.counts[n].sum()) for n in rec.names if n.startswith("bo_")) > 100


@pytest.mark.slow
def test_a_model_keeps_one_backend_and_gives_a_fresh_models_maps():
    """The spiking model runs every input on one backend object (so the fast
    engine's tables and cell arrays serve them all); a frame run after
    another must give exactly what a fresh model gives."""
    from snn_fg.models import Still, get_model

    first, second = (image_to_frame(disc(r).image) for r in (12, 9))
    kept = get_model("spiking", SMALL, duration_ms=80)
    kept.run_still(Still(*first))
    backend = kept._sim()
    again = kept.run_still(Still(*second))
    assert kept._sim() is backend and backend._tables is not None
    fresh = get_model("spiking", SMALL, duration_ms=80).run_still(Still(*second))
    assert np.abs(fresh.fg_x).sum() > 0
    for k in ("fg_x", "fg_y", "grouping"):
        np.testing.assert_array_equal(getattr(again, k), getattr(fresh, k), err_msg=k)


def test_the_maps_read_only_their_populations_and_are_the_whole_decode_s(small_run):
    """decode(maps_only=True) (what a window's maps use) leaves out the simple
    cells and the border-ownership cells above level 1, and its maps are
    those of the whole decode bit for bit."""
    from snn_fg.models.spiking.decode import decode

    whole, part = decode(small_run.result), decode(small_run.result, maps_only=True)
    assert np.abs(whole[0]).sum() > 0 and whole[2].max() > 0
    for key, a, b in zip(("fg_x", "fg_y", "grouping"), whole[:3], part[:3]):
        np.testing.assert_array_equal(a, b, err_msg=key)
    assert len(whole[3].s) == len(whole[3].bl1) == 2
    assert part[3].s == [] and len(part[3].bl1) == len(part[3].bd2) == 1 and len(part[3].gl) == 2
