"""Shared test fixtures.

* ``shared`` - path of the read-only ``../shared`` folder; tests that need it
  skip with a reason when it is absent (a user's fresh clone has none).
* an autouse fixture that resets Brian2's global state around every test, so
  that one test's magic network or device settings never leak into another.
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

SHARED = Path(__file__).resolve().parents[1].parent / "shared"


def shared_path(*parts) -> Path:
    """Path under ../shared, skipping the calling test if it is absent."""
    p = SHARED.joinpath(*parts)
    if not p.exists():
        pytest.skip(f"needs {p} (the project's ../shared data), which is absent on this machine")
    return p


@pytest.fixture
def shared():
    return shared_path


@pytest.fixture(autouse=True)
def _reset_brian2():
    yield
    b2 = sys.modules.get("brian2")
    if b2 is not None:
        b2.start_scope()
        b2.device.reinit()
        b2.device.activate()
        b2.prefs.reset_to_defaults()
