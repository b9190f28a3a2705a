"""What a command may write over (snn_fg.results.outputs): ``--force`` replaces only a folder that
holds an earlier output of the same command and nothing else (or nothing); a destination that cannot
be written ends in one line naming it, exit 2, nothing partial; a file a command writes is replaced
only with ``--force``, whichever command writes it."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from snn_fg.cli.main import main
from snn_fg.errors import InputError
from snn_fg.events import image_to_events, save_events
from snn_fg.frames.scenes import disc
from snn_fg.results.maps import Maps
from snn_fg.results.outputs import check_output_folder


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A disc seen by a simulated camera moving in a circle (64 x 64 sensor, 0.45 s: 6 windows of
    85 ms), as a .es recording."""
    rec = image_to_events(disc(8).image, motion="circle")
    path = tmp_path_factory.mktemp("rec") / "disc.es"
    save_events(path, rec.events, rec.sensor_size)
    return path


def _maps(folder, r0=8.0):
    folder.mkdir()
    Maps(*(np.zeros((8, 8), np.float32) for _ in range(3)), params={"r0": r0}).save(folder / "maps.npz")
    return folder


def _one_error(capsys) -> str:
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1, err
    return err[0]


# -- --force -----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("command", ["still", "recording", "decode", "export", "export lava"])
def test_force_never_deletes_a_file_snn_fg_did_not_write(tmp_path, recording, capsys, command):
    """The new user's ``snn-fg run demo --out sb3 --force`` where sb3/ held only their recording: it
    was deleted. Now each command that writes a folder refuses in one line, nothing deleted, also when
    the folder holds an earlier run beside the user's file."""
    out = tmp_path / "sb3"
    out.mkdir()
    (out / "my_recording.es").write_bytes(recording.read_bytes())
    if command.startswith("export"):
        (out / "network.json").write_text('{"schema": "snn-fg.pynn/1"}')  # (an earlier export's beside it)
    else:
        Maps(*(np.zeros((4, 4), np.float32) for _ in range(3))).save(out / "maps.npz")
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    argv = {
        "still": ["run", "demo", "--out", str(out), "--force", "--no-progress"],
        "recording": ["run", str(recording), "--out", str(out), "--force", "--no-progress"],
        "decode": ["decode", str(tmp_path / "counts.npz"), "--export", str(tmp_path), "--out", str(out), "--force"],
        "export": [
            "export",
            "--format",
            "pynn",
            "--out",
            str(out),
            "--sensor-size",
            "16x16",
            "--levels",
            "1",
            "--force",
        ],
        "export lava": ["export", "--format", "lava", "--out", str(out), "--sensor-size", "16x16", "--force"],
    }[command]
    assert main(argv) == 2
    line = _one_error(capsys)
    assert f"{out}: holds my_recording.es, which snn-fg did not write" in line and "nothing was deleted" in line
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sb3"]  # nothing set aside or staged beside it


def test_an_earlier_export_is_refused_as_an_export_not_as_a_batch(tmp_path, capsys):
    """An export folder has none of a run's maps: the batch rule (a folder without them is a batch of
    runs) once named it "an earlier batch of runs" too; only a run's folder can hold a batch."""
    from snn_fg.export.folder import EXPORT_FOLDER
    from snn_fg.results.outputs import check_output_folder

    out = tmp_path / "exp"
    out.mkdir()
    (out / "network.json").write_text(json.dumps({"schema": "snn-fg.pynn/1"}))
    with pytest.raises(InputError, match=r"holds an snn-fg export already \(network.json\); .* pass --force"):
        check_output_folder(out, EXPORT_FOLDER)


