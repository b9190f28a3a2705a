"""Interrupting a run with a real signal (Ctrl-C's SIGINT, or SIGTERM) exits
non-zero and says so in one line. A frame's run leaves the output folder
exactly as it was before the run (an earlier run in it stays whole); a
recording's leaves the windows completed so far, which --resume continues."""

import os
import signal
import subprocess
import sys
import time

import cv2
import numpy as np
import pytest

from snn_fg.events import image_to_events, save_events
from snn_fg.frames.scenes import demo
from snn_fg.results.maps import Maps
from tests.conftest import earlier_run_files

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp("inputs")
    # edges all over the frame: both image models take seconds on it (on an
    # upscaled demo the rate model could finish within the second the test
    # waits, and the frame-based one had about a second to spare)
    noise = np.random.default_rng(0).random((90, 120))
    texture = cv2.resize(noise, (960, 720), interpolation=cv2.INTER_CUBIC)
    cv2.imwrite(str(d / "texture.png"), (np.clip(texture, 0, 1) * 255).astype(np.uint8))
    rec = image_to_events(demo().image, motion="circle")
    ev = np.concatenate([rec.events] + [rec.events.copy() for _ in range(29)])
    ev["t"] += np.repeat(np.arange(30) * 400_000, len(rec.events))  # 12 s of saccades
    save_events(d / "long.npz", ev, rec.sensor_size)
    return d


CASES = {
    "rate-image": lambda d: ["texture.png"],
    "fbfg-image": lambda d: ["texture.png", "--model", "fbfg"],
    "spiking-frame": lambda d: ["demo", "--model", "spiking", "--duration-ms", "60000"],
}


