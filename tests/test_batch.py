"""snn-fg run on several recordings: one output each plus summary.csv, on a
Dask LocalCluster; a broken recording is reported with its one-line error and
stops nothing; a rerun skips the recordings already complete."""

import csv

import numpy as np
import pytest

from snn_fg.cli import main
from snn_fg.cli.batch import output_names, recordings_of
from snn_fg.errors import InputError
from snn_fg.results.maps import Maps


@pytest.fixture()
def folder(tmp_path):
    from snn_fg.events import image_to_events, save_events
    from snn_fg.frames.scenes import disc

    d = tmp_path / "recs"
    d.mkdir()
    for name, r in (("a", 10), ("c", 14)):
        rec = image_to_events(disc(r).image, motion="circle")
        save_events(d / f"{name}.npy", rec.events, rec.sensor_size)
    (d / "b.npy").write_bytes(b"not a recording at all")
    (d / "notes.md").write_text("not a recording either: skipped by its suffix")
    return d


def _summary(out):
    with open(out / "summary.csv") as fh:
        return {r["recording"].rsplit("/", 1)[-1]: r for r in csv.DictReader(fh)}


@pytest.mark.slow
def test_three_recordings_on_a_local_cluster_one_broken(folder, tmp_path, capsys):
    distributed = pytest.importorskip("dask.distributed", reason="Dask is in the test extra")
    out = tmp_path / "out"
    opts = [
        "--window-ms",
        "60",
        "--max-windows",
        "2",
        "--levels",
        "3",
        "--sensor-size",
        "64x64",
        "--no-figures",
        "--no-progress",
    ]
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None
    ) as cluster:
        code = main(["run", str(folder), "--out", str(out), "--scheduler", cluster.scheduler_address, *opts])
    printed = capsys.readouterr().out
    assert code == 1 and "3 recordings, 1 failed" in printed
    rows = _summary(out)
    assert sorted(rows) == ["a.npy", "b.npy", "c.npy"]
    assert rows["b.npy"]["status"] == "failed" and "b.npy" in rows["b.npy"]["error"]
    assert "\n" not in rows["b.npy"]["error"] and "Traceback" not in rows["b.npy"]["error"]
    (line,) = (x for x in printed.splitlines() if x.lstrip().startswith("failed"))
    assert line.count("b.npy") == 1, line  # (the error's own file name is not said twice)
    for name in ("a", "c"):
        assert rows[f"{name}.npy"]["status"] == "done" and rows[f"{name}.npy"]["windows"] == "2"
        m = Maps.load(out / name)
        assert m.fg_x.shape == (2, 64, 64) and np.count_nonzero(m.fg_x) > 0
    assert sorted(p.name for p in out.iterdir()) == ["a", "c", "summary.csv"]
    # a rerun (here on one local process) skips what is complete and tries the broken one again
    assert main(["run", str(folder), "--out", str(out), "--workers", "1", *opts]) == 1
    again = _summary(out)
    assert [again[k]["status"] for k in sorted(again)] == ["skipped", "failed", "skipped"]
    # a rerun with other options keeps nothing made with the old ones as if it were theirs (until 30 Nov it was
    # skipped, its 60 ms windows read as the 50 ms ones asked for), and is refused before it runs anything: until
    # 1 Dec each recording failed and the summary was rewritten to say nothing had been done
    before, summary = Maps.load(out / "a").fg_x, (out / "summary.csv").read_text()
    capsys.readouterr()
    assert main(["run", str(folder), "--out", str(out), "--workers", "1", *opts[:1], "50", *opts[2:]]) == 2
    assert capsys.readouterr().err == (
        f"snn-fg: error: {out / 'a'}: holds an earlier run made with other options (these differ: window_ms (60.0 "
        "before, 50.0 now)) (and 1 other input has an earlier run here): nothing was run; --force replaces the "
        "earlier runs, or choose another --out\n"
    )
    np.testing.assert_array_equal(Maps.load(out / "a").fg_x, before)
    assert (out / "summary.csv").read_text() == summary