def test_force_replaces_an_earlier_run_and_a_folder_is_refused_without_it(tmp_path, capsys):
    out = _maps(tmp_path / "o")
    assert main(["run", "demo", "--out", str(out), "--levels", "2", "--no-progress", "--no-figures"]) == 2
    assert "holds an snn-fg run already (maps.npz)" in _one_error(capsys)
    assert main(["run", "demo", "--out", str(out), "--levels", "2", "--no-progress", "--no-figures", "--force"]) == 0
    assert Maps.load(out).params["levels"] == 2 and sorted(os.listdir(out)) == ["maps.npz"]
    assert sorted(os.listdir(tmp_path)) == ["o"]


def test_a_folder_of_window_figures_in_a_run_is_the_runs(tmp_path, capsys):
    """snn-fg plot RUN --windows 2-3 --out RUN/w, then snn-fg run ... --out RUN --force: refused,
    'holds w, which snn-fg did not write'; a folder of snn-fg plot's window figures is the run's."""
    out = _maps(tmp_path / "o")
    (out / "w").mkdir()
    (out / "w" / "window_0002.png").write_bytes(b"a figure")
    assert main(["run", "demo", "--out", str(out), "--levels", "2", "--no-progress", "--no-figures", "--force"]) == 0
    assert sorted(os.listdir(out)) == ["maps.npz"]
    (out / "mine").mkdir()
    (out / "mine" / "window_0002.png").write_bytes(b"a figure")
    (out / "mine" / "notes.txt").write_text("the user's")
    assert main(["run", "demo", "--out", str(out), "--no-progress", "--no-figures", "--force"]) == 2
    assert "holds mine, which snn-fg did not write" in _one_error(capsys)
    assert (out / "mine" / "notes.txt").read_text() == "the user's"


def test_a_folder_of_figures_only_is_not_an_earlier_run(tmp_path, capsys):
    """A folder holding only a ``maps.png`` (the user's own figure, say) holds no run's maps: refused."""
    out = tmp_path / "figs"
    out.mkdir()
    (out / "maps.png").write_bytes(b"a user's figure")
    assert main(["run", "demo", "--out", str(out), "--force", "--no-progress"]) == 2
    assert "holds maps.png, which snn-fg did not write" in _one_error(capsys)
    assert (out / "maps.png").read_bytes() == b"a user's figure"


def test_the_current_folder_is_written_in_place(tmp_path, monkeypatch, capsys):
    """``--out .`` (empty, then holding the earlier run, with --force): it ended in a traceback
    (the current folder cannot be renamed) and left hidden .old and .staging folders behind."""
    here = tmp_path / "here"
    here.mkdir()
    monkeypatch.chdir(here)
    opts = ["--levels", "2", "--no-progress", "--no-figures"]
    assert main(["run", "demo", "--out", ".", *opts]) == 0
    assert main(["run", "demo", "--out", ".", *opts, "--r0", "6", "--force"]) == 0
    assert sorted(os.listdir(here)) == ["maps.npz"] and Maps.load(here).params["r0"] == 6
    assert sorted(os.listdir(tmp_path)) == ["here"]


def test_a_folder_holding_the_current_one_is_refused(tmp_path, monkeypatch, capsys):
    out = _maps(tmp_path / "o")
    (out / "maps.zarr").mkdir()
    monkeypatch.chdir(out / "maps.zarr")
    assert main(["run", "demo", "--out", str(out), "--force", "--no-progress"]) == 2
    assert "holds the current folder" in _one_error(capsys)
    assert sorted(os.listdir(out)) == ["maps.npz", "maps.zarr"]


def test_a_forced_re_export_keeps_nothing_but_what_the_export_and_run_py_wrote(tmp_path, capsys):
    """An export folder after the README's loop (sPyNNaker's folder and mapping) is replaced with
    --force; with run.py's counts (under a name the user chose) or a user's notes in it, refused."""
    out = tmp_path / "model"
    export = ["export", "--format", "pynn", "--out", str(out), "--sensor-size", "16x16", "--levels", "1"]
    assert main(export) == 0
    (out / "spinnaker").mkdir()
    (out / "mapping.json").write_text("{}")
    assert main([*export, "--force"]) == 0
    assert not (out / "spinnaker").exists() and not (out / "mapping.json").exists()
    np.savez(out / "my_counts.npz", duration_ms=400.0, dt_ms=0.5, count_from_ms=200.0)
    assert main([*export, "--force"]) == 2
    assert "holds my_counts.npz: run.py's counts" in capsys.readouterr().err and (out / "my_counts.npz").exists()
    (out / "my_counts.npz").unlink()
    (out / "notes.txt").write_text("mine")
    assert main([*export, "--force"]) == 2
    assert "holds notes.txt, which snn-fg did not write" in capsys.readouterr().err
    assert (out / "notes.txt").read_text() == "mine"


