"""Shared test fixtures.

* ``dataset`` - ``dataset(name, *parts)``: the path of a dataset of
  :mod:`snn_fg.datasets` (or of a file in it); the test skips, naming the
  fetch command, when the dataset is absent. Every test that uses it is
  marked ``shared``, so ``-m "not shared"`` leaves them all out.
* ``warm_simulators`` (session) - Brian2 and the fast engine run once on a
  network with every kind of projection, which compiles their code (Brian2's
  Cython, numba's loops) once per test process before the first test that
  asks for it; modules that run a simulator ask for it, so no behavioural
  test's time is a cold compile, whatever order ``-n 2`` runs them in.
* an autouse fixture that resets Brian2's global state around every test, so
  that one test's magic network or device settings never leak into another.
"""

from __future__ import annotations

import sys
from types import SimpleNamespace

import pytest

from snn_fg import datasets


def dataset_path(name: str, *parts):
    """Path of dataset ``name`` (or of a file in it); skips the calling test when the dataset is absent."""
    path = datasets.find(name, *parts)
    if path is None:
        pytest.skip(f"needs the {name} dataset, absent from {datasets.data_root()}: {datasets.how_to_get(name)}")
    return path


def earlier_run_files() -> dict:
    """An earlier run's ``maps.npz`` and ``maps.png`` as snn-fg writes them, each with the mark
    ``--force`` tells them by (bytes of other content are a user's: never replaced)."""
    import tempfile
    from pathlib import Path

    import numpy as np
    from matplotlib.figure import Figure

    from snn_fg.results.atomic import save_figure
    from snn_fg.results.maps import Maps

    with tempfile.TemporaryDirectory() as tmp:
        Maps(*(np.zeros((4, 4), np.float32) for _ in range(3)), params={}).save(Path(tmp) / "maps.npz")
        save_figure(Figure(figsize=(1, 1)), Path(tmp) / "maps.png", dpi=20)
        return {name: (Path(tmp) / name).read_bytes() for name in ("maps.npz", "maps.png")}


@pytest.fixture
def dataset():
    return dataset_path


def pytest_collection_modifyitems(items):
    for item in items:
        if "dataset" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.shared)


@pytest.fixture(scope="session")
def warm_simulators():
    """The level-1 default network on a radius-8 disc (every delay and receptor) run 40 ms on both engines."""
    from snn_fg.backends import RunSettings, get_backend
    from snn_fg.events import image_to_frame
    from snn_fg.frames.scenes import disc
    from snn_fg.lowering.input_spikes import frame_spikes
    from snn_fg.network import build_network
    from snn_fg.params import ModelParams

    pos, neg = image_to_frame(disc(8).image)
    net = build_network(ModelParams(levels=1), pos.shape)
    spikes = frame_spikes(pos, neg, 200.0, 0.5, 40.0)
    settings = RunSettings(duration_ms=40.0, dt_ms=net.dt_ms, record_spikes=False)
    brian2 = get_backend("brian2")
    return SimpleNamespace(
        network=net,
        brian2=brian2.simulate(net, spikes, settings),
        brian2_codegen=brian2.describe()["codegen"],
        fast=get_backend("fast").simulate(net, spikes, settings),
    )


@pytest.fixture(autouse=True)
def _reset_brian2():
    yield
    b2 = sys.modules.get("brian2")
    if b2 is not None:
        b2.start_scope()
        b2.device.reinit()
        b2.device.activate()
        b2.prefs.reset_to_defaults()


@pytest.fixture(scope="session")
def run_py():
    """``run(folder, *args, python=sys.executable)``: an export's run.py as a
    user runs it, in its folder, with any snn_fg import failing."""
    import subprocess
    import sys

    def run(folder, *args, python=sys.executable):
        code = (
            "import sys; sys.modules['snn_fg'] = None; "
            f"sys.argv = ['run.py'] + {list(args)!r}; exec(open('run.py').read())"
        )
        return subprocess.run([str(python), "-c", code], cwd=folder, capture_output=True, text=True, timeout=1200)

    return run


@pytest.fixture(scope="session")
def disc_recording(tmp_path_factory):
    """A simulated camera's events of a disc of radius 8 (64 x 64 sensor), as a .es recording."""
    from snn_fg.events import image_to_events, save_events
    from snn_fg.frames.scenes import disc

    rec = image_to_events(disc(8).image)
    path = tmp_path_factory.mktemp("rec") / "disc.es"
    save_events(path, rec.events, rec.sensor_size)
    return path
