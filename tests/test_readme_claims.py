"""What the README tells a new user holds (issue 56 item 10): it names every subcommand, the
Python it takes, what a .txt input is and how a board's maps meet the reference. (It said the
quick loop was about 350 tests in 40 s where 381 ran in 184 s: the README gives no dated timing
now, docs/ does.)"""

from __future__ import annotations

import re
from pathlib import Path

from snn_fg.cli.main import build_parser

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def test_the_readme_names_every_subcommand():
    _, subs = build_parser()
    missing = [name for name in subs if f"snn-fg {name}" not in README]
    assert not missing, missing


def test_the_readme_says_what_a_new_user_asked():
    req = re.search(r'requires-python = ">=(3\.\d+)', (ROOT / "pyproject.toml").read_text()).group(1)
    assert f"Python {req}" in README and f"python{req}" in README  # (which Python, and how to pick it)
    assert ".txt of paths, one a line" in README
    compares = [line for line in README.splitlines() if "snn-fg compare" in line]
    assert any("out/maps" in c and "--levels 2" in c for c in compares)  # (the export's decoded maps, its levels)
