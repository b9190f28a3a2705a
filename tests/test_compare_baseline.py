"""What ``snn-fg compare`` prints beside a comparison: how far the reference
moves on its own (the baseline), how much of it is compared (cover), and the
spiking maps' per-pixel confidence it can filter on."""

import numpy as np
import pytest

from snn_fg.cli import main
from snn_fg.models.rate.edfg import GroupingResult
from snn_fg.models.spiking.decode import vector_confidence
from snn_fg.results.maps import CONFIDENCE, Maps
from snn_fg.scoring.metrics import compare_maps


def _grouping(n=8, shape=(1, 3)):
    z = [np.zeros((n, *shape))]
    return GroupingResult(
        z, [a.copy() for a in z], [a.copy() for a in z], [a.copy() for a in z], [a.copy() for a in z], [], []
    )


def test_a_vectors_confidence_is_its_length_in_standard_errors_of_its_counts():
    g = _grouping()
    g.bl2[0][0, 0, 0] = 100.0  # pixel 0: 10 spikes in 100 ms, all on one side -> 10 / sqrt(10)
    g.bl2[0][0, 0, 1] = 50.0  # pixel 1: 5 spikes a side: no vector at all
    g.bd1[0][0, 0, 1] = 50.0
    conf = vector_confidence(g, 100.0)
    assert conf[0, 0] == pytest.approx(np.sqrt(10.0))
    assert conf[0, 1] == 0.0 and conf[0, 2] == 0.0  # (pixel 2: no spike)
    assert vector_confidence(g, 400.0)[0, 0] == pytest.approx(np.sqrt(40.0))  # 4x the spikes: 2x as sure


def test_min_confidence_compares_only_the_confident_vectors_and_says_how_much_of_b_is_left():
    fx = np.zeros((4, 5), np.float32)
    fx[1, :] = 1.0
    fx[2, :] = 1.0  # ten vectors pointing right in both maps
    conf = np.zeros_like(fx)
    conf[1, :] = 1.0  # five decided by a spike or two
    conf[2, :] = 3.0
    a = Maps(fx, 0 * fx, fx.copy(), extra={CONFIDENCE: conf})
    b = Maps(fx.copy(), 0 * fx, fx.copy())  # a rate model's maps: no confidence, every vector kept
    (every,) = compare_maps(a, b)
    (sure,) = compare_maps(a, b, min_confidence=2.0)
    assert every["pixels_compared"] == 10 and every["coverage_of_b"] == 1.0
    assert sure["pixels_compared"] == 5 and sure["coverage_of_b"] == 0.5 and sure["confident_a"] == 0.5


@pytest.fixture(scope="module")
def demo_runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("runs")
    for name, its in (("one", "1"), ("ten", "10")):
        assert (
            main(["run", "demo", "--out", str(root / name), "--iterations", its, "--no-figures", "--no-progress"]) == 0
        )
    return root


def test_compare_prints_how_far_the_reference_moves_on_its_own(demo_runs, capsys):
    from snn_fg.frames.still import load_frame
    from snn_fg.models import get_model
    from snn_fg.params import ModelParams
    from snn_fg.scoring.metrics import agreement

    main(["compare", str(demo_runs / "ten"), str(demo_runs / "one")])
    out = capsys.readouterr().out
    row = out.splitlines()[1].split()
    b_within, b_r = float(row[-2]), float(row[-1])
    # B ran 1 iteration: the baseline is B against the model at 2, which the test computes itself
    one = Maps.load(demo_runs / "one")
    two = get_model("rate", ModelParams(iterations=2)).run_still(load_frame("demo", "events")[0])
    want = agreement(one, two)
    assert b_within == pytest.approx(want["within_45"], abs=1e-3) and b_r == pytest.approx(want["grouping_r"], abs=1e-3)
    assert b_within < 1.0  # the demo's map still moves after one iteration
    assert "at 2 iterations instead of 1" in out


def test_without_a_baseline_compare_says_why(demo_runs, tmp_path, capsys):
    spiking = Maps.load(demo_runs / "one")
    spiking.params["model"] = "spiking"
    spiking.save(tmp_path / "s.npz")
    main(["compare", str(demo_runs / "one"), str(tmp_path / "s.npz")])
    out = capsys.readouterr().out
    assert "no baseline: B comes from the spiking model" in out
    assert "two runs with another --seed show a spiking run's spread" in " ".join(out.split())
    assert out.splitlines()[1].split()[-2:] == ["-", "-"]
    main(["compare", str(demo_runs / "ten"), str(demo_runs / "one"), "--no-baseline"])
    assert "B against its own model" not in capsys.readouterr().out


