"""The ``window`` input coding: a recording's events held as the window's
event frame while they arrive (snn_fg.lowering.held_input)."""

import numpy as np
import pytest

from snn_fg.errors import ParameterError
from snn_fg.events.frame import events_to_frame
from snn_fg.lowering.held_input import HeldStream, held_spikes, hold_period_steps
from snn_fg.network import build_network
from snn_fg.network.graph import Network
from snn_fg.params import ModelParams

DT = 0.5  # ms
EV = np.dtype([("x", "<i2"), ("y", "<i2"), ("t", "<i8"), ("p", "<i1")])


def events(rows):
    """Events from (x, y, step, polarity) on the DT grid (t in us, mid-step)."""
    out = np.zeros(len(rows), EV)
    for i, (x, y, step, p) in enumerate(rows):
        out[i] = (x, y, int(step * DT * 1000 + 100), p)
    return out


def stream(shape=(1, 2), resets=(0, 40), seed=0):
    return HeldStream(shape, DT, 0.0, 200.0, resets, seed)


def expected(source, begin, stop, phase, period=10):
    return [s for s in range(begin, stop) if (s - phase[source]) % period == 0]


def test_the_period_is_the_input_rate_on_the_step_grid():
    assert hold_period_steps(200.0, 0.5) == 10
    assert hold_period_steps(200.0, 1.0) == 5
    assert hold_period_steps(3000.0, 1.0) == 1


def test_an_event_holds_its_source_until_the_window_ends():
    st = stream()
    st.add(events([(0, 0, 3, 1)]))
    idx, steps = st.take_until(60)
    assert set(idx) == {0}  # pixel 0, ON; nothing else fires
    assert list(steps) == expected(0, 3, 40, st.phase)  # from its step to the window's end, once a period
    assert st.on.tolist() == [[True, False]] and not st.off.any()


def test_the_next_event_of_a_pixel_switches_its_source():
    st = stream()
    st.add(events([(1, 0, 3, 1), (1, 0, 17, 0)]))  # pixel 1: ON at step 3, OFF at step 17
    idx, steps = st.take_until(40)
    on, off = 1, 2 + 1  # ON source of pixel 1; OFF sources follow the 2 ON ones
    assert list(steps[idx == on]) == expected(on, 3, 17, st.phase)
    assert list(steps[idx == off]) == expected(off, 17, 40, st.phase)


def test_a_window_start_clears_every_pixel():
    st = stream(resets=(0, 20, 40))
    st.add(events([(0, 0, 3, 1), (1, 0, 25, 0)]))
    idx, steps = st.take_until(40)
    assert list(steps[idx == 0]) == expected(0, 3, 20, st.phase)  # cut at the window boundary (step 20)
    assert list(steps[idx == 3]) == expected(3, 25, 40, st.phase)  # the next window builds its own frame


@pytest.mark.parametrize(
    "make",
    [
        lambda: stream((4, 6), resets=(0, 100, 170, 300), seed=3),  # (holds cleared at window edges)
        lambda: HeldStream((4, 6), DT, 0.0, 200.0, (), 3, hold_steps=70),  # (sliding: 70 steps after each event)
    ],
    ids=["window", "sliding"],
)
def test_steps_taken_in_chunks_give_the_spikes_taken_at_once(make):
    rng = np.random.default_rng(5)
    rows = sorted(
        (
            (int(rng.integers(0, 6)), int(rng.integers(0, 4)), int(rng.integers(0, 300)), int(rng.integers(0, 2)))
            for _ in range(200)
        ),
        key=lambda r: r[2],
    )
    ev = events(rows)
    whole = make()
    whole.add(ev)
    a_idx, a_steps = whole.take_until(300)
    parts = make()
    got_i, got_s, done = [], [], 0
    t = ev["t"] / (DT * 1000)
    for cut in (37, 100, 101, 180, 255, 300):  # events added only as the steps before them are taken
        parts.add(ev[(t >= done) & (t < cut)])
        i, s = parts.take_until(cut)
        got_i.append(i)
        got_s.append(s)
        done = cut
    assert np.array_equal(np.concatenate(got_i), a_idx) and np.array_equal(np.concatenate(got_s), a_steps)