# -- unwritable destinations -------------------------------------------------------------------------------------
#: each command that writes, with RO standing for a folder that cannot be written
WRITERS = {
    "run a frame": ["run", "demo", "--out", "RO/run", "--no-progress"],
    "run a recording": ["run", "REC", "--out", "RO/rec", "--no-progress"],
    "run into the folder itself": ["run", "REC", "--out", "RO", "--no-progress"],
    "run several recordings": ["run", "LIST", "--out", "RO/batch", "--no-progress"],
    "plot": ["plot", "MAPS", "--windows", "0", "--out", "RO/plots"],
    "plot --animate": ["plot", "MAPS", "--animate", "RO/maps.gif"],
    "export pynn": ["export", "--format", "pynn", "--out", "RO/m", "--sensor-size", "16x16", "--levels", "1"],
    "export lava": ["export", "--format", "lava", "--out", "RO/l", "--sensor-size", "16x16", "--levels", "1"],
    "export nir": ["export", "--format", "nir", "--out", "RO/n.nir", "--sensor-size", "16x16", "--levels", "1"],
    "export report": ["export", "--format", "report", "--out", "RO/r.json", "--sensor-size", "16x16", "--levels", "1"],
    "export network": ["export", "--format", "network", "--out", "RO/n.json", "--sensor-size", "16x16"],
    "decode": ["decode", "COUNTS", "--export", "EXPORT", "--out", "RO/maps"],
    "compare --json": ["compare", "MAPS", "MAPS2", "--json", "RO/c.json"],
    "compare --plot": ["compare", "MAPS", "MAPS2", "--plot", "RO/c.png"],
    "events --plot": ["events", "REC", "--plot", "RO/a.png", "--no-progress"],
    "events --write-frame": ["events", "REC", "--write-frame", "RO/f.npz", "--no-progress"],
    "events --write-events": ["events", "REC", "--write-events", "RO/e.npy", "--no-progress"],
    "events --write-spikes": ["events", "REC", "--write-spikes", "RO/s.npz", "--export", "EXPORT", "--no-progress"],
    "data fetch": ["data", "fetch", "events", "--no-progress"],
}

#: the child that runs every command of WRITERS in one process (each through main()) and reports
CHILD = textwrap.dedent(
    """
    import contextlib, io, json, sys
    from snn_fg.cli.main import main
    out = {}
    for name, argv in json.loads(sys.argv[1]).items():
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            out[name] = [main(argv), err.getvalue()]
    print(json.dumps(out))
    """
)


def _run_unwritable(ro, commands: dict, env: dict) -> dict:
    """Run ``commands`` (each ``main``'s argv) in a child process for which folder ``ro`` cannot be
    written: a read-only file system mounted there in a mount namespace of its own when the tests run
    as root (whom permissions do not stop), a folder without write permission otherwise."""
    child = [sys.executable, "-c", CHILD, json.dumps(commands)]
    if os.geteuid() == 0:
        if shutil.which("unshare") is None:
            pytest.skip("running as root without unshare: no way to make a folder unwritable")
        probe = subprocess.run(["unshare", "-m", "true"], capture_output=True)
        if probe.returncode != 0:
            pytest.skip(f"running as root and cannot make a mount namespace: {probe.stderr.decode().strip()}")
        mount = f'mount -t tmpfs -o ro tmpfs {ro} && exec "$@"'
        child = ["unshare", "-m", "sh", "-c", mount, "sh", *child]
    else:
        os.chmod(ro, 0o555)
    try:
        done = subprocess.run(child, capture_output=True, text=True, timeout=600, env={**os.environ, **env})
    finally:
        os.chmod(ro, 0o755)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1])


