"""The models ``snn-fg run`` can run, behind one interface: :class:`~.base.Model`.

A model runs one still input (a :class:`~snn_fg.frames.still.Still`: an event
frame, or an image for the frame-based model) or one window of a recording, and draws
its figures. The command line and the experiments pick a model by name from
:data:`MODELS` and never branch on which one it is. To add a model, subclass
:class:`~.base.Model` and register it.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from .. import validate as check
from ..backends import DEFAULT_BACKEND
from ..errors import InputError
from ..events.aps import ApsWindow
from ..events.images import as_float_image
from ..frames.still import Still
from ..params import EDGE_OPERATORS, NATURAL_PARAMS, RUN_PARAMS, ModelParams
from ..results.maps import SPIKING_GROUPING_LABEL, Maps
from . import blank, checks
from .base import Model

# Each model's own package is imported by the methods that run it: the rate model compiles its numba loops and
# the spiking model loads its backends on import (seconds); the figures (matplotlib) only by a run that draws.


class RateModel(Model):
    """The rate reference (EDFG, stages 1-9) on an event frame.

    Option ``carry_state`` (recordings): each window's grouping and feedback
    start where the previous window's stopped
    (:meth:`~snn_fg.models.rate.grouping.SparseGrouping.continue_from`), as in a
    network that is never reset, instead of afresh as in the paper. A window
    without events carries nothing on.
    """

    name = "rate"
    options = ("carry_state", "maps_grid")
    grouping_label = "grouping activity (rate-model units)"
    vector_at_every_event = True  # (stage 9 reads B2 - B1 out at every event pixel: never exactly 0)

    def __init__(
        self, params: ModelParams = ModelParams(), progress=None, *, carry_state: bool = False, maps_grid="sensor"
    ):
        super().__init__(params, progress, maps_grid=maps_grid)
        self.carry_state = check.flag("rate", "carry_state", carry_state)

    def run_still(self, still: Still) -> Maps:
        checks.still("run_still", still, self)
        from .rate.edfg import run_edfg

        t = time.perf_counter()
        on_blocks = self.maps_grid == "blocks"
        maps = self.named(run_edfg(still.pos, still.neg, self.params, progress=self.progress, on_blocks=on_blocks))
        maps.params["timings_s"] = {"run": time.perf_counter() - t}
        return maps

    def run_windows(self, windows, start: int = 0):
        """As :meth:`Model.run_windows`; with ``carry_state`` the windows
        before ``start`` are run again (the state they pass on is not stored)."""
        if not self.carry_state:
            yield from super().run_windows(windows, start)
            return
        from .rate.edfg import run_edfg_state

        previous = None
        for w in checks.windows("run_windows", windows):
            if not (w.pos.any() or w.neg.any()):
                previous = None
                if w.index >= start:
                    yield w, self.empty_maps(w.pos.shape)
                continue
            continued = previous is not None
            t = time.perf_counter()
            previous = run_edfg_state(
                w.pos, w.neg, self.params, self.progress, previous, on_blocks=self.maps_grid == "blocks"
            )
            if w.index >= start:
                timings = {"run": time.perf_counter() - t}
                maps = previous.maps(carry_state=True, continued_from_previous_window=continued, timings_s=timings)
                yield w, self.named(maps)


class FbfgModel(Model):
    """The frame-based model (FBFG) on a grey or RGB image; option ``edge_operator``
    (``"gaussian"`` or ``"corf"``, see :mod:`snn_fg.models.rate.fbfg`).

    On a recording it reads a DAVIS camera's grey-level frames: each window,
    an :class:`~snn_fg.events.aps.ApsWindow`, runs on its frame, the last one
    before the window's end (none before the first frame: empty maps). Its
    maps keep the frame (``aps_frame``), its index in the file
    (``aps_index``, -1: none) and time (``aps_t_us``, on ``t_start_us``'s clock).
    """

    name = "fbfg"
    needs = "image"
    options = ("edge_operator",)
    grouping_label = "grouping (normalised to 1)"
    blank_window_hint = blank.FRAMES

    def __init__(self, params: ModelParams = ModelParams(), progress=None, *, edge_operator="gaussian"):
        super().__init__(params, progress)
        self.edge_operator = check.choice("fbfg", "edge_operator", edge_operator, EDGE_OPERATORS)
        self._last = None  # (frame index, maps): windows that share a frame share its maps

    def run_still(self, still: Still) -> Maps:
        checks.still("run_still", still, self)
        from .rate.fbfg import run_fbfg

        return run_fbfg(still.image, self.params, progress=self.progress, edge_operator=self.edge_operator)

    def run_window(self, window) -> Maps:
        if not isinstance(window, ApsWindow):
            raise InputError(
                "<recording>",
                "the fbfg model reads a DAVIS recording's APS frames, which these windows do not carry: give "
                "run_windows FramedWindows(iter_windows(path, ...), require_frames(path), sensor_size) (from "
                "snn_fg.events.aps), as snn-fg run --model fbfg does",
            )
        frame, origin = window.aps, window.t_start_us if window.t_first_event_us is None else window.t_first_event_us
        if frame is None:
            return dataclasses.replace(self.empty_maps(window.pos.shape), extra={"aps_index": np.int64(-1)})
        if self._last is None or self._last[0] != frame.index:
            t = time.perf_counter()
            maps = self.run_still(Still(image=as_float_image(frame.image, grey=False)))
            maps.params["timings_s"] = {"run": time.perf_counter() - t}
            self._last = (frame.index, maps)
        at = {"aps_frame": frame.image, "aps_index": np.int64(frame.index), "aps_t_us": np.int64(frame.t_us - origin)}
        return dataclasses.replace(self._last[1], extra={**self._last[1].extra, **at})

    def figure_input(self, still: Still) -> np.ndarray:
        return still.image


#: how a frame becomes input spikes: regular trains at every event pixel, or
#: (for an image) the simulated camera's events with their own timing, replayed
SPIKE_INPUTS = ("regular", "events")


class SpikingModel(Model):
    """The spiking network (:func:`snn_fg.models.spiking.run_spiking`) on a backend.

    Options: ``network`` (a stored description), ``backend``, ``feedback``,
    ``dt_ms``, ``instantiate``; for one frame ``duration_ms``, ``settle_ms``, ``seed``,
    ``spike_input`` (:data:`SPIKE_INPUTS`); ``maps_grid`` (:class:`Model`); for a recording ``readout_lag_ms``,
    ``readout_ms``, ``window_clock``, ``input_coding`` and ``save_spikes`` (keep each window's
    per-cell spike counts, :class:`~snn_fg.models.spiking.SpikingRecord`; a frame always keeps
    them): a recording runs as one continuous network (:mod:`snn_fg.models.spiking.continuous`),
    its window clock firing as each window starts, or once every window length where windows
    overlap (:class:`~snn_fg.models.spiking.stream_input.StreamLayout`).
    """

    name = "spiking"
    grouping_label = SPIKING_GROUPING_LABEL
    blank_window_hint = blank.SPIKING
    options = (
        "network",
        "backend",
        "duration_ms",
        "settle_ms",
        "dt_ms",
        "seed",
        "feedback",
        "readout_lag_ms",
        "readout_ms",
        "window_clock",
        "input_coding",
        "spike_input",
        "instantiate",
        "save_spikes",
        "maps_grid",
    )

    def __init__(
        self,
        params: ModelParams = ModelParams(),
        progress=None,
        *,
        network=None,
        backend=DEFAULT_BACKEND,
        spike_input: str = "regular",
        save_spikes: bool = False,
        maps_grid: str = "sensor",
        **run_options,
    ):
        from .spiking.options import SpikingOptions

        super().__init__(params, progress, maps_grid=maps_grid)
        self.network = network  # a stored description (its own ModelParams), or None: build from params
        self._backend = None  # the backend object, made on first use and kept (see _sim)
        self.spike_input = check.choice("spiking model", "spike_input", spike_input, SPIKE_INPUTS)
        self.save_spikes = check.flag("spiking model", "save_spikes", save_spikes)
        built = {"params": params} if network is None else {"network": network}
        #: the keyword options of every run (a frame takes its frame options, a recording its recording options)
        self.run_keywords = {
            **built, "backend": backend, "progress": progress is not None, "maps_grid": maps_grid, **run_options
        }  # fmt: skip
        self.run_options = SpikingOptions.from_keywords("run_spiking", self.run_keywords)  # (checked here, once)

    @property
    def backend(self):
        """The backend asked for (a name or a Backend object)."""
        return self.run_options.simulator.backend

    def _sim(self):
        """The backend, one object for every input this model runs: the
        fast engine keeps its tables and cell arrays from one run to the next."""
        if self._backend is None:
            self._backend = self.run_options.simulator.backend_object()
        return self._backend

    def _keywords(self, run: str, **changes) -> dict:
        """The keyword options of a ``run`` (``"frame"``: :func:`run_spiking`'s, without
        the recording's; ``"recording"``: without the frame's), on the backend
        object this model keeps, with ``changes``."""
        from .spiking.options import FrameOptions, RecordingOptions

        own, other = (FrameOptions, RecordingOptions) if run == "frame" else (RecordingOptions, FrameOptions)
        left_out = {f.name for f in dataclasses.fields(other)} - {f.name for f in dataclasses.fields(own)}
        kept = {k: v for k, v in self.run_keywords.items() if k not in left_out}
        return {**kept, "backend": self._sim(), "backend_options": None, **changes}

    def __getstate__(self):
        return {**self.__dict__, "_backend": None}  # (a copy elsewhere makes its own: the arrays stay here)

    def _run(self, **inputs) -> Maps:
        from .spiking import run_spiking

        return self.named(run_spiking(**inputs, **self._keywords("frame")))

    def run_still(self, still: Still) -> Maps:
        checks.still("run_still", still, self)
        if self.spike_input == "events":
            if still.recording is None:
                raise InputError(
                    "<frame>",
                    "spike input 'events' needs an image (its simulated events carry "
                    "their timing); an event frame has none: use 'regular'",
                )
            rec = still.recording
            return self._run(events=rec.events, sensor_size=rec.sensor_size)
        return self._run(pos=still.pos, neg=still.neg)

    def run_window(self, window) -> Maps:
        """One window, run as a recording of that one window (:meth:`run_windows`): its events fed once (no
        replay), the window clock, and the window plus the read-out lag simulated, as in a longer one."""
        if not (window.pos.any() or window.neg.any()):
            return self.empty_maps(window.pos.shape)
        ((_, maps),) = self.run_windows([window])
        return maps

    def run_windows(self, windows, start: int = 0):
        """One network over the whole recording (:func:`~snn_fg.models.spiking.run_spiking_windows`), fed its
        events as they come (how they become spikes: docs/spiking-network.md, "How events become input spikes"),
        each window read from its own spikes. A run continued from window ``start`` simulates the windows before
        it again (the network's state at a window's start comes from every event before it), and yields them
        not. Each window's per-cell spike counts are kept only with ``save_spikes``."""
        out = []
        self.run_windows_into(windows, lambda w, m: out.append((w, m)), start)
        yield from out

    def run_windows_into(self, windows, emit, start: int = 0) -> dict:
        """As :meth:`run_windows`, each window handed to ``emit`` while the
        simulation runs (:func:`~snn_fg.models.spiking.continuous.stream_spiking_windows`)."""
        from .spiking.continuous import stream_spiking_windows

        def done(window, maps):
            if window.index >= start:
                emit(window, self.named(maps))

        # without save_spikes the counts and spike trains would be dropped unread: not made
        keywords = self._keywords("recording", **({} if self.save_spikes else {"record_spikes": False}))
        return stream_spiking_windows(checks.windows("run_windows", windows), done, cells=self.save_spikes, **keywords)

    def write_figures(self, out: Path, maps: Maps, inputs, titles=None, crop=None, **options) -> list[Path]:
        """``maps.png``; and the spike raster and rate histograms where the
        spike counts were kept (a frame, or a recording with ``save_spikes``)."""
        written = super().write_figures(out, maps, inputs, titles, crop, **options)
        if maps.fg_x.ndim == 3 and not self.save_spikes:
            return written
        from .spiking.figures import save_spiking_figures

        return written + save_spiking_figures(maps, out, with_maps=False)


class NaturalModel(RateModel):
    """The natural-scene variant (:mod:`snn_fg.models.rate.natural`): the rate model
    with contrast-invariant grouping and the parameters chosen on natural images."""

    name = "natural"
    base_params = NATURAL_PARAMS
    options = ("carry_state",)  # (its parameters pool no input: no blocks to keep maps on)


class NaturalSpikingModel(SpikingModel):
    """The natural-scene variant as a spiking network: the default network's
    construction with :data:`~snn_fg.models.rate.natural.NATURAL_PARAMS` (pooled
    grouping polarities, no rival inhibition), on a backend."""

    name = "natural-spiking"
    base_params = NATURAL_PARAMS
    options = tuple(o for o in SpikingModel.options if o != "maps_grid")  # (as the natural model)


MODELS: dict[str, type[Model]] = {
    m.name: m for m in (RateModel, FbfgModel, SpikingModel, NaturalModel, NaturalSpikingModel)
}


def get_model(name: str, params: ModelParams | None = None, progress=None, **options) -> Model:
    """The model ``name`` (one of :data:`MODELS`) with its options, as ``snn-fg run --model NAME`` takes
    them (a mistyped one is refused here, naming the model's). ``params``: its own by default, or those of
    the ``network`` option (``"compact"``, a stored description), which the rate model takes too for its
    model parameters (``--model rate --network compact``); or the parameters ``snn-fg run`` takes as
    options, as keywords (``r0=4``: :data:`~snn_fg.params.RUN_PARAMS`), over the model's own."""
    model = MODELS[check.choice("get_model", "name", name, tuple(MODELS))]
    given = {k: options.pop(k) for k in RUN_PARAMS if k in options}
    network = options.get("network")
    if network is not None and "network" not in model.options and model is RateModel:
        options.pop("network")  # (the rate model reads a network's model parameters only)
    checks.model_options(name, options, model.options + (("network",) if model is RateModel else ()))
    if given and (params is not None or network is not None):
        check.fail(
            "get_model", None, None,
            f"{', '.join(given)}: give the model parameters as params=ModelParams(...) or as keywords, and not "
            "with a network, which carries its own",
        )  # fmt: skip
    if params is None and network is not None:
        from ..network.recipes import model_params_of  # (a mistyped recipe name is refused here too)

        params = model_params_of(network)
    params = (model.base_params if params is None else params).replace(**given)
    return model(params, progress, **options)
