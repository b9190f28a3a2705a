"""A requested stop (snn_fg.backends.cancel, set by the CLI's signal handler) ends the
long loops at their next check, even when the KeyboardInterrupt the signal
raised was swallowed by a library."""

import numpy as np
import pytest

from snn_fg.backends import available_backends, cancel
from snn_fg.events import image_to_frame
from snn_fg.frames.scenes import disc
from snn_fg.models.rate.edfg import run_edfg
from snn_fg.models.spiking import run_spiking_result

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)

AVAILABLE = available_backends()


@pytest.fixture
def stop_requested():
    cancel.request("SIGTERM")
    yield
    cancel.clear()


@pytest.mark.slow
@pytest.mark.parametrize(
    "backend",
    [
        pytest.param(n, marks=pytest.mark.skipif(not ok, reason=f"backend {n}: {why}"))
        for n, (ok, why) in AVAILABLE.items()
    ],
)
def test_a_requested_stop_ends_a_simulation_on_every_backend(stop_requested, backend):
    pos, neg = image_to_frame(disc(16).image)
    with pytest.raises(KeyboardInterrupt, match="SIGTERM"):
        run_spiking_result(pos, neg, backend=backend, instantiate="input", duration_ms=60, settle_ms=20, progress=False)


@pytest.mark.slow
def test_the_fast_engine_stops_after_the_chunk_it_is_in(stop_requested, monkeypatch):
    from snn_fg.backends.fast import core as fast_core

    calls = []
    real = fast_core.run_steps
    monkeypatch.setattr(fast_core, "run_steps", lambda *a: calls.append(a[:2]) or real(*a))
    pos, neg = image_to_frame(disc(16).image)
    with pytest.raises(KeyboardInterrupt):
        run_spiking_result(pos, neg, backend="fast", duration_ms=400, progress=False)
    assert calls == [(0, calls[0][1])] and calls[0][1] < 800  # one chunk of the 800 steps


def test_the_rate_model_stops_after_the_iteration_it_is_in(stop_requested, monkeypatch):
    from snn_fg.models.rate.grouping import SparseGrouping

    steps = []
    real = SparseGrouping._step
    monkeypatch.setattr(SparseGrouping, "_step", lambda self, pool: steps.append(1) or real(self, pool))
    pos, neg = image_to_frame(disc(16).image)
    with pytest.raises(KeyboardInterrupt):
        run_edfg(pos, neg)
    assert len(steps) == 1


def test_nothing_stops_once_the_request_is_cleared():
    cancel.request("SIGINT")
    cancel.clear()
    pos, neg = image_to_frame(disc(16).image)
    assert np.any(run_edfg(pos, neg).grouping > 0)