def test_inputs_a_folder_a_glob_or_a_list_name(folder, tmp_path):
    listed = tmp_path / "list.txt"
    listed.write_text("# two of them\nrecs/c.npy\n\n" + str(folder / "a.npy") + "\n")
    assert [p.name for p in recordings_of(str(folder))] == ["a.npy", "b.npy", "c.npy"]
    assert [p.name for p in recordings_of(str(folder / "[ac].npy"))] == ["a.npy", "c.npy"]
    assert recordings_of(str(listed)) == [tmp_path / "recs" / "c.npy", folder / "a.npy"]
    twice = tmp_path / "twice.txt"  # (the same recording, named two ways: it ran twice, as a_1 and a_2)
    twice.write_text(f"recs/a.npy\n# again\n{folder / 'a.npy'}\n")
    with pytest.raises(InputError, match=r"names .*a.npy twice \(lines 1 and 3\): a recording runs once"):
        recordings_of(str(twice))
    assert output_names([tmp_path / "x" / "r.es", tmp_path / "y" / "r.es", tmp_path / "q.raw"]) == ["x_r", "y_r", "q"]
    assert main(["run", str(folder / "*.es"), "--out", str(tmp_path / "o")]) == 2  # names nothing
    assert main(["run", str(folder / "a.npy"), "--out", str(tmp_path / "p"), "--workers", "2"]) == 2


