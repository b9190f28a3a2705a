"""``snn-fg export``: the network for neuromorphic boards and other simulators.

Formats: ``pynn`` (a folder: self-contained PyNN model), ``lava`` (a
folder: the network as Lava processes for Loihi 2, :mod:`snn_fg.export.lava`), ``nir`` (a NIR
graph file; with ``--nir-profile snntorch`` and an ``--out`` not ending ``.nir``, a folder with
the graph and its loop in snnTorch, :mod:`snn_fg.export.nir_folder`), ``report`` (hardware
resource report, JSON, also printed) and
``network`` (the snn-fg JSON description; with ``--network FILE.nir`` this
is the NIR import). Bad arguments end with one line and exit status 2;
nothing partial is written.
"""

from __future__ import annotations

import dataclasses
import json
import shlex
from pathlib import Path

from .. import validate as check
from ..errors import InputError
from ..events.yarp import SENSOR_SIZE as ICUB_SENSOR_SIZE
from ..export.folder import EXPORT_FOLDER, INPUT_NAME
from ..export.lava import export_lava
from ..export.nir import describe_nir, export_nir
from ..export.nir_folder import export_nir_folder
from ..export.nir_import import read_nir
from ..export.nir_snntorch import export_nir_snntorch
from ..export.pynn import TARGETS as PYNN_TARGETS
from ..export.pynn import export_pynn
from ..export.report import largest_sensor, report_table, resource_report
from ..frames.pool import pooled_shape
from ..frames.pyramid import check_levels
from ..lowering.quantise import BITS_RANGE, check_bits
from ..network.graph import INPUT_RATE_HZ
from ..network.recipes import RECIPES, TIME_STEPS_TEXT, is_recipe, load_description, network_for
from ..params import LOWER, ModelParams
from ..results.atomic import save_text
from ..results.outputs import check_output_file, check_output_folder, check_writable
from .options import number, sensor_size, size_text, subcommand, written_size

FORMATS = ("pynn", "lava", "nir", "report", "network")
#: the model parameters' defaults, as the help gives them
_PARAMS = ModelParams()
TARGETS = ("generic", "spinnaker", "loihi2")
#: the targets each format takes (generic: none in particular) and, for the
#: report, which of its chips each one shows
FORMAT_TARGETS = {"pynn": PYNN_TARGETS, "report": TARGETS}
REPORT_CHIPS = {"spinnaker": ("spinnaker1", "spinnaker2"), "loihi2": ("loihi2",)}
NIR_PROFILES = ("exact", "snntorch")
#: the file name each single-file format writes (--force replaces only an earlier file of that kind)
FILE_SUFFIXES = {"nir": (".nir",), "report": (".json",), "network": (".json",)}


