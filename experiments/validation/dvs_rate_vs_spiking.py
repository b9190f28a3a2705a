"""Why the spiking network beats the rate model on dvs.es: its gain taken apart.

    python -m experiments.validation.dvs_rate_vs_spiking [--start-ms 100]

On the 85 ms windows of dvs.es (dataset ``events``; from --start-ms, the
spiking run's start in dvs_biplane_spiking_fast.md), each map is scored by
the share of outline vectors pointing into the plane (outline.outline_scores),
and the spiking network's advantage is split into steps, each changing one
thing:

1. the rate model, 10 iterations (the paper's), and with 1-20 iterations:
   the spiking network's read-out counts spikes while its feedback is still
   building up, where the rate model's early iterations are;
2. the spiking network on each window's event frame (regular trains at
   every event pixel: the rate model's binary input, no timing);
3. the spiking network on the recording (one network, each event a spike in
   its 0.5 ms step: the default network's ``events`` input coding,
   docs/spiking-network.md; the window clock): the default ``snn-fg run`` on
   a recording;
4. scored only on the pixels where step 3 has a vector (which pixels it
   leaves blank), and only on the busy pixels (at least the median event
   count of the window), for steps 1-3.

The spiking maps are kept in experiments/results/cache/dvs_rate_vs_spiking/,
named by the start, the recording's bytes and snn_fg's source
(:func:`cache_file`), and read back by a second run of the same code on the
same recording (the spiking runs are most of the time); the page says which
were read back. Writes experiments/results/dvs_rate_vs_spiking.{json,md}.
"""

from __future__ import annotations

import argparse
import hashlib
from pathlib import Path

import numpy as np

from experiments.common import (
    CACHE,
    DVS_FROM_MS,
    Run,
    dataset,
    describe,
    markdown_table,
    save_json,
    save_markdown,
    source_digest,
)

ITERATIONS = (1, 2, 3, 5, 10, 20)


def cache_file(kind: str, recording: Path, start_ms: float) -> Path:
    """Where the spiking maps of ``kind`` (``"timed"``, ``"frame"``) are kept: named by the start, a digest
    of the recording's bytes and :func:`~experiments.common.source_digest`, so that maps of another
    recording or of other code are made again instead of read back as this code's."""
    recording_digest = hashlib.sha1(Path(recording).read_bytes()).hexdigest()[:10]
    name = f"{kind}_{start_ms:g}_{recording_digest}_{source_digest()}.npz"
    return CACHE / "dvs_rate_vs_spiking" / name


def cached_maps(path: Path, make) -> tuple[list[tuple[np.ndarray, np.ndarray]], bool]:
    """``[(fg_x, fg_y)]`` per window from ``path``, or made by ``make()`` and stored there (atomically: an
    interrupted run leaves no half-written file to be read back); and whether they were read back."""
    from snn_fg.results.atomic import save_npz

    if path.exists():
        with np.load(path) as z:
            return [(z[f"x{k}"], z[f"y{k}"]) for k in range(sum(f.startswith("x") for f in z.files))], True
    maps = make()
    path.parent.mkdir(parents=True, exist_ok=True)
    save_npz(path, **{f"x{k}": m.fg_x for k, m in enumerate(maps)}, **{f"y{k}": m.fg_y for k, m in enumerate(maps)})
    return [(m.fg_x, m.fg_y) for m in maps], False


def _score(fields, regions, masks=None) -> dict:
    from snn_fg.scoring.outline import outline_scores

    inward, vectors = [], 0
    for k, (region, (fx, fy)) in enumerate(zip(regions, fields)):
        if masks is not None:
            fx, fy = np.where(masks[k], fx, 0), np.where(masks[k], fy, 0)
        o = outline_scores(fx, fy, region)
        inward.append(o["inward"])
        vectors += o["vectors"]
    return {
        "inward_min": float(np.nanmin(inward)),
        "inward_max": float(np.nanmax(inward)),
        "inward_median": float(np.nanmedian(inward)),
        "vectors": int(vectors),
        "per_window": inward,
    }


