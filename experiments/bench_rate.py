"""Benchmark: rate EDFG model per 321 x 481 frame vs the authors' ~200 s.

Times ``run_edfg`` on each bsds-edfg frame (median of --repeats runs after one
warm-up) and prints the speed-up over the reference implementation's 200 s per
frame measured on a 2-core machine of this project's size (../shared/data/README.md).
Without ../shared it uses a synthetic 321 x 481 event frame.

    python experiments/bench_rate.py [--repeats 5]
"""
from __future__ import annotations

import argparse
import json
import platform
import statistics
import time
from pathlib import Path

import numpy as np

from snn_fg.atomic import save_text
from snn_fg.rate.edfg import run_edfg

REFERENCE_S = 200.0
SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "bsds-edfg"


def frames():
    if SHARED.exists():
        for p in sorted(SHARED.glob("*.npz")):
            d = np.load(p)
            yield p.stem, d["pos"], d["neg"]
    else:
        from snn_fg.events import image_to_frame

        rng = np.random.default_rng(0)
        img = np.kron(rng.random((11, 16)), np.ones((30, 31)))[:321, :481]
        pos, neg = image_to_frame(np.pad(img, ((0, 321 - img.shape[0]), (0, 481 - img.shape[1])), mode="edge"))
        yield "synthetic", pos, neg


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    rows = []
    for name, pos, neg in frames():
        run_edfg(pos, neg)  # warm-up: kernel FFT caches
        times = []
        for _ in range(args.repeats):
            t = time.perf_counter()
            run_edfg(pos, neg)
            times.append(time.perf_counter() - t)
        med = statistics.median(times)
        rows.append({"frame": name, "shape": list(pos.shape), "median_s": med, "min_s": min(times),
                     "speedup_vs_200s": REFERENCE_S / med})
        print(f"{name:>10s} {pos.shape}  median {med:.3f} s  (min {min(times):.3f})  "
              f"speed-up {REFERENCE_S / med:.0f}x", flush=True)
    overall = statistics.median(r["median_s"] for r in rows)
    print(f"median over frames: {overall:.3f} s per frame -> {REFERENCE_S / overall:.0f}x faster than 200 s")
    out = Path(__file__).with_name("results") / "bench_rate.json"
    save_text(out, json.dumps({"machine": platform.platform(), "cpus": __import__("os").cpu_count(),
                               "frames": rows, "median_s": overall,
                               "speedup_vs_200s": REFERENCE_S / overall}, indent=2))
    print(f"saved {out}")


if __name__ == "__main__":
    main()
