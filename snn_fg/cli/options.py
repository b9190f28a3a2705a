"""What several commands share, defined once: a subcommand's parser
(:func:`subcommand`), the checked argument types (:func:`number`,
:func:`sensor_size`, :func:`crop`) and the progress bar of a model's
iterations. The rule for an output file that exists already is
:func:`~snn_fg.results.outputs.check_output_file`, beside the folders' rule."""

from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path

from tqdm import tqdm

from ..events import MAX_SENSOR_SIDE
from ..events.aedat23 import CHIPS
from .commands import COMMANDS


def subcommand(sub, name: str, *, description: str) -> argparse.ArgumentParser:
    """The parser of subcommand ``name`` on an ``argparse`` subparsers object, with its
    line of :data:`~.commands.COMMANDS`: its long options must be typed whole (an
    abbreviation is refused, so that a later option cannot change what an abbreviation means)."""
    return sub.add_parser(name, allow_abbrev=False, help=COMMANDS[name].help, description=description)


#: the name that stands for the built-in demo: its still scene for ``snn-fg run``, its recording where a command
#: takes a recording (:func:`recording_or_demo`)
DEMO = "demo"
#: ``--force`` of a command that writes a run's folder (run, live, decode): the one wording of its rule
FORCE_FOLDER_HELP = "replace the output folder if it holds an earlier run (and nothing else)"


def recording_or_demo(spec: str):
    """A command's recording argument as :func:`~snn_fg.events.iter_recording` reads it: the path given,
    or for :data:`DEMO` the built-in demo recording (:func:`~snn_fg.frames.scenes.demo_recording`)."""
    if spec != DEMO:
        return spec
    from ..frames.scenes import demo_recording  # (the event simulator loaded only for it)

    return demo_recording()


def size_text(n_bytes: int) -> str:
    """A size as a line of output gives it: ``7.0 MB``, or ``12 kB`` under a tenth of a megabyte."""
    return f"{n_bytes / 1e6:.1f} MB" if n_bytes >= 100_000 else f"{max(1, round(n_bytes / 1e3))} kB"


def written_size(path) -> str:
    """:func:`size_text` of a file written, or of every file in a folder written."""
    path = Path(path)
    files = [path] if path.is_file() else [p for p in path.rglob("*") if p.is_file()]
    return size_text(sum(p.stat().st_size for p in files))


def number(kind, lo, strict=True, hi=None):
    """argparse type for an ``int`` or ``float`` (``kind``) above ``lo``
    (``strict``) or at least ``lo``, and at most ``hi`` where given; infinities
    and NaN are refused."""

    def parse(text):
        try:
            v = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected {'an integer' if kind is int else 'a number'}, got {text!r}"
            ) from None
        finite = v - v == 0  # False for inf and nan
        if finite and (v > lo if strict else v >= lo) and (hi is None or v <= hi):
            return v
        if finite and hi is not None and not strict:
            raise argparse.ArgumentTypeError(f"must be {lo} to {hi}, got {text}")
        above = f"{'>' if strict else '>='} {lo}" + ("" if hi is None else f" and <= {hi}")
        raise argparse.ArgumentTypeError(f"must be {'' if finite else 'a finite number '}{above}, got {text}")

    return parse


def sensor_size(text):
    """argparse type for ``WxH`` sensor sizes."""
    m = re.fullmatch(r"\s*(\d+)\s*[xX,]\s*(\d+)\s*", text)
    if not m:
        raise argparse.ArgumentTypeError(f"sensor size must look like 640x480, got {text!r}")
    w, h = int(m.group(1)), int(m.group(2))
    if not (0 < w <= MAX_SENSOR_SIDE and 0 < h <= MAX_SENSOR_SIDE):
        raise argparse.ArgumentTypeError(f"width and height must be 1 to {MAX_SENSOR_SIDE} pixels, got {text!r}")
    return w, h


#: a recording's camera as the command line names it (``--channel``): the ``channel`` format option
CHANNELS = {"0": 0, "left": 0, "1": 1, "right": 1, "both": "both"}


def channel(text):
    """argparse type for ``--channel``: 0 or left, 1 or right, both."""
    if text.lower() not in CHANNELS:
        raise argparse.ArgumentTypeError(f"expected 0 (left), 1 (right) or both, got {text!r}")
    return CHANNELS[text.lower()]


def add_camera_options(parser) -> None:
    """``--chip`` and ``--channel``: which camera a recording's events come from, for the files
    that do not say (the ``chip`` and ``channel`` format options); :func:`camera_options` gives them."""
    parser.add_argument(
        "--chip",
        type=str.lower,
        choices=tuple(CHIPS),
        default=None,
        metavar="CHIP",
        help="recordings: the camera of an AEDAT 2.0 file (.aedat) whose header names none ('# AEChip:'): "
        f"{', '.join(c for c in CHIPS if c != 'davis')}, or davis (a DAVIS of --sensor-size)",
    )
    parser.add_argument(
        "--channel",
        type=channel,
        default=None,
        metavar="CAM",
        help="recordings of two cameras, MVSEC's .hdf5 (davis/left, davis/right) and an iCub data.log: "
        "0 or left (the default), 1 or right; both (a data.log only) merges the two",
    )


def camera_options(args) -> dict:
    """The format options of :func:`add_camera_options` given on the command line, as
    :func:`~snn_fg.events.iter_recording` takes them."""
    return {k: getattr(args, k) for k in ("chip", "channel") if getattr(args, k, None) is not None}


def add_image_scale_option(parser, before: str) -> None:
    """``--image-scale``: resize an image ``before`` (what reads it) uses it
    (:func:`~snn_fg.frames.still.sized_image`)."""
    parser.add_argument(
        "--image-scale",
        type=number(float, 0),
        default=None,
        metavar="F",
        help=f"images: resize by F before {before} (0.25: a quarter of the width and height); the model's "
        "sizes in pixels were chosen for images of about 481 x 321 (BSDS), and a larger image gets a note "
        "with the F that brings it there",
    )


def crop(text):
    """argparse type for ``X0,Y0,X1,Y1`` (four integers)."""
    try:
        box = tuple(int(v) for v in text.split(","))
    except ValueError:
        box = ()
    if len(box) != 4:
        raise argparse.ArgumentTypeError(f"expected four integers X0,Y0,X1,Y1, got {text!r}")
    return box


def iterations_bar(no_progress: bool):
    """What a model reports its iterations to: a progress bar on stderr, or
    None with ``--no-progress``."""
    if no_progress:
        return None
    return lambda it: tqdm(it, desc="iterations", leave=False, file=sys.stderr, disable=None)


def blank(value) -> bool:
    """Whether a cell of a command's table has no number: not measured, or nothing to measure it on
    (a nan is shown as "-", never as "nan", and --json writes it as null)."""
    return value is None or (isinstance(value, float) and math.isnan(value))


def cell(value, width: int, spec: str) -> str:
    """One number of a command's text table, right-aligned in ``width`` by ``spec``; "-" where :func:`blank`."""
    return "-".rjust(width) if blank(value) else f"{value:>{width}{spec}}"


def nulls(record: dict) -> dict:
    """``record`` with each :func:`blank` number as None, for --json (json.dumps writes nan as NaN,
    which is not JSON, and other readers refuse it)."""
    return {k: None if blank(v) else v for k, v in record.items()}
