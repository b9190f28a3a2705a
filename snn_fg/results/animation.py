"""A recording's maps over time as an animation: one frame per window (input, figure-ground,
grouping on one scale for the whole recording, the window's time in its title), as a GIF (Pillow,
which matplotlib brings) or an MP4 (OpenCV's video writer, a dependency already). Written
atomically: an interrupted animation leaves no file."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from .atomic import atomic_path

#: what an animation can be written as
SUFFIXES = (".gif", ".mp4")
#: resolution of an animation's frames (a figure's is 110 dpi)
FRAME_DPI = 80


#: windows a second of an animation unless told otherwise (``snn-fg plot --fps``)
FPS = 4.0


def _frames(maps, *, grouping_label: str, crop=None):
    """Each window of ``maps`` drawn as an RGB array (:func:`~.overview.window_figure`)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from .overview import grouping_top, window_figure

    top = grouping_top(maps)
    for i in range(maps.fg_x.shape[0]):
        fig = window_figure(maps, i, grouping_label=grouping_label, grouping_max=top, crop=crop)
        fig.set_dpi(FRAME_DPI)
        canvas = FigureCanvasAgg(fig)
        canvas.draw()
        yield np.asarray(canvas.buffer_rgba())[..., :3].copy()


def save_animation(path, maps, *, grouping_label: str, fps: float = FPS, crop=None) -> Path:
    """The windows of a recording's ``maps`` as an animation at ``fps`` windows a second into
    ``path`` (``.gif`` or ``.mp4``)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise InputError(path, f"an animation is written as {' or '.join(SUFFIXES)}, not {suffix or 'no suffix'}")
    frames = _frames(maps, grouping_label=grouping_label, crop=crop)
    with atomic_path(path) as tmp:
        if suffix == ".gif":
            from PIL import Image

            first, *rest = (Image.fromarray(f) for f in frames)
            first.save(tmp, format="GIF", save_all=True, append_images=rest, duration=round(1000 / fps), loop=0)
        else:
            _write_mp4(tmp, frames, fps, path)
    return path


def _write_mp4(tmp: Path, frames, fps: float, path: Path) -> None:
    import cv2

    writer = None
    try:
        for f in frames:
            h, w = (v - v % 2 for v in f.shape[:2])  # (the codec takes even sides)
            if writer is None:
                writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
                if not writer.isOpened():
                    raise InputError(path, "OpenCV here has no MP4 encoder: write a .gif instead")
            writer.write(cv2.cvtColor(np.ascontiguousarray(f[:h, :w]), cv2.COLOR_RGB2BGR))
    finally:
        if writer is not None:
            writer.release()
