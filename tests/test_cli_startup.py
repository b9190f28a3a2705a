"""The command line's start: ``snn-fg --help`` imports no command (no simulator, no
model, no numba), and Ctrl-C while a command's modules are still being imported
ends in one line and exit status 130, as it does once the command runs."""

import signal
import subprocess
import sys
import time

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


@pytest.mark.parametrize("after_s", [0.3, 0.8])
def test_ctrl_c_while_the_command_is_imported_is_one_line_and_130(tmp_path, after_s):
    """``snn-fg run`` spends its first 1-2 s importing the models and simulators; a
    Ctrl-C then printed Python's traceback of the import it cut."""
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-m", "snn_fg.cli", "run", "demo", "--model", "spiking", "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    time.sleep(after_s)
    assert proc.poll() is None, "the command ended before it could be interrupted"
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    lines = [line for line in err.splitlines() if line.strip()]
    assert proc.returncode == 130, err
    assert len(lines) == 1 and lines[0].startswith("snn-fg: interrupted (Ctrl-C)"), err
    assert not out.exists()
