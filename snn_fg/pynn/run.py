"""Run the exported figure-ground network with PyNN (written by ``snn-fg export --format pynn``).

Needs only PyNN, numpy and a PyNN simulator; run it from its own folder:

    python run.py --input input.npz --out counts.npz [--simulator nest] [--threads 2] [--count-from-ms 200]
    python run.py --simulator spinnaker --virtual-board      # sPyNNaker's mapping, no board needed

``input.npz`` holds ``indices`` (source of each spike: ON pixel y*W+x, OFF
pixel H*W + y*W+x), ``steps`` (time step of each spike), ``dt_ms``,
``period_steps`` (the pattern repeats with this period; -1: it does not) and
``shape`` (H, W); ``snn-fg events INPUT --write-spikes input.npz --export .``
writes one. The output gets, per population, ``count_<name>``: every cell's
spikes from ``--count-from-ms`` (default: half the run) to the end; with
``--spikes`` also ``cell_<name>`` and ``t_<name>`` (ms) of every spike (on
NEST a recorded cell costs 32 KB: use it on small networks);
``snn-fg decode counts.npz --export . --out maps`` turns it into maps.

On SpiNNaker (``--simulator spinnaker``, sPyNNaker) the projections that
``spinnaker.json`` gives to ``ConvolutionConnector`` go through it (see
``fg_spinnaker.py``); with ``--virtual-board`` sPyNNaker maps the network
onto virtual SpiNN-5 boards with a configuration of its own in
``spinnaker/`` (the user's is not read) and ``mapping.json`` says what it used,
beside the export's own estimate.
"""

import argparse
import json
import os
import sys
import time

import fg_cells
import fg_files
import fg_inputs
import fg_memory
import fg_network as fg
import fg_simulator
import fg_tables

SIMULATORS = {"spinnaker": "spiNNaker"}  # our name -> pyNN module


def make_network(sim, meta, tables, dt_ms, args, plan):
    """The simulator's network object, and the projections that are convolutions on SpiNNaker."""
    cells = [p for p in meta["populations"] if p["neuron"] is not None]
    inputs = [p for p in meta["populations"] if p["neuron"] is None]
    kw = dict(
        dt_ms=dt_ms,
        max_delay_ms=max([pr["delay_ms"] for pr in meta["projections"]] + [dt_ms]),
        threads=args.threads,
        n_cells=sum(p["size"] for p in cells),
        n_sources=sum(p["size"] for p in inputs),
    )
    if plan is None:
        return fg.PyNNNetwork(sim, portable=args.portable, **kw), {}
    import fg_spinnaker

    conv = fg_spinnaker.plan_kernels(meta, tables, plan)
    lay = fg_spinnaker.layout({p["name"]: p for p in meta["populations"]}, conv.values())
    return fg_spinnaker.SpiNNakerNetwork(
        sim,
        layout=lay,
        populations={p["name"]: p for p in meta["populations"]},
        combined_cores=args.combined_cores,
        **kw,
    ), conv


def build(sim, meta, tables, sources, dt_ms, args, edges, plan=None):
    pops = {p["name"]: p for p in meta["populations"]}
    net, conv = make_network(sim, meta, tables, dt_ms, args, plan)
    if net.threads > args.threads:
        print(
            f"run.py: {net.threads} threads, not {args.threads}: NEST addresses at most "
            f"{fg.NEST_MAX_LOCAL_SENDERS:,} spike-sending cells per thread"
        )
    cells = [p for p in meta["populations"] if p["neuron"] is not None]
    for p in cells:  # cells before sources: NEST's spike generators would take room on every thread
        net.add_cells(p["name"], p["size"], p["neuron"])
    offset = 0
    for p in meta["populations"]:
        if p["neuron"] is None:
            net.add_sources(p["name"], sources[offset : offset + p["size"]])
            offset += p["size"]
    for i, pr in enumerate(meta["projections"]):
        src, tgt = pops[pr["source"]], pops[pr["target"]]
        if pr["name"] in conv:
            drive = fg_cells.quantise(
                pr["sign"] * pr["gain_mv"] * conv[pr["name"]][2], meta["weight_bits"], pr["scale_mv"]
            )
            net.convolve(
                pr["source"],
                pr["target"],
                drive,
                sign=pr["sign"],
                delay_ms=pr["delay_ms"],
                strides=tgt["stride"] // src["stride"],
            )
            continue
        if pr["type"] == "conv":
            taps, values = tables[pr["name"]]
            pre, post, k = fg_tables.conv_pairs(taps, values, src, tgt, pr["wrap"])
        else:
            rows, cols = tables[pr["name"]]
            pre, post, k = fg_tables.resize_pairs(rows, cols, src["channels"], src, tgt, pr["k_min"])
        drive = fg_cells.quantise(pr["sign"] * pr["gain_mv"] * k, meta["weight_bits"], pr["scale_mv"])
        net.connect(pr["source"], pr["target"], pre, post, drive, sign=pr["sign"], delay_ms=pr["delay_ms"])
        fg_memory.progress(
            f"built {i + 1}/{len(meta['projections'])} projections", last=i + 1 == len(meta["projections"])
        )
    net.record([p["name"] for p in cells], spikes=args.spikes, count_edges_ms=edges)
    return net


