"""The quick-start notebook's words agree with what runs (its execution is
tests/test_notebook.py)."""

import json
from pathlib import Path

from snn_fg.backends import DEFAULT_BACKEND

NOTEBOOK = Path(__file__).resolve().parents[1] / "notebooks" / "quickstart.ipynb"


def _markdown() -> str:
    cells = json.loads(NOTEBOOK.read_text())["cells"]
    return "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "markdown")


def test_the_spiking_section_names_the_backend_that_runs_and_its_compile_time():
    from snn_fg.backends.fast.backend import COMPILE_S  # what the engine says while it compiles

    text = " ".join(_markdown().split())
    spiking = text[text.index("## The spiking network") : text.index("## Against ground truth")]
    assert DEFAULT_BACKEND == "fast"
    assert "simulated by the default backend, `fast`" in spiking
    assert "Brian2" not in spiking.replace('backend="brian2"', "")  # (named only as the alternative)
    assert f"compiles the engine's code (numba, about {COMPILE_S} s" in spiking
    assert "a minute or two" not in text
