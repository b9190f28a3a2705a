"""The BSDS experiments on a new user's runs: a subset never overwrites the full-set results, a changed
label file is computed again (not read back from the cache; nor are dvs_rate_vs_spiking's spiking maps
after a change of code or recording), a bad label file ends the run with one line naming it, and
impossible option values are argparse errors.

Most tests build a tiny synthetic bsds-fg folder in tmp_path (two 10 x 12 images and their labels);
the end-to-end ones need the dataset and skip without it."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from argparse import Namespace
from pathlib import Path
from types import SimpleNamespace

import cv2
import numpy as np
import pytest

import experiments.common as common
import experiments.paper.bsds as bsds
from snn_fg.errors import InputError
from snn_fg.scoring.groundtruth import load_bsds_fg

REPO = Path(__file__).resolve().parents[1]
SHAPE = (10, 12)


def _labels(value=1):
    fg = np.zeros((2, *SHAPE), np.int8)
    fg[:, 5, :] = value
    fg[:, 6, :] = -value
    return fg


def fake_root(tmp_path, ids=("1", "2")) -> Path:
    """A bsds-fg folder: ``images/<id>.jpg`` (10 x 12 grey) and ``labels/<id>.npz`` (two labellers)."""
    root = tmp_path / "bsds-fg"
    (root / "images").mkdir(parents=True)
    (root / "labels").mkdir()
    for i in ids:
        cv2.imwrite(str(root / "images" / f"{i}.jpg"), np.full(SHAPE, 128, np.uint8))
        np.savez(root / "labels" / f"{i}.npz", fg=_labels(), labellers=np.array([1, 2], np.int32))
    return root


def label_sum(*, root, image_id, **settings) -> dict:
    """A stand-in for the per-image evaluation: what it reads of the labels."""
    return {
        "sum": int(load_bsds_fg(root, image_id).fg.sum(dtype=np.int64)),
        "abs": int(np.abs(load_bsds_fg(root, image_id).fg).sum()),
    }


@pytest.fixture
def in_process(monkeypatch, tmp_path):
    """bsds.sweep on a fake dataset, with the sweep's Dask run replaced by an in-process loop that
    writes the same cache files (the cache logic under test is in run_sweep and bsds.sweep)."""
    import experiments.sweep as sweep_mod
    from snn_fg.results.atomic import save_text

    root = fake_root(tmp_path)
    calls = []

    def run_here(func, todo, cache_dir, results, **_):
        calls.append([t.key for t in todo])
        for t in todo:
            results[t.key] = func(**t.kwargs)
            save_text(Path(cache_dir) / f"{t.key}.json", __import__("json").dumps(results[t.key]))

    monkeypatch.setattr(sweep_mod, "_run", run_here)
    monkeypatch.setattr(bsds, "dataset", lambda *parts: root.joinpath(*parts[1:]))
    monkeypatch.setattr(bsds, "CACHE", tmp_path / "cache")
    return Namespace(root=root, calls=calls, args=Namespace(scheduler=None, workers=1, no_progress=True))


# 1. a subset writes under its own name


def test_a_subset_or_ids_get_a_name_of_their_own_and_the_full_set_keeps_the_plain_one(in_process):
    args = Namespace(ids=None, images=None, quick=False)
    assert bsds.subset_name("table1", args, 2) == "table1"  # the fake dataset's 2 images: all of them
    assert bsds.subset_name("table1", args, 1) == "table1_1images"
    assert bsds.subset_name("spiking_groundtruth", args, 20, 20) == "spiking_groundtruth"
    assert bsds.subset_name("table1", Namespace(ids=["2092", "100"]), 2) == "table1_ids-100-2092"
    many = bsds.subset_name("fig6", Namespace(ids=[str(i) for i in range(6)]), 6)
    assert many.startswith("fig6_6ids-") and many != bsds.subset_name("fig6", Namespace(ids=list("012346")), 6)


def _fake_results(ids):
    from snn_fg.scoring.label_scores import error_stats

    units = [
        {"model": m, "motion": mo, "threshold": t, **error_stats([10.0, -20.0, 100.0], n_truth=5)}
        for m, mo, t in (("rate", "paper", 0.10), ("rate", "shift4", 0.10), ("fbfg", "image", None))
    ]
    return {i: {"units": units, "ceiling": error_stats([1.0, 2.0], n_truth=3)} for i in ids}


def test_table1_on_fewer_than_all_images_leaves_the_full_set_files_alone(in_process, monkeypatch, tmp_path):
    import experiments.paper.table1 as table1

    out = tmp_path / "results"
    out.mkdir()
    for mod in (common, bsds):
        monkeypatch.setattr(mod, "RESULTS", out)
    monkeypatch.setattr(table1, "evaluate", lambda args, settings=None: _fake_results(bsds.chosen_ids(args)))
    monkeypatch.setattr(table1, "authors_outputs", list)
    monkeypatch.setattr(sys, "argv", ["table1", "--images", "1", "--workers", "1", "--no-progress"])
    table1.main()
    written = sorted(p.name for p in out.iterdir())
    assert "table1.json" not in written and "table1.md" not in written
    assert {"table1_1images.json", "table1_1images.md", "table1_1images.png", "table1_1images_extra.json"} <= set(
        written
    )


def _capture_saves(monkeypatch, module, *names):
    """Replace ``module``'s writers ``names`` by one that records the stem each is given."""
    stems = []
    for name in names:
        monkeypatch.setattr(module, name, lambda stem, *a, **k: stems.append(str(stem)))
    return stems