@pytest.mark.slow
def test_every_command_that_writes_says_in_one_line_that_it_cannot(tmp_path, recording):
    """A read-only --out (``OSError: [Errno 30] Read-only file system: 'romnt/maps.zarr'``) and the
    same for export, compare --json and events --plot ended in tracebacks."""
    ro = tmp_path / "ro"
    ro.mkdir()
    maps = _maps(tmp_path / "a")
    assert main(["run", str(recording), "--out", str(tmp_path / "r"), "--no-progress", "--no-figures"]) == 0
    export = tmp_path / "m"
    assert main(["export", "--format", "pynn", "--out", str(export), "--sensor-size", "16x16", "--levels", "1"]) == 0
    (tmp_path / "list.txt").write_text(f"{recording}\n")
    names = {
        "RO": str(ro),
        "REC": str(recording),
        "LIST": str(tmp_path / "list.txt"),
        "MAPS": str(tmp_path / "r"),
        "MAPS2": str(maps),
        "EXPORT": str(export),
        "COUNTS": str(tmp_path / "counts.npz"),
    }

    def named(word):
        for key, value in names.items():
            if word == key or word.startswith(key + "/"):
                return value + word[len(key) :]
        return word

    commands = {name: [named(w) for w in argv] for name, argv in WRITERS.items()}
    results = _run_unwritable(ro, commands, {"SNN_FG_DATA": str(ro / "data")})
    for name, (code, err) in results.items():
        lines = [line for line in err.splitlines() if line.strip() and "warning" not in line]
        assert code == 2 and len(lines) == 1, (name, err)
        assert "cannot write" in lines[0] and str(ro) in lines[0] and "Traceback" not in err, (name, err)
    assert os.listdir(ro) == []  # nothing partial


# -- one rule for files that exist -------------------------------------------------------------------------------
def test_files_that_exist_are_replaced_only_with_force(tmp_path, recording, capsys):
    """events --plot and compare --json/--plot overwrote without asking while run and export refused;
    then --force replaced any file of the name. Now, as for folders, --force replaces only an earlier
    output of the kind being written: the user's file of that name is refused and kept."""
    a, b = _maps(tmp_path / "a"), _maps(tmp_path / "b", r0=6.0)
    for argv, out in (
        (["compare", str(a), str(b), "--json"], tmp_path / "c.json"),
        (["compare", str(a), str(b), "--plot"], tmp_path / "c.png"),
        (["events", str(recording), "--no-progress", "--plot"], tmp_path / "e.png"),
        (["events", str(recording), "--no-progress", "--write-frame"], tmp_path / "f.npz"),
    ):
        out.write_bytes(b"the user's")
        assert main([*argv, str(out)]) == 2  # (told it is not snn-fg's at once: "pass --force" led to a refusal)
        assert f"{out}: is not a {out.suffix} file snn-fg wrote: --force replaces only" in _one_error(capsys)
        assert main([*argv, str(out), "--force"]) == 2
        assert f"{out}: is not a {out.suffix} file snn-fg wrote: --force replaces only" in _one_error(capsys)
        assert out.read_bytes() == b"the user's"
        out.unlink()
        assert main([*argv, str(out)]) == 0
        capsys.readouterr()
        assert main([*argv, str(out)]) == 2  # (an earlier output of snn-fg's: --force replaces it)
        assert f"{out}: exists; pass --force to replace it" in _one_error(capsys)
        os.utime(out, ns=(0, 0))  # (told apart from what --force writes next: the same bytes, another time)
        assert main([*argv, str(out), "--force"]) == 0
        assert out.stat().st_mtime_ns != 0
        capsys.readouterr()


