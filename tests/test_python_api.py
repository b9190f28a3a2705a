"""The Python API as the README and docs/usage.md show it: the windows of
``get_model(...).run_windows(iter_windows(...))`` are those of ``snn-fg run``
with the same settings, the last one too (issue A)."""

import numpy as np
import pytest

from snn_fg.cli.main import main
from snn_fg.events import image_to_events, iter_windows, save_events
from snn_fg.frames.scenes import disc
from snn_fg.models import get_model
from snn_fg.params import ModelParams
from snn_fg.results.maps import Maps

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)


@pytest.fixture(scope="module")
def recording():
    return image_to_events(disc(12).image, motion="circle")


@pytest.mark.slow
@pytest.mark.parametrize("in_memory", [False, True])
def test_the_readme_call_gives_the_cli_windows_bit_for_bit_the_last_one_too(recording, tmp_path, in_memory):
    path = tmp_path / "disc.npz"
    save_events(path, recording.events, recording.sensor_size)
    cli = ["--window-ms", "40", "--start-ms", "5", "--max-windows", "2", "--levels", "3", "--readout-lag-ms", "10"]
    assert main(["run", str(path), "--out", str(tmp_path / "o"), "--model", "spiking", *cli, "--no-progress"]) == 0
    want = Maps.load(tmp_path / "o" / "maps.zarr")
    model = get_model("spiking", ModelParams(levels=3), readout_lag_ms=10.0, progress=None)
    source = (recording.events,) if in_memory else (path,)
    size = {"sensor_size": recording.sensor_size[:2]} if in_memory else {}
    got = list(model.run_windows(iter_windows(*source, window_ms=40, start_ms=5, max_windows=2, **size)))
    assert [w.index for w, _ in got] == [0, 1]
    for (_, m), fx, fy, g in zip(got, want.fg_x, want.fg_y, want.grouping):
        np.testing.assert_array_equal(m.fg_x, fx)
        np.testing.assert_array_equal(m.fg_y, fy)
        np.testing.assert_array_equal(m.grouping, g)
    assert np.count_nonzero(want.grouping[1]) > 0  # (equal and not empty)


def test_iter_windows_still_reads_as_a_generator(recording):
    size = recording.sensor_size[:2]
    windows = iter_windows(recording.events, window_ms=40, max_windows=3, sensor_size=size)
    first = next(windows)
    assert first.index == 0 and [w.index for w in windows] == [1, 2] and list(windows) == []
