"""snn-fg live offers only what a live run can run: its --help lists no frame-only option and no
model that needs an image, and each of them given is refused in one line, before any stream is opened."""

import numpy as np
import pytest

from snn_fg.cli.main import main

#: run's options a live run cannot use (with a value where they take one)
REFUSED = [
    ["--max-windows", "3"],
    ["--end-ms", "200"],
    ["--stride-ms", "40"],
    ["--denoise-us", "1000"],
    ["--refractory-us", "1000"],
    ["--save-spikes"],
    ["--duration-ms", "100"],
    ["--settle-ms", "50"],
    ["--spike-input", "events"],
    ["--edge-operator", "corf"],
]


def _live(tmp_path, *extra):
    # (a port nothing sends to, and a short wait: a run that went on to open the stream ends on "no packet")
    out = tmp_path / "o"
    argv = ["live", "udp://127.0.0.1:9", "--sensor-size", "24x24", "--out", str(out), "--wait-s", "0.2", *extra]
    return main(argv), out


def test_live_help_lists_only_what_a_live_run_takes(capsys):
    with pytest.raises(SystemExit):
        main(["live", "--help"])
    text = capsys.readouterr().out
    for flag, *_ in REFUSED:
        assert flag not in text
    assert "fbfg" not in text and "{rate,spiking,natural,natural-spiking}" in text
    for kept in ("--hop-ms", "--window-ms", "--start-ms", "--network", "--readout-lag-ms", "--carry-state"):
        assert kept in text


@pytest.mark.parametrize("option", REFUSED, ids=lambda o: o[0])
def test_an_option_a_live_run_cannot_use_is_refused_in_one_line(tmp_path, capsys, option):
    status, out = _live(tmp_path, *option)
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1, err
    assert err[0].startswith("snn-fg: error: udp://127.0.0.1:9: not for a live stream: ") and option[0] in err[0]
    assert not out.exists()


def test_several_are_named_together_with_their_reasons(tmp_path, capsys):
    status, _ = _live(tmp_path, "--end-ms", "200", "--max-windows", "2", "--denoise-us", "5")
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert status == 2
    assert "--max-windows, --end-ms: a live run ends with its stream" in line
    assert "--denoise-us: a live stream is not filtered" in line


def test_the_frame_based_model_is_not_offered(tmp_path, capsys):
    with pytest.raises(SystemExit) as ended:
        _live(tmp_path, "--model", "fbfg")
    err = capsys.readouterr().err.strip().splitlines()
    assert ended.value.code == 2 and len(err) == 1
    assert "invalid choice: 'fbfg'" in err[0] and "snn-fg live" in err[0]


@pytest.mark.parametrize(
    "argv",
    [
        ["live", "udp://127.0.0.1:99999", "--sensor-size", "24x24"],
        ["live", "udp://127.0.0.1:abc", "--sensor-size", "24x24"],
        ["live", "udp://127.0.0.1:9", "--sensor-size", "24x24", "--publish", "udp://127.0.0.1:70000"],
        ["stream", "REC", "--to", "udp://127.0.0.1:70000"],
    ],
)
def test_a_port_out_of_range_is_one_line_naming_the_address(tmp_path, capsys, argv):
    # (urllib raised ValueError "Port out of range 0-65535" from inside: a traceback)
    if "REC" in argv:
        from snn_fg.events import image_to_events
        from snn_fg.frames.scenes import disc

        np.save(tmp_path / "rec.npy", image_to_events(disc(12).image, motion="circle").events)
        argv = [str(tmp_path / "rec.npy") if a == "REC" else a for a in argv]
    status = main([*argv, *(["--out", str(tmp_path / "o")] if argv[0] == "live" else [])])
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and "with PORT an integer 0 to 65535" in line
    assert line.startswith(
        f"snn-fg: error: {next(a for a in argv if '://' in a and a.endswith(('99999', 'abc', '70000')))}:"
    )
    assert not (tmp_path / "o").exists()


def test_a_view_port_out_of_range_is_refused_by_the_option(tmp_path, capsys):
    with pytest.raises(SystemExit) as ended:
        _live(tmp_path, "--view", "70000")
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert ended.value.code == 2 and "--view: must be 0 to 65535, got 70000" in line


def test_a_view_host_without_a_page_is_refused_in_one_line(tmp_path, capsys):
    status, out = _live(tmp_path, "--view-host", "0.0.0.0")
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and line == (
        "snn-fg: error: --view-host 0.0.0.0: serves the page of --view PORT, which is not given"
    )
    assert not out.exists()