def test_the_validation_scripts_name_a_part_run_apart_from_the_full_one(monkeypatch, tmp_path):
    import experiments.validation.compact_dog as compact_dog
    import experiments.validation.spiking_dt as spiking_dt
    import experiments.validation.spiking_fidelity as spiking_fidelity
    import experiments.validation.spiking_heldout as spiking_heldout
    import snn_fg.scoring.groundtruth as groundtruth

    assert spiking_heldout._stem(6) == "spiking_heldout" and spiking_heldout._stem(2) == "spiking_heldout_2images"
    import experiments.validation.live_latency as live_latency

    assert live_latency.stem(list(reversed(live_latency.CASES))) == "live_latency"
    assert live_latency.stem(["compact-1", "compact-2"]) == "live_latency_cases-compact-1-compact-2"
    with pytest.raises(SystemExit):  # (an unknown case: one argparse line, before any run)
        live_latency.main(["--cases", "compact-1,nope"])
    fid = spiking_fidelity._parser()
    assert spiking_fidelity._stem(fid.parse_args([])) == "spiking_fidelity"
    assert spiking_fidelity._stem(fid.parse_args(["--quick"])) == "spiking_fidelity_quick"
    assert spiking_fidelity._stem(fid.parse_args(["--only", "disc r16"])) == "spiking_fidelity_only-disc_r16"

    # spiking_dt --quick, with its three measurements stubbed out
    for name in ("_timing", "_frames", "_recording"):
        monkeypatch.setattr(spiking_dt, name, lambda *a, **k: {})
    monkeypatch.setattr(spiking_dt, "dataset", lambda *a: None)
    monkeypatch.setattr(spiking_dt, "_markdown", lambda rec: [])
    stems = _capture_saves(monkeypatch, spiking_dt, "save_json", "save_markdown")
    monkeypatch.setattr(spiking_dt, "_figure", lambda rec, path: stems.append(str(path)))
    monkeypatch.setattr(sys, "argv", ["spiking_dt", "--quick"])
    spiking_dt.main()
    assert stems[:2] == ["spiking_dt_quick", "spiking_dt_quick"] and stems[2].endswith("spiking_dt_quick.png")

    # compact_dog --images 2 of the every-8th images, with the BSDS runs stubbed out
    monkeypatch.setattr(groundtruth, "bsds_ids", lambda root: [str(i) for i in range(40)])
    monkeypatch.setattr(compact_dog, "dataset", lambda *a: tmp_path)
    monkeypatch.setattr(compact_dog, "bsds", lambda ids, *a: {"images": ids})
    monkeypatch.setattr(compact_dog, "lines", lambda record: [])
    monkeypatch.setattr(compact_dog, "figure", lambda record: None)
    stems = _capture_saves(monkeypatch, compact_dog, "save_results")
    monkeypatch.setattr(compact_dog, "save_figure", lambda fig, stem, **k: stems.append(stem))
    for argv, stem in ((["--images", "2"], "compact_dog_2images"), ([], "compact_dog")):
        monkeypatch.setattr(sys, "argv", ["compact_dog", "--windows", *argv])
        compact_dog.main()
        assert stems[-2:] == [stem, stem]


# 2. the cache follows the inputs


