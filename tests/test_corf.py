"""The CORF push-pull edge operator and the frame-based model's choice of edge operator."""

import numpy as np
import pytest

from snn_fg.cli import main
from snn_fg.frames.scenes import disc
from snn_fg.models import get_model
from snn_fg.models.rate.corf import configuration, corf_edges, corf_responses
from snn_fg.models.rate.fbfg import run_fbfg
from snn_fg.scoring.metrics import truth_scores
from snn_fg.validate import ParameterError


@pytest.mark.parametrize("turns", [0, 1, 2, 3])
def test_step_edge_peaks_on_the_edge_pointing_to_the_light_side(turns):
    img = np.zeros((64, 64))
    img[:, :32] = 1.0  # light on the left: direction 180
    img = np.rot90(img, turns)  # rot90 turns the picture counter-clockwise
    strength, direction = corf_edges(img)
    want = (180 + 90 * turns) % 360
    mid = strength[16:48, 16:48]
    r, c = np.unravel_index(np.argmax(mid), mid.shape)
    assert round(np.degrees(direction[16 + r, 16 + c])) % 360 == want
    # the strongest responses sit within 2 px of the edge line (between pixels 31 and 32)
    across = c if turns % 2 == 0 else r
    assert 29 <= 16 + across <= 34


def test_configuration_puts_centre_on_units_on_the_light_side():
    units = configuration()
    assert len(units) >= 8
    assert all((x < 0) == (p == 1) for p, x, _ in units)


def test_push_pull_suppresses_texture_more_than_edges():
    rng = np.random.default_rng(0)
    edge = np.zeros((64, 64))
    edge[:, :32] = 1.0
    noise = rng.random((64, 64))
    ratio = {}
    for k in (0.0, 1.8):
        e = corf_responses(edge, inhibition=k).max(axis=0)[8:56, 8:56].max()
        n = corf_responses(noise, inhibition=k).max(axis=0)[8:56, 8:56].mean()
        ratio[k] = n / e
    assert ratio[1.8] < 0.5 * ratio[0.0]


def test_fbfg_with_corf_finds_the_disc():
    scene = disc(radius=20)
    maps = run_fbfg(scene.image, edge_operator="corf")
    t = truth_scores(maps.fg_x, maps.fg_y, scene)
    assert t["frac_within_45"] > 0.9 and t["coverage"] > 0.5
    assert maps.params["edge_operator"] == "corf"
    with pytest.raises(ParameterError, match="edge_operator"):
        get_model("fbfg", edge_operator="sobel")


@pytest.mark.slow
def test_cli_edge_operator_is_for_the_frame_based_model_only(tmp_path, capsys):
    assert (
        main(
            ["run", "demo", "--model", "fbfg", "--edge-operator", "corf", "--out", str(tmp_path / "a"), "--no-progress"]
        )
        == 0
    )
    assert main(["run", "demo", "--edge-operator", "corf", "--out", str(tmp_path / "b"), "--no-progress"]) == 2
    assert "--edge-operator" in capsys.readouterr().err
