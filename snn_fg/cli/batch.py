"""Many recordings in one ``snn-fg run``: a folder, a glob or a list file.

Each recording is one job, run as ``snn-fg run RECORDING --out DIR/NAME``
would run it, on local processes (``workers``) or on a Dask cluster
(``scheduler``, an address). A recording that fails is reported in the
summary with its one-line error and does not stop the others; a recording
whose run is complete is skipped, and one cut short is continued
(:mod:`snn_fg.results.store`). ``DIR/summary.csv`` lists every recording: its
status (``done``, ``skipped``, ``failed``), windows, seconds and error.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import functools
import glob
import io
import multiprocessing
import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures import as_completed as done
from pathlib import Path

from tqdm import tqdm

from ..backends.cores import usable_cores
from ..errors import InputError, InputWarning, SnnFgError, install_hint
from ..events.formats import SUFFIX_FORMAT, looks_like
from ..events.images import IMAGE_SUFFIXES
from ..events.text_events import reads_as_events
from ..frames.still import input_kind
from ..results.atomic import save_text
from ..results.maps import Maps
from ..results.outputs import SUMMARY_COLUMNS, SUMMARY_NAME, check_writable, is_batch_summary, writing
from ..results.progress import bar as progress_bar
from ..results.store import STORE_NAME, key_differences, read_attrs, run_finished, windows_complete
from .run_options import WINDOW_LIMITS, run_key
from .runner import goes_on

#: the summary table's name in the output folder, and its columns
_GLOB = set("*?[")


def is_dataset(spec: str) -> bool:
    """Whether INPUT names several recordings: a folder, a glob pattern or a ``.txt`` list of paths
    (a ``.txt`` whose first line is an event, ``t x y p``, is a recording)."""
    path = Path(spec)
    listed = path.suffix.lower() == ".txt" and not reads_as_events(path)
    return path.is_dir() or listed or (not path.exists() and bool(_GLOB & set(spec)))


def recordings_of(spec: str) -> list[Path]:
    """The recordings INPUT names: a folder's files with a recording's or an
    image's suffix (sorted), a glob's matches, or a list file's lines (blank lines and
    ``#`` comments skipped, relative paths from the list's folder)."""
    path = Path(spec)
    if path.is_dir():
        runs = set(SUFFIX_FORMAT) | set(IMAGE_SUFFIXES)  # (a folder of images runs as a glob of them does)
        found = sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in runs)
        found = [p for p in found if p.suffix.lower() != ".txt" or reads_as_events(p)]  # (not calib.txt...)
    elif path.suffix.lower() == ".txt":
        lines = [line.strip() for line in _list_text(path).splitlines()]
        named = [(i + 1, Path(line)) for i, line in enumerate(lines) if line and not line.startswith("#")]
        found = [p if p.is_absolute() else path.parent / p for _, p in named]
        first: dict = {}
        for (line, _), p in zip(named, found, strict=True):  # (one recording twice ran twice, _1 and _2)
            key = p.resolve()
            if key in first:
                raise InputError(path, f"names {p} twice (lines {first[key]} and {line}): a recording runs once")
            first[key] = line
    else:
        found = sorted(Path(p) for p in glob.glob(spec))
    if not found:
        raise InputError(
            path, "names no recording or image (a folder of recordings or images, a glob or a .txt list of paths)"
        )
    return found


def _list_text(path: Path) -> str:
    """The text of a ``.txt`` list of recordings; a file that is not text (a recording named ``.txt``,
    say) is refused in one line saying what it looks like."""
    if not path.is_file():
        raise InputError(path, "no such list file")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(path, f"cannot read file ({exc.strerror or exc})") from None
    bad = data.find(b"\0")
    try:
        text = data.decode()
    except UnicodeDecodeError as exc:
        bad = exc.start if bad < 0 else min(bad, exc.start)
    if bad < 0:
        return text
    seen, suffixes = looks_like(data[:4096])
    if suffixes:
        hint = f"it looks like {seen}: give it the suffix {' or '.join(suffixes)} to run it as a recording"
    else:
        hint = f"a recording needs its format's suffix ({' '.join(sorted(SUFFIX_FORMAT))})"
    raise InputError(
        path,
        f"not a list of paths: a .txt INPUT is read as a list of recordings, one path a line, and this file "
        f"holds binary data; {hint}",
        f"byte offset {bad}",
    )


