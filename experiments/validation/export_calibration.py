"""How far an export's maps move when its gains are calibrated to the input's rate.

``snn-fg run`` calibrates its network's input gains to the input's mean rate
per active pixel (``Network.calibrated``); an export's gains are set for
200 Hz unless it is made with ``--input-rate-hz``. The README's loop, as a
user runs it: the small export (32 x 24, two levels), the ``dvs.es`` window
from 100 ms (85 ms) cut to the crop ``snn-fg events --write-spikes``
picks (its busiest before 29 Nov 2026, its most outlined since), ``run.py`` on NEST (400 ms, counting from 200 ms),
``snn-fg decode``; once with the export as it comes and once re-exported
with the ``--input-rate-hz`` that ``--write-spikes`` prints. Each decoded
map against our own run of the calibrated network on the same input file:
the NEST backend and the fast engine (``snn-fg run --backend nest|fast``
calibrates the same way).

Writes experiments/results/export_calibration.{json,md}.
Usage: python -m experiments.validation.export_calibration
"""

from __future__ import annotations

import contextlib
import io
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from experiments.common import DVS_FROM_MS, Run, dataset, describe, load, load_change, markdown_table, save_results
from snn_fg.backends import RunSettings, get_backend
from snn_fg.cli import main as snn_fg
from snn_fg.events.cutter import WINDOW_MS
from snn_fg.export.board import board_network
from snn_fg.export.loop import export_network
from snn_fg.export.pynn import read_input
from snn_fg.models.spiking.decode import decode
from snn_fg.results.maps import Maps
from snn_fg.scoring.metrics import agreement

EXPORT = ["--format", "pynn", "--sensor-size", "32x24", "--levels", "2"]
WINDOW = ["--start-ms", f"{DVS_FROM_MS:g}", "--window-ms", f"{WINDOW_MS:g}"]
DURATION_MS, COUNT_FROM_MS = 400.0, 200.0


def _cli(*args) -> str:
    """``snn-fg ARGS`` in this process; its printed lines."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        if snn_fg([str(a) for a in args]) != 0:
            raise SystemExit(f"snn-fg {' '.join(map(str, args))} failed")
    return out.getvalue()


def _run_py(folder: Path) -> dict:
    """The export's run.py on NEST, as a user runs it from its folder; its wall time and load."""
    load0, t0 = load(), time.perf_counter()
    done = subprocess.run(
        [
            sys.executable,
            "run.py",
            "--input",
            "input.npz",
            "--out",
            "counts.npz",
            "--force",
            "--simulator",
            "nest",
            "--duration-ms",
            f"{DURATION_MS:g}",
            "--count-from-ms",
            f"{COUNT_FROM_MS:g}",
        ],
        cwd=folder,
        capture_output=True,
        text=True,
        check=True,
    )
    last = [line for line in done.stdout.splitlines() if line.startswith("run.py: built")][0]
    return {"wall_s": round(time.perf_counter() - t0, 1), "load": load_change(load0), "run_py": last}


def _ours(backend: str, net, inp):
    result = get_backend(backend).simulate(
        net, inp, RunSettings(duration_ms=DURATION_MS, dt_ms=net.dt_ms, count_from_ms=COUNT_FROM_MS, instantiate="all")
    )
    fx, fy, g, _ = decode(result)
    return fx, fy, g


def main():
    run = Run()
    rec = dataset("events", "dvs.es").resolve()
    out = {
        "export": " ".join(EXPORT),
        "window": " ".join(WINDOW),
        "duration_ms": DURATION_MS,
        "count_from_ms": COUNT_FROM_MS,
    }
    with tempfile.TemporaryDirectory() as tmp, contextlib.chdir(tmp):  # (folder names as a user types them)
        tmp = Path(".")
        plain, calibrated = Path("plain"), Path("calibrated")
        _cli("export", *EXPORT, "--out", plain)
        said = _cli("events", rec, *WINDOW, "--write-spikes", plain / "input.npz", "--export", plain, "--no-progress")
        out["write_spikes"] = said.strip().splitlines()
        rate = re.search(r"--input-rate-hz ([0-9.e+]+)", said)
        if rate is None:
            raise SystemExit(f"--write-spikes gave no --input-rate-hz: {said}")
        out["input_rate_hz"] = float(rate.group(1))
        _cli("export", *EXPORT, "--out", calibrated, "--input-rate-hz", rate.group(1))
        shutil.copyfile(plain / "input.npz", calibrated / "input.npz")
        maps = {}
        for name, folder in (("export", plain), ("export --input-rate-hz", calibrated)):
            out[f"run_{name}"] = _run_py(folder)
            _cli("decode", folder / "counts.npz", "--export", folder, "--out", tmp / f"maps_{folder.name}")
            maps[name] = Maps.load(tmp / f"maps_{folder.name}" / "maps.npz")
        inp = read_input(plain / "input.npz")
        net = board_network(export_network(plain)[0]).calibrated(inp.rate_hz)
        out["exact_input_rate_hz"] = inp.rate_hz
        refs = {}
        for backend in ("nest", "fast"):
            load0, t0 = load(), time.perf_counter()
            refs[backend] = _ours(backend, net, inp)
            out[f"ours_{backend}"] = {"wall_s": round(time.perf_counter() - t0, 1), "load": load_change(load0)}
    out["rows"] = [
        {
            "export": name,
            "against": f"ours, {backend}, calibrated to {inp.rate_hz:.3g} Hz",
            **agreement(m, refs[backend]),
        }
        for name, m in maps.items()
        for backend in refs
    ]
    out["run"] = run.record()
    lines = [
        "# An export calibrated to its input's rate",
        "",
        describe(out["run"]),
        "",
        f"`snn-fg export {out['export']}`; `snn-fg events dvs.es {out['window']} --write-spikes` said:",
        "",
    ]
    lines += [f"    {line}" for line in out["write_spikes"]] + [""]
    lines += markdown_table(
        ["export run on NEST", "against", "grouping r", "within 45°", "mean angle", "coverage"],
        [
            [
                r["export"],
                r["against"],
                f"{r['grouping_r']:.3f}",
                f"{100 * r['within_45']:.0f} %",
                f"{r['mean_deg']:.1f}°",
                f"{100 * r['coverage']:.0f} %",
            ]
            for r in out["rows"]
        ],
    )
    lines += [
        "",
        "run.py on NEST: "
        + "; ".join(f"{k[4:]}: {v['run_py']} ({v['load']})" for k, v in out.items() if k.startswith("run_")),
    ]
    save_results("export_calibration", out, lines)


if __name__ == "__main__":
    main()
