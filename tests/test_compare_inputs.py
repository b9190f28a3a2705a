"""``snn-fg compare`` says when a pair is not one input through two models, whatever the files are
named (snn_fg.scoring.inputs): other recordings, other event frames, one run twice; and its verdict
tells maps that point the other way from unrelated ones."""

import shutil

import numpy as np
import pytest

from snn_fg.cli import main
from snn_fg.cli.compare_maps import mismatches
from snn_fg.cli.compare_verdict import axis_flip, chance_margins, verdict
from snn_fg.errors import ParameterError
from snn_fg.events import image_to_events, save_events
from snn_fg.frames.scenes import disc
from snn_fg.results.maps import Maps
from snn_fg.scoring.metrics import compare_maps, flipped_within_45
from snn_fg.scoring.pairing import pair_windows

RUN = ["--window-ms", "50", "--levels", "4", "--max-windows", "2", "--no-figures", "--no-progress"]


@pytest.fixture(scope="module")
def same_names(tmp_path_factory):
    """Two recordings both named ``rec.npz``, times from 0 in both: a disc and a larger one; the
    first also as ``copy/rec.es`` (the same events in another format); a run of each."""
    tmp = tmp_path_factory.mktemp("names")
    for folder, radius in (("one", 10), ("two", 14)):
        rec = image_to_events(disc(radius).image, motion="circle")
        ev = rec.events.copy()
        ev["t"] -= ev["t"][0]
        (tmp / folder).mkdir()
        save_events(tmp / folder / "rec.npz", ev, rec.sensor_size)
        if folder == "one":
            (tmp / "copy").mkdir()
            save_events(tmp / "copy" / "rec.es", ev, rec.sensor_size)
    for name, path in (("run_one", "one/rec.npz"), ("run_two", "two/rec.npz"), ("run_copy", "copy/rec.es")):
        assert main(["run", str(tmp / path), "--out", str(tmp / name), *RUN]) == 0
    return tmp


def _notes(capsys, a, b, *more):
    capsys.readouterr()
    status = main(["compare", str(a), str(b), "--no-baseline", *more])
    said = capsys.readouterr()
    return status, [x for x in said.out.splitlines() if x.startswith("snn-fg: note:")], said


def test_runs_of_two_recordings_with_one_name_are_told_apart_by_their_events(same_names, capsys):
    status, notes, _ = _notes(capsys, same_names / "run_one", same_names / "run_two")
    assert status == 0 and notes == [
        "snn-fg: note: A and B come from different inputs (both rec.npz: their first events differ)"
    ]
    # the same events in another file and format are one input
    status, notes, _ = _notes(capsys, same_names / "run_one", same_names / "run_copy")
    assert status == 0 and notes == []


def test_runs_stored_before_their_inputs_first_events_were_kept_are_told_by_their_windows_event_counts(same_names):
    old = [Maps.load(same_names / name) for name in ("run_one", "run_two", "run_copy")]
    for m in old:  # (as stored before: no sensor size, no digest)
        for key in ("events_head", "sensor_size"):
            m.params["source"].pop(key, None)
    notes = mismatches(old[0], old[1], pair_windows(old[0], old[1]))
    assert len(notes) == 1 and notes[0].startswith(
        "A and B come from different inputs (both rec.npz: A's window 0 and B's window 0 start together and hold"
    )
    assert mismatches(old[0], old[2], pair_windows(old[0], old[2])) == []  # (rec.npz, rec.es: counts agree)
    assert mismatches(old[0], old[2]) == ["A and B come from different inputs (rec.npz, rec.es)"]  # (names alone)


def _maps(starts_us, first_event_us, name, n=8):
    fx = np.ones((len(starts_us), n, n), np.float32)
    source = {"input": name, "clock": "recording", "first_event_us": first_event_us}
    return Maps(fx, fx * 0, fx, {"source": source}, extra={"t_start_us": np.asarray(starts_us, np.int64)})


def test_two_inputs_that_share_no_clock_are_refused_in_words():
    a = _maps([0, 85_000], 0, "/data/dvs.es")
    b = _maps([0, 85_000], 1_605_537_493_718_345, "/data/person.aedat4")
    with pytest.raises(ParameterError, match=r"A and B are runs of different inputs \(dvs.es, person.aedat4\): their "):
        pair_windows(a, b)
    same = _maps([0, 85_000], 1_605_537_493_718_345, "/elsewhere/dvs.es")
    with pytest.raises(ParameterError, match="A's first window starts 18,583 days before B's first event"):
        pair_windows(a, same)


def _still(**source):
    z = np.zeros((4, 4), np.float32)
    return Maps(z, z, z, {"source": {"input": "bear.jpg", "kind": "image", **source}})