def output_names(recordings: list[Path]) -> list[str]:
    """One output folder name per recording: its file name without suffix,
    with its parent folder's name too where two would clash (then a number)."""
    stems = [p.stem for p in recordings]
    names = [f"{p.parent.name}_{p.stem}" if stems.count(p.stem) > 1 else p.stem for p in recordings]
    seen: dict[str, int] = {}
    out = []
    for n in names:
        seen[n] = seen.get(n, 0) + 1
        out.append(f"{n}_{seen[n]}" if names.count(n) > 1 else n)
    return out


def run_job(options: dict, command) -> dict:
    """One recording: ``command`` (``snn-fg run``'s handler) with ``options``
    (``input``, ``out`` and the rest); a row of the summary, whatever happens
    (an interrupt ends the job as it ends a run)."""
    out = Path(options["out"])
    row = {
        "recording": options["input"],
        "output": str(out),
        "status": "done",
        "windows": 0,
        "seconds": 0.0,
        "error": "",
    }
    store = out / STORE_NAME
    # (a finished run is skipped only when made with these options: until 30 Nov, whatever options had made it;
    # and only when it has nothing to add: a larger window limit continues one cut by its own, as --resume does;
    # a frame's or image's run, by the key its maps keep)
    differ = earlier_differences(options)
    if differ:
        said = f"{out}: holds a finished run made with other options (these differ: {differ}); --force replaces it"
        return {**row, "status": "failed", "error": said}
    if differ == "" and not store.is_dir():
        return {**row, "status": "skipped", "windows": ""}
    if not options["force"] and run_finished(out):
        if not _goes_further(read_attrs(store), options):
            return {**row, "status": "skipped", "windows": windows_complete(out)}
    # (a finished run handed on, which its run may find nothing to add to: then it is skipped all the same)
    held = windows_complete(out) if not options["force"] and run_finished(out) else None
    t = time.perf_counter()
    args = argparse.Namespace(**{**options, "resume": True if store.is_dir() and not options["force"] else None})
    err, caught = io.StringIO(), []
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
            with warnings.catch_warnings(record=True) as caught:
                command(args)
    except Exception as exc:  # (every failure is one line in the summary)
        said = exc.for_command_line() if isinstance(exc, SnnFgError) else str(exc)
        first = said.splitlines()[0] if said else ""
        row.update(status="failed", error=first if isinstance(exc, SnnFgError) else f"{type(exc).__name__}: {first}")
    # what the job said: its input warnings and stderr lines by the parent, with the recording's name, above its
    # progress bar (_say); other warnings as Python says them, once out of the recording (inside it, showwarning
    # appended them to the list being read, for ever)
    said = [f"snn-fg: warning: {w.message}" for w in caught if issubclass(w.category, InputWarning)]
    row["said"] = said + [line for line in err.getvalue().splitlines() if line.strip()]
    for w in caught:
        if not issubclass(w.category, InputWarning):
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    still = input_word(options["input"]) != "recording"  # (its maps are one frame's: no windows)
    row.update(windows="" if still else windows_complete(out), seconds=round(time.perf_counter() - t, 2))
    if held is not None and row["status"] == "done" and row["windows"] == held:
        row["status"] = "skipped"
    return row