def add_export_command(sub):
    """Register ``export`` on an ``argparse`` subparsers object; returns the parser."""
    p = subcommand(
        sub,
        "export",
        description="Export the whole spiking network (every cell: a board holds one fixed network) "
        "as a self-contained PyNN model (--format pynn, a folder), Lava processes in Loihi 2's "
        "fixed-point arithmetic (--format lava, a folder; runs in Python 3.10), a NIR graph "
        "(--format nir; with --nir-profile snntorch, a folder with the graph and its run.py in snnTorch "
        "unless --out ends .nir), a hardware resource report for SpiNNaker 1/2 and Loihi 2 "
        "(--format report, JSON, also printed) or the snn-fg description (--format "
        "network; with --network FILE.nir this reads a NIR export back).",
    )
    p.add_argument("--format", required=True, metavar="|".join(FORMATS))
    p.add_argument(
        "--out",
        metavar="PATH",
        help="output folder (pynn, lava; nir --nir-profile snntorch: a folder with its run.py unless PATH ends "
        ".nir) or file; optional for --format report, which prints its table",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="replace PATH if it holds an earlier export of the format "
        "(a folder: that and nothing else; a file: one of the format's kind)",
    )
    p.add_argument(
        "--network",
        metavar="NAME|FILE",
        help="a network by name (default, the one used when none is given; compact, the deployment "
        "form) or a stored description (.json) or NIR export (.nir)",
    )
    p.add_argument(
        "--sensor-size",
        type=sensor_size,
        metavar="WxH",
        help=f"sensor size (default {ICUB_SENSOR_SIZE[0]}x{ICUB_SENSOR_SIZE[1]}, the iCub ATIS; a stored network "
        "keeps its own unless given)",
    )
    p.add_argument("--levels", type=number(int, *LOWER["levels"]), help=f"pyramid levels ({_PARAMS.levels})")
    p.add_argument("--n-ori", type=number(int, *LOWER["n_ori"]), help=f"orientations per half-turn ({_PARAMS.n_ori})")
    p.add_argument("--r0", type=number(float, *LOWER["r0"]), help=f"grouping radius in px ({_PARAMS.r0:g})")
    p.add_argument(
        "--target",
        default="generic",
        metavar="|".join(TARGETS),
        help="pynn: generic, or spinnaker (also writes spinnaker.json: which projections sPyNNaker's "
        "ConvolutionConnector can carry); report: every chip (generic), SpiNNaker 1 and 2 "
        "(spinnaker) or Loihi 2 (loihi2)",
    )
    p.add_argument(
        "--weight-bits",
        type=number(int, BITS_RANGE[0], strict=False, hi=BITS_RANGE[1]),
        metavar="B",
        help=f"quantise weights to B bits ({BITS_RANGE[0]}-{BITS_RANGE[1]}), one scale per projection (pynn, nir)",
    )
    p.add_argument(
        "--input-rate-hz",
        type=number(float, 0),
        metavar="HZ",
        help="gains calibrated for input spikes at HZ per active pixel, as snn-fg run calibrates its "
        "network to its input's rate (Network.calibrated; snn-fg events --write-spikes prints the "
        f"input's rate); default: the network's own ({INPUT_RATE_HZ:g} Hz; a stored network keeps its own)",
    )
    p.add_argument(
        "--dt-ms",
        type=number(float, 0),
        help=f"time step delays are counted in ({TIME_STEPS_TEXT})",
    )
    p.add_argument(
        "--nir-profile",
        default="exact",
        metavar="|".join(NIR_PROFILES),
        help="nir: exact (every mechanism NIR can hold), or snntorch (the node kinds snnTorch imports: "
        "one-level networks, no delays, no refractoriness; see snn_fg/export/nir_snntorch.py)",
    )
    p.add_argument(
        "--nir-one-grid",
        action="store_true",
        help="nir, snntorch profile: every pyramid level on the frame's grid (dilated kernels, identity "
        "between levels), so a network of octave levels (--network compact) goes through",
    )
    p.add_argument(
        "--nir-refractory-as-deeper-reset",
        action="store_true",
        help="nir, snntorch profile: NIR neurons have no refractory period; each cell resets lower "
        "instead, by as much as holds it for its refractory period when driven 4x its threshold "
        "above the reset (without: it may fire again one step later)",
    )
    p.set_defaults(handler=cmd_export, export_options=_options(p))
    return p


#: what a re-export command leaves out of the export's own options (it adds --input-rate-hz and --force itself)
_NOT_REPEATED = ("help", "force", "input_rate_hz")


def _options(parser) -> tuple:
    """``(flag, dest, default, takes a value)`` of each option of ``parser``, in its order
    (argparse keeps them in ``_actions``, its only list of them)."""
    return tuple(
        (a.option_strings[-1], a.dest, a.default, a.nargs != 0)
        for a in parser._actions
        if a.option_strings and a.dest not in _NOT_REPEATED
    )


#: what a report of a NIR file counts (snn_fg.export.nir's module docstring says why)
NIR_READ_BACK = (
    "a NIR file is read back as NIR holds it: coarser lattices on their level's full grid (stride 1, 4x the "
    "cells) and each projection's receptors split, so it counts more cells and synapses than the network it was "
    "written from (report that one by its name or .json); the sensor is given by --sensor-size"
)


def _network(args):
    """The network to export, for the sensor size asked for and calibrated to ``--input-rate-hz``,
    and that sensor size (rows, cols)."""
    net, sensor = _sized_network(args)
    if args.input_rate_hz is not None:
        net = net.calibrated(args.input_rate_hz)
    return net, sensor


