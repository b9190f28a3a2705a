"""experiments.validation.dvs_biplane: what its page says about the continuous run."""

from experiments.validation.dvs_biplane import _maps
from snn_fg.events import image_to_events, iter_windows
from snn_fg.frames.scenes import disc


def test_the_simulated_time_is_the_whole_runs_not_the_first_windows():
    rec = image_to_events(disc(radius=6).image)
    windows = list(iter_windows(rec, window_ms=2))
    assert len(windows) >= 2
    maps, summary, run = _maps("spiking", windows, "fast")
    assert summary["simulated_ms"] == run.spans[-1][1] > run.spans[0][1]