def _goes_further(attrs: dict, options: dict) -> bool:
    """Whether a finished run (its store's ``attrs``) has windows to add for ``options``' window
    limits: it ended at its own limit (not the recording's end) and the limit asked for now is
    larger (no limit, a larger ``max_windows``, or another ``end_ms``, which the run itself
    weighs against the windows it holds)."""
    if options.get("end_ms") is None:
        return goes_on(attrs, options.get("max_windows"))
    stored = attrs["snn_fg"].get("run_key") or {}
    changed = any(stored.get(k) != options.get(k) for k in WINDOW_LIMITS)
    return changed and goes_on(attrs, None)  # (the run itself weighs --end-ms against the windows it holds)


def batch_key(options: dict, stored: dict) -> dict:
    """:func:`~.run_options.run_key` of a job, its input named as the earlier run's ``stored`` key
    names it where both name a file of the same name: a batch run again from another folder, or
    with the folder's path made absolute, names each recording another way (its output folder is
    the same, made from the file's name; ``--resume`` inside the run then knows the recording by
    its sensor and first events)."""
    key = run_key(argparse.Namespace(**options))
    before = stored.get("input")
    if before is not None and Path(str(before)).name == Path(str(key.get("input"))).name:
        key["input"] = before
    return key


def earlier_differences(options: dict) -> str | None:
    """How a job's options differ from those of the earlier run in its output folder (empty: they
    do not; None: no earlier run of ours that says, or ``--force``): a recording's store, or a
    frame's or image's ``maps.npz``, which keeps its run key from 1 Dec 2026 on."""
    out = Path(options["out"])
    if options["force"]:
        return None
    if (out / STORE_NAME).is_dir():
        try:
            stored = read_attrs(out / STORE_NAME)["snn_fg"].get("run_key") or {}
        except (InputError, OSError, KeyError):
            return None
        return key_differences(stored, batch_key(options, stored), WINDOW_LIMITS)
    if (out / "maps.npz").is_file():
        try:
            stored = Maps.load(out / "maps.npz").params.get("run_key")
        except (InputError, OSError, ValueError, KeyError):
            return None
        return None if stored is None else key_differences(stored, batch_key(options, stored))
    return None


def refused_before_running(jobs: list[dict], out: Path) -> None:
    """Refuse a batch in one line before any recording runs (nothing run, nothing written) when it
    could only end half-done: a ``summary.csv`` in ``out`` that is not a batch's (the user's own
    table, which the batch would replace), or, without ``--force``, a recording's earlier run that
    was made with other options (every such recording would fail, and the summary say nothing was done)."""
    summary = out / SUMMARY_NAME
    if (summary.exists() or summary.is_symlink()) and not is_batch_summary(summary):
        raise InputError(
            summary,
            f"is not a batch's summary (its first line is not {','.join(SUMMARY_COLUMNS)}), and the batch would "
            "replace it: nothing was run; choose another output folder",
        )
    for job in jobs:
        differ = earlier_differences(job)
        if not differ:  # (none there, the same options, or not a run of ours: the job's own run says what is wrong)
            continue
        others = sum(Path(j["out"]).is_dir() for j in jobs) - 1
        have = "has an earlier run" if others == 1 else "have earlier runs"
        more = f" (and {others} other input{'s' * (others != 1)} {have} here)" if others else ""
        raise InputError(
            Path(job["out"]),
            f"holds an earlier run made with other options (these differ: {differ}){more}: nothing was run; "
            "--force replaces the earlier runs, or choose another --out",
        )


def input_word(path: str) -> str:
    """What an input of several is, in the lines that count them: ``recording``, ``image`` or
    ``event frame`` (a file that cannot be told is a recording: its run says why)."""
    try:
        kind = input_kind(path)
    except InputError:
        return "recording"
    return {"frame": "event frame"}.get(kind, kind)


def _counted(inputs: list[str]) -> str:
    """``2 images``, ``1 recording, 2 images``: how many inputs of each kind."""
    words = [input_word(p) for p in inputs]
    return ", ".join(f"{words.count(w)} {w}{'' if words.count(w) == 1 else 's'}" for w in dict.fromkeys(words))