def export_command(args) -> str:
    """The ``snn-fg export`` command line of ``args`` without ``--input-rate-hz``
    and ``--force``: what a PyNN export records, to say how to re-export it
    calibrated. Every option given a value other than its default is in it,
    in the parser's order (so an option added to the parser is too)."""
    words = ["snn-fg", "export"]
    for flag, dest, default, takes_value in args.export_options:
        value = getattr(args, dest)
        if value is None or value is False or value == default:
            continue
        if not takes_value:
            words.append(flag)
        elif isinstance(value, tuple):  # (--sensor-size: width, height)
            words += [flag, "x".join(str(v) for v in value)]
        else:
            words += [flag, f"{value:g}" if isinstance(value, float) else str(value)]
    return " ".join(shlex.quote(w) for w in words)


def _sized_network(args):
    """The network to export, for the sensor size asked for, and that sensor size (rows, cols)."""
    given = {k: getattr(args, k) for k in ("levels", "n_ori", "r0") if getattr(args, k) is not None}
    if args.network and given:
        raise InputError(
            args.network, "--levels/--n-ori/--r0: a named or stored network carries its own model parameters"
        )
    if args.network and not is_recipe(args.network):
        net = read_network_file(Path(args.network))
        if not args.sensor_size:
            return net, None
        w, h = args.sensor_size
        _check_sensor(net.params, (h, w), f"--sensor-size {w}x{h}")
        return network_for(net, (h, w))[0], (h, w)
    w, h = args.sensor_size or ICUB_SENSOR_SIZE
    recipe = RECIPES[args.network or "default"]
    params = recipe.params.replace(**given)
    _check_sensor(params, (h, w), f"--sensor-size {w}x{h}")
    return dataclasses.replace(recipe, params=params).build((h, w)), (h, w)


def _check_sensor(params, shape, source: str):
    check_levels(pooled_shape(shape, params.input_pool), params.levels, source, params.levels_per_octave)


def describe_network(net) -> str:
    """``55 populations, 180 projections, 3 levels, a 102 x 80 frame``: a description's size, for the
    export's last line (width x height, as the resource report gives it)."""
    h, w = net.frame_shape
    return (
        f"{len(net.populations)} populations, {len(net.projections)} projections, "
        f"{net.params.levels} levels, a {w} x {h} frame"
    )


def read_network_file(path: Path):
    """A description from ``.json`` or a NIR export (``.nir``)."""
    if path.suffix.lower() == ".nir" or path.name.lower().endswith(".nir.gz"):
        return read_nir(path)
    return load_description(path)


def _checked_bits(args) -> int | None:
    """The options that go together checked (one line naming the option that does not apply), and the weight bits."""
    check.choice("snn-fg export", "--format", args.format, FORMATS)
    check.choice("snn-fg export", "--target", args.target, TARGETS)
    if args.target not in FORMAT_TARGETS.get(args.format, ("generic",)):
        takes = [f for f, targets in FORMAT_TARGETS.items() if args.target in targets]
        raise InputError(f"--target {args.target}", f"applies to --format {' and '.join(takes)}, not {args.format}")
    check.choice("snn-fg export", "--nir-profile", args.nir_profile, NIR_PROFILES)
    if args.nir_profile != "exact" and (args.format != "nir" or args.weight_bits is not None):
        raise InputError("--nir-profile", "applies to --format nir without --weight-bits")
    for flag in ("nir_one_grid", "nir_refractory_as_deeper_reset"):
        if getattr(args, flag) and args.nir_profile != "snntorch":
            raise InputError("--" + flag.replace("_", "-"), "applies to --format nir --nir-profile snntorch")
    bits = None if args.weight_bits is None else check_bits(args.weight_bits, "snn-fg export")
    if bits is not None and args.format not in ("pynn", "nir"):
        raise InputError("--weight-bits", "applies to --format pynn and nir only")
    if args.out is None and args.format != "report":
        raise InputError("--out", f"--format {args.format} needs an output path")
    return bits


