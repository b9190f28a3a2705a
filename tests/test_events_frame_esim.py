"""events_to_frame (model stage 1) and the ESIM-style simulator."""

import numpy as np
import pytest

from snn_fg.errors import InputError, ParameterError
from snn_fg.events import EVENT_DTYPE, events_to_frame, image_to_events, image_to_frame, motion_frames
from snn_fg.events.esim import LOG_EPS, PixelOptions


def make_events(rows):
    ev = np.zeros(len(rows), dtype=EVENT_DTYPE)
    for i, (x, y, t, p) in enumerate(rows):
        ev[i] = (x, y, t, p)
    return ev


# ---------------------------------------------------------------- events_to_frame
def test_last_event_wins_hand_made():
    # pixel (1,0): ON then OFF -> neg; pixel (2,1): OFF then ON -> pos;
    # pixel (0,2): single ON; pixel (3,2): ON, ON, OFF, ON -> pos
    ev = make_events(
        [
            (1, 0, 10, 1),
            (2, 1, 11, 0),
            (1, 0, 12, 0),
            (0, 2, 13, 1),
            (3, 2, 14, 1),
            (2, 1, 15, 1),
            (3, 2, 16, 1),
            (3, 2, 17, 0),
            (3, 2, 18, 1),
        ]
    )
    pos, neg = events_to_frame(ev, (4, 3))
    want_pos = np.zeros((3, 4), np.uint8)
    want_neg = np.zeros((3, 4), np.uint8)
    want_pos[1, 2] = want_pos[2, 0] = want_pos[2, 3] = 1
    want_neg[0, 1] = 1
    assert pos.dtype == np.uint8 and neg.dtype == np.uint8
    np.testing.assert_array_equal(pos, want_pos)
    np.testing.assert_array_equal(neg, want_neg)
    assert not (pos & neg).any()


def test_last_means_latest_timestamp_even_if_unsorted():
    ev = make_events([(0, 0, 20, 0), (0, 0, 10, 1)])  # the OFF event is later in time
    pos, neg = events_to_frame(ev, (1, 1))
    assert pos[0, 0] == 0 and neg[0, 0] == 1


def test_last_event_wins_on_random_streams_with_ties():
    rng = np.random.default_rng(7)
    for n in (1, 50, 3000):
        ev = make_events(
            list(zip(rng.integers(0, 9, n), rng.integers(0, 6, n), rng.integers(0, 40, n), rng.integers(0, 2, n)))
        )
        want = {}
        for k in sorted(range(n), key=lambda k: (ev["t"][k], k)):  # time order, ties in array order
            want[(int(ev["y"][k]), int(ev["x"][k]))] = int(ev["p"][k])
        pos, neg = events_to_frame(ev, (9, 6))
        assert {(r, c): 1 for r, c in zip(*np.nonzero(pos))} == {k: 1 for k, p in want.items() if p == 1}
        assert {(r, c): 0 for r, c in zip(*np.nonzero(neg))} == {k: 0 for k, p in want.items() if p == 0}


def test_frame_empty_and_bool_polarity():
    pos, neg = events_to_frame(np.zeros(0, EVENT_DTYPE), (5, 4))
    assert pos.shape == (4, 5) and not pos.any() and not neg.any()
    ev = np.zeros(2, dtype=[("x", "u2"), ("y", "u2"), ("t", "u8"), ("p", "?")])
    ev["x"] = [0, 1]
    ev["p"] = [True, False]
    pos, neg = events_to_frame(ev, (2, 1))
    assert pos.tolist() == [[1, 0]] and neg.tolist() == [[0, 1]]


def test_frame_rejects_out_of_sensor_with_event_index():
    ev = make_events([(0, 0, 1, 1), (1, 1, 2, 1), (7, 0, 3, 0)])
    with pytest.raises(InputError, match="event 2"):
        events_to_frame(ev, (4, 3))
    with pytest.raises(InputError, match="event 0"):
        events_to_frame(make_events([(-1, 0, 1, 1)]), (4, 3))


def test_frame_rejects_missing_fields():
    with pytest.raises(InputError, match="lacks field"):
        events_to_frame(np.zeros(3, dtype=[("x", "i2"), ("y", "i2"), ("t", "i8")]), (4, 3))


