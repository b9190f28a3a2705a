"""Run the exported figure-ground network in Lava (written by ``snn-fg export --format lava``).

Needs Python 3.10, Lava (``lava-nc`` 0.10, with its scipy) and numpy; run it from its own folder:

    python run.py --input input.npz --out counts.npz [--duration-ms 150] [--count-from-ms 75]
    python run.py ... --arithmetic float          # Lava's floating point on the same numbers
    python run.py ... --simulator reference       # the same fixed point in numpy alone (fg_reference.py)
    python run.py --count-only                    # resources.json: what Lava holds, beside snn-fg's report

``input.npz`` is what ``snn-fg events INPUT --write-spikes input.npz --export .``
writes. The output gets, per population, ``count_<name>``: every cell's
spikes from ``--count-from-ms`` (default: half the run) to the end;
``snn-fg decode counts.npz --export . --out maps`` turns it into maps.
"""

import argparse
import sys
import time
import warnings

import fg_files
import fg_inputs
import fg_reference
import fg_synapses
import fg_tables

INSTALL = (
    "make the export's environment: python3.10 -m venv .venv-lava && .venv-lava/bin/pip install -r requirements.txt"
)


def progress(message: str, last: bool = False, _state=[0.0]):  # noqa: B006 - the time of the last line
    """Print ``message`` to stderr at most every 5 s; the ``last`` one always."""
    now = time.monotonic()
    if last or now - _state[0] >= 5.0:
        _state[0] = now
        print(f"run.py: {message}", file=sys.stderr, flush=True)


def check_lava():
    """Exit with one line saying what to install unless Lava can be imported."""
    from importlib.util import find_spec

    if sys.version_info[:2] > (3, 10):
        sys.exit(
            f"run.py: error: Python {sys.version_info[0]}.{sys.version_info[1]}: lava-nc 0.10 needs Python 3.8-3.10; "
            f"{INSTALL}"
        )
    if find_spec("lava") is None or find_spec("scipy") is None:
        sys.exit(f"run.py: error: Lava is not installed: {INSTALL}")


def parse(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--input", help="input spike file (required but with --count-only)")
    ap.add_argument("--out", help="output counts file (required but with --count-only)")
    ap.add_argument("--force", action="store_true", help="replace the --out file if it exists")
    ap.add_argument("--duration-ms", type=float, default=150.0)
    ap.add_argument("--count-from-ms", type=float, default=None, help="start of the counting window (half the run)")
    ap.add_argument(
        "--arithmetic", default="fixed", choices=("fixed", "float"), help="fixed_pt (default) or floating_pt"
    )
    ap.add_argument(
        "--simulator",
        default="lava",
        choices=("lava", "reference"),
        help="lava (its CPU simulation), or reference: the same arithmetic in numpy alone",
    )
    ap.add_argument("--count-only", action="store_true", help="build the processes, write resources.json, stop")
    args = ap.parse_args(argv)
    if not args.count_only and not (args.input and args.out):
        ap.error("--input and --out are required (but with --count-only)")
    if args.out and not args.count_only:
        fg_files.check_out(args.out, args.force)
    return args


def load_export():
    meta, npz = fg_tables.load_export()
    return meta, fg_synapses.connections(meta, npz)


def count_only(meta, conns):
    """Build the network in Lava without input and write resources.json beside snn-fg's Loihi 2 report."""
    import fg_lava

    n_src = sum(p["size"] for p in meta["populations"] if p["neuron"] is None)
    net = fg_lava.LavaNetwork(meta, conns, [[]] * n_src, n_steps=1, count_from=0, arithmetic="fixed")
    ours = meta["loihi2_report"]
    exps = [c.weight_exp for c in conns if c.pre.size]
    out = {
        "lava": {**net.resources(), "weight_exp": [min(exps, default=0), max(exps, default=0)]},
        "snn_fg_report": {
            "neurons": ours["totals"]["neurons"],
            "spike_sources": ours["totals"]["sources"],
            "synapses": ours["totals"]["synapses"],
            "loihi2_cores": ours["loihi2"]["cores"],
            "loihi2_chips": ours["loihi2"]["chips"],
        },
        "note": "Lava's synapses are those whose 8-bit mantissa is not 0; the report counts every synapse of "
        "the description",
    }
    fg_files.write_json("resources.json", out)
    lv = out["lava"]
    print(
        f"run.py: Lava holds {lv['processes']['total']} processes, {lv['neurons']:,} neurons and "
        f"{lv['synapses']:,} synapses (snn-fg's report: {ours['totals']['neurons']:,} neurons, "
        f"{ours['totals']['synapses']:,} synapses); wrote resources.json"
    )


def main(argv=None):
    args = parse(argv)
    if args.simulator == "lava" or args.count_only:
        check_lava()
    warnings.simplefilter("ignore")  # scipy's SparseEfficiencyWarning, at every step of a DelaySparse
    meta, conns = load_export()
    if args.count_only:
        return count_only(meta, conns)
    dt = float(meta["dt_ms"])
    n_steps = int(round(args.duration_ms / dt))
    start_ms = args.duration_ms / 2 if args.count_from_ms is None else args.count_from_ms
    count_from = int(round(start_ms / dt))
    n_src = sum(p["size"] for p in meta["populations"] if p["neuron"] is None)
    steps, _ = fg_inputs.input_steps(args.input, n_steps, n_src, meta["frame_shape"], dt)
    t0 = time.perf_counter()
    if args.simulator == "reference":
        t1 = t0
        counts, limits = fg_reference.simulate(meta, conns, steps, n_steps, count_from, args.arithmetic)
        extra = {"max_a_in": limits.max_a_in, "u_wraps": limits.u_wraps, "v_saturated": limits.v_saturated}
    else:
        import fg_lava

        net = fg_lava.LavaNetwork(
            meta, conns, steps, n_steps=n_steps, count_from=count_from, arithmetic=args.arithmetic
        )
        res = net.resources()
        progress(f"built {res['processes']['total']} Lava processes", last=True)
        t1 = time.perf_counter()
        try:
            net.run(n_steps, report=lambda done: progress(f"simulated {done}/{n_steps} steps", last=done == n_steps))
            counts = net.counts()
        finally:
            net.stop()
        extra = {}
    out = {"duration_ms": args.duration_ms, "dt_ms": dt, "count_from_ms": count_from * dt, **extra}
    out[fg_files.EXPORT_KEY] = fg_files.network_digest()
    out.update({f"count_{name}": c for name, c in counts.items()})
    path = fg_files.save_npz(args.out, out)
    tag = {"fixed": "fixed_pt", "float": "floating_pt"}[args.arithmetic]
    tool = f"numpy reference ({tag})" if args.simulator == "reference" else f"Lava ({tag})"
    print(
        f"run.py: {tool}: built in {t1 - t0:.1f} s, simulated {args.duration_ms:g} ms in "
        f"{time.perf_counter() - t1:.1f} s; wrote {path}"
    )


if __name__ == "__main__":
    fg_files.run_main(main)
