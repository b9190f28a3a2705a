"""Every module of snn_fg holds at most 400 lines as ``ruff format`` writes it
(the formatter's config in pyproject.toml): a module that grows past it is
split by concern, not folded to fit."""

import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "snn_fg"
CEILING = 400


def formatted_lengths(folder: Path, scratch: Path) -> dict[str, int]:
    """Lines of each module of ``folder`` (relative path -> lines) once ``ruff format``
    (run on a copy, with the project's config) has written it."""
    copy = scratch / folder.name
    shutil.copytree(folder, copy, ignore=shutil.ignore_patterns("__pycache__"))
    subprocess.run(
        [sys.executable, "-m", "ruff", "format", "--quiet", "--config", str(ROOT / "pyproject.toml"), str(copy)],
        check=True,
    )
    return {p.relative_to(copy).as_posix(): len(p.read_text().splitlines()) for p in sorted(copy.rglob("*.py"))}


def test_every_module_is_within_the_ceiling(tmp_path):
    lengths = formatted_lengths(PACKAGE, tmp_path)
    assert len(lengths) > 100  # (the whole package was read)
    over = {f: n for f, n in lengths.items() if n > CEILING}
    assert over == {}, f"over {CEILING} lines as ruff format writes them; split by concern: {over}"


def test_the_check_counts_what_the_formatter_writes(tmp_path):
    """A module folded onto few long lines is counted as the formatter unfolds it."""
    folder = tmp_path / "pkg"
    folder.mkdir()
    (folder / "folded.py").write_text("x = [" + ", ".join(f"{i:>60}" for i in range(CEILING)) + "]\n")
    assert formatted_lengths(folder, tmp_path / "out")["folded.py"] > CEILING
