"""The fast engine's first run on a machine says that it compiles, and its
progress bar appears only once simulating has begun (it sat at 0 % for the
compile, with an ETA of minutes)."""

import numpy as np
import pytest

from snn_fg.backends.fast import core as fast_core
from snn_fg.events import image_to_frame
from snn_fg.frames.scenes import disc
from snn_fg.models.spiking import run_spiking
from snn_fg.params import ModelParams

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)


def _run(**kw):
    pos, neg = image_to_frame(disc(8).image)
    return run_spiking(pos, neg, params=ModelParams(levels=2), duration_ms=10, **kw)


def test_a_first_run_says_that_it_compiles(monkeypatch):
    said = []
    _run(progress=False, log=said.append)
    assert fast_core.code_is_cached()  # compiled by now, in this process at least
    assert not any("compiling" in s for s in said)
    monkeypatch.setattr(fast_core, "code_is_cached", lambda: False)
    said.clear()
    _run(progress=False, log=said.append)
    assert said[0].startswith(
        "compiling the fast engine's code as it prepares and simulates: the first run on this machine only"
    ), said  # (said first: preparing compiles too)


def test_the_progress_bar_appears_once_the_first_steps_are_done(monkeypatch):
    from snn_fg.results import progress

    calls, made_after = [0], []
    real = fast_core.run_steps

    def counted(*args):
        calls[0] += 1
        return real(*args)

    class Bar:
        def __init__(self, *a, **kw):
            made_after.append(calls[0])

        def update(self, n):
            pass

        def close(self):
            pass

    monkeypatch.setattr(fast_core, "run_steps", counted)
    monkeypatch.setattr(fast_core, "code_is_cached", lambda: True)
    monkeypatch.setattr(progress, "bar", Bar)
    _run(progress=True, log=lambda s: None)
    assert calls[0] >= 1 and np.all(np.array(made_after) >= 1), made_after
