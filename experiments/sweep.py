"""Sweeps (one task per image) on Dask, with a per-task result cache.

:func:`run_sweep` runs ``func(**kwargs)`` for every task as a Dask future:
on a local cluster of worker processes (one per core, one thread each) by
default, or on an existing cluster given by its scheduler address
(``tcp://host:8786``). Each result (a JSON-serialisable dict) is written to
``cache_dir/<key>.json`` as soon as it arrives, atomically, so an interrupted
sweep resumes where it stopped: tasks whose file exists are not run again.
A progress bar (tqdm, on stderr) counts tasks done.

Dask is an optional dependency: ``pip install -e ".[sweep]"``.
"""

from __future__ import annotations

import importlib
import json
import os
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from tqdm import tqdm

from snn_fg.backends.cores import usable_cores
from snn_fg.errors import InputError, SnnFgError, install_hint
from snn_fg.results.atomic import save_text

#: What to install when Dask is missing.
DASK_HINT = f"the sweeps need Dask: {install_hint('sweep')}"
_SAFE_KEY = re.compile(r"^[A-Za-z0-9_.=+-]+$")


class MissingExtraError(SnnFgError):
    """An optional dependency is not installed; the message says what to install."""


@dataclass(frozen=True)
class SweepTask:
    """One unit of a sweep: ``func(**kwargs)`` cached as ``<key>.json``."""

    key: str
    kwargs: dict = field(default_factory=dict)

    def __post_init__(self):
        if not _SAFE_KEY.match(self.key):
            raise SnnFgError(f"sweep task key {self.key!r} must be a plain file name (letters, digits, . _ = + -)")


def _dask():
    try:
        import dask.distributed as dd
    except ImportError:
        raise MissingExtraError(DASK_HINT) from None
    return dd


def cached(cache_dir, key: str):
    """The cached result of ``key``, or None."""
    path = Path(cache_dir) / f"{key}.json"
    if not path.exists():
        return None
    return json.loads(path.read_text())


def _client(scheduler, workers):
    dd = _dask()
    if scheduler:
        return dd.Client(scheduler), None
    import dask

    n = workers or usable_cores()
    # Dask's nanny starts workers with MALLOC_TRIM_THRESHOLD_=65536, which
    # also turns off glibc's adaptive mmap threshold: every large temporary
    # array is then mapped fresh and faulted in page by page. Our tasks make
    # many such arrays; one BSDS image of Table 1 took 19.2 s with it and
    # 12.8 s without, in one process on an idle core.
    with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}):
        cluster = dd.LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None)
    return dd.Client(cluster), cluster


def run_sweep(
    func: Callable[..., dict],
    tasks,
    cache_dir,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: bool = True,
    desc: str = "images",
    preload=(),
) -> dict:
    """Run ``func(**task.kwargs)`` for every task not yet cached; return ``{key: result}`` for all.

    Parameters
    ----------
    func : callable
        A module-level function (workers import it) returning a JSON-serialisable dict.
    tasks : iterable of SweepTask
    cache_dir : path
        Where results are kept, one ``<key>.json`` per task.
    scheduler : str, optional
        Address of a running Dask scheduler; by default a local cluster is
        started with ``workers`` processes (default: one per core).
    progress : bool
        Show a tqdm bar of tasks done (on stderr).
    preload : sequence of str
        Modules every worker imports in its main thread before the tasks run:
        tasks run in a worker thread, where a module that installs signal
        handlers at import (Brian2 does) cannot be imported.

    Examples
    --------
    >>> from experiments.sweep import SweepTask, run_sweep
    >>> out = run_sweep(dict, [SweepTask("a", {"x": 1})], "/tmp/sweep-doc", workers=1,
    ...                 progress=False)                     # doctest: +SKIP
    >>> out["a"]                                            # doctest: +SKIP
    {'x': 1}
    """
    tasks = list(tasks)
    keys = [t.key for t in tasks]
    if len(set(keys)) != len(keys):
        raise SnnFgError("sweep task keys must be unique")
    cache_dir = Path(cache_dir)
    cache_dir.mkdir(parents=True, exist_ok=True)
    results = {t.key: cached(cache_dir, t.key) for t in tasks}
    todo = [t for t in tasks if results[t.key] is None]
    if todo:
        bar = {"total": len(tasks), "initial": len(tasks) - len(todo), "desc": desc, "disable": not progress}
        _run(func, todo, cache_dir, results, client=(scheduler, workers), bar=bar, preload=tuple(preload))
    return results


#: The key under which :func:`_guarded` hands back a task's InputError.
_INPUT_ERROR = "__input_error__"


def _guarded(func, kwargs):
    """``func(**kwargs)``, with an :class:`InputError` (a bad input file) returned as its message
    instead of raised: a task that raises is logged by the Dask worker as "Compute Failed" with its
    traceback, a dozen lines or more before the one line the experiment prints."""
    try:
        return func(**kwargs)
    except InputError as exc:
        return {_INPUT_ERROR: exc.for_command_line()}


def _import_all(modules):
    for name in modules:
        importlib.import_module(name)


def _run(func, todo, cache_dir, results, *, client, bar, preload):
    """Run ``todo`` on a Dask client (``client``: scheduler address, local workers), filling ``results``
    and the cache as tasks end; ``bar``: the progress bar's settings."""
    dd = _dask()
    client, cluster = _client(*client)
    bar = tqdm(unit="img", file=sys.stderr, **bar)
    try:
        if preload:
            client.run(_import_all, preload)  # client.run executes in each worker's main thread
        futures = {
            client.submit(_guarded, func, t.kwargs, key=f"{t.key}-{os.getpid()}", pure=False): t.key for t in todo
        }
        for fut in dd.as_completed(futures):
            key = futures[fut]
            results[key] = fut.result()
            if isinstance(results[key], dict) and _INPUT_ERROR in results[key]:
                raise SnnFgError(results[key][_INPUT_ERROR])  # not cached: a fixed input is run again
            save_text(cache_dir / f"{key}.json", json.dumps(results[key]))
            bar.update(1)
    finally:
        bar.close()
        client.close()
        if cluster is not None:
            cluster.close()
