"""What every figure-ground model is to the rest of the package: :class:`Model`, still inputs and
windows in, :class:`~snn_fg.results.maps.Maps` out, and its figures (the models themselves:
:mod:`.interface`)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from pathlib import Path
from typing import ClassVar

import numpy as np

from .. import validate as check
from ..frames.pool import MAPS_GRIDS, pooled_shape, signed_frame
from ..frames.still import Still
from ..params import ModelParams
from ..results.maps import Maps, made_from
from ..results.timeline import MAPS_FIGURE
from . import blank, checks


class Model(ABC):
    """A figure-ground model: still inputs and windows in, :class:`Maps` out.

    ``needs`` says what a still input must hold (``"events"``: ``pos``/``neg``;
    ``"image"``: an image); ``grouping_label`` labels the grouping map's
    colour bar with its unit. A model that takes the option ``maps_grid``
    (:data:`~snn_fg.frames.pool.MAPS_GRIDS`) keeps the maps of a network that
    pools its input on its blocks when it is ``"blocks"``, and says so in their
    ``params["maps_grid"]``.
    """

    name: ClassVar[str]
    #: the parameters the command line's model flags change (the paper's, or a variant's)
    base_params: ClassVar[ModelParams] = ModelParams()
    needs: ClassVar[str] = "events"
    #: keyword options of the constructor besides params and progress (CLI flags of the same name)
    options: ClassVar[tuple] = ()
    grouping_label: ClassVar[str] = "grouping"
    #: why a recording's window with events can give no figure-ground vector, said with the warning that some did
    blank_window_hint: ClassVar[blank.BlankWindows | None] = None
    #: whether every event pixel gets a vector by construction (``windows.csv``'s ``fg_coverage``, 1, is left empty)
    vector_at_every_event: ClassVar[bool] = False

    def __init__(self, params: ModelParams = ModelParams(), progress=None, *, maps_grid: str = "sensor"):
        self.params, self.progress = params, progress  # progress: a factory wrapping iterables in a bar, or None
        self.maps_grid = check.choice(self.name, "maps_grid", maps_grid, MAPS_GRIDS)

    def maps_shape(self, shape) -> tuple[int, int]:
        """The shape of this model's maps of a sensor frame of ``shape``."""
        return pooled_shape(shape, self.params.input_pool) if self.maps_grid == "blocks" else tuple(shape)

    @abstractmethod
    def run_still(self, still: Still) -> Maps:
        """Maps of one still input."""

    def run_window(self, window) -> Maps:
        """Maps of one window of a recording (an :class:`~snn_fg.events.EventWindow`)."""
        if not (window.pos.any() or window.neg.any()):
            return self.empty_maps(window.pos.shape)
        return self.run_still(Still(window.pos, window.neg))

    def run_windows(self, windows, start: int = 0):
        """``(window, Maps)`` for every window of a recording from window
        ``start`` on (a run continued), in order; by default one window at a
        time (:meth:`run_window`), the windows before ``start`` skipped. A
        model whose windows carry state runs those too, and yields them not."""
        for w in checks.windows("run_windows", windows):
            if w.index >= start:
                yield w, self.run_window(w)

    def run_windows_into(self, windows, emit, start: int = 0) -> dict:
        """:meth:`run_windows` handing each ``(window, maps)`` to ``emit`` as
        soon as it is done (the spiking model's windows come out of one
        simulation while it runs). Returns parameters of the whole run
        known only at its end (none by default; a run's store keeps them as
        ``params["whole_run"]``)."""
        for w, maps in self.run_windows(windows, start):
            emit(w, maps)
        return {}

    def named(self, maps: Maps) -> Maps:
        """``maps`` with this model's name in their parameters."""
        maps.params["model"] = self.name
        if self.maps_grid == "blocks":
            maps.params["maps_grid"] = "blocks"
        return maps

    def empty_maps(self, shape) -> Maps:
        """Maps of no events on a sensor frame of ``shape``: zero."""
        z = np.zeros(self.maps_shape(shape), np.float32)
        return self.named(Maps(z, z.copy(), z.copy(), {"model": self.name, **self.params.to_dict()}))

    def figure_input(self, still: Still) -> np.ndarray:
        """The image shown beside the maps (on their grid: the blocks' frame for maps kept there)."""
        from ..results.figures import event_frame_rgb, signed_frame_rgb  # (matplotlib: only for runs that draw)

        if self.maps_grid == "blocks":  # (as a recording's stored blocks are drawn)
            return signed_frame_rgb(signed_frame(still.pos, still.neg, self.params.input_pool))
        return event_frame_rgb(still.pos, still.neg)

    def write_figures(self, out: Path, maps: Maps, inputs, titles=None, crop=None, **options) -> list[Path]:
        """Figures of a run into folder ``out``; ``inputs`` one image per frame; ``crop``
        ``(x0, y0, x1, y1)``: the part drawn; ``options``: more :func:`~snn_fg.results.figures.maps_figure` keywords."""
        from ..results.figures import IMAGE_INPUT, on_sensor, save_maps_figure

        options.setdefault("made_by", made_from(maps.params))
        if self.needs == "image":  # (its panel is the image it read, not an event frame: until 30 Nov said as one)
            options.setdefault("input_note", IMAGE_INPUT)
        if "placed" not in options:  # (maps kept on blocks: drawn at the sensor's coordinates)
            options.update(on_sensor(maps.params, crop, maps.fg_x.shape))
            crop = options.pop("crop")
        return [
            save_maps_figure(
                out / MAPS_FIGURE,
                inputs,
                maps.fg_x,
                maps.fg_y,
                maps.grouping,
                titles=titles,
                grouping_label=self.grouping_label,
                crop=crop,
                **options,
            )
        ]
