"""The command line's start: ``snn-fg --help`` imports no command (no simulator, no
model, no numba)."""

import subprocess
import sys

import pytest

from snn_fg.cli.commands import COMMANDS

#: what a command's work imports and a help text must not wait for
HEAVY = ("brian2", "numba", "scipy", "matplotlib")


def _modules_after(argv) -> tuple[int, str, set]:
    """Exit status, stdout and the heavy modules imported by ``snn-fg ARGV`` in a fresh interpreter."""
    code = (
        "import sys\n"
        "from snn_fg.cli.main import main\n"
        "try:\n"
        f"    status = main({list(argv)!r})\n"
        "except SystemExit as end:\n"
        "    status = end.code\n"
        f"print('MODULES', *[m for m in {HEAVY!r} if m in sys.modules], file=sys.stderr)\n"
        "sys.exit(status)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    line = [x for x in r.stderr.splitlines() if x.startswith("MODULES")][-1]
    return r.returncode, r.stdout, set(line.split()[1:])


def test_the_help_lists_every_command_without_importing_any():
    status, out, heavy = _modules_after(["--help"])
    assert status == 0
    assert heavy == set(), f"snn-fg --help imported {sorted(heavy)}"
    for name, command in COMMANDS.items():  # (each listed with its line)
        assert name in out and command.help[:40] in " ".join(out.split())


def test_a_command_is_parsed_with_its_own_module_only():
    status, out, _ = _modules_after(["data", "--help"])
    assert status == 0 and "ACTION" in out
    code = (
        "import sys\nfrom snn_fg.cli.main import build_parser, asked_for\n"
        "build_parser(asked_for(['data', 'list']))\n"
        "print(sorted(m for m in sys.modules if m.startswith('snn_fg.cli.')))\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    loaded = eval(r.stdout)
    assert "snn_fg.cli.data" in loaded
    assert not {c.module for n, c in COMMANDS.items() if n != "data"} & set(loaded), loaded


def test_a_typo_in_the_command_lists_the_commands(capsys):
    from snn_fg.cli.main import main

    with pytest.raises(SystemExit) as end:
        main(["rnu", "demo"])
    assert end.value.code == 2
    err = capsys.readouterr().err
    assert "invalid choice: 'rnu'" in err and "'run'" in err
