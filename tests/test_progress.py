"""Progress where stderr is not a terminal (a log file, a pipe, CI): a plain line now and then,
not silence until the end (tqdm turns itself off there)."""

import io

import numpy as np
from tqdm import tqdm

from snn_fg.cli.main import main
from snn_fg.events import image_to_events
from snn_fg.frames.scenes import disc
from snn_fg.results import progress


class Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


def test_lines_come_at_most_every_interval_with_the_count_and_the_total():
    clock, out = Clock(), io.StringIO()
    count = progress.bar("windows done", "win", 200, clock=clock, file=out)
    assert isinstance(count, progress.Lines)
    for step in (1, 10, 25, 31, 40, 95):  # seconds since the start at each update
        clock.t = 100.0 + step
        count.update()
    lines = out.getvalue().splitlines()
    # 31 s passes the first 30 s; 40 s is only 9 s after it; 95 s is 64 s after it
    assert lines == ["snn-fg: windows done 4 of 200 (31 s)", "snn-fg: windows done 6 of 200 (95 s)"]


def test_a_short_run_prints_nothing_and_minutes_read_as_minutes():
    clock, out = Clock(), io.StringIO()
    with progress.bar("recordings", "rec", None, clock=clock, file=out) as count:
        count.update(3)
    assert out.getvalue() == ""
    clock.t += 600
    count.update()
    assert out.getvalue() == "snn-fg: recordings 4 (10.0 min)\n"


def test_a_terminal_gets_a_bar_and_disable_gets_silence():
    class Terminal(io.StringIO):
        def isatty(self):
            return True

    assert isinstance(progress.bar("windows read", "win", 3, file=Terminal()), tqdm)
    silent = progress.bar("windows read", "win", 3, disable=True, file=io.StringIO())
    assert isinstance(silent, tqdm) and silent.disable


def test_a_run_logged_to_a_file_says_how_far_it_is(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(progress, "EVERY_S", 0.0)  # (a line at every window, not every 30 s)
    rec = image_to_events(disc(12).image, motion="circle")
    np.save(tmp_path / "rec.npy", rec.events)
    h, w = disc(12).image.shape
    args = ["run", str(tmp_path / "rec.npy"), "--model", "rate", "--sensor-size", f"{w}x{h}"]
    assert main([*args, "--window-ms", "40", "--max-windows", "2", "--no-figures", "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err
    assert "snn-fg: windows read 1 of 2 (" in err and "snn-fg: windows read 2 of 2 (" in err
    assert (
        main(
            [
                *args,
                "--window-ms",
                "40",
                "--max-windows",
                "2",
                "--no-figures",
                "--no-progress",
                "--out",
                str(tmp_path / "q"),
            ]
        )
        == 0
    )
    assert "windows read" not in capsys.readouterr().err


def test_a_download_counts_megabytes_and_simulated_time_counts_ms():
    clock, out = Clock(), io.StringIO()
    download = progress.bar("fetching bsds-fg", "B", 13_200_000, clock=clock, file=out)
    clock.t += 31
    download.update(4_500_000)
    simulated = progress.bar("simulating", "ms", 3000, clock=clock, file=out)
    clock.t += 31
    simulated.update(1200.5)
    assert out.getvalue().splitlines() == [
        "snn-fg: fetching bsds-fg 4.5 of 13.2 MB (31 s)",
        "snn-fg: simulating 1200 of 3000 ms (31 s)",
    ]
