"""``snn-fg compare``: how two maps files agree, window by window, or a run's maps against human
figure/ground labels (:mod:`.compare_labels`).

Prints a table; writes the metrics (``--json FILE``) and a figure of both
maps and their difference (``--plot FILE.png``) only when asked. Wire it in
with :func:`add_compare_command`.
"""

from __future__ import annotations

import json
from pathlib import Path

from ..errors import InputError
from ..results.atomic import save_text
from ..results.maps import made_by
from ..results.outputs import check_output_file
from .compare_labels import cmd_compare_labels, names_labels, runs_of
from .compare_maps import _record, _run_name, compare_pair, compare_table
from .options import number, subcommand


def add_compare_command(sub):
    """Register ``compare`` on an ``argparse`` subparsers object; returns the parser."""
    p = subcommand(
        sub,
        "compare",
        description="Print, window by window, how two maps files agree: grouping Pearson r and "
        "SSIM, and on the pixels where both have a figure-ground vector the angle "
        "difference (mean, fraction within 45 degrees) and angle-map SSIM (--json also "
        "keeps their median and MSE). Two recordings' windows are paired by the events they hold: by "
        "their start on the events' own clock (a live run of snn-fg stream's replay: the recording's), a "
        "line under the table says how; t counts from B's first event. Nothing is written "
        "unless --json or --plot is given. A PyNN export's maps (snn-fg decode) against a run on "
        "the whole recording: the run is cut to the export's crop and input window. With human "
        "figure/ground labels as B (a bsds-fg folder, or one labels/<id>.npz), it prints per image and "
        "labeller: labelled pixels; coverage (the share of them where A has a vector); on those, side "
        "accuracy (within 90 degrees of the labelled direction, the figure's side; chance 0.5), the share "
        "within 45 degrees (chance 0.25), the mean absolute difference (chance 90) and the mean signed "
        "difference (the paper's number: signs cancel in it), and pooled over the images of a folder "
        "of runs; the numbers of experiments/paper/table1.py.",
    )
    p.add_argument(
        "a",
        metavar="A",
        nargs="+",
        help="a run's maps: its folder, maps.npz or maps.zarr; against labels also a folder of runs "
        "(snn-fg run on several images: its summary.csv). Several: runs made one at a time, pooled: "
        "against labels each image's run (A1 A2 ... LABELS); against maps first one model's runs, then as "
        "many of the reference's (A1 A2 B1 B2), paired by their input image",
    )
    p.add_argument(
        "b",
        metavar="B",
        help="the maps to compare A with (the reference), as A; or human figure/ground labels: a bsds-fg "
        "folder or its labels/ (A's image found as labels/<id>.npz by A's input file name) or one such .npz (fg: -1 "
        "ground, +1 figure side of each boundary, one map per labeller)",
    )
    p.add_argument(
        "--window",
        type=number(int, 0, strict=False),
        metavar="I",
        help="compare the window at place I (from 0) among those each recording stored, whatever their "
        "starts (a single frame is used as it is); by default windows are paired by their start on the "
        "events' own clock",
    )
    p.add_argument(
        "--outline",
        type=number(int, 1, strict=False),
        metavar="PX",
        default=None,
        help="compare the vectors only within PX pixels of the outline of each window's largest "
        "filled event region (a recording whose objects fill with events: the pixels inside "
        "carry no border, and their vectors, noise in both maps, swamp the outline's "
        "agreement; 3 is what the validation uses)",
    )
    p.add_argument(
        "--min-confidence",
        type=number(float, 0, strict=False),
        metavar="Z",
        default=None,
        help="compare only the spiking maps' vectors at least Z standard errors of their spike counts "
        "long (fg_confidence, stored by every spiking run; 2 leaves out vectors that a couple of "
        "spikes decide); the cover column says how much of B is still compared, and --plot draws "
        "only those vectors (against labels: the others count as no vector)",
    )
    p.add_argument(
        "--no-baseline",
        action="store_true",
        help="do not run B's model again to see how far B moves on its own (the B columns)",
    )
    p.add_argument("--json", metavar="FILE.json", default=None, help="also save the metrics to FILE.json")
    p.add_argument(
        "--plot",
        metavar="FILE.png",
        default=None,
        help="also draw both figure-ground maps and their angle difference, one row per compared "
        "window (at most 6, evenly spaced); against labels the image, A's vectors and per labeller "
        "the labelled directions and A's error, one row per image",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="replace the files --json and --plot name if snn-fg wrote them (its mark in each figure and "
        "record; a user's other file is refused)",
    )
    p.set_defaults(handler=cmd_compare)
    return p


def cmd_compare(args) -> int:
    """Handler of ``snn-fg compare``; prints the table, returns 0."""
    inputs = [Path(x).resolve() for x in (*args.a, args.b)]
    for flag, out, suffix in (("--json", args.json, ".json"), ("--plot", args.plot, ".png")):
        if out is not None and Path(out).resolve() in inputs:
            raise InputError(out, "output would overwrite an input")
        if out is not None:
            check_output_file(out, args.force, flag, (suffix,))
    if names_labels(args.b):
        return cmd_compare_labels(args)
    if len(args.a) > 1 or runs_of(args.a[0]) != [Path(args.a[0])]:  # (runs made one by one, or folders of runs)
        from .compare_pooled import cmd_compare_pooled

        return cmd_compare_pooled(args)
    args.a = args.a[0]
    a, b, rows, where, baseline, paired = compare_pair(args, args.a, args.b)
    runs = (("A", _run_name(args.a), a), ("B", _run_name(args.b), b))  # (a path may be wider than the table)
    named = [f"{side}: {run}, {made_by(m.params)}" for side, run, m in runs]  # (until 30 Nov: the model only)
    print(compare_table(rows, args.outline, baseline, named, paired))
    if args.json:
        save_text(args.json, json.dumps(_record(args, rows, baseline, paired), indent=2))
        print(f"snn-fg: metrics saved to {args.json}")
    if args.plot:
        # (matplotlib is imported only when a command draws)
        from ..scoring.compare_figure import aps_inputs, save_compare_figure

        names = tuple(f"{side} ({run})" for side, run, _ in runs)
        inputs = aps_inputs(a, b)
        save_compare_figure(
            args.plot,
            a,
            b,
            rows,
            names=names,
            where=where,
            inputs=inputs,
            min_confidence=args.min_confidence,
            described=named,
        )
        print(f"snn-fg: figure saved to {args.plot}")
    return 0
