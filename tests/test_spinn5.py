"""SpiNN-5 boards in the resource report: how they are counted, checked against sPyNNaker's own
mappings (experiments/results/export_spinnaker.json), and the widest sensor one board holds."""

import json
from pathlib import Path

import pytest

from snn_fg.cli import main
from snn_fg.export.board import board_network
from snn_fg.export.report import resource_report
from snn_fg.export.spinn5 import board_cores, boards_allocated, width_ranges
from snn_fg.network import build_network
from snn_fg.network.recipes import load_description, network_for
from snn_fg.params import ModelParams

MAPPINGS = Path(__file__).parents[1] / "experiments" / "results" / "export_spinnaker.json"
#: chips x cores of a SpiNN-5 board, and the one core of each chip SCAMP's monitor keeps
BOARD_CHIPS, CHIP_CORES, SCAMP_CORES = 48, 18, 1


def _rows():
    return [r for r in json.loads(MAPPINGS.read_text())["rows"] if not r["combined_cores"]]


def test_a_board_gives_the_network_the_cores_spynnaker_left_free():
    """767: what every one-board mapping of sPyNNaker left of a board's 864 cores once SCAMP's
    monitors and its own system cores (an extra monitor a chip, a packet gatherer) were placed."""
    one = [r for r in _rows() if r["machine_boards"] == 1]
    assert one
    for r in one:
        system = sum(r["cores_system"].values())
        assert BOARD_CHIPS * (CHIP_CORES - SCAMP_CORES) - system == board_cores() == 767, r["config"]


def test_machines_of_more_than_one_board_come_in_triads():
    """SpiNNMachine's size_from_n_boards (spalloc's rule): a rectangle of triads near a square."""
    assert [boards_allocated(n) for n in range(1, 11)] == [1, 3, 3, 6, 6, 6, 12, 12, 12, 12]
    assert width_ranges([148, 136, 137, 142, 143, 144]) == "136-137, 142-144, 148"


def _network(config: str):
    a, _, b = config.partition(":")
    if a.endswith(".json"):
        return load_description(str(MAPPINGS.parents[2] / a))
    if a == "compact":
        w, h = (int(v) for v in b.split("x"))
        return network_for("compact", (h, w))[0]
    w, h = (int(v) for v in a.split("x"))
    return build_network(ModelParams(levels=int(b)), (h, w))


@pytest.mark.slow
@pytest.mark.parametrize("row", _rows(), ids=lambda r: r["config"])
def test_the_reports_boards_are_the_machine_spynnaker_mapped_onto(row):
    """sPyNNaker sizes its virtual machine as a real one is allocated: one board, or triads. The
    report's boards make that machine for every stored mapping, and it says one board where
    sPyNNaker placed the network on one (compact 147 x 116: 721 cores on 47 chips, where the report
    said 49 chips, 2 boards, counting 15 cores a chip against 48 chips; 150 x 118: 756 on 48 chips;
    151 x 119, 769 cores: a machine of 3)."""
    sp = resource_report(board_network(_network(row["config"])))["targets"]["spinnaker1"]
    assert sp["boards_allocated"] == row["machine_boards"], (sp["cores"], sp["chips"], row["chips_used"])
    assert (sp["boards_spinn5"] == 1) == row["fits"]
    if row["fits"]:
        assert sp["chips"] <= 48


@pytest.mark.slow
def test_the_widest_sensor_one_board_holds_is_the_same_whatever_size_is_asked(tmp_path, capsys):
    """The compact network's report at 304 x 240 said one board holds at most 135 x 107 and at
    152 x 120 141 x 111: a halving search over a count of cores that is not monotonic in the width
    (tiles whose sides divide the grid's: 148 x 117 needs 807 cores, 150 x 118 756). Now every width
    is counted up to the widest whose cells alone could fit: one answer, the widest that fits."""
    answers = []
    for size in ("304x240", "152x120"):
        out = tmp_path / f"{size}.json"
        args = ["export", "--format", "report", "--target", "spinnaker", "--network", "compact"]
        assert main([*args, "--sensor-size", size, "--out", str(out)]) == 0
        answers.append(json.loads(out.read_text())["targets"]["spinnaker1"]["largest_sensor_one_board"])
    assert answers[0] == answers[1]
    one = answers[0]
    assert (one["width"], one["height"]) == (150, 118) and one["cores"] <= one["board_cores"]
    assert one["narrower_not_fitting"] == [148]
    assert "one board holds at most a 150 x 118 sensor" in capsys.readouterr().out