def test_at_a_window_end_the_held_sources_are_the_window_event_frame():
    rng = np.random.default_rng(11)
    h, w = 5, 7
    rows = sorted(
        (
            (int(rng.integers(0, w)), int(rng.integers(0, h)), int(rng.integers(0, 160)), int(rng.integers(0, 2)))
            for _ in range(80)
        ),
        key=lambda r: r[2],
    )
    ev = events(rows)
    st = stream((h, w), resets=(0, 170))
    st.add(ev)
    idx, steps = st.take_until(170)
    last_period = idx[steps >= 160]  # every held source fires once in the last period (10 steps)
    pos, neg = events_to_frame(ev, (w, h))
    assert set(last_period[last_period < h * w]) == set(np.flatnonzero(pos))
    assert set(last_period[last_period >= h * w] - h * w) == set(np.flatnonzero(neg))


def test_held_spikes_carries_a_hold_across_chunks_and_cuts_it_at_a_reset_on_the_boundary():
    phase = np.zeros(4, np.int64)
    (i1, s1), carried = held_spikes(np.array([2]), np.array([0]), 2, 5, phase, 0, 10, np.array([10, 20]), None)
    assert list(s1) == [5] and list(carried[0]) == [0]
    (i2, s2), carried = held_spikes(
        np.zeros(0, np.int64), np.zeros(0, np.int64), 2, 5, phase, 10, 20, np.array([10, 20]), carried
    )
    assert s2.size == 0 and carried[0].size == 0  # the reset at step 10 ended it


@pytest.mark.parametrize("coding", ["window", "sliding"])
def test_the_coding_is_part_of_a_stored_description(coding):
    net = build_network(ModelParams(levels=2), (16, 16))
    assert net.input_coding == "events" and "input_coding" not in net.to_dict()  # (old files unchanged)
    held = Network.from_dict({**net.to_dict(), "input_coding": coding})
    assert held.input_coding == coding and Network.from_dict(held.to_dict()).input_coding == coding
    with pytest.raises(ParameterError, match="input_coding"):
        Network.from_dict({**net.to_dict(), "input_coding": "frames"})


@pytest.mark.slow
@pytest.mark.parametrize("coding", ["window", "sliding"])
def test_a_recording_run_with_a_held_coding_holds_the_frame_and_owns_a_disc_inward(coding):
    from snn_fg.events import image_to_events, iter_windows
    from snn_fg.frames.scenes import disc
    from snn_fg.models.spiking import run_spiking_windows
    from snn_fg.results.maps import CONFIDENCE
    from snn_fg.scoring.metrics import truth_scores

    scene = disc(radius=10)
    rec = image_to_events(scene.image, motion="circle")
    wins = list(iter_windows(rec, window_ms=60, max_windows=2))
    maps = run_spiking_windows(wins, params=ModelParams(levels=3), input_coding=coding, seed=4, progress=False)
    sim = maps[0].params["simulation"]
    assert sim["input_coding"] == coding and sim["seed"] == 4
    assert sim["rate_hz_used"] == 200.0  # held sources fire at the network's own rate: nothing to calibrate
    for m in maps:
        assert truth_scores(m.fg_x, m.fg_y, scene)["frac_within_45"] >= 0.9
        has = np.hypot(m.fg_x, m.fg_y) > 0
        conf = m.extra[CONFIDENCE]
        assert conf.shape == m.fg_x.shape and np.all(conf[~has] == 0) and np.all(conf[has] > 0)