def _busy(window) -> np.ndarray:
    count = np.zeros(window.pos.shape, int)
    np.add.at(count, (window.events["y"], window.events["x"]), 1)
    return count >= np.median(count[count > 0])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--start-ms", type=float, default=DVS_FROM_MS)
    a = ap.parse_args()
    rec = dataset("events", "dvs.es")
    from snn_fg.backends import as_backend
    from snn_fg.events import iter_windows
    from snn_fg.models.rate.edfg import run_edfg
    from snn_fg.models.spiking import run_spiking
    from snn_fg.models.spiking.continuous import run_spiking_windows
    from snn_fg.params import ModelParams
    from snn_fg.scoring.outline import filled_outline

    run = Run()
    windows = list(iter_windows(rec, window_ms=85, start_ms=a.start_ms))
    regions = [filled_outline(w.pos | w.neg) for w in windows]
    rate = {
        it: [(m.fg_x, m.fg_y) for m in (run_edfg(w.pos, w.neg, ModelParams(iterations=it)) for w in windows)]
        for it in ITERATIONS
    }
    timed, timed_read_back = cached_maps(
        cache_file("timed", rec, a.start_ms), lambda: run_spiking_windows(windows, backend="fast", progress=False)
    )
    backend = as_backend("fast")
    frame, frame_read_back = cached_maps(
        cache_file("frame", rec, a.start_ms),
        lambda: [run_spiking(w.pos, w.neg, backend=backend, progress=False, seed=0) for w in windows],
    )
    blank = [np.hypot(*f) > 0 for f in timed]
    busy = [_busy(w) for w in windows]
    rows = {f"rate, {it} iterations": _score(rate[it], regions) for it in ITERATIONS}
    rows["spiking, each window's event frame"] = _score(frame, regions)
    rows["spiking, the recording (timed events, window clock)"] = _score(timed, regions)
    for name, fields in (
        ("rate, 10 iterations", rate[10]),
        ("rate, 3 iterations", rate[3]),
        ("spiking, each window's event frame", frame),
    ):
        rows[f"{name}, on the recording run's vector pixels"] = _score(fields, regions, blank)
    for name, fields in (
        ("rate, 10 iterations", rate[10]),
        ("spiking, each window's event frame", frame),
        ("spiking, the recording (timed events, window clock)", timed),
    ):
        rows[f"{name}, on busy pixels"] = _score(fields, regions, busy)
    read_back = {"the recording's": timed_read_back, "the frames'": frame_read_back}
    record = {
        "recording": rec.name,
        "start_ms": a.start_ms,
        "windows": len(windows),
        "spiking_maps_read_back": {"recording": timed_read_back, "frames": frame_read_back},
        "rows": rows,
        "run": run.record(),
    }
    save_json("dvs_rate_vs_spiking", record)
    lines = [
        f"# Why the spiking network beats the rate model on {rec.name}",
        "",
        f"{describe(record['run'])} {len(windows)} windows of 85 ms ({_maps_made(read_back)}). "
        "Inward: the share of outline vectors pointing into the plane, per window.",
        "",
        *_table(rows),
    ]
    save_markdown("dvs_rate_vs_spiking", lines)
    print("\n".join(lines))


def _maps_made(read_back: dict) -> str:
    """Where the page's spiking maps came from: ``{"the recording's": True, ...}`` -> words."""
    cached = [name for name, was in read_back.items() if was]
    if not cached:
        return "spiking maps made in this run"
    return f"{' and '.join(cached)} spiking maps read from the cache, made by the same snn_fg source"


def _table(rows) -> list[str]:
    return markdown_table(
        ["map", "inward, median over windows", "range", "outline vectors"],
        [
            [name, f"{r['inward_median']:.2f}", f"{r['inward_min']:.2f}-{r['inward_max']:.2f}", f"{r['vectors']:,}"]
            for name, r in rows.items()
        ],
    )


if __name__ == "__main__":
    main()
