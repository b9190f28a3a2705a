"""The Dask sweep runner: a tiny sweep on a LocalCluster, the per-task cache, resuming."""

import json

import pytest

from experiments.sweep import SweepTask, run_sweep
from snn_fg.errors import SnnFgError

pytest.importorskip("dask.distributed", reason='needs the sweep extra: pip install -e ".[sweep]"')


def square_task(*, x: int) -> dict:
    """Module-level, so that worker processes can import it."""
    import os

    return {"x": x, "square": x * x, "pid": os.getpid()}


@pytest.mark.slow
def test_tiny_sweep_on_a_local_cluster_caches_and_resumes(tmp_path):
    from dask.distributed import LocalCluster

    tasks = [SweepTask(f"t{x}", {"x": x}) for x in range(4)]
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        out = run_sweep(square_task, tasks, tmp_path, scheduler=cluster.scheduler_address, progress=False)
        assert {k: v["square"] for k, v in out.items()} == {"t0": 0, "t1": 1, "t2": 4, "t3": 9}
        assert len({v["pid"] for v in out.values()}) >= 1
        assert sorted(p.name for p in tmp_path.iterdir()) == ["t0.json", "t1.json", "t2.json", "t3.json"]
        # an interrupted sweep resumes: a cached task is not run again, a missing one is
        (tmp_path / "t1.json").write_text(json.dumps({"x": 1, "square": -1}))
        (tmp_path / "t2.json").unlink()
        again = run_sweep(square_task, tasks, tmp_path, scheduler=cluster.scheduler_address, progress=False)
        assert again["t1"]["square"] == -1 and again["t2"]["square"] == 4


def bad_input_task(*, x: int) -> dict:
    from snn_fg.errors import InputError

    raise InputError(f"labels/{x}.npz", "not an .npz file")


@pytest.mark.slow
def test_a_bad_input_in_a_task_is_one_error_and_no_worker_traceback(tmp_path, capfd):
    with pytest.raises(SnnFgError, match=r"^labels/7.npz: not an .npz file$"):
        run_sweep(bad_input_task, [SweepTask("t", {"x": 7})], tmp_path, workers=1, progress=False)
    err = capfd.readouterr().err
    assert "Compute Failed" not in err and "Traceback" not in err, err
    assert not (tmp_path / "t.json").exists()


def test_fully_cached_sweep_needs_no_cluster(tmp_path):
    (tmp_path / "a.json").write_text('{"v": 1}')
    assert run_sweep(
        square_task, [SweepTask("a", {"x": 0})], tmp_path, scheduler="tcp://127.0.0.1:1", progress=False
    ) == {"a": {"v": 1}}


def test_task_keys_are_plain_file_names():
    with pytest.raises(SnnFgError, match="file name"):
        SweepTask("../escape", {})


def test_missing_dask_says_what_to_install(tmp_path, monkeypatch):
    import sys

    from experiments.sweep import MissingExtraError

    monkeypatch.setitem(sys.modules, "dask.distributed", None)  # import fails as if not installed
    with pytest.raises(MissingExtraError, match=r'pip install -e "\.\[sweep\]" in the snn-fg folder'):
        run_sweep(square_task, [SweepTask("a", {"x": 0})], tmp_path, progress=False)


def main_thread_task(*, x: int) -> dict:
    import sys

    return {"x": x, "preloaded": "tabnanny" in sys.modules}


@pytest.mark.slow
def test_preload_imports_modules_on_every_worker_first(tmp_path):
    plain = run_sweep(main_thread_task, [SweepTask("p", {"x": 1})], tmp_path / "a", workers=1, progress=False)
    out = run_sweep(
        main_thread_task, [SweepTask("p", {"x": 1})], tmp_path / "b", workers=1, progress=False, preload=("tabnanny",)
    )
    assert out["p"]["preloaded"] and not plain["p"]["preloaded"]


def environ_task(*, name: str) -> dict:
    import os

    return {"value": os.environ.get(name)}


@pytest.mark.slow
def test_local_workers_keep_glibcs_adaptive_malloc(tmp_path, monkeypatch):
    """Dask's default MALLOC_TRIM_THRESHOLD_ for workers made a Table 1 image 1.5x slower."""
    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)
    out = run_sweep(
        environ_task, [SweepTask("e", {"name": "MALLOC_TRIM_THRESHOLD_"})], tmp_path, workers=1, progress=False
    )
    assert out["e"]["value"] is None
