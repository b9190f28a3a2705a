"""The quick-start notebook runs top to bottom, headless, on built-in inputs,
shows its figures, and writes nothing into the repository."""

from pathlib import Path

import pytest

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)

NOTEBOOK = Path(__file__).resolve().parents[1] / "notebooks" / "quickstart.ipynb"


@pytest.mark.slow
def test_quickstart_notebook_runs_and_shows_its_figures():
    nbformat = pytest.importorskip("nbformat", reason="the test extras (nbformat, nbclient, ipykernel) are needed")
    nbclient = pytest.importorskip("nbclient", reason="the test extras (nbformat, nbclient, ipykernel) are needed")
    before = sorted(p.name for p in NOTEBOOK.parent.iterdir())
    nb = nbformat.read(NOTEBOOK, as_version=4)
    nbclient.NotebookClient(
        nb, timeout=900, kernel_name="python3", resources={"metadata": {"path": str(NOTEBOOK.parent)}}
    ).execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    images = [o for o in outputs if "image/png" in o.get("data", {})]
    # rate maps, spiking maps, raster, labels vs models, recording windows, a window's raster
    # (and dvs.es and a BSDS image when ../shared is there)
    assert len(images) >= 6
    assert sorted(p.name for p in NOTEBOOK.parent.iterdir()) == before
