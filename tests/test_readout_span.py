"""A recording run's read-out: each window counted over the last ``readout_ms`` of its span,
and the ``sliding`` input coding run end to end."""

import numpy as np
import pytest

from snn_fg.errors import ParameterError
from snn_fg.events import image_to_events, iter_windows
from snn_fg.frames.scenes import disc
from snn_fg.models.spiking import run_spiking_windows
from snn_fg.params import ModelParams

PARAMS = ModelParams(levels=2)


@pytest.fixture(scope="module")
def windows():
    rec = image_to_events(disc(radius=8).image, motion="circle")
    return list(iter_windows(rec, window_ms=40, max_windows=2))


def _run(windows, **options):
    return run_spiking_windows(windows, params=PARAMS, backend="fast", progress=False, **options)


def test_a_window_is_counted_over_the_last_readout_ms_of_its_span(windows):
    whole = _run(windows, readout_lag_ms=10.0)
    last = _run(windows, readout_lag_ms=10.0, readout_ms=15.0)
    for k, (w, p) in enumerate(zip(whole, last)):
        sw, sp = w.params["simulation"], p.params["simulation"]
        assert sw["count_from_ms"] == pytest.approx(40 * k + 10) and sw["count_to_ms"] == pytest.approx(40 * k + 50)
        assert sp["count_from_ms"] == pytest.approx(40 * k + 35) and sp["count_to_ms"] == pytest.approx(40 * k + 50)
        assert sp["readout_ms"] == 15.0
        fewer = [p.extra[n].sum() <= w.extra[n].sum() for n in w.extra if n.startswith("spikes_bo_")]
        assert fewer and all(fewer)  # (the same run, counted over a part of the span)
        assert sum(p.extra[n].sum() for n in p.extra if n.startswith("spikes_bo_")) < sum(
            w.extra[n].sum() for n in w.extra if n.startswith("spikes_bo_")
        )


def test_a_readout_longer_than_the_window_counts_the_whole_window(windows):
    m = _run(windows[:1], readout_lag_ms=10.0, readout_ms=500.0)[0].params["simulation"]
    assert m["count_from_ms"] == pytest.approx(10.0) and m["count_to_ms"] == pytest.approx(50.0)


def test_the_readout_must_be_positive(windows):
    with pytest.raises(ParameterError, match="readout_ms"):
        _run(windows, readout_ms=0.0)


def test_the_sliding_coding_holds_across_window_edges_in_a_run(windows):
    held = _run(windows, input_coding="window", readout_lag_ms=0.0)
    sliding = _run(windows, input_coding="sliding", readout_lag_ms=0.0)
    assert sliding[0].params["simulation"]["input_coding"] == "sliding"
    assert sliding[0].params["simulation"]["rate_hz_used"] == 200.0  # (held sources: nothing to calibrate)
    # the first window is the same either way (nothing held before it); in the second the sliding input
    # still holds the first window's pixels as it starts, so the network's spikes differ
    for n in held[0].extra:
        if n.startswith("spikes_"):
            np.testing.assert_array_equal(held[0].extra[n], sliding[0].extra[n])
    assert any(
        not np.array_equal(held[1].extra[n], sliding[1].extra[n]) for n in held[1].extra if n.startswith("spikes_")
    )


def test_the_command_line_takes_the_sliding_coding_and_refuses_a_readout_on_a_still_input(tmp_path, capsys):
    from snn_fg.cli import main

    base = ["run", "demo", "--out", str(tmp_path / "o"), "--model", "spiking", "--no-progress"]
    assert main([*base, "--readout-ms", "30"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--readout-ms" in err and "recordings only" in err, err
    assert main([*base, "--input-coding", "sliding"]) == 2  # (a choice it knows: refused for a still input only)
    err = capsys.readouterr().err
    assert "--input-coding" in err and "recordings only" in err and "invalid choice" not in err, err
    with pytest.raises(SystemExit):
        main([*base, "--readout-ms", "0"])
    assert "--readout-ms: must be > 0" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_a_run_that_reaches_the_recordings_end_says_its_last_read_out_ran_without_input(tmp_path, capsys):
    """The last window's read-out lag runs past the recording's end with no events: a live run's
    last window showed a grouping peak of 211 against about 120 before it (a new user's trial,
    1 Dec). The run says so; one cut by --max-windows reads on through the events after it, and
    does not."""
    from snn_fg.cli import main
    from snn_fg.events import save_events

    rec = image_to_events(disc(radius=8).image, motion="circle")
    path = tmp_path / "disc.npz"
    save_events(path, rec.events, rec.sensor_size)
    base = [
        "run",
        str(path),
        "--model",
        "spiking",
        "--levels",
        "2",
        "--window-ms",
        "40",
        "--no-figures",
        "--no-progress",
    ]
    assert main([*base, "--out", str(tmp_path / "all")]) == 0
    n = sum(1 for _ in open(tmp_path / "all" / "windows.csv")) - 1
    err = capsys.readouterr().err
    assert n >= 3 and (
        "snn-fg: note: the last window's read-out lag ran 20 ms past the recording's end, without input: its maps can "
        f"differ from the windows before it (--max-windows {n - 1} leaves it out"
    ) in " ".join(err.split())
    assert main([*base, "--out", str(tmp_path / "cut"), "--max-windows", str(n - 1)]) == 0
    assert "past the recording's end" not in capsys.readouterr().err


def test_a_live_runs_last_window_note_offers_no_max_windows():
    """A live run's note offered --max-windows 23, which snn-fg live refuses (a new user's trial, 1 Dec)."""
    from snn_fg.cli.runner import last_window_note

    assert "--max-windows 23 leaves it out" in last_window_note(20.0, 24, {"kind": "recording"})
    live = last_window_note(20.0, 24, {"kind": "live"})
    assert "--max-windows" not in live and live.endswith("its maps can differ from the windows before it")
    assert "past the stream's end" in live  # (not "the recording's": a live run reads a stream)