def test_a_changed_label_file_is_computed_again_not_read_back(in_process):
    first = bsds.sweep(label_sum, ["1", "2"], {"k": 1}, in_process.args)
    assert first["1"]["sum"] == 0 and first["1"]["abs"] == 2 * 2 * SHAPE[1]
    again = bsds.sweep(label_sum, ["1", "2"], {"k": 1}, in_process.args)
    assert again == first and in_process.calls == [[k for k in in_process.calls[0]]]  # the cache, read back
    fg = _labels()
    fg[:, 5, :3] = 0  # fewer labelled pixels, same file size class: a stale cache would give the old count
    np.savez(in_process.root / "labels" / "1.npz", fg=fg, labellers=np.array([1, 2], np.int32))
    changed = bsds.sweep(label_sum, ["1", "2"], {"k": 1}, in_process.args)
    assert changed["1"]["abs"] == first["1"]["abs"] - 6 and changed["2"] == first["2"]
    assert len(in_process.calls) == 2 and len(in_process.calls[1]) == 1  # only image 1 again


def test_natural_cues_keys_its_cache_on_the_label_files_too(in_process, monkeypatch):
    import experiments.sweep as sweep_mod
    import experiments.validation.natural_cues as natural_cues
    import experiments.validation.natural_scenes as natural_scenes

    keys = []

    def stop(func, tasks, *a, **k):
        keys.append([t.key for t in tasks])
        raise SystemExit(0)  # the cues themselves are not under test

    monkeypatch.setattr(sweep_mod, "run_sweep", stop)
    monkeypatch.setattr(natural_cues, "CACHE", in_process.root.parent / "cache")
    monkeypatch.setattr(natural_cues, "dataset", lambda *a: in_process.root)
    monkeypatch.setattr(natural_scenes, "halves", lambda: {"tune": ["1"], "report": ["2"]})
    monkeypatch.setattr(sys, "argv", ["natural_cues", "--workers", "1"])
    for _ in range(2):
        with pytest.raises(SystemExit):
            natural_cues.main()
        np.savez(in_process.root / "labels" / "2.npz", fg=-_labels(), labellers=np.array([1, 2], np.int32))
    assert keys[0][0] == keys[1][0] and keys[0][1] != keys[1][1] and keys[0][1].startswith("2-")


@pytest.mark.parametrize("module", ["experiments.paper.r0_sweep", "experiments.validation.natural_cues"])
def test_scripts_that_run_every_image_refuse_a_selection_instead_of_ignoring_it(module, monkeypatch, capsys):
    import importlib

    import experiments.sweep as sweep_mod

    def ran(*a, **k):
        raise AssertionError("the sweep ran, --images ignored")

    monkeypatch.setattr(sweep_mod, "run_sweep", ran)  # nor anything written to experiments/results
    monkeypatch.setattr(sys, "argv", [module, "--images", "2"])
    with pytest.raises(SystemExit) as end:
        importlib.import_module(module).main()
    assert end.value.code == 2 and "do not apply" in capsys.readouterr().err


def test_the_input_digest_follows_the_bytes_not_the_mtime(tmp_path):
    root = fake_root(tmp_path)
    before = bsds.input_digest(root, "1")
    label = root / "labels" / "1.npz"
    os.utime(label, ns=(1, 1))  # what a copy of the dataset does to every file
    assert bsds.input_digest(root, "1") == before
    (root / "images" / "1.jpg").write_bytes(b"x" + (root / "images" / "1.jpg").read_bytes()[1:])
    assert bsds.input_digest(root, "1") != before


def test_dvs_rate_vs_spiking_makes_its_spiking_maps_again_for_other_code_or_another_recording(monkeypatch, tmp_path):
    import experiments.validation.dvs_rate_vs_spiking as page

    monkeypatch.setattr(page, "CACHE", tmp_path / "cache")
    recording = tmp_path / "dvs.es"
    recording.write_bytes(b"events")

    def served(value):
        made = [SimpleNamespace(fg_x=np.full((2, 3), value), fg_y=np.zeros((2, 3)))] * 2
        maps, read_back = page.cached_maps(page.cache_file("timed", recording, 100.0), lambda: made)
        assert len(maps) == 2 and read_back == (maps[0][0][0, 0] != value)
        return maps[0][0][0, 0]

    monkeypatch.setattr(page, "source_digest", lambda: "old-code")
    assert served(1.0) == 1.0
    assert served(2.0) == 1.0  # the same code and recording: read back
    monkeypatch.setattr(page, "source_digest", lambda: "new-code")  # say, input gains set another way
    assert served(3.0) == 3.0
    recording.write_bytes(b"others")
    assert served(4.0) == 4.0


# 3. bad label files: one line naming the file, nothing run