@pytest.mark.slow
def test_an_export_whose_network_holds_the_frame_is_given_held_input_spikes(tmp_path, capsys):
    """A stored description edited to ``"input_coding": "window"`` is exported with it, and
    ``--write-spikes`` then hands the board the window's frame as held sources."""
    import dataclasses

    from snn_fg.cli import main
    from snn_fg.events import image_to_events, save_events
    from snn_fg.frames.scenes import disc

    rec = image_to_events(disc(radius=8).image, motion="circle")
    save_events(tmp_path / "disc.npz", rec.events, rec.sensor_size)
    net = build_network(ModelParams(levels=2), (24, 32))
    dataclasses.replace(net, input_coding="window").save(tmp_path / "held.json")
    assert (
        main(["export", "--format", "pynn", "--out", str(tmp_path / "ex"), "--network", str(tmp_path / "held.json")])
        == 0
    )
    assert (
        main(
            [
                "events",
                str(tmp_path / "disc.npz"),
                "--window-ms",
                "40",
                "--write-spikes",
                str(tmp_path / "in.npz"),
                "--export",
                str(tmp_path / "ex"),
            ]
        )
        == 0
    )
    assert "held as the window's frame at 200 Hz" in capsys.readouterr().out
    d = np.load(tmp_path / "in.npz")
    assert int(d["period_steps"]) == 80  # the window (40 ms at 0.5 ms), replayed
    for source in np.unique(d["indices"]):
        gaps = np.diff(np.sort(d["steps"][d["indices"] == source]))
        assert np.all(gaps == 10)  # one spike each 5 ms (200 Hz) from the pixel's last event on


def sliding(shape=(1, 2), hold=20, seed=0):
    return HeldStream(shape, DT, 0.0, 200.0, (), seed, hold_steps=hold)


def test_a_sliding_hold_crosses_a_window_edge_and_ends_a_window_after_its_event():
    st = sliding(hold=20)
    st.add(events([(0, 0, 15, 1)]))  # a window of 20 steps would start at step 20; the hold does not stop there
    idx, steps = st.take_until(60)
    assert set(idx) == {0} and list(steps) == expected(0, 15, 35, st.phase)


def test_a_sliding_hold_is_renewed_by_its_pixel_next_event():
    st = sliding(hold=20)
    st.add(events([(1, 0, 5, 1), (1, 0, 18, 1), (1, 0, 30, 0)]))  # ON, ON again, then OFF
    idx, steps = st.take_until(80)
    on, off = 1, 3
    assert list(steps[idx == on]) == expected(on, 5, 30, st.phase)  # the second event keeps it past step 25
    assert list(steps[idx == off]) == expected(off, 30, 50, st.phase)


def test_at_every_window_end_the_sliding_hold_is_that_window_event_frame():
    """Windows of 40 steps, one after the other, sources firing every step (2 kHz at 0.5 ms): at
    each window's last step the sources that fire are exactly the event frame of that window's
    events, although no hold was cleared as it started."""
    rng = np.random.default_rng(12)
    h, w, length = 4, 5, 40
    rows = sorted(
        (
            (int(rng.integers(0, w)), int(rng.integers(0, h)), int(rng.integers(0, 160)), int(rng.integers(0, 2)))
            for _ in range(120)
        ),
        key=lambda r: r[2],
    )
    ev = events(rows)
    st = HeldStream((h, w), DT, 0.0, 2000.0, (), 0, hold_steps=length)
    assert st.period == 1
    st.add(ev)
    idx, steps = st.take_until(160)
    step_of = np.array([r[2] for r in rows])
    for end in (40, 80, 120, 160):
        pos, neg = events_to_frame(ev[(step_of >= end - length) & (step_of < end)], (w, h))
        frame = set(np.flatnonzero(pos)) | {h * w + i for i in np.flatnonzero(neg)}
        assert set(idx[steps == end - 1]) == frame, end
        assert set(idx[steps == end - length - 1]) != frame  # (the frame a window earlier is another)