def test_force_never_replaces_a_users_photo_settings_or_recording_of_the_format(tmp_path, recording, capsys):
    """A new user's ``compare ... --plot photo.png --force`` replaced their own photo: any PNG passed
    for an earlier figure. Figures, .npz files and JSON records now carry snn-fg's mark, and --force
    replaces a file of those formats only when it carries it: a real PNG, a JSON object and an events
    .npz of the user's are refused and kept byte for byte."""
    import cv2

    a, b = _maps(tmp_path / "a"), _maps(tmp_path / "b", r0=6.0)
    photo, settings, events = tmp_path / "photo.png", tmp_path / "settings.json", tmp_path / "mine.npz"
    cv2.imwrite(str(photo), np.full((12, 16, 3), 200, np.uint8))
    settings.write_text('{"threshold": 0.4, "schema": "my-lab/1"}')
    np.savez(events, events=np.zeros(3), sensor_size=np.array([16, 12]))
    kept = {p: p.read_bytes() for p in (photo, settings, events)}
    for argv in (
        ["compare", str(a), str(b), "--plot", str(photo)],
        ["events", str(recording), "--no-progress", "--plot", str(photo)],
        ["compare", str(a), str(b), "--json", str(settings)],
        ["events", str(recording), "--no-progress", "--write-events", str(events)],
    ):
        assert main([*argv, "--force"]) == 2
        err = _one_error(capsys)
        assert "file snn-fg wrote: --force replaces only" in err and "has no mark" in err, err
    assert all(p.read_bytes() == data for p, data in kept.items())


@pytest.mark.slow
def test_export_force_replaces_only_an_earlier_file_of_its_format(tmp_path, capsys):
    """The new user's ``snn-fg export --format nir --out mine/notes.txt --force`` replaced their notes
    with an HDF5 file and exited 0. Now a name with another suffix than the format's is refused (saying
    which), with or without --force; a file of the format's suffix that is not one (notes.nir) is
    refused with --force; an earlier .nir is replaced with --force. Refused: each file byte for byte."""
    export = ["export", "--format", "nir", "--sensor-size", "16x16", "--levels", "1", "--force", "--out"]
    notes, fake, earlier = tmp_path / "notes.txt", tmp_path / "notes.nir", tmp_path / "net.nir"
    for path in (notes, fake):
        path.write_bytes(b"my notes\n\x00\xff")
    assert main([*export, str(notes)]) == 2
    assert _one_error(capsys).endswith("notes.txt: --format nir writes .nir: give a file name ending .nir")
    assert main([*export, str(fake)]) == 2
    assert "notes.nir: is not a .nir file snn-fg wrote: --force replaces only" in _one_error(capsys)
    assert notes.read_bytes() == fake.read_bytes() == b"my notes\n\x00\xff"
    assert main([*export, str(earlier)]) == 0
    first = earlier.stat().st_mtime_ns
    assert main([*export, str(earlier)]) == 0 and earlier.stat().st_mtime_ns != first
    assert earlier.read_bytes().startswith(b"\x89HDF")
    report = ["export", "--format", "report", "--sensor-size", "16x16", "--levels", "1", "--out"]
    assert main([*report, str(tmp_path / "r.txt")]) == 2
    assert "--format report writes .json" in _one_error(capsys) and not (tmp_path / "r.txt").exists()


def test_an_earlier_live_run_is_replaced_with_force(tmp_path):
    """snn-fg live --force on the folder of an earlier live run (its maps, table and live.json):
    it was refused, 'holds live.json, which snn-fg did not write'."""
    out = _earlier_live_run(tmp_path / "live")
    assert check_output_folder(out, force=True) is True
    (out / "notes.txt").write_text("the user's")
    with pytest.raises(InputError, match="holds notes.txt, which snn-fg did not write"):
        check_output_folder(out, force=True)


