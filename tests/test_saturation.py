"""Windows whose events cover the whole sensor (a start-up burst) are shown
and warned about: the events timeline, its plot, and run's warning and params."""

import numpy as np
import pytest

from snn_fg.cli import main
from snn_fg.events import EVENT_DTYPE, save_events
from snn_fg.results.maps import Maps

W, H = 48, 32


def _burst_then_bar() -> np.ndarray:
    """Every pixel fires once in the first millisecond (a camera's start-up
    burst), then a vertical bar moves right, one column every 5 ms, for 250 ms."""
    burst = np.zeros(W * H, EVENT_DTYPE)
    burst["x"], burst["y"] = np.arange(W * H) % W, np.arange(W * H) // W
    burst["t"] = np.arange(W * H) * 1000 // (W * H)
    burst["p"] = 1
    bar = np.zeros(45 * H, EVENT_DTYPE)
    k = np.arange(45 * H)
    bar["x"], bar["y"], bar["t"], bar["p"] = k // H, k % H, 1000 + (k // H) * 5000 + k % H, k % 2
    return np.concatenate([burst, bar])


@pytest.fixture(scope="module")
def burst_es(tmp_path_factory):
    path = tmp_path_factory.mktemp("burst") / "burst.es"
    save_events(path, _burst_then_bar(), (W, H))
    return path


def test_activity_counts_events_and_pixel_share_window_by_window(burst_es):
    from snn_fg.events.activity import activity, timeline_text

    act = activity(burst_es, window_ms=85)
    assert act.t_start_ms.tolist() == [0, 85, 170] and act.t_end_ms[-1] == pytest.approx(221.032)
    # window 0: the burst (every pixel) and the bar's first 17 columns; then 17 and 11 columns
    assert act.events.tolist() == [W * H + 17 * H, 17 * H, 11 * H]
    assert act.share.tolist() == [1.0, 17 / W, 11 / W] and act.saturated.tolist() == [0]
    text = timeline_text(act).splitlines()
    assert len(text) == 2 + 3 and text[2].split()[:4] == ["0-85", f"{W * H + 17 * H:,}", "100.0", "%"]
    assert text[2].endswith("saturated") and not any(line.endswith("saturated") for line in text[3:])


def test_events_shows_the_timeline_flags_the_burst_and_plots_it(burst_es, tmp_path, capsys):
    assert main(["events", str(burst_es), "--no-progress", "--plot", str(tmp_path / "a.png")]) == 0
    out = capsys.readouterr().out
    assert "activity:" in out and "saturated: window 0 (0-85 ms): events on 100.0% of the sensor's pixels" in out
    wrapped = [line for line in out.splitlines() if not line.startswith("snn-fg: figure saved to")]  # (a path)
    assert "--start-ms 85 skips window 0" in out and max(len(line) for line in wrapped) <= 100
    assert (tmp_path / "a.png").read_bytes()[:4] == b"\x89PNG"
    assert out.splitlines()[-1] == f"snn-fg: figure saved to {tmp_path / 'a.png'}"  # (as compare --plot says it)
    assert main(["events", str(burst_es), "--no-progress", "--window-ms", "1"]) == 0
    out = capsys.readouterr().out
    assert "rows: 8 windows of 1 ms each" in out and "--start-ms 1 skips window 0" in out


def test_the_events_timeline_and_its_advice_start_at_start_ms(burst_es, capsys):
    """--start-ms cuts the table's windows as it cuts --write-frame's and a run's: numbered
    from there, and the start that skips a burst counted from the first event as --start-ms is."""
    assert main(["events", str(burst_es), "--no-progress", "--start-ms", "100"]) == 0
    out = capsys.readouterr().out.splitlines()
    table = out[out.index("activity:") + 1 :]
    assert table[0].startswith("rows: 85 ms windows from 100 ms (--start-ms; times from the first event);")
    assert table[2].split()[:2] == ["100-185", f"{17 * H:,}"]
    assert not any("saturated" in line for line in out)
    # a start inside the burst: window 0 is 0.2-0.8 ms (60 % of the pixels), and 0.8 skips it
    assert main(["events", str(burst_es), "--no-progress", "--start-ms", "0.2", "--window-ms", "0.6"]) == 0
    out = capsys.readouterr().out
    assert "saturated: window 0 (0.2-0.8 ms): events on 60.0% of the sensor's pixels" in out
    assert "--start-ms 0.8 skips window 0" in out


@pytest.mark.slow
def test_run_warns_per_saturated_window_and_records_the_shares(burst_es, tmp_path, capsys):
    assert main(["run", str(burst_es), "--out", str(tmp_path / "a"), "--levels", "3", "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert "snn-fg: warning: window 0 (0-85 ms): events on 100.0% of the sensor's pixels" in err
    assert "1 of 3 windows" in err and "--start-ms 85 skips window 0" in err
    src = Maps.load(tmp_path / "a" / "maps.zarr").params["source"]
    assert src["pixel_share"] == [1.0, round(17 / W, 4), round(11 / W, 4)] and src["saturated_windows"] == [0]
    assert (
        main(["run", str(burst_es), "--out", str(tmp_path / "b"), "--levels", "3", "--start-ms", "1", "--no-progress"])
        == 0
    )
    err = capsys.readouterr().err
    assert "warning" not in err and "more than 50%" not in err
    assert Maps.load(tmp_path / "b" / "maps.zarr").params["source"]["saturated_windows"] == []
    # only the burst: the warning still says how to get past it
    assert (
        main(
            ["run", str(burst_es), "--out", str(tmp_path / "c"), "--levels", "3", "--max-windows", "1", "--no-progress"]
        )
        == 0
    )
    err = capsys.readouterr().err
    assert "1 of 1 window has events on more than 50%" in err and "start later with --start-ms" in err