def _jobs(args) -> list[dict]:
    recordings = recordings_of(args.input)
    base = {k: v for k, v in vars(args).items() if k not in ("handler", "interrupted", "interrupt_note")}
    return [
        {
            **base,
            "input": str(p),
            "out": str(Path(args.out) / name),
            "no_progress": True,
            "workers": None,
            "scheduler": None,
        }
        for p, name in zip(recordings, output_names(recordings))
    ]


def _run_all(jobs: list[dict], command, workers: int, scheduler: str | None, progress: bool):
    """``run_job`` of ``command`` over ``jobs``: rows in completion order."""
    run_one = functools.partial(run_job, command=command)

    bar = progress_bar("recordings", "rec", len(jobs), disable=not progress)
    if scheduler is not None:
        try:
            from dask.distributed import Client, as_completed  # (an optional extra: only for --scheduler)
        except ImportError:
            raise InputError(scheduler, f"--scheduler needs Dask: {install_hint('sweep')}") from None
        with Client(scheduler) as client:
            for future in as_completed(client.map(run_one, jobs, pure=False)):
                bar.update()
                yield _say(future.result())
    elif workers == 1:
        for job in jobs:
            yield _say(run_one(job))
            bar.update()
    else:
        with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
            for future in done([pool.submit(run_one, job) for job in jobs]):
                bar.update()
                yield _say(future.result())
    bar.close()


def _say(row: dict) -> dict:
    """What a job said on stderr (its warnings), each a line naming its recording, above the progress bar (a
    worker's own line went to the end of the bar's, and did not say which recording it was about); the row
    without it."""
    name = f"{row['recording']}: "
    for line in row.pop("said", ()):
        head = "snn-fg: warning: " if line.startswith("snn-fg: warning: ") else "snn-fg: "
        said = line.removeprefix(head)
        tqdm.write(f"{head}{'' if said.startswith(name) else name}{said}", file=sys.stderr)  # (named once)
    return row


def run_dataset(args, command) -> int:
    """``snn-fg run`` (its handler ``command``) on several recordings (:func:`is_dataset`): one output
    folder per recording in ``args.out``, ``summary.csv`` beside them, a
    table on stdout. ``args.workers`` local processes (default: one per
    core, at most one per recording) or the Dask cluster at
    ``args.scheduler``. ``--force`` runs complete recordings again. Returns
    0, or 1 when a recording failed."""
    jobs = _jobs(args)
    out = Path(args.out)
    refused_before_running(jobs, out)
    check_writable(out)
    with writing(out):
        out.mkdir(parents=True, exist_ok=True)
    workers = min(args.workers or usable_cores(), len(jobs))
    args.interrupt_note = (
        f"the recordings done so far are in {out}/, a folder each, and one cut short keeps the windows it "
        f"completed; no {SUMMARY_NAME} was written: the same command goes on (it skips the recordings done "
        "and continues the one cut short)"
    )
    rows = sorted(
        _run_all(jobs, command, workers, args.scheduler, not args.no_progress),
        key=lambda r: [j["input"] for j in jobs].index(r["recording"]),
    )
    text = io.StringIO()
    writer = csv.DictWriter(text, SUMMARY_COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    save_text(out / SUMMARY_NAME, text.getvalue())
    for r in rows:
        error = r["error"].removeprefix(f"{r['recording']}: ")  # (an input error names its file already)
        made = f"{r['windows']:5d} windows" if r["windows"] != "" else f"{input_word(r['recording']):>13}"
        print(f"{r['status']:>8}  {made}  {r['seconds']:8.1f} s  {r['recording']}" + (f": {error}" if error else ""))
    failed = sum(r["status"] == "failed" for r in rows)
    print(f"snn-fg: {_counted([r['recording'] for r in rows])}, {failed} failed; summary in {out / SUMMARY_NAME}")
    return 1 if failed else 0
