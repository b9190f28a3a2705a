"""Maps over time for every sample recording (dataset ``events``): a figure sequence and an animated GIF each.

    python -m experiments.validation.recordings [--max-windows N] [--spiking]

Each recording is cut into windows (85 ms, the iCub's microsaccade period,
except where the recording is too short for more than one) and every window
runs through the rate model (and, with ``--spiking``, the spiking network).
Each model runs a recording as ``snn-fg run`` does (``Model.run_windows``):
the rate model window by window, the spiking network as one continuous
network over all the windows, built once.
For each recording: ``recordings_<name>_<model>.png`` (one row per window:
events, figure-ground map, grouping map) and ``recordings_<name>_<model>.gif``
(the same rows as frames). Writes experiments/results/recordings.json / .csv
(per window: event count, vector pixels, grouping peak and its value, and
``runtime_s``, the recording's time divided by its windows).
"""

from __future__ import annotations

import argparse
import io
import time
from pathlib import Path

import numpy as np

from experiments.common import RESULTS, Run, dataset, fail, save_figure
from experiments.paper.bsds import write_table

#: name -> (file, window_ms, start_ms, sensor size or None); dvs.es starts with a 1 ms reset burst
RECORDINGS = {
    "dvs_biplane": ("dvs.es", 85.0, 1.0, None),
    "person": ("tonic_sample_person.aedat4", 85.0, 0.0, None),
    "spinner": ("expelliarmus_evt2_spinner.raw", 5.0, 0.0, (640, 480)),
    "nmnist": ("tonic_sample_nmnist.bin", 50.0, 0.0, None),
}
GIF_FRAME_MS = 400


def _frames_gif(fig_rows, path: Path):
    """An animated GIF from a list of matplotlib Figures (one per window)."""
    from PIL import Image

    from snn_fg.results.atomic import atomic_path

    images = []
    for fig in fig_rows:
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=70)
        images.append(Image.open(io.BytesIO(buf.getvalue())).convert("P", palette=Image.ADAPTIVE))
    with atomic_path(path) as tmp:
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], duration=GIF_FRAME_MS, loop=0)
    return path


def run_recording(name, model, max_windows):
    from snn_fg.events import iter_windows
    from snn_fg.models import get_model
    from snn_fg.results.figures import event_frame_rgb, maps_figure
    from snn_fg.scoring.metrics import grouping_peak

    file, window_ms, start_ms, sensor = RECORDINGS[name]
    m = get_model(model)
    rows, maps, inputs, titles = [], [], [], []
    path = dataset("events", file)
    windows = list(
        iter_windows(path, window_ms=window_ms, start_ms=start_ms, max_windows=max_windows, sensor_size=sensor)
    )
    if not windows:
        fail(f"{path}: no {window_ms:g} ms window from {start_ms:g} ms")
    t_first = windows[0].t_start_us
    t = time.perf_counter()
    results = list(m.run_windows(windows))  # (the spiking network: one continuous run over them all)
    seconds_each = (time.perf_counter() - t) / len(windows)
    for i, (w, mp) in enumerate(results):
        r, c = grouping_peak(mp.grouping)
        rows.append(
            {
                "recording": name,
                "model": model,
                "window": i,
                "t_start_ms": (w.t_start_us - t_first) / 1000,
                "events": int(len(w.events)),
                "vector_pixels": int((mp.magnitude > 0).sum()),
                "grouping_peak_row": r,
                "grouping_peak_col": c,
                "grouping_peak": float(mp.grouping.max()),
                "runtime_s": seconds_each,
            }
        )
        maps.append(mp)
        inputs.append(event_frame_rgb(w.pos, w.neg))
        titles.append(
            f"{name} {(w.t_start_us - t_first) / 1000:.0f}-{(w.t_end_us - t_first) / 1000:.0f} ms "
            "(from the first window)"
        )
    stack = lambda k: np.stack([getattr(mp, k) for mp in maps])  # noqa: E731
    label = m.grouping_label
    seq = maps_figure(inputs, stack("fg_x"), stack("fg_y"), stack("grouping"), titles, grouping_label=label)
    written = [save_figure(seq, f"recordings_{name}_{model}")]
    per_window = [
        maps_figure(inputs[i], maps[i].fg_x, maps[i].fg_y, maps[i].grouping, [titles[i]], grouping_label=label)
        for i in range(len(maps))
    ]
    written.append(_frames_gif(per_window, RESULTS / f"recordings_{name}_{model}.gif"))
    return rows, written


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--max-windows", type=int, default=12, metavar="N", help="windows per recording (12)")
    p.add_argument("--spiking", action="store_true", help="also run the spiking network on every window")
    p.add_argument("--only", nargs="+", choices=tuple(RECORDINGS), help="these recordings only")
    args = p.parse_args()
    run = Run()
    rows, written = [], []
    for name in args.only or RECORDINGS:
        for model in ("rate", "spiking") if args.spiking else ("rate",):
            r, w = run_recording(name, model, args.max_windows)
            rows += r
            written += w
            print(f"{name:12s} {model:8s} {len(r)} windows, {sum(x['runtime_s'] for x in r):.1f} s", flush=True)
    written += write_table("recordings", rows, run=run.record())
    print(f"runtime {run.seconds:.0f} s; wrote " + ", ".join(str(w.name) for w in written))


if __name__ == "__main__":
    main()
