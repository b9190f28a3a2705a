"""A spiking run's options are passed one way, as keywords, checked once
(``SpikingOptions.from_keywords``) and handed on whole."""

import inspect

import numpy as np
import pytest

from snn_fg.events import image_to_events, image_to_frame, iter_windows
from snn_fg.frames.scenes import disc
from snn_fg.models import Still, get_model
from snn_fg.models.spiking import run_spiking, run_spiking_result, run_spiking_windows
from snn_fg.models.spiking.continuous import simulate_windows, stream_spiking_windows
from snn_fg.params import ModelParams

#: each public run function and the positional inputs it needs
RUNS = [
    (run_spiking, (None, None)),
    (run_spiking_result, (None, None)),
    (run_spiking_windows, ([],)),
    (stream_spiking_windows, ([], None)),
    (simulate_windows, ([],)),
]


@pytest.mark.parametrize("run, inputs", RUNS, ids=[r.__name__ for r, _ in RUNS])
def test_a_run_takes_its_options_as_keywords_only(run, inputs):
    parameters = inspect.signature(run).parameters
    assert "options" not in parameters
    assert [p.kind for p in parameters.values()][-1] is inspect.Parameter.VAR_KEYWORD
    with pytest.raises(TypeError, match=rf"{run.__name__.replace('_result', '')}\(\) got an unexpected keyword"):
        run(*inputs, options=object())


@pytest.mark.slow
def test_a_model_given_frame_and_recording_options_runs_both():
    """A model's frame runs leave its recording options out, and its
    recording runs its frame options: each run takes the keywords it has,
    and one both parts have (``seed``) goes to both."""
    model = get_model(
        "spiking", ModelParams(levels=2), duration_ms=40.0, readout_lag_ms=5.0, seed=3, input_coding="window"
    )
    maps = model.run_still(Still(*image_to_frame(disc(8).image)))
    assert maps.params["simulation"]["duration_ms"] == 40.0
    assert maps.params["simulation"]["seed"] == 3
    windows = list(iter_windows(image_to_events(disc(8).image), window_ms=4, max_windows=2))
    (_, first), (_, second) = model.run_windows(windows)
    assert second.params["simulation"]["readout_lag_ms"] == 5.0
    assert second.params["simulation"]["seed"] == 3
    assert np.isfinite(first.fg_x).all()