def test_runs_made_from_other_event_frames_are_noted_by_the_setting():
    assert mismatches(_still(threshold=0.1, motion="paper"), _still(threshold=0.3, motion="shift4")) == [
        "A and B were made from other event frames (threshold 0.1 against 0.3, motion paper against shift4): "
        "the windows compared hold other events, so the maps part by more than the models do; make both "
        "with the same options"
    ]
    cut = {"input": "dvs.es", "clock": "recording", "first_event_us": 0, "window_ms": 85.0, "stride_ms": 85.0}
    a, b = (_maps([0, 85_000], 0, "dvs.es") for _ in range(2))
    a.params["source"] = {**cut, "start_ms": 0.0}
    b.params["source"] = {**cut, "start_ms": 85.0, "denoise_us": 1000}
    # paired by their start: the runs' starts do not change a paired window's events; the filter does
    assert "(denoise_us off against 1000)" in mismatches(a, b, pair_windows(a, b))[0]
    # paired by place: window 0 of one starts 85 ms before window 0 of the other
    assert "(denoise_us off against 1000, start_ms 0.0 against 85.0)" in mismatches(a, b, pair_windows(a, b, 0))[0]
    b.params["source"] = {**cut, "window_ms": 50.0}
    assert "(window_ms 85.0 against 50.0)" in mismatches(a, b, pair_windows(a, b))[0]


def test_a_run_against_itself_or_its_copy_is_said_to_agree_by_construction(same_names, capsys, tmp_path):
    _, notes, _ = _notes(capsys, same_names / "run_one", same_names / "run_one" / "maps.zarr")
    assert notes == [
        "snn-fg: note: A and B are the same run: they agree by construction, which says nothing of a model"
    ]
    shutil.copytree(same_names / "run_one", tmp_path / "copied")
    _, notes, _ = _notes(capsys, same_names / "run_one", tmp_path / "copied")
    assert notes == [
        "snn-fg: note: A and B are identical runs (the same maps and parameters: a copy?): they agree by "
        "construction, which says nothing of a model"
    ]


def _field(angles):
    """Unit vectors at ``angles`` (radians; nan: no vector)."""
    have = ~np.isnan(angles)
    return (np.where(have, np.cos(angles), 0).astype(np.float32), np.where(have, np.sin(angles), 0).astype(np.float32))


def _judged(a, b):
    """The verdict on ``a`` against ``b`` (each ``(fg_x, fg_y)``), after the note on a flipped axis if any."""
    (ax, ay), (bx, by) = a, b
    a, b = Maps(ax, ay, ax * 0), Maps(bx, by, bx * 0)
    pairing = pair_windows(a, b)
    rows = compare_maps(a, b, pairing=pairing)
    return f"{axis_flip(rows, flipped_within_45(a, b, pairing))} {verdict(rows)}"


def test_the_verdict_tells_maps_that_point_the_other_way_from_unrelated_ones():
    """A disc's border owned by the disc (vectors towards its centre) against itself, unrelated
    directions and itself negated; horizontal edges against their vectors' y negated (an axis flip
    reads as opposed where edges run across that axis). On the disc's every direction a flipped
    axis spreads the differences over 0-180 degrees as chance does: a note says it, from B's
    agreement once that axis is flipped back."""
    yy, xx = np.mgrid[-20:21, -20:21]
    r = np.hypot(xx, yy)
    ring = np.where(np.abs(r - 12) < 1.5, np.arctan2(-yy, -xx), np.nan)  # (towards the centre)
    a = _field(ring)
    rng = np.random.default_rng(0)
    # (a map against itself: the same directions, said so; it read "above chance", a new user's trial, 1 Dec)
    same = _judged(a, a)
    assert same.startswith("None The frame") and same.endswith(
        "the same directions on every compared pixel (under 0.01° apart)."
    )
    unrelated = _judged(a, _field(np.where(np.isnan(ring), np.nan, rng.uniform(0, 2 * np.pi, ring.shape))))
    assert unrelated.startswith("None") and unrelated.endswith("near chance: the two maps' directions are unrelated.")
    opposed = "opposed: B points the other way on most pixels (a sign or axis flip?)."
    assert _judged(a, _field(ring + np.pi)).endswith(opposed)
    stripes = np.full(r.shape, np.nan)
    stripes[[5, 30]] = np.pi / 2
    stripes[[10, 35]] = -np.pi / 2
    assert _judged(_field(stripes), _field(-stripes)).endswith(opposed)
    # turned 90 degrees: none within 45, mean 90: not unrelated, not opposed
    assert "below chance" in _judged(a, _field(ring + np.pi / 2))
    # one axis flipped on the disc: as drawn its differences spread like chance's; flipped back, all agree
    y_flipped = _judged(a, (a[0], -a[1]))
    assert y_flipped.startswith("A agrees with B once B's y axis is flipped (within 45° on 100.0% of the pixels")
    assert y_flipped.endswith("near chance: the two maps' directions are unrelated.")
    assert _judged(a, (-a[0], a[1])).startswith("A agrees with B once B's x axis is flipped")
    assert _judged(a, tuple(f[::-1] for f in a)).startswith("A agrees with B once B's y axis is flipped")  # upside down
    assert _judged(a, _field(ring + np.pi)).startswith("None")  # (negated: the verdict's "opposed" says it)


def test_the_margin_from_chance_is_three_binomial_deviations_of_the_pixels_with_a_floor():
    assert chance_margins(100) == pytest.approx((3 * np.sqrt(0.25 * 0.75 / 100), 3 * 180 / np.sqrt(12) / 10))
    assert chance_margins(10_000) == (0.10, 10.0)
