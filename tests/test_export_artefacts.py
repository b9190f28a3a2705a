"""networks/ keeps the default iCub-size (304 x 240) network as a NIR graph and
its resource report; both must have been made from the network the code builds
today (python experiments/spiking_export_network.py regenerates them)."""

import gzip
import json
import re
from pathlib import Path

import pytest

from snn_fg.export.artefacts import NIR_NAME, REPORT_NAME, REPORT_TABLE, default_icub_network
from snn_fg.export.board import fingerprint

NETWORKS = Path(__file__).resolve().parents[1] / "networks"
MAX_BYTES = 8_000_000


@pytest.mark.slow
def test_stored_icub_artefacts_are_current_and_small():
    nir = pytest.importorskip("nir", reason='needs pip install -e ".[nir]"')
    sha = fingerprint(default_icub_network())
    rep = json.loads((NETWORKS / REPORT_NAME).read_text())
    assert rep["network_sha256"] == sha, "networks/ is stale: run python experiments/spiking_export_network.py"
    assert rep["frame_shape"] == [240, 304] and rep["totals"]["neurons"] > 0
    assert (NETWORKS / REPORT_TABLE).read_text().startswith("Whole network for a 304 x 240 sensor (width x height)")
    from snn_fg.export.nir_import import read_graph

    g = read_graph(nir, NETWORKS / NIR_NAME)  # gunzip, then nir.read
    assert json.loads(g.metadata["snn_fg"])["network_sha256"] == sha
    assert {"Conv2d", "LIF", "LI", "Delay"} <= {type(n).__name__ for n in g.nodes.values()}
    for name in (NIR_NAME, REPORT_NAME, REPORT_TABLE):
        assert (NETWORKS / name).stat().st_size < MAX_BYTES, name


def test_the_readme_gives_the_nir_files_size():
    """networks/README.md says how large the gunzipped HDF5 file is: the stored file's size, in MB."""
    said = re.search(r"the HDF5 file is ([\d.]+) MB", (NETWORKS / "README.md").read_text()).group(1)
    assert said == f"{len(gzip.decompress((NETWORKS / NIR_NAME).read_bytes())) / 1e6:.1f}"
