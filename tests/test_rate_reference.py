"""The rate model reproduces the authors' published outputs (dataset ``bsds-edfg``)."""

import numpy as np
import pytest

from snn_fg.cli import main
from snn_fg.models.rate.edfg import run_edfg_state
from snn_fg.results.maps import Maps

FRAMES = ["12003", "35070", "105053", "159091", "22090", "41004"]


def _angle_median_deg(ax, ay, bx, by, mask):
    d = np.angle(np.exp(1j * (np.arctan2(ay, ax) - np.arctan2(by, bx))))[mask]
    return np.degrees(np.median(np.abs(d)))


@pytest.mark.parametrize("name", FRAMES)
def test_reproduces_published_frame(dataset, name):
    ref = np.load(dataset("bsds-edfg", f"{name}.npz"))
    st = run_edfg_state(ref["pos"], ref["neg"])
    for key in ("grouping", "fg_x", "fg_y"):
        r = np.corrcoef(getattr(st, key).ravel(), ref[key].ravel())[0, 1]
        assert r >= 0.999, f"{name} {key}: r = {r}"
    ours_orient = (st.winner * (2 * np.pi / 16)).astype(np.float32)
    assert np.mean(ours_orient == ref["orientation"]) >= 0.999
    assert np.abs(st.resp.transpose(1, 2, 0) - ref["resp"]).max() < 1e-5
    mag = np.hypot(ref["fg_x"], ref["fg_y"])
    mask = mag > 0.01 * mag.max()
    assert _angle_median_deg(st.fg_x, st.fg_y, ref["fg_x"], ref["fg_y"], mask) <= 1.0


def test_cli_run_reproduces_published_frame(dataset, tmp_path):
    src = dataset("bsds-edfg", "35070.npz")
    ref = np.load(src)
    assert main(["run", str(src), "--out", str(tmp_path), "--model", "rate", "--no-progress"]) == 0
    m = Maps.load(tmp_path / "maps.npz")
    assert m.fg_x.dtype == np.float32 and m.fg_x.shape == ref["fg_x"].shape
    for key in ("grouping", "fg_x", "fg_y"):
        assert np.corrcoef(getattr(m, key).ravel(), ref[key].ravel())[0, 1] >= 0.999
    assert m.params["r0"] == 8 and m.params["levels"] == 10 and m.params["model"] == "rate"
    assert (tmp_path / "maps.png").stat().st_size > 10_000
