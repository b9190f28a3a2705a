"""Smaller things a new user met on their own recordings: what an option's help promises, the
range of --iterations, --end-ms, progress bars in a log (a pipe is not a terminal), the times a
spike file names, and an offline ``data fetch``."""

from __future__ import annotations

import subprocess
import sys
import urllib.error

import numpy as np
import pytest

from snn_fg import datasets
from snn_fg.cli.main import build_parser, main
from snn_fg.events import image_to_events, save_events
from snn_fg.export.pynn import export_pynn
from snn_fg.frames.scenes import disc
from snn_fg.network import build_network
from snn_fg.params import ModelParams
from snn_fg.results.maps import Maps


@pytest.fixture(scope="module")
def late_clock(tmp_path_factory):
    """A disc's events on a camera clock that starts 1,500 s in (as a DAVIS346's does), 0.45 s long."""
    rec = image_to_events(disc(8).image, motion="circle")
    ev = rec.events.copy()
    ev["t"] += 1_500_000_000
    path = tmp_path_factory.mktemp("rec") / "davis.npz"
    save_events(path, ev, rec.sensor_size)
    return path


def _help(command: str, flag: str) -> str:
    parser = build_parser()[1][command]
    action = next(a for a in parser._actions if flag in a.option_strings)
    return action.help


def test_frame_only_options_say_so_in_their_help(late_clock, capsys):
    """--duration-ms said 'per frame or window' while a recording refuses it."""
    for flag in ("--duration-ms", "--settle-ms", "--seed"):
        assert _help("run", flag).startswith("frames and images:"), flag
    assert main(["run", str(late_clock), "--out", "o", "--model", "spiking", "--duration-ms", "50"]) == 2
    assert "--duration-ms: applies to a single frame or image only" in capsys.readouterr().err


def test_zero_iterations_is_refused(tmp_path, capsys):
    """--iterations 0 was accepted and gave empty maps with a misleading warning."""
    with pytest.raises(SystemExit) as stop:
        main(["run", "demo", "--out", str(tmp_path / "o"), "--iterations", "0"])
    assert stop.value.code == 2 and "--iterations: must be >= 1, got 0" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_end_ms_ends_the_windows(late_clock, tmp_path, capsys):
    """--end-ms 300 with 85 ms windows from 50 ms: the windows that end by 300 ms, [50, 135) to [220, 305) not."""
    out = tmp_path / "o"
    argv = ["run", str(late_clock), "--out", str(out), "--no-progress", "--no-figures", "--start-ms", "50"]
    assert main([*argv, "--end-ms", "300"]) == 0
    m = Maps.load(out)
    assert m.extra["t_start_us"].tolist() == [50_000, 135_000] and m.extra["t_end_us"].tolist() == [135_000, 220_000]
    assert m.params["source"]["end_ms"] == 300
    assert main([*argv, "--end-ms", "100", "--force"]) == 2
    assert "--end-ms 100: no window of 85 ms fits between --start-ms 50 and it" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize("model", [[], ["--model", "spiking", "--network", "compact"]], ids=["rate", "spiking"])
def test_a_log_gets_no_progress_bars(late_clock, tmp_path, model):
    """Progress bars went into a log unless --no-progress was given; a pipe is not a terminal
    (the fast engine's bar on a still image, too). Read as bytes: text mode would turn a bar's
    carriage returns into newlines."""
    source = [str(late_clock)] if not model else ["demo", *model]
    done = subprocess.run(
        [sys.executable, "-m", "snn_fg.cli", "run", *source, "--out", str(tmp_path / "o"), "--no-figures"],
        capture_output=True,
        timeout=600,
    )
    err = done.stderr.decode()
    assert done.returncode == 0, err
    assert not any(mark in err for mark in ("\r", "\x1b[", "it/s", "%|")), err


def test_write_spikes_names_the_window_from_the_first_event(late_clock, tmp_path, capsys):
    """--write-spikes gave a DAVIS recording's window on the camera's clock (1500000000..1500085000 us)."""
    folder = export_pynn(build_network(ModelParams(levels=1), (16, 16)), tmp_path / "model")
    spikes = folder / "input.npz"
    argv = ["events", str(late_clock), "--write-spikes", str(spikes), "--export", str(folder), "--no-progress"]
    assert main(argv) == 0
    said = capsys.readouterr().out
    assert "window 0-85 ms after the first event" in said and "1500000000" not in said
    with np.load(spikes) as d:
        assert "window 0-85 ms after the first event" in str(d["origin"])


def test_an_offline_fetch_leaves_no_empty_folder(tmp_path, monkeypatch, capsys):
    """``snn-fg data fetch events`` without a network left an empty events/ folder behind."""

    def offline(*args, **kwargs):
        raise urllib.error.URLError("no network")

    monkeypatch.setenv(datasets.ENV_VAR, str(tmp_path / "data"))
    monkeypatch.setattr("urllib.request.urlopen", offline)
    assert main(["data", "fetch", "events", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no network" in err[0] and "nothing was written" in err[0]
    assert not (tmp_path / "data").exists()


def test_export_pynn_refuses_a_target_it_does_not_know(tmp_path):
    """``export_pynn(target="bogus")`` wrote ``"target": "bogus"`` into network.json."""
    from snn_fg.errors import ParameterError

    with pytest.raises(ParameterError, match="target.*must be one of 'generic', 'spinnaker'"):
        export_pynn(build_network(ModelParams(levels=1), (16, 16)), tmp_path / "model", target="bogus")
    assert not (tmp_path / "model").exists()
