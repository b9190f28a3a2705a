"""What ``snn-fg compare`` says of what it measured: its figure shows the vectors its numbers
score (``--min-confidence``) and says in words where nothing was compared; its verdict says how
much of B the pixels compared are and how sure a spiking A's vectors on them are; two stills are
spoken of as stills, not recordings."""

import json

import numpy as np

from snn_fg.cli import main
from snn_fg.cli.compare_maps import compare_table
from snn_fg.cli.compare_verdict import verdict
from snn_fg.results.maps import CONFIDENCE, Maps
from snn_fg.scoring.compare_figure import compare_figure
from snn_fg.scoring.metrics import compare_maps


def _edge(windows=2):
    """A horizontal edge of 20 vectors in each of ``windows`` windows (a recording's maps)."""
    fx = np.zeros((windows, 20, 30), np.float32)
    fx[:, 10, 5:25] = 1.0
    return fx


def test_the_compare_figure_leaves_out_the_vectors_min_confidence_leaves_out_and_says_so():
    """A's left half of the edge is sure (3 standard errors), its right half a spike or two (0.5);
    in window 1 no vector is sure. With --min-confidence 2 the figure draws A's sure vectors only,
    as the numbers took them, says so in A's title, and titles window 1's difference in words."""
    fx = _edge()
    conf = np.where(fx > 0, 0.5, 0.0).astype(np.float32)
    conf[0, 10, 5:15] = 3.0
    starts = {"t_start_us": np.array([0, 50_000])}
    a = Maps(fx, 0 * fx, fx.copy(), {"model": "spiking"}, {**starts, CONFIDENCE: conf})
    b = Maps(fx.copy(), 0 * fx, fx.copy(), {"model": "rate"}, starts)
    rows = compare_maps(a, b, min_confidence=2.0)
    assert [r["pixels_compared"] for r in rows] == [10, 0]
    fig = compare_figure(a, b, rows, min_confidence=2.0)
    axes = np.array(fig.axes[:6]).reshape(2, 3)
    diff = np.ma.filled(axes[0, 2].images[1].get_array().astype(float), np.nan)
    assert np.all(diff[10, 5:15] == 0) and np.isnan(diff[10, 15:25]).all()  # (the unsure half left out)
    shown_a = np.asarray(axes[0, 0].images[0].get_array())
    assert shown_a[10, 5:15].any() and not shown_a[10, 15:25].any()
    assert "only vectors at confidence >= 2 (50% of them)" in axes[0, 0].get_title()
    assert "mean 0°, 100% within 45°" in axes[0, 2].get_title()
    titles = " ".join(ax.get_title() for ax in fig.axes)
    assert "nan" not in titles
    assert "no pixel where both maps have a vector at confidence >= 2: nothing compared" in axes[1, 2].get_title()
    assert "(none of them)" in axes[1, 0].get_title()
    text = compare_table(rows)  # (A has vectors there, none sure enough: the table says which)
    assert "A has no figure-ground vector at the confidence threshold in 1 of 2 compared windows (1)" in text


def test_the_verdict_says_how_much_of_b_it_measured_and_how_sure_a_spiking_a_is(tmp_path, capsys):
    """A spiking A that has a vector on a quarter of B's, each a spike or two long (0.7 standard
    errors): the verdict says both beside the agreement, and --json carries the same numbers."""
    fx = _edge()
    a_x = fx.copy()
    a_x[:, 10, 10:25] = 0.0  # (A: 5 of B's 20 vectors)
    conf = np.where(a_x > 0, 0.7, 0.0).astype(np.float32)
    starts = {"t_start_us": np.array([0, 50_000])}
    a = Maps(a_x, 0 * fx, fx.copy(), {"model": "spiking"}, {**starts, CONFIDENCE: conf})
    b = Maps(fx, 0 * fx, fx.copy(), {"model": "rate"}, starts)
    line = verdict(compare_maps(a, b))
    assert line.startswith(
        "All windows: A within 45° of B on 100.0% of 10 pixels, which are 25% of B's vectors, most of A's "
        "decided by a spike or two (none at confidence 2 or more, median 0.7); mean absolute difference 0.0°"
    )
    rate = verdict(compare_maps(b, a))  # (a rate A: no confidence to speak of)
    assert "which are 100% of B's vectors; mean absolute difference 0.0°" in rate and "confidence" not in rate

    a.save(tmp_path / "a.npz"), b.save(tmp_path / "b.npz")
    out = tmp_path / "c.json"
    assert main(["compare", str(tmp_path / "a.npz"), str(tmp_path / "b.npz"), "--no-baseline", "--json", str(out)]) == 0
    pooled = json.loads(out.read_text())["all_windows"]
    assert pooled["coverage_of_b"] == 0.25 and pooled["within_45_of_b"] == 0.25
    assert pooled["confidence_sure_a"] == 0.0 and np.allclose(pooled["confidence_median_a_range"], 0.7)
    assert pooled["verdict"] == line and line in " ".join(capsys.readouterr().out.split())


def test_two_stills_are_compared_in_the_words_of_a_still(tmp_path, capsys):
    """One photo each, run with --image-scale 0.12 and other model parameters: the note's command
    names the photo and the scale a run again needs, and nothing speaks of windows or recordings."""
    fx = _edge(1)[0]
    source = {"input": "data/phone.jpg", "kind": "image", "image_scale": 0.12, "threshold": 0.1, "motion": "shift4"}
    network = {"origin": "recipe", "recipe": "compact"}
    a = Maps(fx, 0 * fx, fx.copy(), {"model": "spiking", "levels": 3, "source": source, "network": network})
    b = Maps(fx.copy(), 0 * fx, fx.copy(), {"model": "rate", "levels": 10, "source": source})
    a.save(tmp_path / "photo_spk" / "maps.npz"), b.save(tmp_path / "photo_rate" / "maps.npz")
    assert main(["compare", str(tmp_path / "photo_spk"), str(tmp_path / "photo_rate"), "--no-baseline"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert (
        "run B's model with A's --network: snn-fg run data/phone.jpg --out DIR --model rate --network compact "
        "--image-scale 0.12" in out
    )
    assert "REC" not in out and "window" not in out.lower() and "recording" not in out
    assert "The frame: A within 45° of B on 100.0% of 20 pixels" in out and "A, B, t: - (each map is one frame)" in out