def test_with_outline_the_baseline_is_scored_on_the_outline_pixels_too(tmp_path, capsys):
    """snn-fg compare --outline: A against B on the outline band, and B's baseline
    on that band as well (it was on the whole map, beside A's on the band)."""
    import json

    from snn_fg.events import save_events
    from snn_fg.frames.scenes import flipping_disc_recording
    from snn_fg.scoring.baseline import self_agreement
    from snn_fg.scoring.outline import event_outlines

    _, rec = flipping_disc_recording(32, windows=2, window_ms=40.0)
    path = tmp_path / "disc.npz"
    save_events(path, rec.events, rec.sensor_size)
    for name, its in (("one", "1"), ("ten", "10")):
        argv = ["run", str(path), "--out", str(tmp_path / name), "--iterations", its, "--window-ms", "40"]
        assert main([*argv, "--no-figures", "--no-progress"]) == 0
    a, b = Maps.load(tmp_path / "ten"), Maps.load(tmp_path / "one")
    got = {}
    for outline in (None, 1):
        argv = ["compare", str(tmp_path / "ten"), str(tmp_path / "one"), "--json", str(tmp_path / "m.json"), "--force"]
        assert main(argv + ([] if outline is None else ["--outline", str(outline)])) == 0
        got[outline] = json.loads((tmp_path / "m.json").read_text())["windows"]
    capsys.readouterr()
    where = event_outlines(a, b, 1)
    windows = [r["window_b"] for r in got[1]]
    masks = [where(r["window_a"], r["window_b"]) for r in got[1]]
    band, whole = self_agreement(b, windows, masks=masks), self_agreement(b, windows)
    for row, on_band in zip(got[1], band, strict=True):
        assert row["baseline_within_45"] == on_band["within_45"] and row["baseline_coverage"] == on_band["coverage"]
    for row, on_all in zip(got[None], whole, strict=True):
        assert row["baseline_within_45"] == on_all["within_45"]
    for band_row, whole_row, keep in zip(got[1], got[None], masks, strict=True):  # (the band holds fewer)
        assert 0 < band_row["baseline_pixels"] <= keep.sum() < whole_row["baseline_pixels"]
    nothing = self_agreement(b, windows, masks=[np.zeros_like(m) for m in masks])
    assert all(np.isnan(r["within_45"]) for r in nothing)  # (no pixel kept: no vector compared)


def test_the_pixels_compared_are_the_band_and_both_maps_confident_vectors():
    from snn_fg.scoring.metrics import compared_pixels

    fx = np.ones((3, 4), np.float32)
    conf = np.array([[0, 1, 2, 3]] * 3, np.float32)
    a = Maps(fx, 0 * fx, fx.copy(), extra={CONFIDENCE: conf})
    b = Maps(fx.copy(), 0 * fx, fx.copy())  # (a rate model's: no confidence, every vector kept)
    band = np.zeros((3, 4), bool)
    band[1] = True
    assert compared_pixels(a, b, None, None) is None
    np.testing.assert_array_equal(compared_pixels(a, b, None, None, min_confidence=2.0), conf >= 2)
    keep = compared_pixels(a, b, None, None, where=lambda ia, ib: band, min_confidence=2.0)
    np.testing.assert_array_equal(keep, band & (conf >= 2))


def test_compare_says_which_run_is_a_and_which_is_b(demo_runs, capsys):
    main(["compare", str(demo_runs / "ten"), str(demo_runs / "one"), "--no-baseline"])
    lines = capsys.readouterr().out.splitlines()
    assert lines[2:4] == ["A: ten, the rate model", "B: one, the rate model"]


def test_the_verdict_puts_the_agreement_beside_chance_and_beside_b_against_itself():
    """Over all windows (pixel-weighted): unrelated maps (a quarter within 45 degrees) are called near
    chance, and a pair as close as B to itself is called so; a mean of the per-window fractions would
    give another number here (0.5 rather than the pooled 0.28)."""
    from snn_fg.cli.compare_verdict import verdict

    rows = [
        {"pixels_compared": 900, "angle_within_45_frac": 0.25, "angle_diff_mean_deg": 90.0, "baseline_within_45": 0.9},
        {"pixels_compared": 100, "angle_within_45_frac": 0.75, "angle_diff_mean_deg": 30.0, "baseline_within_45": 0.9},
    ]
    line = verdict(rows)
    assert "30.0% of 1,000 pixels, mean absolute difference 84.0°" in line and "B against itself 90.0%" in line
    assert line.endswith("near chance: the two maps' directions are unrelated.")
    close = [dict(r, angle_within_45_frac=0.88) for r in rows]
    assert verdict(close).endswith("as close as B's model comes to itself.")
    assert verdict([{"pixels_compared": 0}]).startswith("All windows: no pixel")


def test_compare_notes_a_pair_from_other_inputs_or_other_stage_parameters():
    from snn_fg.cli.compare_maps import mismatches

    z = np.zeros((4, 4), np.float32)
    a = Maps(z, z, z, {"levels": 3, "r0": 4.0, "input_pool": 3, "source": {"input": "/data/dvs.es"}})
    b = Maps(z, z, z, {"levels": 10, "r0": 4.0, "input_pool": 1, "source": {"input": "/other/person.aedat4"}})
    notes = mismatches(a, b)
    assert len(notes) == 2 and "different inputs (dvs.es, person.aedat4)" in notes[0]
    assert "levels 3 against 10, input_pool 3 against 1)" in notes[1] and "r0" not in notes[1]
    same = Maps(z, z, z, {"levels": 3, "r0": 4.0, "input_pool": 3, "source": {"input": "/elsewhere/dvs.es"}})
    assert mismatches(a, same) == []