def check_simulator(name):
    """Exit with one line saying what to install unless ``pyNN.<name>`` and
    the simulator under it can be imported (before anything is built)."""
    from importlib.util import find_spec

    extra = "spinnaker" if name == "spiNNaker" else "nest"
    packages = "sPyNNaker==1!7.4.1 PyNN==0.13.0" if extra == "spinnaker" else "PyNN==0.13.0 nest-simulator==3.10.0"
    install = f'pip install -e ".[{extra}]" in the snn-fg folder, or pip install {packages}'
    if find_spec("pyNN") is None:
        sys.exit(f"run.py: error: PyNN is not installed: {install}")
    if find_spec(f"pyNN.{name}") is None:
        sys.exit(
            f"run.py: error: --simulator {name}: PyNN has no simulator module pyNN.{name} (nest, spinnaker, or "
            f"another PyNN backend such as neuron or brian2)"
        )
    needs = {"nest": "nest", "spiNNaker": "spynnaker"}.get(name)
    if needs and find_spec(needs) is None:
        sys.exit(
            f"run.py: error: --simulator {name}: pyNN.{name} needs the module {needs!r}, which is not "
            f"installed: {install}"
        )


def parse(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--input", help="input spike file (required but with --virtual-board)")
    ap.add_argument("--out", help="output counts file (required but with --virtual-board)")
    ap.add_argument("--force", action="store_true", help="replace the --out file if it exists")
    ap.add_argument("--simulator", default="nest", help="nest, spinnaker (sPyNNaker) or another pyNN.<module>")
    ap.add_argument(
        "--virtual-board",
        action="store_true",
        help="spinnaker: map onto virtual SpiNN-5 boards (no hardware) and write mapping.json",
    )
    ap.add_argument(
        "--map-only",
        action="store_true",
        help="--virtual-board: stop after sPyNNaker's partitioning, placement and routing (skip its "
        "data generation, which writes every explicit synapse in Python: hours for 40 M)",
    )
    ap.add_argument(
        "--combined-cores",
        action="store_true",
        help="spinnaker: each population's synapses on the core that updates its cells (sPyNNaker "
        "otherwise adds synapse cores as it sees fit)",
    )
    ap.add_argument("--duration-ms", type=float, default=400.0)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--portable", action="store_true", help="PyNN's own connectors and recording on NEST too")
    ap.add_argument("--count-from-ms", type=float, default=None, help="start of the counting window (half the run)")
    ap.add_argument("--spikes", action="store_true", help="also write every spike")
    ap.add_argument(
        "--memory-gb", type=float, default=None, help="memory the run may use (default: what the machine has available)"
    )
    args = ap.parse_args(argv)
    args.simulator = SIMULATORS.get(args.simulator.lower(), args.simulator)
    if args.virtual_board and args.simulator != "spiNNaker":
        ap.error("--virtual-board needs --simulator spinnaker")
    if args.map_only and not args.virtual_board:
        ap.error("--map-only needs --virtual-board")
    if not args.virtual_board and not (args.input and args.out):
        ap.error("--input and --out are required (but with --virtual-board)")
    if args.out:
        fg_files.check_out(args.out, args.force)
    return args


def main(argv=None):
    args = parse(argv)
    if args.simulator == "spiNNaker" and not os.path.exists("spinnaker.json"):  # (only a SpiNNaker export has it)
        sys.exit(
            "run.py: error: spinnaker.json: no such file: --simulator spinnaker needs an export made with "
            "snn-fg export --format pynn --target spinnaker"
        )
    check_simulator(args.simulator)
    meta, npz = fg_tables.load_export()
    tables = fg_tables.load_tables(meta, npz)
    n_src = sum(p["size"] for p in meta["populations"] if p["neuron"] is None)
    n_steps = int(round(args.duration_ms / meta["dt_ms"]))
    sources, dt_ms = (
        fg_inputs.input_steps(args.input, n_steps, n_src, meta.get("frame_shape"), meta["dt_ms"])
        if args.input
        else ([[]] * n_src, meta["dt_ms"])
    )
    plan = None
    if args.simulator == "spiNNaker":
        with open("spinnaker.json") as fh:
            plan = json.load(fh)
        if args.virtual_board:
            import fg_spinnaker

            fg_spinnaker.use_virtual_board("spinnaker")
            if args.map_only:
                fg_spinnaker.skip_data_generation()
    elif args.simulator == "nest":
        fg_memory.check_memory(meta, args.memory_gb, args.duration_ms)
    sim = fg_simulator.import_simulator(args.simulator)
    t0 = time.perf_counter()
    start = args.duration_ms / 2 if args.count_from_ms is None else args.count_from_ms
    net = build(sim, meta, tables, sources, dt_ms, args, (start, args.duration_ms), plan)
    t1 = time.perf_counter()
    if args.virtual_board:
        return write_mapping(sim, meta, plan, args, t1 - t0, net.n_convolution_connectors)
    net.run(
        args.duration_ms,
        report=lambda done: fg_memory.progress(
            f"simulated {done:g}/{args.duration_ms:g} ms", last=done >= args.duration_ms
        ),
    )
    out = {"duration_ms": args.duration_ms, "dt_ms": dt_ms, "count_from_ms": start}
    out[fg_files.EXPORT_KEY] = fg_files.network_digest()
    for p in meta["populations"]:
        if p["neuron"] is not None:
            out[f"count_{p['name']}"] = net.counts(p["name"], p["size"], start, args.duration_ms)
            if args.spikes:
                out[f"cell_{p['name']}"], out[f"t_{p['name']}"] = net.spikes(p["name"], p["size"])
    net.end()
    path = fg_files.save_npz(args.out, out)
    print(
        f"run.py: built in {t1 - t0:.1f} s, simulated {args.duration_ms:g} ms in {time.perf_counter() - t1:.1f} s; "
        f"wrote {path}"
    )


def write_mapping(sim, meta, plan, args, build_s, n_conv):
    """sPyNNaker's partitioning, placement, routing and data generation on the
    virtual board (``sim.run`` stops before loading), summarised in mapping.json."""
    import fg_spinnaker
    from spynnaker import _version

    t0 = time.perf_counter()
    sim.run(args.duration_ms)
    names = [p["name"] for p in meta["populations"]]
    used = fg_spinnaker.mapping_summary(names)
    spent = fg_spinnaker.spynnaker_timings()
    sim.end()
    conv = [e for e in plan["projections"] if e["connector"] == "ConvolutionConnector"]
    est = plan.get("estimate", {})
    out = {
        "tool": {"name": "sPyNNaker", "version": _version.__version__},
        "board": "SpiNN-5 (48 chips), virtual",
        **used,
        "estimate": {k: est.get(k) for k in ("cores", "chips", "boards_spinn5")},
        "connectors": {
            "ConvolutionConnector": len(conv),
            "FromListConnector": len(plan["projections"]) - len(conv),
            "ConvolutionConnector_instances": n_conv,
        },
        "duration_ms": args.duration_ms,
        "data_generation": not args.map_only,
        "combined_cores": args.combined_cores,
        "build_s": round(build_s, 1),
        "sPyNNaker_s": {k: round(v, 1) for k, v in spent.items()},
        "run_s": round(time.perf_counter() - t0, 1),
    }
    fg_files.write_json("mapping.json", out)
    print(
        f"run.py: sPyNNaker {out['tool']['version']} mapped the network onto {used['chips_used']} chips, "
        f"{used['cores_used']} cores (estimate: {est.get('chips')} chips, {est.get('cores')} cores); "
        f"fits one SpiNN-5 board: {used['fits']}; wrote mapping.json"
    )


if __name__ == "__main__":
    fg_files.run_main(main)
