"""A recording's windows decoded on a second thread while the simulation
goes on (where the process has a second core): the same maps, in the same
order, as decoding in line, and an error on that thread still stops the run."""

import numpy as np
import pytest

import snn_fg.models.spiking.continuous as continuous
from snn_fg.events import image_to_events, iter_windows
from snn_fg.frames.scenes import disc
from snn_fg.params import ModelParams

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)


@pytest.fixture(scope="module")
def windows():
    rec = image_to_events(disc(16).image, motion="circle")
    return list(iter_windows(rec, window_ms=40.0, max_windows=4))


def _stream(windows, cores, monkeypatch, on_window=None):
    monkeypatch.setattr(continuous, "usable_cores", lambda: cores)
    got = []

    def keep(w, maps):
        got.append((w.index, maps))
        if on_window is not None:
            on_window(w, maps)

    continuous.stream_spiking_windows(windows, keep, params=ModelParams(levels=3), backend="fast", progress=False)
    return got


def test_decoding_on_a_second_thread_gives_the_same_maps_in_order(windows, monkeypatch):
    inline = _stream(windows, 1, monkeypatch)
    threaded = _stream(windows, 2, monkeypatch)
    assert [i for i, _ in threaded] == [i for i, _ in inline] == list(range(len(windows)))
    assert all(m.params["simulation"]["decode_thread"] is False for _, m in inline)
    assert all(m.params["simulation"]["decode_thread"] is True for _, m in threaded)
    with_vectors = [int((np.hypot(m.fg_x, m.fg_y) > 0).sum()) for _, m in inline]
    # (not empty maps compared: the gains calibrated to window 0's rate, 97 Hz, leave fewer vectors in these
    # 40 ms windows than the mean over the windows did, 87 Hz)
    assert sum(with_vectors) >= 5, with_vectors
    for (_, a), (_, b) in zip(inline, threaded):
        for k in ("fg_x", "fg_y", "grouping"):
            np.testing.assert_array_equal(getattr(a, k), getattr(b, k), err_msg=k)
        assert a.extra.keys() == b.extra.keys()
        for k in a.extra:
            np.testing.assert_array_equal(a.extra[k], b.extra[k], err_msg=k)


def test_an_error_on_the_decoding_thread_stops_the_run(windows, monkeypatch):
    seen = []

    def fail_on_second(w, maps):
        seen.append(w.index)
        if w.index == 1:
            raise OSError("disk full (raised by the test)")

    with pytest.raises(OSError, match="disk full"):
        _stream(windows, 2, monkeypatch, fail_on_second)
    # the failing window is the last one handed over: none after it, none twice
    assert seen == [0, 1]
