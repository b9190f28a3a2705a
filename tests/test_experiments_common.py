"""experiments.common: the record every result carries, the markdown tables, the data an experiment needs;
and every experiment module imports (run from the repository root as ``python -m experiments...``)."""

import importlib
import pkgutil
import sys
import types
from pathlib import Path

import pytest

import experiments
from experiments import common
from snn_fg import datasets

ROOT = Path(__file__).resolve().parents[1]


def test_a_markdown_table_has_a_header_a_rule_and_one_line_per_row():
    lines = common.markdown_table(["a", "b"], [[1, "x"], [2.5, ""]])
    assert lines == ["| a | b |", "| --- | --- |", "| 1 | x |", "| 2.5 |  |"]


def test_the_command_line_is_the_module_as_typed(monkeypatch):
    main = types.ModuleType("__main__")
    main.__spec__ = importlib.util.find_spec("experiments.paper.table1")
    monkeypatch.setitem(sys.modules, "__main__", main)
    monkeypatch.setattr(sys, "argv", [str(ROOT / "experiments" / "paper" / "table1.py"), "--quick"])
    assert common.command_line() == "python -m experiments.paper.table1 --quick"
    monkeypatch.setattr(sys, "argv", ["x.py", "--variant", 'p={"prune_vm": 0.2}', "--rounds", "3"])
    assert common.command_line() == "python -m experiments.paper.table1 --variant 'p={\"prune_vm\": 0.2}' --rounds 3"


def test_a_run_record_names_the_commit_the_command_the_date_the_processor_and_the_load():
    run = common.Run()
    rec = run.record()
    assert set(rec) == {"commit", "command", "date", "seconds", "processor", "load_before", "load_after"}
    head = rec["commit"].removesuffix("-dirty")
    assert len(head) == 10 and int(head, 16) >= 0  # a short hash of this checkout
    assert rec["command"].startswith("python ")
    assert len(rec["load_before"]) == len(rec["load_after"]) == 3
    assert 0 <= rec["seconds"] < 60
    line = common.describe(rec)
    assert rec["commit"] in line and rec["date"] in line and "load average" in line
    assert rec["processor"] in line


def test_a_run_record_names_the_commit_as_it_was_when_the_run_began(monkeypatch):
    monkeypatch.setattr(common, "git_commit", lambda: "0123456789")
    run = common.Run()
    monkeypatch.setattr(common, "git_commit", lambda: "0123456789-dirty")  # the run wrote its results
    assert run.record()["commit"] == "0123456789"


def test_the_processor_is_read_from_the_first_cpu_of_cpuinfo(tmp_path):
    info = tmp_path / "cpuinfo"
    info.write_text(
        "processor\t: 0\ncpu family\t: 6\nmodel\t\t: 207\nmodel name\t: Some Xeon\n"
        "cache size\t: 266240 KB\n\nprocessor\t: 1\nmodel name\t: Other\n"
    )
    assert common.processor(str(info)) == "Some Xeon, family 6 model 207, cache 266240 KB"
    assert common.processor(str(tmp_path / "absent")) == ""


def test_the_source_digest_follows_each_code_file_its_bytes_and_its_name(tmp_path):
    package = tmp_path / "pkg"
    (package / "sub").mkdir(parents=True)
    (package / "gains.py").write_text("PER_ACTIVE_SOURCE = False\n")
    (package / "sub" / "read.py").write_text("")
    first = common.source_digest(package)
    assert common.source_digest(package) == first and len(first) == 10
    (package / "notes.txt").write_text("not code")
    assert common.source_digest(package) == first
    (package / "gains.py").write_text("PER_ACTIVE_SOURCE = True\n")  # same size, other behaviour
    edited = common.source_digest(package)
    assert edited != first
    (package / "sub" / "read.py").rename(package / "sub" / "once.py")
    assert common.source_digest(package) != edited
    assert common.source_digest() == common.source_digest(ROOT / "snn_fg")  # the snn_fg imported


def test_an_absent_dataset_ends_the_experiment_with_the_fetch_command(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(datasets.ENV_VAR, str(tmp_path))
    with pytest.raises(SystemExit) as stop:
        common.dataset("events", "dvs.es")
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "snn-fg data fetch events" in err[0]


def _experiment_modules():
    names = []
    for info in pkgutil.walk_packages(experiments.__path__, "experiments."):
        if info.name != "experiments.bench.__main__":  # (it runs the bench)
            names.append(info.name)
    return sorted(names)


@pytest.mark.slow
def test_every_experiment_module_imports():
    assert len(_experiment_modules()) > 40
    for name in _experiment_modules():
        importlib.import_module(name)
