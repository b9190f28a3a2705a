"""``snn-fg compare``: how two maps files agree, window by window.

Prints a table; writes the metrics (``--json FILE``) and a figure of both
maps and their difference (``--plot FILE.png``) only when asked. Wire it in
with :func:`add_compare_command`.
"""

from __future__ import annotations

import json
from pathlib import Path

from ..errors import InputError, SnnFgError
from ..results.atomic import save_text
from ..results.maps import Maps
from ..scoring.metrics import compare_maps
from ..scoring.outline import event_outlines
from .options import number, subcommand

#: compare's table: (header, row key, width, format spec); at most 100 characters wide
_COLUMNS = (
    ("A", "window_a", 3, "d"),
    ("B", "window_b", 3, "d"),
    ("t (ms)", "t_start_ms", 8, ".1f"),
    ("pixels", "pixels_compared", 7, "d"),
    ("mean°", "angle_diff_mean_deg", 6, ".1f"),
    ("median°", "angle_diff_median_deg", 7, ".1f"),
    ("<=45°", "angle_within_45_frac", 6, ".3f"),
    ("MSE", "angle_mse", 6, ".3f"),
    ("SSIM", "angle_ssim", 6, ".3f"),
    ("grp r", "grouping_pearson_r", 6, ".3f"),
    ("grp SSIM", "grouping_ssim", 8, ".3f"),
)


def add_compare_command(sub):
    """Register ``compare`` on an ``argparse`` subparsers object; returns the parser."""
    p = subcommand(
        sub,
        "compare",
        help="compare two maps.npz files (e.g. spiking vs rate)",
        description="Print, window by window, how two maps files agree: grouping Pearson r and "
        "SSIM, and on the pixels where both have a figure-ground vector the angle "
        "difference (mean, median, fraction within 45 degrees) and angle-map MSE "
        "and SSIM. Times count from the recording's first event. Nothing is written "
        "unless --json or --plot is given.",
    )
    p.add_argument("a", metavar="A.npz")
    p.add_argument("b", metavar="B.npz")
    p.add_argument(
        "--window",
        type=number(int, 0, strict=False),
        metavar="I",
        help="compare window I of each recording (a single frame is used as it is); by default "
        "recordings are paired window by window, by start time when both store it",
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
    p.add_argument("--json", metavar="FILE.json", default=None, help="also save the metrics to FILE.json")
    p.add_argument(
        "--plot",
        metavar="FILE.png",
        default=None,
        help="also draw both figure-ground maps and their angle difference, one row per compared "
        "window (at most 6, evenly spaced)",
    )
    p.set_defaults(handler=cmd_compare)
    return p


def compare_table(rows, outline_px: int | None = None) -> str:
    """The rows of :func:`~snn_fg.scoring.metrics.compare_maps` as a text table."""
    lines = ["  ".join(f"{h:>{w}}" for h, _, w, _ in _COLUMNS)]
    lines += [
        "  ".join("-".rjust(w) if r[k] is None else f"{r[k]:>{w}{spec}}" for _, k, w, spec in _COLUMNS) for r in rows
    ]
    where = "" if outline_px is None else f" within {outline_px} px of the event region's outline"
    lines += [
        "A, B: compared windows; t: window start after the recording's first event; angle columns on",
        f"pixels{where} where both maps have a figure-ground vector (SSIM: where either has one);",
        "grouping r and SSIM on the whole map, SSIM with each map scaled to 1",
    ]
    for side in ("a", "b"):
        empty = [r[f"window_{side}"] for r in rows if r.get(f"pixels_{side}") == 0]
        if empty:
            shown = ", ".join("-" if k is None else str(k) for k in empty[:8]) + (", ..." if len(empty) > 8 else "")
            lines.append(
                f"{side.upper()} has no figure-ground vector in {len(empty)} of {len(rows)} compared "
                f"window{'s' if len(rows) > 1 else ''} ({shown}): nothing to compare there (nan)"
            )
    return "\n".join(lines)


def cmd_compare(args) -> int:
    """Handler of ``snn-fg compare``; prints the table, returns 0."""
    for out in (args.json, args.plot):
        if out is not None and Path(out).resolve() in (Path(args.a).resolve(), Path(args.b).resolve()):
            raise InputError(out, "output would overwrite an input")
    if args.plot is not None and Path(args.plot).suffix.lower() != ".png":
        raise InputError(args.plot, "--plot needs a .png file name")
    a, b = Maps.load(args.a), Maps.load(args.b)
    try:
        where = None if args.outline is None else event_outlines(a, b, args.outline)
        rows = compare_maps(a, b, window=args.window, where=where)
    except SnnFgError as exc:
        raise InputError(args.b, str(exc).removeprefix("compare_maps: ")) from None
    print(compare_table(rows, args.outline))
    if args.json:
        save_text(args.json, json.dumps({"a": str(args.a), "b": str(args.b), "windows": rows}, indent=2))
        print(f"snn-fg: metrics saved to {args.json}")
    if args.plot:
        # (matplotlib is imported only when a command draws)
        from ..scoring.compare_figure import save_compare_figure

        names = tuple(f"{k} ({_run_name(f)})" for k, f in (("A", args.a), ("B", args.b)))
        save_compare_figure(args.plot, a, b, rows, names=names, where=where)
        print(f"snn-fg: figure saved to {args.plot}")
    return 0


def _run_name(path) -> str:
    """The name of the run a maps argument belongs to: its output folder's
    (``out/a``, ``out/a/maps.npz`` and ``out/a/maps.zarr`` are all run ``a``)."""
    p = Path(path).resolve()
    return p.parent.name if p.is_file() or p.suffix in (".npz", ".zarr") else p.name
