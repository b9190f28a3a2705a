"""Run the exported figure-ground network's NIR graph in snnTorch (written by ``snn-fg export --format nir
--nir-profile snntorch --out DIR``).

Needs torch, snnTorch (which brings nirtorch), nir and numpy; no snn-fg. Run it from its own folder:

    python run.py --input input.npz --out counts.npz [--duration-ms 400] [--count-from-ms 200] [--threads 1]

``input.npz`` is what ``snn-fg events INPUT --write-spikes input.npz --export .`` writes: ``indices``
(source of each spike: ON pixel y*W+x, OFF pixel H*W + y*W+x, the window clock 2*H*W), ``steps``,
``dt_ms``, ``period_steps`` (the pattern repeats with this period; -1: it does not) and ``shape`` (H, W).
The graph (``model.nir``) is read by snnTorch's NIR import and stepped by nirtorch, one snnTorch step
for each of the network's time steps (``dt_ms`` in ``network.json``). The graph has no window clock (it
fires only between the windows of a recording, and the input is one window replayed): spikes of the
clock's source are left out, and run.py says how many. The output gets, per population,
``count_<name>``: every cell's spikes from ``--count-from-ms`` (default: half the run) to the end, one
count window as the PyNN and Lava exports' run.py write; ``snn-fg decode counts.npz --export . --out
maps`` turns it into maps.
"""

import argparse
import json
import sys
import time
from importlib.util import find_spec

import fg_files
import fg_inputs
import fg_snntorch
import numpy as np

#: the packages run.py needs, with the module each is imported as
NEEDS = {"torch": "torch", "snntorch": "snntorch", "nirtorch": "nirtorch", "nir": "nir"}
INSTALL = (
    'pip install -e ".[snntorch]" in the snn-fg folder, or pip install torch==2.13.0 snntorch==1.0.0 '
    "nirtorch==2.6 nir==1.0.8 (the CPU build of torch: --index-url https://download.pytorch.org/whl/cpu)"
)


def check_packages():
    """Exit with one line saying what to install unless every package run.py needs can be imported."""
    missing = [name for name, module in NEEDS.items() if find_spec(module) is None]
    if missing:
        sys.exit(f"run.py: error: {', '.join(missing)} not installed: {INSTALL}")


def parse(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--input", required=True, help="input spike file (snn-fg events --write-spikes)")
    ap.add_argument("--out", required=True, help="output counts file")
    ap.add_argument("--force", action="store_true", help="replace the --out file if it exists")
    ap.add_argument("--duration-ms", type=float, default=400.0)
    ap.add_argument("--count-from-ms", type=float, default=None, help="start of the counting window (half the run)")
    ap.add_argument("--threads", type=int, default=1, help="torch's threads (1)")
    args = ap.parse_args(argv)
    if not 0 < args.duration_ms:
        ap.error("--duration-ms must be > 0")
    if args.count_from_ms is not None and not 0 <= args.count_from_ms < args.duration_ms:
        ap.error("--count-from-ms must lie in [0, --duration-ms)")
    fg_files.check_out(args.out, args.force)
    return args


def main(argv=None):
    args = parse(argv)
    with open("network.json") as fh:
        try:
            meta = json.load(fh)
        except ValueError as exc:
            sys.exit(f"run.py: error: network.json: not valid JSON: {exc}")
    missing = [k for k in ("frame_shape", "dt_ms", "graph", "populations") if k not in meta]
    if missing:  # (the network itself is model.nir: this file names it and the populations' sizes)
        sys.exit(f"run.py: error: network.json: no {', '.join(missing)} (snn-fg export --format nir writes it)")
    h, w = meta["frame_shape"]
    dt_ms, n_pixels = float(meta["dt_ms"]), 2 * h * w
    n_steps = int(round(args.duration_ms / dt_ms))
    # (the sources of an input file: every pixel's ON and OFF, and the window clock after them)
    indices, steps, _ = fg_inputs.input_spikes(args.input, n_steps, n_pixels + 1, (h, w), dt_ms)
    clock = int(np.count_nonzero(indices == n_pixels))  # (fg_snntorch leaves them out: no node takes them)
    if clock:
        print(f"run.py: note: {clock} spikes of the window clock left out (the graph has no clock)")
    start = args.duration_ms / 2 if args.count_from_ms is None else args.count_from_ms
    check_packages()
    import nir
    import torch

    torch.set_num_threads(args.threads)
    graph = nir.read(meta["graph"])
    cells = [(p["name"], p["size"]) for p in meta["populations"] if p["neuron"] is not None]
    t0 = time.perf_counter()
    counts = fg_snntorch.count_spikes(
        graph,
        cells,
        indices,
        steps,
        (h, w),
        n_steps=n_steps,
        count_from_step=fg_snntorch.first_counted_step(start, dt_ms),
    )
    out = {"duration_ms": args.duration_ms, "dt_ms": dt_ms, "count_from_ms": start}
    out[fg_files.EXPORT_KEY] = fg_files.network_digest()
    out.update({f"count_{name}": c for name, c in counts.items()})
    path = fg_files.save_npz(args.out, out)
    print(
        f"run.py: snnTorch simulated {args.duration_ms:g} ms ({n_steps} steps) in {time.perf_counter() - t0:.1f} s; "
        f"{sum(int(c.sum()) for c in counts.values()):,} spikes counted from {start:g} ms; wrote {path}"
    )


if __name__ == "__main__":
    fg_files.run_main(main)
