"""``snn-fg decode counts.npz --export DIR --out OUT``: the counts an exported
network's ``run.py`` wrote, decoded as ``snn-fg run`` decodes a spiking run
(:func:`~snn_fg.export.loop.decode_counts`), into ``OUT/maps.npz`` and
``OUT/maps.png``; with ``--reference BACKEND``, also the maps snn-fg's own
``BACKEND`` makes of the same network on the same input file
(:func:`~snn_fg.export.loop.reference_maps`) in ``OUT/reference/``, and how
the two agree."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..backends import backend_names
from ..errors import InputError
from ..export.edits import checked_export
from ..export.loop import (
    EXPORT_KINDS,
    decode_counts,
    export_input,
    export_network,
    last_spike_frame,
    rate_mismatch,
    recalibration_command,
    reference_maps,
)
from ..export.pynn import input_origin
from ..results.atomic import OutputFolder
from ..results.maps import SPIKING_GROUPING_LABEL, made_by
from ..results.outputs import DECODE_FOLDER
from ..results.timeline import MAPS_FIGURE
from ..scoring.metrics import compare_frame
from .options import FORCE_FOLDER_HELP, subcommand


def add_decode_command(sub):
    """Register ``decode`` on an ``argparse`` subparsers object; returns the parser."""
    p = subcommand(
        sub,
        "decode",
        description="Turn the counts an exported network's run.py wrote (counts.npz) into the maps "
        "snn-fg run writes for a spiking run: OUT/maps.npz and OUT/maps.png.",
    )
    p.add_argument("counts", metavar="COUNTS", help="run.py's output (counts.npz)")
    p.add_argument("--export", required=True, metavar="DIR", help="the export folder run.py ran")
    p.add_argument("--out", required=True, metavar="OUT", help="output folder")
    p.add_argument(
        "--input",
        metavar="SPIKES.npz",
        default=None,
        help="the input spike file run.py ran: the figure's input panel, and --reference's input "
        "(default: input.npz beside COUNTS)",
    )
    p.add_argument(
        "--reference",
        metavar="BACKEND",
        choices=backend_names(),
        help="also run the same exported network on the same input file, over the same span, with snn-fg's "
        f"BACKEND ({', '.join(backend_names())}): its maps in OUT/reference/, and how the two agree printed",
    )
    p.add_argument("--force", action="store_true", help=FORCE_FOLDER_HELP)
    p.set_defaults(handler=cmd_decode)
    return p


def cmd_decode(args) -> int:
    """Handler of ``snn-fg decode``; prints what it wrote, returns 0."""
    # (matplotlib, for the figure, is imported only when a command draws one)
    from ..results.figures import event_frame_rgb, save_maps_figure

    folder = OutputFolder(args.out, force=args.force, kind=DECODE_FOLDER)  # (refused, or unwritable, before the work)
    net, meta = export_network(args.export)
    # (an edited network.json: --reference refused, a plain decode noted; before, both went on unsaid)
    edited = checked_export(Path(args.export) / "network.json", net, meta, args.reference)
    if not Path(args.counts).exists():
        raise InputError(args.counts, "no such file")
    _check_made_by(args.counts, Path(args.export) / "network.json")
    maps = decode_counts(net, args.counts, meta)
    spikes = args.input or Path(args.counts).with_name("input.npz")
    # (read once: its frame for the figure, its rate for the agreement line)
    inp = export_input(spikes, net.frame_shape) if Path(spikes).exists() else None
    frame = None if inp is None else last_spike_frame(inp)
    if args.reference and frame is None:
        raise InputError(spikes, "no such file: --reference runs the export's network on the input file run.py ran")
    shown = event_frame_rgb(*frame) if frame is not None else np.zeros((*net.frame_shape, 3))
    origin = input_origin(spikes) if frame is not None else None
    if origin is not None:  # (maps on the export's frame: blocks of the sensor where it pools)
        maps.params["source"] = origin
    placed = None if origin is None else (origin["crop_x_px"], origin["crop_y_px"], origin["pool"])
    ref = reference_maps(net, maps, spikes, args.reference) if args.reference else None
    if ref is not None and origin is not None:
        ref.params["source"] = origin
    with folder as out:
        for m, where in ((maps, out.dir), (ref, out.dir / "reference")):
            if m is None:
                continue
            where.mkdir(exist_ok=True)
            m.save(where / "maps.npz")
            save_maps_figure(
                where / MAPS_FIGURE,
                shown,
                m.fg_x,
                m.fg_y,
                m.grouping,
                grouping_label=SPIKING_GROUPING_LABEL,
                placed=placed,
                made_by=f"the reference, {made_by(m.params)}"
                if m is ref
                else f"the {_kind(m)} export {args.export}, decoded from {Path(args.counts).name}",
            )
    written = "maps.npz, maps.png" + (", reference/" if ref is not None else "")
    print(f"snn-fg: decoded {args.counts} with the export {args.export}: wrote {args.out}/ ({written})")
    if edited:
        print(edited)
    if ref is not None:
        print(agreement_line(maps, ref, args.reference, inp.rate_hz, net, meta.get("export_command"), args.export))
    return 0


def _check_made_by(counts, network_json: Path) -> None:
    """Refuse ``counts`` that name another export than the one whose ``network_json`` decodes them
    (:data:`~snn_fg.pynn.files.EXPORT_KEY`: a digest of the network.json run.py ran; counts that do
    not name theirs, written before 1 Dec 2026, are decoded as before). Counts of another export of
    the same size were decoded silently, and a wrong cause told when the maps then parted."""
    from ..pynn.files import EXPORT_KEY, network_digest

    try:
        with np.load(counts) as d:
            made_by = str(d[EXPORT_KEY]) if EXPORT_KEY in d.files else None
    except (OSError, ValueError, EOFError):
        return  # (not an .npz: decoding says so, in its own words)
    if made_by is not None and made_by != network_digest(str(network_json)):
        raise InputError(
            counts,
            f"not the counts of this export: run.py made them with a network.json whose digest is {made_by}, "
            f"and {network_json} is another ({network_digest(str(network_json))}): another export, or this one "
            "made again or edited since; run python run.py again in this export's folder",
        )


def agreement_line(board, ref, backend: str, input_hz: float, net, command: str | None, folder=None) -> str:
    """How the board's maps agree with ``backend``'s on the same network and input, in one line with
    no nan in it: where a map has no figure-ground vector there is nothing to compare, and the line
    says so and why that is likely (before, a board and a reference with no vector printed "nan %").
    ``input_hz``: the input's rate per active pixel; ``net``: the export's network; ``command``: its
    ``snn-fg export`` command, as ``snn-fg events --write-spikes`` says how to re-export calibrated (into
    ``folder``, the export's folder as the user named it)."""
    c = compare_frame(board.fg_x, board.fg_y, board.grouping, ref.fg_x, ref.fg_y, ref.grouping)
    r = c["grouping_pearson_r"]
    grouping = f"grouping r {r:.3f}" if np.isfinite(r) else "grouping r undefined (a grouping map is flat)"
    head = f"snn-fg: against snn-fg's {backend} backend on the same network and input: "
    if c["pixels_compared"]:
        return head + (
            f"{grouping}, within 45 degrees on {100 * c['angle_within_45_frac']:.1f} % of the "
            f"{c['pixels_compared']:,} pixels where both have a vector, "
            f"mean absolute difference {c['angle_diff_mean_deg']:.1f} degrees; the board's maps have a vector at "
            f"{100 * c['coverage_of_b']:.1f} % of the reference's vector pixels"
        )
    if c["pixels_a"] or c["pixels_b"]:
        has = "the board's maps" if c["pixels_a"] else "the reference"
        what = f"{grouping}; only {has} have a figure-ground vector ({c['pixels_a'] or c['pixels_b']} pixels)"
    else:
        what = "neither the board's maps nor the reference have a figure-ground vector, nothing to compare"
    pixel = "block" if net.params.input_pool > 1 else "pixel"
    if rate_mismatch(input_hz, net.input_rate_hz):
        why = (
            f"likely cause: the input is {input_hz:.3g} Hz per active {pixel}, {input_hz / net.input_rate_hz:.2g} "
            f"times the {net.input_rate_hz:g} Hz the export's gains are set for (snn-fg events --write-spikes "
            f"warned); re-export calibrated: {recalibration_command(input_hz, command, folder)}, then run run.py again"
        )
    elif c["pixels_a"] or c["pixels_b"]:
        why = "the board's run and the reference's part: did run.py run this input file over this span?"
    else:
        why = (
            "the input drives too few cells in the counted span: a longer run (run.py --duration-ms) "
            "or a window with more edges (snn-fg events --start-ms, --crop-at)"
        )
    return head + what + "; " + why


def _kind(maps) -> str:
    """Which kind of export's run ``maps`` were decoded from, in words (``PyNN``, ``Lava``, ``NIR``)."""
    return EXPORT_KINDS.get((maps.params.get("backend") or {}).get("name"), "board")