@pytest.mark.parametrize(
    "content, problem",
    [
        ({"fg": np.zeros((2, 10, 10), np.int8)}, "10 x 10 but the image 1.jpg is 10 x 12"),
        ({"fg": np.zeros((2, *SHAPE), np.float32)}, "integer array"),
        ({"fg": np.full((2, *SHAPE), 2, np.int8)}, "only -1, 0 and 1"),
        ({"fg": _labels(), "labellers": np.array([1, 2, 3])}, "3 labellers but 'fg' holds 2"),
        ({"other": np.zeros(3)}, "lacks key"),
    ],
)
def test_bad_labels_are_one_input_error_naming_the_file(tmp_path, content, problem):
    root = fake_root(tmp_path, ids=("1",))
    np.savez(root / "labels" / "1.npz", **content)
    with pytest.raises(InputError, match="1.npz") as err:
        load_bsds_fg(root, "1")
    assert problem in str(err.value)


def test_a_bad_label_file_ends_the_sweep_before_any_worker_starts(in_process, capsys):
    np.savez(in_process.root / "labels" / "2.npz", fg=np.zeros((2, 10, 10), np.int8))
    with pytest.raises(SystemExit) as end:
        bsds.sweep(label_sum, ["1", "2"], {}, in_process.args)
    assert end.value.code == 2 and in_process.calls == []
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "labels/2.npz" in err[0] and "10 x 10" in err[0]


def test_a_dataset_folder_without_labels_says_so(tmp_path):
    from snn_fg import datasets

    root = fake_root(tmp_path)
    shutil.rmtree(root / "labels")
    with pytest.raises(datasets.DatasetError, match=r"has no labels/ folder"):
        datasets.require("bsds-fg", root=tmp_path)
    shutil.rmtree(root)
    with pytest.raises(datasets.DatasetError, match="which is not in"):
        datasets.require("bsds-fg", root=tmp_path)


def _run(module, *args, data=None):
    env = {**os.environ, **({"SNN_FG_DATA": str(data)} if data else {})}
    return subprocess.run(
        [sys.executable, "-m", module, *args], cwd=REPO, env=env, capture_output=True, text=True, timeout=120
    )


def test_table1_on_a_garbage_label_file_prints_one_line_and_writes_nothing(dataset, tmp_path):
    data = tmp_path / "data"
    shutil.copytree(dataset("bsds-fg"), data / "bsds-fg")
    (data / "bsds-fg" / "labels" / "2092.npz").write_bytes(b"garbage")
    for ids in (["2092"], ["99999"]):
        done = _run("experiments.paper.table1", "--ids", *ids, "--workers", "1", "--no-progress", data=data)
        assert done.returncode == 2, done.stderr
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and f"{ids[0]}.npz" in lines[0], done.stderr
        assert not list(common.RESULTS.glob(f"table1_ids-{ids[0]}*"))


# 4. impossible option values


@pytest.mark.parametrize(
    "argv", [["--images", "0"], ["--workers", "0"], ["--images", "-3"], ["--spiking-threshold", "0"]]
)
def test_table1_refuses_impossible_option_values(argv, capsys):
    import experiments.paper.table1 as table1

    p = bsds.parser(table1.__doc__)
    p.add_argument("--spiking-threshold", type=bsds.contrast_threshold)
    with pytest.raises(SystemExit) as end:
        p.parse_args(argv)
    assert end.value.code == 2 and "error: argument " + argv[0] in capsys.readouterr().err


def test_a_threshold_is_a_step_of_log_intensity_an_image_can_make():
    assert bsds.contrast_threshold("0.4") == 0.4 and bsds.contrast_threshold("5") == 5.0
    for bad in ("0", "-0.1", "7", "nan", "x"):
        with pytest.raises(Exception, match="threshold|number"):
            bsds.contrast_threshold(bad)


def test_near_zero_coverage_gets_a_warning_line():
    few = {"coverage": 0.004, "n_pixels": 40}
    fine = {"coverage": 0.34, "n_pixels": 300_000}
    lines = bsds.coverage_warnings([("spiking model, pooled", few), ("rate model, pooled", fine)])
    assert len(lines) == 1 and lines[0].startswith("Warning: spiking model, pooled: coverage 0.4 %")


# 5. help text


def test_the_help_says_what_each_experiment_measures_in_whole_sentences():
    done = _run("experiments.paper.table1", "--help")
    text = " ".join(done.stdout.split())
    assert "against human labels, per event-simulator contrast threshold, for every model." in text
    # --spiking-images has no default (no spiking run) and refuses 0: its help said "default 0"
    assert "default 0" not in text and "without it no spiking network runs" in text
    done = _run("experiments.validation.spiking_groundtruth", "--help")
    text = " ".join(done.stdout.split())
    assert "issue 11" not in text and "--threshold C contrast threshold of the simulated event camera" in text
