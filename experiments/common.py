"""What every experiment shares: where things are, the record each result carries, markdown tables.

Experiments run from the repository's root as modules,
``python -m experiments.<tier>.<name>``; their data come from
:mod:`snn_fg.datasets` (``snn-fg data list``), their results go to
``experiments/results/``.

A result records how it was made (:class:`Run`): the commit, the command
line, the date, the processor and the machine's load average before and
after, so a number in a table can be traced to the code and the conditions
that produced it.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import os
import shlex
import subprocess
import sys
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import NoReturn

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "experiments" / "results"
CACHE = RESULTS / "cache"
#: where every experiment on dvs.es starts its windows (ms after its first event): past the reset burst
#: and start-up the recording opens with (docs/validation.md); the windows are snn-fg's default length
#: (snn_fg.events.cutter.WINDOW_MS, 85 ms)
DVS_FROM_MS = 100.0


def fail(message: str) -> NoReturn:
    """End the experiment with one line on stderr and exit status 2."""
    print(f"{Path(sys.argv[0]).stem}: error: {message}", file=sys.stderr)
    raise SystemExit(2)


def positive_int(text: str) -> int:
    """argparse type: an integer of at least 1 (``--images 0`` would score nothing and print a table of nan,
    ``--workers 0`` would start no worker), by the command line's own rule for numbers (imported here:
    snn_fg's command line takes a second to import, which an experiment's --help need not wait for)."""
    from snn_fg.cli.options import number

    return number(int, 1, strict=False)(text)


def dataset(name: str, *parts) -> Path:
    """Path of a dataset (or of a file in it); ends the experiment with the fetch command when it is absent."""
    from snn_fg import datasets

    try:
        return datasets.require(name, *parts)
    except datasets.DatasetError as exc:
        fail(str(exc))


def load() -> list[float]:
    """The 1, 5 and 15 minute load averages, rounded."""
    return [round(v, 2) for v in os.getloadavg()]


def peak_rss_mb() -> float:
    """This process's peak resident memory so far (MB): ``VmHWM`` from /proc (Linux)."""
    status = Path("/proc/self/status").read_text()
    return round(int(status.split("VmHWM:")[1].split()[0]) / 1024, 1)


def load_change(before: Sequence[float]) -> str:
    """``"1.2 -> 3.4"``: the 1-minute load average ``before`` (a :func:`load`) and now."""
    return f"{before[0]:.1f} -> {load()[0]:.1f}"


def source_digest(package: Path | None = None) -> str:
    """A short digest of the Python source of ``package`` (a folder; by default the ``snn_fg`` that is
    imported): each ``*.py`` file's path in it and bytes. A cache of maps that code made, named by it, is
    not read back once the code has changed: a change of behaviour with no change of parameters (how a
    recording's input gains are set, say) moves the maps as much as a new parameter does, and
    :func:`git_commit` would miss an edit not yet committed."""
    if package is None:
        package = Path(importlib.util.find_spec("snn_fg").origin).parent
    h = hashlib.sha1()
    for path in sorted(package.rglob("*.py")):
        h.update(path.relative_to(package).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:10]


def git_commit() -> str:
    """The checkout's commit, with ``-dirty`` when files differ from it (``unknown`` outside git)."""

    def git(*args):
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=30).stdout.strip()

    try:
        head = git("rev-parse", "--short=10", "HEAD")
        dirty = git("status", "--porcelain", "--untracked-files=no")
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return (head + ("-dirty" if dirty else "")) if head else "unknown"


def command_line() -> str:
    """The command as typed from the repository root: ``python -m experiments.<tier>.<name> ARGS``, each
    argument quoted as a shell needs it (a ``--variant 'NAME={"a": 1}'`` pasted back runs the same)."""
    main = sys.modules.get("__main__")
    spec = getattr(main, "__spec__", None)
    what = f"-m {spec.name}" if spec is not None and spec.name else Path(sys.argv[0]).as_posix()
    return " ".join(["python", what, *map(shlex.quote, sys.argv[1:])])


def processor(cpuinfo: str = "/proc/cpuinfo") -> str:
    """The processor's name, family and model, and its cache, from Linux's
    ``/proc/cpuinfo`` (empty where there is none): the shared machines these
    experiments run on change between sessions (one core's time for the same
    ``dvs.es`` window moved by 1.7x between two of them), so a timing says
    which processor it was taken on."""
    try:
        first = Path(cpuinfo).read_text().split("\n\n")[0]
    except OSError:
        return ""
    info = {k.strip(): v.strip() for k, v in (line.split(":", 1) for line in first.splitlines() if ":" in line)}
    return (
        f"{info.get('model name', '?')}, family {info.get('cpu family', '?')} model {info.get('model', '?')}, "
        f"cache {info.get('cache size', '?')}"
    )


class Run:
    """How a result is made; create it before the work, take :meth:`record` after."""

    def __init__(self):
        # the commit is taken now: by the time of :meth:`record` the work has rewritten its
        # own tracked results, which would mark every re-run of a page ``-dirty``
        self.commit = git_commit()
        self.date = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
        self.load_before = load()
        self._t0 = time.perf_counter()

    @property
    def seconds(self) -> float:
        return time.perf_counter() - self._t0

    def record(self) -> dict:
        """``commit``, ``command``, ``date`` (start), ``seconds``, ``processor``, ``load_before``, ``load_after``."""
        return {
            "commit": self.commit,
            "command": command_line(),
            "date": self.date,
            "seconds": round(self.seconds, 1),
            "processor": processor(),
            "load_before": self.load_before,
            "load_after": load(),
        }


def describe(run: dict) -> str:
    """One line for a results page from a :meth:`Run.record`."""
    minutes = run["seconds"] / 60
    took = f"{minutes:.1f} min" if minutes >= 1 else f"{run['seconds']:.0f} s"
    on = f" on {run['processor']}" if run.get("processor") else ""
    return (
        f"`{run['command']}` at {run['commit']}, {run['date']}{on}: {took}, load average "
        f"{run['load_before'][0]:.1f} before, {run['load_after'][0]:.1f} after."
    )


def markdown_table(header: Sequence, rows: Iterable[Sequence]) -> list[str]:
    """A markdown table's lines: the header, the rule, one line per row (cells as given, through ``str``)."""
    lines = ["| " + " | ".join(str(h) for h in header) + " |", "|" + " --- |" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return lines


def _plain(value):
    """numpy scalars and arrays as JSON numbers and lists."""
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def save_json(name: str, record) -> Path:
    """``results/<name>.json`` (numpy values as plain numbers), written atomically."""
    from snn_fg.results.atomic import save_text

    return save_text(RESULTS / f"{name}.json", json.dumps(record, indent=1, default=_plain) + "\n")


def save_markdown(name: str, lines: Sequence[str]) -> Path:
    """``results/<name>.md`` from its lines, written atomically."""
    from snn_fg.results.atomic import save_text

    return save_text(RESULTS / f"{name}.md", "\n".join(lines).rstrip("\n") + "\n")


def save_results(name: str, record, lines: Sequence[str]) -> list[Path]:
    """``results/<name>.json`` (the record) and ``results/<name>.md`` (its ``lines``), and the lines printed."""
    written = [save_json(name, record), save_markdown(name, lines)]
    print("\n".join(lines))
    return written


def save_figure(fig, name: str, **kwargs) -> Path:
    """``results/<name>.png`` (``dpi=110, bbox_inches="tight"`` unless given), written atomically."""
    from snn_fg.results.atomic import save_figure as save

    return save(fig, RESULTS / f"{name}.png", **{"dpi": 110, "bbox_inches": "tight", **kwargs})
