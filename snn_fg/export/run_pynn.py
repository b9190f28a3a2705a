"""Run the exported figure-ground network with PyNN (written by ``snn-fg export --format pynn``).

Needs only PyNN, numpy and a PyNN simulator; run it from its own folder:

    python run.py --input input.npz --out counts.npz [--simulator nest] [--threads 2] [--count-from-ms 200]

``input.npz`` holds ``indices`` (source of each spike: ON pixel y*W+x, OFF
pixel H*W + y*W+x), ``steps`` (time step of each spike), ``dt_ms``,
``period_steps`` (the pattern repeats with this period; -1: it does not) and
``shape`` (H, W); ``snn_fg.export.pynn.save_input`` writes one.
The output gets, per population, ``count_<name>``: every cell's spikes from
``--count-from-ms`` (default: half the run) to the end; with ``--spikes`` also
``cell_<name>`` and ``t_<name>`` (ms) of every spike (on NEST a recorded cell
costs 32 KB: use it on small networks).
"""
import argparse
import importlib
import json
import sys
import time

import numpy as np

import fg_network as fg
import fg_tables


def load_tables(meta, tables):
    """Projection name -> what fg_tables' unrollers take."""
    out = {}
    for pr in meta["projections"]:
        key = pr["table"]
        if pr["type"] == "conv":
            out[pr["name"]] = (tables[f"{key}_taps"], tables[f"{key}_values"])
        else:
            out[pr["name"]] = tuple((tables[f"{key}_{a}_idx"], tables[f"{key}_{a}_val"]) for a in ("rows", "cols"))
    return out


def input_steps(path, n_steps, n_sources):
    """Spike steps of every source (periodic patterns repeated up to n_steps)."""
    d = np.load(path)
    idx, steps, period = d["indices"].astype(np.int64), d["steps"].astype(np.int64), int(d["period_steps"])
    if period > 0:
        reps = -(-n_steps // period)
        idx = np.tile(idx, reps)
        steps = (steps[None, :] + period * np.arange(reps)[:, None]).ravel()
    keep = steps < n_steps
    idx, steps = idx[keep], steps[keep]
    order = np.lexsort((steps, idx))
    idx, steps = idx[order], steps[order]
    bounds = np.searchsorted(idx, np.arange(n_sources + 1))
    return [steps[a:b] for a, b in zip(bounds[:-1], bounds[1:])], float(d["dt_ms"])


def build(sim, meta, tables, sources, dt_ms, threads, portable, spikes, edges):
    pops = {p["name"]: p for p in meta["populations"]}
    delays = [pr["delay_ms"] for pr in meta["projections"]] + [dt_ms]
    cells = [p for p in meta["populations"] if p["neuron"] is not None]
    inputs = [p for p in meta["populations"] if p["neuron"] is None]
    net = fg.PyNNNetwork(sim, dt_ms=dt_ms, max_delay_ms=max(delays), threads=threads, portable=portable,
                         n_cells=sum(p["size"] for p in cells), n_sources=sum(p["size"] for p in inputs))
    if net.threads > threads:
        print(f"run.py: {net.threads} threads, not {threads}: NEST addresses at most "
              f"{fg.NEST_MAX_LOCAL_SENDERS:,} spike-sending cells per thread")
    for p in cells:             # cells before sources: NEST's spike generators would take room on every thread
        net.add_cells(p["name"], p["size"], p["neuron"])
    offset = 0
    for p in inputs:
        net.add_sources(p["name"], sources[offset:offset + p["size"]])
        offset += p["size"]
    for pr in meta["projections"]:
        src, tgt = pops[pr["source"]], pops[pr["target"]]
        if pr["type"] == "conv":
            taps, values = tables[pr["name"]]
            pre, post, k = fg_tables.conv_pairs(taps, values, src, tgt, pr["wrap"])
        else:
            rows, cols = tables[pr["name"]]
            pre, post, k = fg_tables.resize_pairs(rows, cols, src["channels"], src, tgt, pr["k_min"])
        drive = fg.quantise(pr["sign"] * pr["gain_mv"] * k, meta["weight_bits"], pr["scale_mv"])
        net.connect(pr["source"], pr["target"], pre, post, drive, sign=pr["sign"], delay_ms=pr["delay_ms"],
                    tau_exc_ms=tgt["neuron"]["tau_exc_ms"], tau_inh_ms=tgt["neuron"]["tau_inh_ms"])
    net.record([p["name"] for p in meta["populations"] if p["neuron"] is not None], spikes=spikes,
               count_edges_ms=edges)
    return net


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--input", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--simulator", default="nest", help="the pyNN.<simulator> module (nest, spiNNaker...)")
    ap.add_argument("--duration-ms", type=float, default=400.0)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--portable", action="store_true", help="PyNN's own connectors and recording on NEST too")
    ap.add_argument("--count-from-ms", type=float, default=None, help="start of the counting window (half the run)")
    ap.add_argument("--spikes", action="store_true", help="also write every spike")
    args = ap.parse_args(argv)
    with open("network.json") as fh:
        meta = json.load(fh)
    tables = load_tables(meta, np.load("tables.npz"))
    n_src = sum(p["size"] for p in meta["populations"] if p["neuron"] is None)
    sources, dt_ms = input_steps(args.input, int(round(args.duration_ms / meta["dt_ms"])), n_src)
    if abs(dt_ms - meta["dt_ms"]) > 1e-9:
        sys.exit(f"run.py: error: {args.input}: dt_ms={dt_ms} differs from the network's {meta['dt_ms']}")
    sim = importlib.import_module(f"pyNN.{args.simulator}")
    t0 = time.perf_counter()
    start = args.duration_ms / 2 if args.count_from_ms is None else args.count_from_ms
    net = build(sim, meta, tables, sources, dt_ms, args.threads, args.portable, args.spikes,
                (start, args.duration_ms))
    t1 = time.perf_counter()
    net.run(args.duration_ms)
    out = {"duration_ms": args.duration_ms, "dt_ms": dt_ms, "count_from_ms": start}
    for p in meta["populations"]:
        if p["neuron"] is not None:
            out[f"count_{p['name']}"] = net.counts(p["name"], p["size"], start, args.duration_ms)
            if args.spikes:
                out[f"cell_{p['name']}"], out[f"t_{p['name']}"] = net.spikes(p["name"], p["size"])
    net.end()
    np.savez(args.out, **out)
    print(f"run.py: built in {t1 - t0:.1f} s, simulated {args.duration_ms:g} ms in {time.perf_counter() - t1:.1f} s; "
          f"wrote {args.out}")


if __name__ == "__main__":
    main()
