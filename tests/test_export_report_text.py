"""The export report as a reader meets it: 100 columns, readable ranges,
width x height, printed without --out, one chip family with --target."""

import json
import re

import pytest

from snn_fg.cli import main
from snn_fg.export.report import report_table, resource_report
from snn_fg.network import build_network
from snn_fg.params import ModelParams


@pytest.fixture(scope="module")
def report():
    return resource_report(build_network(ModelParams(levels=2), (24, 32)))


@pytest.mark.slow
def test_the_table_fits_100_columns_and_writes_ranges_and_sizes_readably(report):
    from snn_fg.export.report import readable

    text = report_table(report)
    lines = text.splitlines()
    assert max(len(line) for line in lines) <= 100
    assert lines[0].startswith("Whole network for a 32 x 24 sensor (width x height), 2 levels")
    weights = [line for line in lines if " weights " in line and " mV" in line]
    assert len(weights) == 2
    for line in weights:
        assert re.search(r"weights \S+ to \S+ mV: range \S+ \(\S+ on one population\)", line), line
        assert not re.search(r"e[-+]\d\d-\d", line), line  # no "9.01e-07-400"
    assert [readable(v) for v in (9.01e-07, 0.00215, 42.5, 399.6, 3000.0, 65535, 4.43e8)] == [
        "9.01e-07",
        "0.00215",
        "42.5",
        "400",
        "3,000",
        "65,535",
        "4.43e+08",
    ]


@pytest.mark.slow
def test_the_report_prints_without_out_and_takes_a_target(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    args = ["export", "--format", "report", "--sensor-size", "32x24", "--levels", "2"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "32 x 24 sensor" in out and {"spinnaker1", "spinnaker2", "loihi2"} <= set(out.split())
    assert list(tmp_path.iterdir()) == []  # printed only
    assert main([*args, "--target", "loihi2", "--out", "r.json"]) == 0
    out = capsys.readouterr().out
    chips = [line.split()[0] for line in out.splitlines() if not line.startswith((" ", "Whole", "snn-fg"))]
    assert chips == ["loihi2"] and list(json.loads((tmp_path / "r.json").read_text())["targets"]) == ["loihi2"]
    assert main([*args, "--target", "spinnaker"]) == 0
    assert [
        line.split()[0]
        for line in capsys.readouterr().out.splitlines()
        if line.startswith("spinnaker") or line.startswith("loihi")
    ] == ["spinnaker1", "spinnaker2"]
    assert main(["export", "--format", "pynn", "--target", "loihi2", "--out", "m"]) == 2
    assert main(["export", "--format", "nir"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == [
        "snn-fg: error: --target loihi2: applies to --format report, not pynn",
        "snn-fg: error: --out: --format nir needs an output path",
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]


def test_a_pooled_network_of_unknown_sensor_is_named_by_its_blocks():
    from snn_fg.network.recipes import RECIPES

    net = RECIPES["compact"].build((48, 57))  # 3 x 3 blocks: 19 x 16
    lines = report_table(resource_report(net)).splitlines()
    assert lines[0].startswith("Whole network for 19 x 16 blocks of a sensor (width x height)")
    assert lines[1] == "  the sensor seen in 3 x 3 blocks: a 19 x 16 frame"
    given = report_table(resource_report(net, sensor_shape=(48, 57))).splitlines()[0]
    assert given.startswith("Whole network for a 57 x 48 sensor (width x height)")


def test_each_chip_family_says_whether_a_limit_is_broken():
    """A family line ends "no limit broken" exactly when the report lists no
    violation for it; one with violations lists them beneath instead."""
    from snn_fg.network.recipes import RECIPES

    rep = resource_report(RECIPES["compact"].build((48, 64)))
    lines = report_table(rep).splitlines()
    for name, tg in rep["targets"].items():
        (line,) = (x for x in lines if x.startswith(name + " "))
        assert line.endswith("no limit broken") == (not tg["violations"]), (line, tg["violations"])
    assert any(tg["violations"] for tg in rep["targets"].values())  # (both kinds of line are met)
    assert any(not tg["violations"] for tg in rep["targets"].values())
