"""An export's run.py on a hand-edited network.json and an existing --out file (a new user's trial,
30 Nov): broken JSON and a misspelt key ended in tracebacks, a negative gain or threshold ran to
the end, and an earlier run's counts.npz was replaced without a word. Each is now one line naming
network.json (or the file), before anything runs."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from snn_fg.cli.main import main
from snn_fg.pynn.tables import export_problem


@pytest.fixture(scope="module")
def export(tmp_path_factory):
    out = tmp_path_factory.mktemp("exp") / "model"
    assert (
        main(["export", "--format", "pynn", "--network", "compact", "--sensor-size", "32x24", "--out", str(out)]) == 0
    )
    return out


def _edited(export, tmp_path, edit):
    folder = tmp_path / "model"
    shutil.copytree(export, folder)
    text = (folder / "network.json").read_text()
    (folder / "network.json").write_text(edit(text))
    return folder


def _one_line(done):
    lines = done.stderr.strip().splitlines()
    assert done.returncode != 0 and len(lines) == 1, done.stderr
    return lines[0]


def test_a_broken_json_and_a_misspelt_key_are_one_line_naming_the_file(export, tmp_path, run_py):
    folder = _edited(export, tmp_path, lambda t: t.replace('"gain_mv":', '"gian_mv":', 1))
    line = _one_line(run_py(folder, "--input", "input.npz", "--out", "c.npz"))
    assert line.startswith("run.py: error: network.json: projection ") and "has no 'gain_mv' (a key misspelt?)" in line
    (folder / "network.json").write_text((export / "network.json").read_text().replace(",", ",,", 1))
    line = _one_line(run_py(folder, "--input", "input.npz", "--out", "c.npz"))
    assert line.startswith("run.py: error: network.json: not valid JSON: ") and "line " in line
    assert not (folder / "c.npz").exists()


def test_values_snn_fg_refuses_are_refused_by_the_export_too(export):
    meta = json.loads((export / "network.json").read_text())
    assert export_problem(meta) == ""
    first = meta["projections"][0]["name"]
    cell = next(p for p in meta["populations"] if p["neuron"] is not None)["name"]
    for change, said in (
        (
            lambda m, pr, pop: pr.update(gain_mv=-300.0),
            f"projection {first!r}: gain_mv=-300.0 must be a number at least 0",
        ),
        (lambda m, pr, pop: pr.update(sign=2), "sign=2 must be 1 or -1"),
        (lambda m, pr, pop: pr.update(target="nowhere"), "its target 'nowhere' is no population of the file"),
        (
            lambda m, pr, pop: pop["neuron"].update(tau_m_ms=-20.0),
            f"population {cell!r}: tau_m_ms=-20.0 must be a number above 0",
        ),
        (
            lambda m, pr, pop: pop["neuron"].update(v_th_mv=-100.0),
            "v_th_mv=-100.0 must lie above v_rest_mv and v_reset_mv",
        ),
        (lambda m, pr, pop: pop.update(lava={"vth": -867}), "lava vth=-867 must be a number above 0"),
        (lambda m, pr, pop: m.update(dt_ms=0), "dt_ms=0 must be a number above 0"),
    ):
        edited = json.loads(json.dumps(meta))
        pop = next(p for p in edited["populations"] if p["neuron"] is not None)
        change(edited, edited["projections"][0], pop)
        assert said in export_problem(edited)


def test_run_py_keeps_an_earlier_runs_counts_unless_forced(export, tmp_path, run_py):
    folder = _edited(export, tmp_path, lambda t: t)
    np.savez(folder / "counts.npz", earlier=np.arange(3))
    before = (folder / "counts.npz").read_bytes()
    line = _one_line(run_py(folder, "--input", "input.npz", "--out", "counts.npz"))
    assert line == (
        "run.py: error: counts.npz: exists (an earlier run's counts?); pass --force to replace it, "
        "or give another --out; nothing was run"
    )
    assert (folder / "counts.npz").read_bytes() == before


def test_the_exports_copy_of_the_neuron_rules_is_snn_fgs():
    """run.py cannot import snn_fg, so fg_tables keeps a copy of the neuron's rules: a value one
    side refuses, the other must refuse too."""
    from snn_fg.errors import ParameterError
    from snn_fg.network.nodes import Neuron
    from snn_fg.pynn.tables import NEURON_RULES

    assert set(NEURON_RULES) == {f for f in Neuron.__dataclass_fields__ if f != "model"}
    for key, (lo, lo_open) in NEURON_RULES.items():
        if lo is None:
            continue
        with pytest.raises(ParameterError, match=key):
            Neuron(**{key: lo if lo_open else lo - 1.0})
        Neuron(**{key: lo + 1.0})  # (just inside: both accept it)


@pytest.mark.parametrize("script", ["pynn/run.py", "export/snntorch_loop/run.py"])
def test_the_exports_run_a_frame_as_long_as_snn_fg_does(script):
    """run.py cannot import snn_fg, so it types the frame's duration itself: it must be snn-fg's
    (Lava's run.py runs 150 ms on purpose, docs/export.md says why)."""
    import re

    import snn_fg
    from snn_fg.models.spiking.options import FRAME_DURATION_MS

    text = (Path(snn_fg.__file__).parent / script).read_text()
    found = re.findall(r'"--duration-ms",\s*type=float,\s*default=([0-9.]+)', text)
    assert found and [float(v) for v in found] == [FRAME_DURATION_MS]