def test_a_recording_named_txt_is_refused_as_a_list_in_one_line(tmp_path, capsys):
    """``snn-fg run atis.txt`` where the file is a binary recording: a UnicodeDecodeError traceback.
    Now one line saying a .txt INPUT is a list of paths, where the binary data starts, and what the
    file looks like."""
    from snn_fg.events import EVENT_DTYPE, save_events

    rng = np.random.default_rng(0)
    ev = np.zeros(500, EVENT_DTYPE)
    ev["x"], ev["y"], ev["p"] = rng.integers(0, 32, 500), rng.integers(0, 24, 500), rng.integers(0, 2, 500)
    ev["t"] = np.cumsum(rng.integers(0, 5000, 500))
    save_events(tmp_path / "atis.es", ev, (32, 24))
    (tmp_path / "atis.es").rename(tmp_path / "atis.txt")
    assert main(["run", str(tmp_path / "atis.txt"), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0]
    assert "atis.txt: not a list of paths: a .txt INPUT is read as a list of recordings, one path a line" in err[0]
    assert "it looks like an Event Stream (.es) file: give it the suffix .es" in err[0] and "(at byte offset" in err[0]
    assert not (tmp_path / "o").exists()


def test_a_folder_of_images_is_a_batch_as_their_glob_is(tmp_path, capsys):
    """A new user's 'snn-fg run imgs --out batch' (BSDS images in a folder) was refused, 'names no
    recording', while 'imgs/*.jpg' ran them: a folder's images are its inputs too, notes left out."""
    import cv2

    imgs = tmp_path / "imgs"
    imgs.mkdir()
    for name in ("b.png", "a.jpg"):
        cv2.imwrite(str(imgs / name), np.full((24, 32, 3), 90, np.uint8))
    (imgs / "notes.txt").write_text("mine")
    assert [p.name for p in recordings_of(str(imgs))] == ["a.jpg", "b.png"]
    (tmp_path / "none").mkdir()
    for name in ("b.png", "a.jpg"):  # (a bright square: events to run on)
        img = np.full((24, 32, 3), 90, np.uint8)
        img[8:16, 10:22] = 200
        cv2.imwrite(str(imgs / name), img)
    assert main(["run", str(imgs), "--out", str(tmp_path / "b"), "--no-progress", "--no-figures", "--levels", "2"]) == 0
    printed = capsys.readouterr().out.splitlines()
    # an image's run has no windows: the table and the count say images (the summary's windows left empty)
    assert [line.split()[:2] for line in printed[:2]] == [["done", "image"], ["done", "image"]]
    assert printed[2].startswith("snn-fg: 2 images, 0 failed; summary in ")
    assert {r["windows"] for r in _summary(tmp_path / "b").values()} == {""}
    assert main(["run", str(tmp_path / "none"), "--out", str(tmp_path / "o")]) == 2
    assert "names no recording or image (a folder of recordings or images" in capsys.readouterr().err


def test_a_recordings_warning_names_it_once(tmp_path, capsys):
    """A new user's batch said 'snn-fg: warning: data/u.aedat: data/u.aedat: no sensor size given':
    a warning that names its file already is said as it is (one that does not gets the name, as before)."""
    from snn_fg.events import image_to_events
    from snn_fg.frames.scenes import disc

    d = tmp_path / "recs"
    d.mkdir()
    for name in ("a", "b"):
        np.save(d / f"{name}.npy", image_to_events(disc(10).image, motion="circle").events)  # (no sensor size)
    opts = ["--max-windows", "1", "--levels", "3", "--no-figures", "--no-progress", "--workers", "1"]
    assert main(["run", str(d / "*.npy"), "--out", str(tmp_path / "o"), *opts]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if "no sensor size given" in line]
    assert len(warned) == 2, warned
    for line, name in zip(sorted(warned), ("a", "b")):
        assert line.startswith(f"snn-fg: warning: {d / name}.npy: no sensor size given;"), line
        assert line.count(f"{name}.npy") == 1, line


def test_an_interrupted_batch_says_what_it_left_and_that_the_same_command_goes_on(
    folder, tmp_path, capsys, monkeypatch
):
    """Ctrl-C during a batch said 'the output was left as it was before the run', while its folder held
    the recordings done and the windows of the one cut short (a new user's trial, 1 Dec)."""
    from snn_fg.cli import batch

    def cut_short(jobs, *args):
        yield from ()
        raise KeyboardInterrupt

    monkeypatch.setattr(batch, "_run_all", cut_short)
    assert main(["run", str(folder), "--out", str(tmp_path / "out"), "--no-progress"]) == 130
    said = capsys.readouterr().err
    assert "left as it was" not in said and "no summary.csv was written: the same command goes on" in said


def test_an_earlier_batch_is_an_earlier_run_to_force_not_a_users_folder(folder, tmp_path, capsys):
    """A single run with --force into the folder of an earlier batch was refused: 'holds a, summary.csv,
    ..., which snn-fg did not write' (a new user's trial, 1 Dec). A batch's folder (its summary.csv and
    a run per recording) is an earlier run: replaced with --force, never continued with --resume; a
    user's own summary.csv is still not snn-fg's; plot names a run in the batch."""
    from snn_fg.results.outputs import SUMMARY_COLUMNS

    out = tmp_path / "batch"
    one = [str(folder / "a.npy"), "--model", "rate", "--levels", "3", "--no-progress", "--no-figures"]
    assert main(["run", *one, "--out", str(out / "a")]) == 0
    (out / "summary.csv").write_text(",".join(SUMMARY_COLUMNS) + "\n")
    capsys.readouterr()
    assert main(["plot", str(out)]) == 2
    assert f"a batch, a run per recording (a): plot one, {out / 'a'}" in capsys.readouterr().err
    assert main(["run", *one, "--out", str(out)]) == 2
    assert "holds an earlier batch of runs (a, summary.csv); choose another output folder or pass --force" in (
        capsys.readouterr().err
    )
    assert main(["run", *one, "--out", str(out), "--resume"]) == 2
    assert "not one run to continue" in capsys.readouterr().err
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "summary.csv").write_text("my,own,table\n")
    assert main(["run", *one, "--out", str(mine), "--force"]) == 2
    assert "which snn-fg did not write" in capsys.readouterr().err and (mine / "summary.csv").exists()
    assert main(["run", *one, "--out", str(out), "--force"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["maps.zarr", "windows.csv"]


def _one_recording(tmp_path):
    from snn_fg.events import image_to_events, save_events
    from snn_fg.frames.scenes import disc

    d = tmp_path / "recs"
    d.mkdir()
    rec = image_to_events(disc(10).image, motion="circle")
    save_events(d / "a.npy", rec.events, rec.sensor_size)
    save_events(d / "c.npy", rec.events[: rec.events.size // 2], rec.sensor_size)
    return d


_QUICK = ["--window-ms", "60", "--levels", "3", "--sensor-size", "64x64", "--no-figures", "--no-progress"]


def test_a_users_summary_csv_is_refused_before_anything_runs(tmp_path, capsys):
    """A batch wrote its table over a user's summary.csv in the output folder, without --force."""
    d, out = _one_recording(tmp_path), tmp_path / "out"
    out.mkdir()
    (out / "summary.csv").write_text("my summary\n")
    assert main(["run", str(d), "--out", str(out), "--workers", "1", "--max-windows", "1", *_QUICK]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "summary.csv: is not a batch's summary" in err and "nothing was run" in err
    assert (out / "summary.csv").read_text() == "my summary\n" and sorted(p.name for p in out.iterdir()) == [
        "summary.csv"
    ]


def test_a_rerun_with_a_larger_window_limit_continues_the_runs_it_cut(tmp_path, capsys):
    """A batch rerun with --max-windows 3 after one with 2 said 'skipped 2 windows' for every recording,
    where a single run's --resume --max-windows 3 goes on to 3 windows."""
    d, out = _one_recording(tmp_path), tmp_path / "out"
    run = ["run", str(d), "--out", str(out), "--workers", "1", *_QUICK]
    assert main([*run, "--max-windows", "2"]) == 0
    assert {k: r["windows"] for k, r in _summary(out).items()} == {"a.npy": "2", "c.npy": "2"}
    first = Maps.load(out / "a").fg_x
    assert main([*run, "--max-windows", "3"]) == 0
    rows = _summary(out)
    assert {k: (r["status"], r["windows"]) for k, r in rows.items()} == {"a.npy": ("done", "3"), "c.npy": ("done", "3")}
    np.testing.assert_array_equal(Maps.load(out / "a").fg_x[:2], first)  # (continued, not made again)
    assert main([*run, "--max-windows", "3"]) == 0  # (nothing to add now)
    assert [r["status"] for r in _summary(out).values()] == ["skipped", "skipped"]


def test_a_batch_named_another_way_goes_on_with_its_runs(tmp_path, monkeypatch):
    """Run again with the folder's path made absolute (or from another folder), a batch was refused
    whole: 'these differ: input (recs/a.npy before, /abs/recs/a.npy now)', where --resume goes on."""
    d = _one_recording(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert main(["run", "recs", "--out", "out", "--workers", "1", "--max-windows", "2", *_QUICK]) == 0
    assert main(["run", str(d), "--out", "out", "--workers", "1", "--max-windows", "3", *_QUICK]) == 0
    assert {k: (r["status"], r["windows"]) for k, r in _summary(tmp_path / "out").items()} == {
        "a.npy": ("done", "3"),
        "c.npy": ("done", "3"),
    }


def test_a_rerun_whose_runs_have_nothing_to_add_skips_them(tmp_path):
    """With --end-ms and --max-windows both given, a larger --max-windows was skipped; a limit the runs
    already hold goes through the run and is said skipped, not done."""
    d, out = _one_recording(tmp_path), tmp_path / "out"
    run = ["run", str(d), "--out", str(out), "--workers", "1", "--end-ms", "5000", *_QUICK]
    assert main([*run, "--max-windows", "2"]) == 0
    assert main([*run, "--max-windows", "3"]) == 0
    assert {r["windows"] for r in _summary(out).values()} == {"3"}
    assert main([*run, "--max-windows", "2"]) == 0  # (fewer than they hold: nothing to add)
    assert {(r["status"], r["windows"]) for r in _summary(out).values()} == {("skipped", "3")}


def test_a_batch_of_images_run_again_skips_them_and_refuses_other_options(tmp_path, capsys):
    """Run again, a batch of images marked every image failed ('holds an snn-fg run already') and
    rewrote the summary, where the interrupt note says the same command goes on: an image's maps now
    keep the run's key, and a rerun skips the images done; with other options it is refused whole."""
    import cv2

    imgs, out = tmp_path / "imgs", tmp_path / "b"
    imgs.mkdir()
    for name in ("a.png", "b.png"):
        img = np.full((24, 32, 3), 90, np.uint8)
        img[8:16, 10:22] = 200
        cv2.imwrite(str(imgs / name), img)
    run = ["run", str(imgs), "--out", str(out), "--no-progress", "--no-figures", "--workers", "1"]
    assert main([*run, "--levels", "2"]) == 0
    first = (out / "a" / "maps.npz").read_bytes()
    assert main([*run, "--levels", "2"]) == 0
    assert [r["status"] for r in _summary(out).values()] == ["skipped", "skipped"]
    assert (out / "a" / "maps.npz").read_bytes() == first
    capsys.readouterr()
    assert main([*run, "--levels", "3"]) == 2
    err = capsys.readouterr().err
    assert "holds an earlier run made with other options (these differ: levels (2 before, 3 now))" in err
    assert [r["status"] for r in _summary(out).values()] == ["skipped", "skipped"]  # (the summary kept)
