"""Usage errors and refused options: one line each, naming the real reason."""
import subprocess
import sys

import pytest


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "snn_fg.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=300)


@pytest.mark.slow
@pytest.mark.parametrize("args, says", [
    (["run", "demo", "--out", "o", "--window-ms", "-5"], "--window-ms: must be > 0"),
    (["run", "demo", "--out", "o", "--max-windows", "0"], "--max-windows: must be >= 1"),
    (["run", "demo", "--out", "o", "--leves", "3"], "unrecognized arguments: --leves 3"),
    (["run", "demo"], "required: --out"),
    (["compare", "a.npz"], "required: B.npz"),
    (["events"], "required: INPUT"),
    (["export", "--format", "report", "--levels", "x"], "--levels: expected an integer"),
])
def test_a_usage_error_is_one_line_without_the_usage_block(tmp_path, args, says):
    res = run_cli(*args)
    assert res.returncode == 2
    assert res.stderr.count("\n") == 1 and "usage:" not in res.stderr, res.stderr
    assert res.stderr.startswith(f"snn-fg {args[0]}: error:") and says in res.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
@pytest.mark.parametrize("args, says, not_says", [
    (["--seed", "3"], "--seed: applies to the spiking and natural-spiking models only (--model spiking)", "they do not apply"),
    (["--window-ms", "20"], "--window-ms: applies to event recordings only; the demo is one image", "rate model"),
    (["--model", "spiking", "--window-ms", "20"], "event recordings only", "spiking model"),
    (["--model", "fbfg", "--motion", "circle"], "reads the image itself", "rate model"),
    (["--duration-ms", "5", "--dt-ms", "1"], "--duration-ms, --dt-ms: apply to the spiking and natural-spiking models only", "they"),
])
def test_a_refused_option_names_the_real_reason(tmp_path, args, says, not_says):
    res = run_cli("run", "demo", "--out", tmp_path / "o", *args, "--no-progress")
    assert res.returncode == 2 and res.stderr.count("\n") == 1
    assert says in res.stderr and not_says not in res.stderr, res.stderr


@pytest.mark.slow
def test_a_read_error_is_not_preceded_by_an_empty_progress_bar(tmp_path):
    bad = tmp_path / "bad.es"      # a DVS Event Stream whose first event lies far outside its 320 x 240 sensor
    bad.write_bytes(b"Event Stream\x02\x00\x00\x01\x40\x01\xf0\x00" + bytes([0x02, 0x51, 0x4c, 0x3d, 0x20]))
    res = run_cli("run", bad, "--out", tmp_path / "o")           # with progress bars
    assert res.returncode == 2
    assert res.stderr.count("\n") == 1 and "windows" not in res.stderr, res.stderr
    assert res.stderr.startswith(f"snn-fg: error: {bad}: event at (x=19537") and "byte offset 20" in res.stderr