# ---------------------------------------------------------------- simulator
def disc(h=48, w=64, r=12, bright=255, dark=0):
    yy, xx = np.mgrid[:h, :w]
    img = np.full((h, w), dark, np.uint8)
    img[(yy - h // 2) ** 2 + (xx - w // 2) ** 2 <= r * r] = bright
    return img


def test_shift4_on_leading_off_trailing_none_inside():
    img = disc()
    rec = image_to_events(img, threshold=0.10, motion="shift4")
    frames, times = motion_frames(img, "shift4")
    # expected frames built independently: content moved up, then right, down, left (edges replicated)
    f0 = img.astype(float) / 255
    up = np.vstack([f0[1:], f0[-1:]])
    up_right = np.hstack([up[:, :1], up[:, :-1]])
    right = np.hstack([f0[:, :1], f0[:, :-1]])
    expected = [f0, up, up_right, right, f0]
    for got, want in zip(frames, expected):
        np.testing.assert_array_equal(got, want)
    ev = rec.events
    for i in range(1, len(expected)):
        sel = (ev["t"] > times[i - 1]) & (ev["t"] <= times[i])
        e = ev[sel]
        brighter = expected[i] > expected[i - 1]
        darker = expected[i] < expected[i - 1]
        on = e[e["p"] == 1]
        off = e[e["p"] == 0]
        # ON exactly on pixels that got brighter (leading edge), OFF exactly where darker (trailing)
        assert set(zip(on["y"], on["x"])) == set(zip(*np.nonzero(brighter)))
        assert set(zip(off["y"], off["x"])) == set(zip(*np.nonzero(darker)))
        # a 0 -> 1 step crosses floor(log((1+eps)/eps)/C) levels at every changed pixel
        n_cross = int(np.floor(np.log((1 + LOG_EPS) / LOG_EPS) / 0.10))
        assert len(on) == n_cross * brighter.sum() and len(off) == n_cross * darker.sum()
    # nothing inside uniform regions: interior and background far from the rim never fire
    yy, xx = np.mgrid[:48, :64]
    r2 = (yy - 24) ** 2 + (xx - 32) ** 2
    quiet = (r2 < 9**2) | (r2 > 15**2)
    assert not quiet[ev["y"], ev["x"]].any()


def test_counts_fall_as_threshold_rises():
    img = disc()
    counts = [len(image_to_events(img, threshold=c).events) for c in (0.10, 0.15, 0.20, 0.30, 0.40)]
    assert all(a > b for a, b in zip(counts, counts[1:])), counts
    assert counts[-1] > 0


def test_multiple_crossings_get_distinct_increasing_times():
    img = np.zeros((1, 2), np.uint8)
    img[0, 1] = 255
    ev = image_to_events(img, threshold=0.5, motion="shift4").events
    first = ev[(ev["t"] <= 5000)]  # the up shift changes nothing in a 1-row image
    assert len(first) == 0
    second = ev[(ev["t"] > 5000) & (ev["t"] <= 10000)]  # right shift: pixel 1 goes bright -> dark
    assert (second["x"] == 1).all() and (second["p"] == 0).all()
    assert len(second) == int(np.floor(np.log((1 + LOG_EPS) / LOG_EPS) / 0.5))
    assert (np.diff(second["t"]) > 0).all()


def test_time_sorted_and_deterministic_with_noise_seed():
    img = disc()
    a = image_to_events(img, motion="circle", pixels=PixelOptions(threshold_sigma=0.03), seed=7).events
    b = image_to_events(img, motion="circle", pixels=PixelOptions(threshold_sigma=0.03), seed=7).events
    c = image_to_events(img, motion="circle", pixels=PixelOptions(threshold_sigma=0.03), seed=8).events
    assert (np.diff(a["t"]) >= 0).all()
    np.testing.assert_array_equal(a, b)
    assert len(a) != len(c) or not np.array_equal(a, c)


def test_circle_motion_positions_and_timing():
    img = disc()
    frames, times = motion_frames(img, "circle", amplitude_px=2.0)
    assert len(frames) == 73 and times[1] - times[0] == 5000
    np.testing.assert_array_equal(frames[0], frames[-1])  # returns to start
    # position 18 is a quarter turn: content moved 2 px down (integer shift is exact)
    f = img.astype(float) / 255
    np.testing.assert_allclose(frames[18], np.vstack([f[:1], f[:1], f[:-2]]), atol=1e-9)
    rec = image_to_events(img, motion="circle")
    assert rec.sensor_size == (64, 48, 2) and len(rec.events) > 0
    assert rec.events["t"].max() <= 72 * 5000


def test_refractory_limits_rate_per_pixel():
    img = disc()
    ev = image_to_events(img, pixels=PixelOptions(refractory_us=1000)).events
    for x, y in {(int(e["x"]), int(e["y"])) for e in ev[:50]}:
        t = ev["t"][(ev["x"] == x) & (ev["y"] == y)]
        assert (np.diff(t) >= 1000).all()
    assert len(ev) < len(image_to_events(img).events)


def test_rgb_and_float_inputs_and_frame():
    g = disc()
    rgb = np.stack([g, g, g], axis=2)
    pos1, neg1 = image_to_frame(g)
    pos2, neg2 = image_to_frame(rgb)
    pos3, neg3 = image_to_frame(g.astype(np.float64) / 255)
    for p, n in ((pos2, neg2), (pos3, neg3)):
        np.testing.assert_array_equal(p, pos1)
        np.testing.assert_array_equal(n, neg1)
    # the frame of the shift4 protocol: last move is "left", so a bright disc ends with
    # ON on its left rim and OFF on its right rim
    rows, cols = np.nonzero(pos1)
    assert cols.mean() < 32
    rows, cols = np.nonzero(neg1)
    assert cols.mean() > 32


@pytest.mark.parametrize(
    "bad", [np.full((4, 4), np.nan), np.full((4, 4), 2.0), np.zeros((2, 2, 2, 2)), np.zeros((0, 5)), np.array([["a"]])]
)
def test_bad_images_raise_input_error(bad):
    with pytest.raises(InputError):
        image_to_events(bad)


def test_bad_parameters_raise_parameter_error():
    with pytest.raises(ParameterError):
        image_to_events(disc(), threshold=0)
    with pytest.raises(ParameterError):
        image_to_events(disc(), motion="zigzag")
    for bad in ({"threshold_sigma": -0.1}, {"refractory_us": -1}, {"eps": 0}, {"threshold_off": 0}):
        with pytest.raises(ParameterError):
            PixelOptions(**bad)
