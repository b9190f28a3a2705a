"""``snn-fg plot RUN``: figures of a recording's run, drawn from its stored maps.

``--windows 3,5`` (or ``10-14``, ``all``) draws each window as a figure of its own; ``--animate``
the maps over the recording as a GIF or MP4; without either, the run's overview (``maps.png``,
``timeline.png``, ``windows.csv``, as ``snn-fg run`` writes them: for a run made with
``--no-figures``). Every window is drawn on the recording's one grouping scale.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import InputError
from ..models import MODELS
from ..results.animation import FPS, SUFFIXES, save_animation
from ..results.figures import on_sensor, save_maps_figure
from ..results.maps import Maps, maps_scale
from ..results.outputs import WINDOW_FIGURE, check_output_file
from ..results.overview import (
    input_images,
    overview_options,
    save_window_figures,
    write_run_tables,
)
from ..results.store import STORE_NAME
from ..results.timeline import MAPS_FIGURE, TABLE_NAME, TIMELINE_NAME, window_numbers
from ..validate import check_crop
from .options import crop, number, subcommand

#: the animation's name in the run's folder when --animate names no file
ANIMATION_NAME = "maps.gif"


def add_plot_command(sub):
    """Register ``plot`` on an ``argparse`` subparsers object; returns the parser."""
    p = subcommand(
        sub,
        "plot",
        description="Figures of a recording's run (RUN: the output folder of snn-fg run on a recording), "
        "from its stored maps: --windows draws chosen windows, one figure each; --animate the maps "
        "over the recording (GIF or MP4); without either, the overview snn-fg run writes (maps.png, "
        "timeline.png, windows.csv). Every window is drawn on the recording's one grouping scale.",
    )
    p.add_argument("run", metavar="RUN", help="a recording's run: its output folder (or its maps.zarr)")
    p.add_argument(
        "--windows",
        metavar="I,J,...",
        help="windows to draw, one figure each: their numbers (windows.csv's) and ranges (3,5,10-14) or all; "
        "into --out (default RUN/windows/) as window_0003.png, ...",
    )
    p.add_argument("--out", metavar="DIR", help="folder of the --windows figures (default: RUN/windows)")
    p.add_argument(
        "--animate",
        nargs="?",
        const="",
        metavar="FILE",
        help=f"the maps over the recording as an animation, one frame per window: FILE.gif or FILE.mp4 "
        f"(default RUN/{ANIMATION_NAME})",
    )
    p.add_argument("--fps", type=number(float, 0), default=FPS, help=f"--animate: windows per second ({FPS:g})")
    p.add_argument("--crop", type=crop, metavar="X0,Y0,X1,Y1", help="draw only pixels X0 <= x < X1, Y0 <= y < Y1")
    p.add_argument(
        "--force",
        action="store_true",
        help="replace figures and files that exist if snn-fg wrote them (its mark in each figure; a GIF or MP4 "
        "by its format; a user's other file is refused)",
    )
    p.set_defaults(handler=cmd_plot)
    return p


def window_list(text: str, numbers) -> list[int]:
    """The places of the windows ``3,5,10-14`` (or ``all``) names among the run's window ``numbers``
    (:func:`~snn_fg.results.timeline.window_numbers`; a range takes the run's windows in it); one line
    naming what is wrong otherwise."""
    numbers = [int(k) for k in numbers]
    if text.strip().lower() == "all":
        return list(range(len(numbers)))
    place, chosen = {k: i for i, k in enumerate(numbers)}, []
    for part in text.split(","):
        lo, _, hi = part.strip().partition("-")
        try:
            a, b = int(lo), int(hi or lo)
        except ValueError:
            raise InputError(f"--windows {text}", "expected indices and ranges such as 3,5,10-14, or all") from None
        held = [place[k] for k in range(a, b + 1) if k in place] if a <= b else []
        if not held:
            kept = f"{len(numbers)} windows, 0 to {numbers[-1]}"
            if numbers != list(range(len(numbers))):
                kept = f"{len(numbers)} windows (windows.csv lists their numbers, {numbers[0]} to {numbers[-1]})"
            raise InputError(f"--windows {text}", f"the run has {kept}")
        chosen += held
    return sorted(set(chosen))


def _recording_maps(run: Path) -> tuple[Path, Maps]:
    """The run's folder and its maps (a recording's, read lazily); one line for anything else."""
    folder = run.parent if run.name == STORE_NAME else run
    if not run.exists():
        raise InputError(run, "no such folder")
    if not (folder / STORE_NAME).is_dir():
        runs = sorted(p.name for p in folder.iterdir() if (p / STORE_NAME).is_dir()) if folder.is_dir() else []
        if (folder / "maps.npz").is_file():
            what = "a frame's run (maps.npz): its figure is maps.png (snn-fg run ... --crop X0,Y0,X1,Y1 draws a part)"
        elif runs:  # (a batch: a run per recording)
            named = ", ".join(runs[:3]) + (", ..." if len(runs) > 3 else "")
            what = f"a batch, a run per recording ({named}): plot one, {folder / runs[0]}"
        else:
            what = "no run"
        raise InputError(run, f"holds {what}; snn-fg plot draws a recording's run (its maps.zarr)")
    maps = Maps.load(folder / STORE_NAME)
    if maps.fg_x.shape[0] == 0:
        raise InputError(run, "the run holds no complete window yet")
    return folder, maps


def cmd_plot(args) -> int:
    """Handler of ``snn-fg plot``; prints what it wrote, returns 0."""
    folder, maps = _recording_maps(Path(args.run))
    model = MODELS.get(maps.params.get("model"))
    label = "grouping" if model is None else model.grouping_label
    if args.out is not None and args.windows is None:
        raise InputError(f"--out {args.out}", "names the folder of the --windows figures: give --windows")
    if args.crop is not None:  # (checked on the sensor's pixels, the run named: before, the figure's function was)
        h, w, s = *maps.fg_x.shape[1:], maps_scale(maps.params)
        check_crop(args.crop, (h * s, w * s), owner=f"{args.run}: --crop")
    written = []
    if args.windows is not None:
        numbers = window_numbers(maps)
        chosen = window_list(args.windows, numbers)
        out = Path(args.out) if args.out is not None else folder / "windows"
        for i in chosen:
            check_output_file(out / WINDOW_FIGURE.format(numbers[i]), args.force, "--windows", (".png",))
        written += save_window_figures(maps, chosen, out, grouping_label=label, crop=args.crop)
    if args.animate is not None:
        movie = Path(args.animate) if args.animate else folder / ANIMATION_NAME
        check_output_file(movie, args.force, "--animate", SUFFIXES)
        written.append(save_animation(movie, maps, grouping_label=label, fps=args.fps, crop=args.crop))
    if args.windows is None and args.animate is None:
        for name in (MAPS_FIGURE, TIMELINE_NAME):
            check_output_file(folder / name, args.force, "plot", (Path(name).suffix,))
        # (a run made with --no-figures wrote its table: kept, not refused, unless --force asks it written again)
        table = args.force or not (folder / TABLE_NAME).exists()
        if table:
            check_output_file(folder / TABLE_NAME, args.force, "plot", (".csv",))
        coverage = model is None or not model.vector_at_every_event
        write_run_tables(folder, maps, figures=True, coverage=coverage, table=table)
        options = {
            **overview_options(maps, folder),
            "grouping_label": label,
            **on_sensor(maps.params, args.crop),  # (the crop was checked above)
        }
        save_maps_figure(folder / MAPS_FIGURE, input_images(maps), maps.fg_x, maps.fg_y, maps.grouping, **options)
        written += [folder / MAPS_FIGURE, folder / TIMELINE_NAME, *([folder / TABLE_NAME] if table else [])]
    shown = ", ".join(str(p) for p in written[:4]) + (f", ... ({len(written)} files)" if len(written) > 4 else "")
    print(f"snn-fg: wrote {shown}")
    return 0