def writes_folder(args) -> bool:
    """Whether the export is a folder with a run.py: ``pynn``, ``lava``, and ``nir`` of the snnTorch
    profile unless ``--out`` names a ``.nir`` file (the graph alone, as before the folder existed)."""
    if args.format == "nir":
        return args.nir_profile == "snntorch" and not str(args.out).lower().endswith(FILE_SUFFIXES["nir"])
    return args.format in ("pynn", "lava")


def cmd_export(args) -> int:
    """Handler of ``snn-fg export``; prints what it wrote (a report: its table too), returns 0."""
    bits = _checked_bits(args)
    out = None if args.out is None else Path(args.out)
    folder = writes_folder(args)
    if out is not None and folder:
        check_output_folder(out, EXPORT_FOLDER, args.force)
        check_writable(out)
    elif out is not None:
        check_output_file(out, args.force, "--format " + args.format, FILE_SUFFIXES[args.format])
    net, sensor = _network(args)
    if args.format == "pynn":
        export_pynn(
            net,
            out,
            dt_ms=args.dt_ms,
            weight_bits=bits,
            target=args.target,
            force=args.force,
            command=export_command(args),
            sensor_shape=sensor,
        )
        what = f"PyNN model ({_folder_summary(out)})"
    elif args.format == "lava":
        export_lava(net, out, force=args.force, command=export_command(args), sensor_shape=sensor, dt_ms=args.dt_ms)
        what = f"Lava model ({_folder_summary(out)}); its run.py needs Python 3.10 (README.md)"
    elif args.format == "nir" and folder:
        export_nir_folder(
            net,
            out,
            step_ms=args.dt_ms,
            one_grid=args.nir_one_grid,
            deeper_reset=args.nir_refractory_as_deeper_reset,
            force=args.force,
            command=export_command(args),
            sensor_shape=sensor,
        )
        what = (
            f"NIR graph, snntorch profile, with its loop ({_folder_summary(out)}); "
            "its run.py needs torch and snntorch (README.md)"
        )
    elif args.format == "nir" and args.nir_profile == "snntorch":
        export_nir_snntorch(
            net, out, step_ms=args.dt_ms, one_grid=args.nir_one_grid, deeper_reset=args.nir_refractory_as_deeper_reset
        )
        what = f"NIR graph, snntorch profile ({describe_nir(out)})"
    elif args.format == "nir":
        export_nir(net, out, weight_bits=bits, force=True)
        what = f"NIR graph ({describe_nir(out)})"
    elif args.format == "report":
        rep = resource_report(net, dt_ms=args.dt_ms, sensor_shape=sensor)
        if args.target != "generic":
            rep["targets"] = {k: v for k, v in rep["targets"].items() if k in REPORT_CHIPS[args.target]}
        sp = rep["targets"].get("spinnaker1")
        if sensor is not None and sp is not None and sp["boards_spinn5"] > 1:
            sp["largest_sensor_one_board"] = largest_sensor(
                lambda shape: network_for(net, shape)[0], sensor, args.dt_ms
            )
        print(report_table(rep))
        if args.network and Path(args.network).name.endswith((".nir", ".nir.gz")):
            print(f"snn-fg: note: {NIR_READ_BACK}")
        if out is None:
            return 0
        save_text(out, json.dumps(rep, indent=1) + "\n")
        what = f"resource report ({written_size(out)}, JSON)"
    else:
        net.save(out)
        what = f"network description ({written_size(out)}; {describe_network(net)})"
    if folder and (out / INPUT_NAME).exists():
        what += f"; {INPUT_NAME} kept from the folder it replaced (the same frame and time step)"
    if folder:
        kept = sorted(p.name for p in out.iterdir() if EXPORT_FOLDER.keeps(p))
        what += "".join(f"; {k} kept where it was (the environment the README has you make there)" for k in kept)
    print(f"snn-fg: wrote {what} to {out}")
    return 0


def _folder_summary(out: Path) -> str:
    """The size and names of what an export wrote into ``out`` (not what it kept there: an environment)."""
    written = sorted((p for p in out.iterdir() if not EXPORT_FOLDER.keeps(p)), key=lambda p: p.name)
    files = [f for p in written for f in ([p] if p.is_file() else p.rglob("*")) if f.is_file()]
    return f"{size_text(sum(f.stat().st_size for f in files))}: {', '.join(p.name for p in written)}"
