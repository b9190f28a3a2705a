"""Every snn-fg command refuses an abbreviated option, so that an option added later cannot change
what an abbreviation means (snn-fg events and snn-fg data took them: --wind for --window-ms,
data list --ver for --verify)."""

import argparse

import pytest

from snn_fg.cli.main import build_parser, main


def _parsers(parser):
    """``parser`` and every subcommand parser under it."""
    yield parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                yield from _parsers(sub)


def test_no_command_takes_an_abbreviated_option():
    parser, _ = build_parser()
    took = [p.prog for p in _parsers(parser) if p.allow_abbrev]
    assert took == []


@pytest.mark.parametrize(
    "argv, flag",
    [
        (["events", "demo.npy", "--wind", "5"], "--wind"),
        (["events", "demo.npy", "--start", "5"], "--start"),
        (["data", "list", "--ver"], "--ver"),
        (["data", "fetch", "events", "--no-prog"], "--no-prog"),
    ],
)
def test_an_abbreviation_is_refused_in_one_line_naming_it(argv, flag, capsys):
    with pytest.raises(SystemExit) as ended:
        main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert ended.value.code == 2 and len(err) == 1
    assert f"unrecognized arguments: {flag}" in err[0] and err[0].startswith(f"snn-fg {argv[0]}")


def test_the_whole_option_is_still_taken(tmp_path, capsys):
    assert main(["data", "list", "--verify"]) == 0
    assert "events" in capsys.readouterr().out