def test_the_folders_made_for_a_file_go_again_when_it_is_not_written(tmp_path):
    """Missing folders above a file are made, as mkdir -p makes them (usage.md), and removed
    again, innermost first, when the file is not written; a folder that was there stays."""
    from snn_fg.results.atomic import atomic_path

    with atomic_path(tmp_path / "a" / "b" / "x.json") as part:
        part.write_text("{}")
    assert (tmp_path / "a" / "b" / "x.json").read_text() == "{}"
    with pytest.raises(RuntimeError), atomic_path(tmp_path / "c" / "d" / "x.json") as part:
        part.write_text("{")
        raise RuntimeError("the write failed")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a"]


def _earlier_live_run(out):
    """The entries of an earlier live run, each with the content snn-fg gives it (its store's
    attributes, live.json's version, the table's header, the figure's mark)."""
    from snn_fg.results.outputs import WINDOWS_TABLE_HEAD

    (out / "maps.zarr" / "fg_x").mkdir(parents=True)
    (out / "maps.zarr" / "fg_x" / ".zarray").write_text("{}")
    (out / "maps.zarr" / ".zgroup").write_text('{"zarr_format": 2}')
    (out / "maps.zarr" / ".zattrs").write_text(json.dumps({"snn_fg": {"format": "snn-fg maps 1"}}))
    (out / "live.json").write_text(json.dumps({"snn_fg_version": "0.1", "windows": 3}))
    (out / "windows.csv").write_text(WINDOWS_TABLE_HEAD + "events\n0,0,85,10\n")
    (out / "timeline.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"tEXtSoftware\x00snn-fg 0.1")
    return out


@pytest.mark.parametrize(
    "entry",
    ["maps.npz", "maps.zarr/data.txt", "maps.zarr", "windows/notes.txt", "windows.csv", "live.json", "timeline.png"],
)
def test_force_never_replaces_a_users_entry_that_has_a_runs_name(tmp_path, entry):
    """A user's maps.npz in a folder, or a maps.zarr folder of their own, was taken for a run's by its
    name: `snn-fg run demo --out D --force` replaced the file and emptied the folder. Each entry of a
    run's name is now judged by its content too; a user's is refused, with or without --force, and kept."""
    out = _earlier_live_run(tmp_path / "o")
    assert check_output_folder(out, force=True) is True  # (every entry snn-fg's: replaced)
    path = out / entry
    if entry in (
        "maps.zarr",
        "windows.csv",
        "live.json",
        "timeline.png",
    ):  # (the name of the run's, the user's content)
        shutil.rmtree(path) if path.is_dir() else path.unlink()
        if entry == "maps.zarr":
            path.mkdir()
            (path / ".zattrs").write_text(json.dumps({"project": "mine"}))
        else:
            path.write_text("the user's")
    else:
        path.parent.mkdir(exist_ok=True)
        if entry == "maps.npz":
            np.savez(path, fg_x=np.zeros(2), fg_y=np.zeros(2), grouping=np.zeros(2), params="{}")
        else:
            path.write_text("the user's")
    top = entry.split("/")[0]
    with pytest.raises(InputError, match=f"holds {top}, which snn-fg did not write"):
        check_output_folder(out, force=True)
    assert path.exists()


def test_the_table_head_a_run_is_told_by_is_the_tables(tmp_path):
    from snn_fg.results.outputs import WINDOWS_TABLE_HEAD
    from snn_fg.results.timeline import COLUMNS

    assert ",".join(COLUMNS).startswith(WINDOWS_TABLE_HEAD)


def test_run_force_keeps_a_users_maps_npz(tmp_path, capsys):
    """The new user's case, through the command line."""
    out = tmp_path / "d"
    out.mkdir()
    np.savez(out / "maps.npz", mydata=np.arange(3))
    before = (out / "maps.npz").read_bytes()
    assert main(["run", "demo", "--out", str(out), "--force", "--no-progress", "--no-figures"]) == 2
    assert "holds maps.npz, which snn-fg did not write" in _one_error(capsys)
    assert (out / "maps.npz").read_bytes() == before and sorted(os.listdir(out)) == ["maps.npz"]


def test_earlier_outputs_without_a_mark_are_still_a_runs(tmp_path):
    """A review of the content checks: a live.json from before it carried the version, the figure of
    window 10000 (five digits), a figure drawn before figures carried a mark beside the run's own store,
    and a store whose write was killed before an array's .zarray, were all refused as not snn-fg's."""
    out = _earlier_live_run(tmp_path / "o")
    (out / "live.json").write_text(json.dumps({"windows": 3, "latency_ms": None, "ended": "stream ended"}))
    (out / "windows").mkdir()
    (out / "windows" / "window_10000.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"tEXtSoftware\x00snn-fg 0.1")
    (out / "maps.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"tEXtSoftware\x00Matplotlib version3.9")  # (no mark)
    (out / "maps.zarr" / "grouping").mkdir()
    (out / "maps.zarr" / "grouping" / ".zarray.x1y2.part").write_text("{")
    assert check_output_folder(out, force=True) is True
    assert check_output_folder(out, resume=True) is True
    # (a user's photo of a figure's name, beside the run's maps: not drawn by matplotlib, so not the run's)
    (out / "timeline.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"tEXtSoftware\x00Phone camera 2.0")
    with pytest.raises(InputError, match="holds timeline.png, which snn-fg did not write"):
        check_output_folder(out, force=True)
    (out / "timeline.png").write_bytes((out / "maps.png").read_bytes())
    # (without the run's own maps beside it, an unmarked figure is a user's)
    (tmp_path / "figs").mkdir()
    (tmp_path / "figs" / "maps.png").write_bytes((out / "maps.png").read_bytes())
    with pytest.raises(InputError, match="holds maps.png, which snn-fg did not write"):
        check_output_folder(tmp_path / "figs", force=True)


def test_a_batch_recording_folder_named_like_a_runs_entry_is_the_batchs(tmp_path):
    """A recording named windows.aedat4 gives a batch folder windows/, a run's figure folder's name."""
    from snn_fg.results.outputs import BATCH_OR_RUN, SUMMARY_COLUMNS

    out = tmp_path / "batch"
    out.mkdir()
    (out / "summary.csv").write_text(",".join(SUMMARY_COLUMNS) + "\n")
    _earlier_live_run(out / "windows")
    assert check_output_folder(out, BATCH_OR_RUN, force=True) is True


@pytest.mark.parametrize("fmt", ["pynn", "lava"])
def test_export_force_keeps_a_users_network_json_and_run_py(tmp_path, capsys, fmt):
    """A folder of the user's own run.py and network.json was taken for an earlier export by the names:
    'export --force' replaced both. network.json is told by its schema, the rest by being beside it."""
    out = tmp_path / "mine"
    out.mkdir()
    (out / "run.py").write_text("print('mine')\n")
    (out / "network.json").write_text('{"my": 1}\n')
    argv = ["export", "--format", fmt, "--out", str(out), "--sensor-size", "32x24", "--force"]
    assert main([*argv, *(["--levels", "2"] if fmt == "pynn" else ["--network", "compact"])]) == 2
    assert (
        "holds network.json, run.py, which snn-fg did not write: --force replaces only a folder holding an "
        "snn-fg export and nothing else" in _one_error(capsys)
    )
    assert (out / "run.py").read_text() == "print('mine')\n" and (out / "network.json").read_text() == '{"my": 1}\n'
    # (an export's own folder, with a run.py the user changed in it, is the export's: replaced whole)
    (out / "network.json").unlink()
    (out / "run.py").unlink()
    base = ["export", "--format", fmt, "--out", str(out), "--sensor-size", "32x24"]
    base += ["--levels", "2"] if fmt == "pynn" else ["--network", "compact"]
    assert main(base) == 0
    (out / "run.py").write_text("print('changed')\n")
    assert main([*base, "--force"]) == 0 and "changed" not in (out / "run.py").read_text()
