"""The natural-scene variant (model ``natural``): pooled grouping polarities,
its spiking form's wiring, and the command line."""

import numpy as np
import pytest

from snn_fg.cli import main
from snn_fg.events import image_to_frame
from snn_fg.frames.scenes import disc
from snn_fg.models.rate.edfg import run_edfg
from snn_fg.models.rate.natural import NATURAL_PARAMS, run_natural
from snn_fg.network import build_network
from snn_fg.params import ModelParams
from snn_fg.results.maps import Maps
from snn_fg.scoring.metrics import truth_scores

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)


def _two_tone_disc(radius=20):
    """A disc lighter than the grey ground on its left half and darker on its right."""
    scene = disc(radius=radius)
    image = np.full(scene.image.shape, 0.5)
    left = np.arange(image.shape[1])[None, :] < image.shape[1] / 2
    image[(scene.labels > 0) & left] = 0.9
    image[(scene.labels > 0) & ~left] = 0.1
    return scene, image_to_frame(image)


def test_pooled_polarities_own_a_figure_whose_contrast_flips_along_its_outline():
    # light/dark competition picks one polarity per place and loses the other
    # half's rim; pooled grouping counts both (measured: 0.76 against 0.91)
    scene, (pos, neg) = _two_tone_disc()
    ref = truth_scores(*(lambda m: (m.fg_x, m.fg_y))(run_edfg(pos, neg)), scene)
    nat = truth_scores(*(lambda m: (m.fg_x, m.fg_y))(run_natural(pos, neg)), scene)
    assert nat["coverage"] == ref["coverage"] > 0.4  # the same vectors, other directions
    assert nat["frac_within_45"] >= 0.9 > 0.8 > ref["frac_within_45"]


def test_pooled_grouping_is_the_sum_of_both_polarities_without_competition():
    from snn_fg.models.rate.grouping import SparseGrouping
    from snn_fg.models.rate.pooled import PooledGrouping, grouping_engine

    assert grouping_engine(ModelParams()) is SparseGrouping
    assert grouping_engine(NATURAL_PARAMS) is PooledGrouping
    scene = disc(radius=12)
    pos, neg = image_to_frame(scene.image)
    from snn_fg.models.rate.edfg import run_edfg_state

    state = run_edfg_state(pos, neg, NATURAL_PARAMS.replace(iterations=1))
    lv = state.engine.levels[0]
    inner = lv.interior
    expect = np.maximum(inner(lv.a_l), 0) + np.maximum(inner(lv.a_d), 0)
    assert np.array_equal(inner(lv.g_l), expect) and np.array_equal(inner(lv.g_d), expect)
    assert (inner(lv.a_l) > 0).any() and (inner(lv.a_d) > 0).any()  # both polarities take part
    # the read-out's grouping map counts G once
    assert np.allclose(state.grouping_result.gd[0], 0) and np.array_equal(state.grouping_result.gl[0], expect)


def test_grouping_polarity_is_checked_and_the_paper_s_by_default():
    from snn_fg.errors import ParameterError

    assert ModelParams().grouping_polarity == "compete"
    assert ModelParams.from_dict(NATURAL_PARAMS.to_dict()) == NATURAL_PARAMS
    with pytest.raises(ParameterError, match="grouping_polarity='both' must be one of 'compete', 'pool'"):
        ModelParams(grouping_polarity="both")


def test_pooled_network_reads_both_polarities_into_every_feedback_cell_and_drops_their_competition():
    net = build_network(NATURAL_PARAMS.replace(levels=2), (40, 52))
    paper = build_network(ModelParams(levels=2), (40, 52))
    inputs = sorted(p.name for p in net.incoming("feedback_1p_1") if p.source.startswith("group_"))
    assert inputs == [
        "group_D_1_inh_feedback_1p_1",
        "group_D_1_to_feedback_1p_1",
        "group_L_1_inh_feedback_1p_1",
        "group_L_1_to_feedback_1p_1",
    ]
    assert [p for p in net.projections if p.source.startswith("group_") and p.target.startswith("group_")] == []
    assert any(p.name == "group_L_1_inh_group_D_1" for p in paper.projections)
    # no rival inhibition (w_inh 0): no excess cells, grouping cells only excited by their own families
    assert not [p for p in net.populations if p.role.startswith("excess_")]
    assert {p.sign for p in net.incoming("group_L_1") if p.source.startswith("bo_")} == {1}


@pytest.mark.slow
def test_natural_models_run_from_the_command_line_with_their_own_parameters(tmp_path):
    assert main(["run", "demo", "--model", "natural", "--out", str(tmp_path / "a"), "--no-progress"]) == 0
    params = Maps.load(tmp_path / "a" / "maps.npz").params
    assert params["model"] == "natural" and params["grouping_polarity"] == "pool"
    assert params["w_inh"] == NATURAL_PARAMS.w_inh and params["iterations"] == NATURAL_PARAMS.iterations
    assert params["side_cue"] == NATURAL_PARAMS.side_cue > 0
    # a flag changes the variant's parameters, not the paper's
    assert (
        main(
            [
                "run",
                "demo",
                "--model",
                "natural",
                "--r0",
                "6",
                "--side-cue",
                "0",
                "--out",
                str(tmp_path / "b"),
                "--no-progress",
            ]
        )
        == 0
    )
    params = Maps.load(tmp_path / "b" / "maps.npz").params
    assert params["r0"] == 6 and params["side_cue"] == 0 and params["grouping_polarity"] == "pool"


@pytest.mark.slow
def test_spiking_form_owns_the_disc_of_both_polarities():
    from snn_fg.models import Still, get_model

    model = get_model("natural-spiking", NATURAL_PARAMS.replace(levels=5), backend="fast")
    for light in (True, False):
        scene = disc(radius=16, light_on_dark=light)
        maps = model.run_still(Still(*image_to_frame(scene.image)))
        assert maps.params["model"] == "natural-spiking"
        t = truth_scores(maps.fg_x, maps.fg_y, scene)
        assert t["frac_within_45"] >= 0.95 and t["coverage"] > 0.6


@pytest.mark.slow
def test_exporters_write_the_pooled_network(tmp_path):
    pytest.importorskip("nir", reason='needs pip install -e ".[nir]"')
    from snn_fg.export.nir import export_nir
    from snn_fg.export.nir_import import read_nir
    from snn_fg.export.pynn import export_pynn

    net = build_network(NATURAL_PARAMS.replace(levels=2), (32, 40))
    back = read_nir(export_nir(net, tmp_path / "n.nir"))
    # (NIR carries each signed kernel as an excitatory and an inhibitory part)
    into = sorted((p.source, p.sign) for p in back.projections if p.target == "feedback_1p_1")
    assert into == [
        ("feedback_1n_2", -1),
        ("feedback_1p_2", 1),
        ("group_D_1", -1),
        ("group_D_1", 1),
        ("group_L_1", -1),
        ("group_L_1", 1),
        ("side_n_2", -1),
        ("side_p_2", 1),
    ]
    folder = export_pynn(net, tmp_path / "pynn")
    written = "".join(p.read_text(errors="ignore") for p in folder.rglob("*.json"))
    assert "group_D_1_to_feedback_1p_1" in written and "side_p_2_to_feedback_1p_1" in written