@pytest.mark.slow
@pytest.mark.parametrize(
    "case, sig, after_s",
    [
        ("rate-image", signal.SIGINT, 1.0),
        ("fbfg-image", signal.SIGTERM, 1.0),
        ("spiking-frame", signal.SIGINT, 1.0),
        ("spiking-frame", signal.SIGTERM, 1.0),
        # at once: while the simulator is still being imported (an interrupt there can be swallowed by importlib)
        ("spiking-frame", signal.SIGINT, 0.0),
        ("spiking-frame", signal.SIGINT, 0.1),
    ],
)
def test_an_interrupted_run_leaves_the_output_folder_as_it_was(inputs, tmp_path, case, sig, after_s):
    out = tmp_path / "out"
    out.mkdir()
    earlier = earlier_run_files()
    for name, data in earlier.items():
        (out / name).write_bytes(data)
    args = CASES[case](inputs)
    args[0] = args[0] if args[0] == "demo" else str(inputs / args[0])
    proc = subprocess.Popen(
        [sys.executable, "-m", "snn_fg.cli", "run", *args, "--out", str(out), "--force", "--no-progress"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 120
    while not list(out.glob(".snn-fg.*.staging")):  # the run has started writing (inside the folder it replaces)
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.05)
    time.sleep(after_s)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == (130 if sig == signal.SIGINT else 143), err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "interrupted" in lines[0] and "left as it was" in lines[0], err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == earlier
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no staging folder left


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_an_interrupted_recording_keeps_its_complete_windows_and_resumes(inputs, tmp_path, sig):
    from snn_fg.results.store import read_attrs, windows_complete

    out = tmp_path / "out"
    cmd = [
        sys.executable,
        "-m",
        "snn_fg.cli",
        "run",
        str(inputs / "long.npz"),
        "--window-ms",
        "50",
        "--max-windows",
        "40",
        "--no-figures",
        "--no-progress",
        "--out",
        str(out),
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while windows_complete(out) < 2:
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.02)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == (130 if sig == signal.SIGINT else 143), err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "interrupted" in lines[0] and "--resume" in lines[0], err
    n = windows_complete(out)
    assert 2 <= n < 40 and Maps.load(out).fg_x.shape[0] == n
    assert f"the {n} windows completed so far are in {out}/ (maps.zarr: snn-fg plot {out} draws them)" in lines[0]
    assert not read_attrs(out / "maps.zarr")["snn_fg"]["complete"]
    done = subprocess.run(cmd + ["--resume"], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    m = Maps.load(out)
    assert m.fg_x.shape[0] == 40 and np.all(np.diff(m.extra["t_start_us"]) == 50_000)


class _SwallowsAnInterrupt:
    """Receives Ctrl-C inside its finalizer, where Python can only print the
    KeyboardInterrupt and go on (as when a signal lands in garbage collection)."""

    def __del__(self):
        signal.raise_signal(signal.SIGINT)
        for _ in range(10):  # the handler runs at the next check of the eval loop
            pass


@pytest.mark.parametrize("then", ["goes_on", "fails"])
def test_an_interrupt_swallowed_by_a_finalizer_still_stops_a_recording_at_the_next_window(
    inputs, tmp_path, monkeypatch, capsys, then
):
    """The run goes on after the swallowed interrupt (and stops at the next
    window), or fails because of it (and the interrupt is reported, not the
    error)."""
    from snn_fg import cli
    from snn_fg.cli import runner

    appended = []
    real_append = runner.MapsStore.append

    def append(self, *a, **kw):
        appended.append(1)
        if len(appended) == 2:
            _SwallowsAnInterrupt()  # made and dropped at once: its finalizer runs here
            if then == "fails":
                raise RuntimeError("a library left in a broken state by the interrupt")
        return real_append(self, *a, **kw)

    monkeypatch.setattr(runner.MapsStore, "append", append)
    out = tmp_path / "out"
    out.mkdir()
    (out / "maps.npz").write_bytes(earlier_run_files()["maps.npz"])
    before = signal.getsignal(signal.SIGINT), sys.unraisablehook
    code = cli.main(
        ["run", str(inputs / "long.npz"), "--window-ms", "50", "--out", str(out), "--force", "--no-progress"]
    )
    err = capsys.readouterr().err
    assert code == 130
    assert len(appended) == 2, f"the run went on for {len(appended)} windows after the interrupt"
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "interrupted" in lines[0], err  # no "Exception ignored" report
    # the windows completed: the second too when the run went on through it
    assert os.listdir(out) == ["maps.zarr"] and Maps.load(out).fg_x.shape[0] == (2 if then == "goes_on" else 1)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert (signal.getsignal(signal.SIGINT), sys.unraisablehook) == before  # both restored


def test_an_interrupt_while_the_figures_are_drawn_says_to_draw_them_not_to_resume(
    inputs, tmp_path, monkeypatch, capsys
):
    """Every window done, the run interrupted as it drew its figures: it had said '--resume continues',
    and --resume then said 'finished already' with no figure drawn (two new users' trials, 30 Nov)."""
    from snn_fg import cli
    from snn_fg.cli import runner

    def interrupted(*a, **kw):
        raise KeyboardInterrupt

    out = tmp_path / "out"
    args = ["run", str(inputs / "long.npz"), "--window-ms", "50", "--max-windows", "2", "--out", str(out)]
    with monkeypatch.context() as m:
        m.setattr(runner, "write_run_tables", interrupted)
        assert cli.main([*args, "--no-progress"]) == 130
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].endswith(
        f"every window was done: the 2 windows are in {out}/ (maps.zarr), but not every figure was drawn: "
        f"snn-fg plot {out} --force draws them (--resume has nothing left to run)"
    )
    assert cli.main([*args, "--resume", "--no-progress"]) == 0
    said = capsys.readouterr().out
    assert (
        f"finished already (2 windows): nothing to resume, nothing written (maps.png is not there: "
        f"snn-fg plot {out} --force draws the figures)" in said
    )
    assert cli.main(["plot", str(out), "--force"]) == 0 and (out / "maps.png").exists()
