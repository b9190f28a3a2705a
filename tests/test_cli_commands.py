"""The command line's surface as users type it: the subcommands, a few flags
of each, the entry point, and the shared argument types defined once
(snn_fg.cli.options) and used by every command that takes them."""

from importlib.metadata import entry_points

import pytest

from snn_fg.cli import build_parser, options
from snn_fg.cli.main import console

#: a few flags of each subcommand that scripts and the docs rely on
FLAGS = {
    "run": {
        "--out",
        "--force",
        "--resume",
        "--model",
        "--network",
        "--backend",
        "--sensor-size",
        "--crop",
        "--workers",
    },
    "compare": {"--window", "--outline", "--json", "--plot"},
    "plot": {"--windows", "--out", "--animate", "--fps", "--crop", "--force"},
    "events": {"--window-ms", "--sensor-size", "--write-frame", "--write-events", "--write-spikes", "--export"},
    "export": {"--format", "--out", "--force", "--network", "--sensor-size", "--target", "--weight-bits"},
    "decode": {"--export", "--out", "--input", "--force"},
    "data": set(),
    "stream": {"--to", "--speed", "--loop", "--start-ms", "--sensor-size"},
    "live": {"--out", "--force", "--model", "--network", "--sensor-size", "--hop-ms", "--publish", "--max-behind"},
}


def _flags(parser) -> set[str]:
    return {f for a in parser._actions for f in a.option_strings}


def test_the_subcommands_are_the_ones_users_type():
    _, subs = build_parser()
    assert set(subs) == set(FLAGS)
    data_actions = next(a for a in subs["data"]._actions if a.dest == "data_command")
    assert set(data_actions.choices) == {"list", "info", "fetch"}


@pytest.mark.parametrize("command", sorted(FLAGS))
def test_each_subcommand_keeps_its_flags(command):
    _, subs = build_parser()
    assert FLAGS[command] <= _flags(subs[command])


def test_the_console_script_is_the_cli_entry_point():
    (script,) = [e for e in entry_points(group="console_scripts") if e.name == "snn-fg"]
    assert script.value == "snn_fg.cli.main:console"
    assert script.load() is console


def test_the_shared_argument_types_are_defined_once():
    """--sensor-size is one parser function in every command that takes it; a
    number flag of run, compare and export is checked by options.number."""
    _, subs = build_parser()
    types = {a.type for p in subs.values() for a in p._actions if "--sensor-size" in a.option_strings}
    assert types == {options.sensor_size}
    checked = [
        a
        for c in ("run", "compare", "export")
        for a in subs[c]._actions
        if "--levels" in a.option_strings or "--window" in a.option_strings
    ]
    assert checked and all(a.type.__qualname__ == "number.<locals>.parse" for a in checked)
