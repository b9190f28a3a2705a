"""The options of a spiking run, as objects checked once where they are made.

:func:`~snn_fg.models.spiking.run_spiking`, :func:`~snn_fg.models.spiking.run_spiking_result`,
:func:`~snn_fg.models.spiking.run_spiking_windows` and
:func:`~snn_fg.models.spiking.continuous.simulate_windows` take their options as
keywords, the one way to pass them; :meth:`SpikingOptions.from_keywords` sorts
them into the parts below (a keyword no part has is refused, as Python refuses
an unexpected keyword argument) and the run passes them on whole.

* :class:`NetworkOptions` - which network: built from parameters or a stored
  one, with or without feedback, calibrated to the input or not;
* :class:`SimulatorOptions` - on which backend and how: time step, cells,
  what to record, progress;
* :class:`FrameOptions` - one frame (or window) presented for a while:
  duration, counting start, the input spike trains;
* :class:`RecordingOptions` - a recording run as one network: read-out lag
  and window clock.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Callable
from dataclasses import InitVar, dataclass, field
from pathlib import Path

from tqdm import tqdm

from ... import validate as check
from ...backends import DEFAULT_BACKEND, Backend, as_backend, backend_names
from ...frames.pool import MAPS_GRIDS, pooled_shape
from ...lowering.input_spikes import check_trains
from ...lowering.unroll import INSTANTIATE
from ...network.builder import build_network
from ...network.graph import INPUT_CODINGS, INPUT_RATE_HZ, Network
from ...network.recipes import network_for
from ...network.spiking_params import SpikingParams
from ...params import ModelParams

#: Default read-out lag (ms) of a recording's windows: see
#: :mod:`snn_fg.models.spiking.continuous` and ``experiments/validation/dvs_latency.py`` for how
#: long the network takes to answer.
READOUT_LAG_MS = 20.0
#: how long a frame or image is shown to a spiking network, unless told otherwise (ms); the PyNN and NIR
#: exports' run.py default to the same (tests/test_export_edits.py)
FRAME_DURATION_MS = 400.0


def stderr_log(message: str):
    """A stage message on its own line of stderr, above any progress bar
    (a plain print landed on the bar's line: "windows read: 0%| 0/3 ...snn-fg: fast engine: ...")."""
    tqdm.write(f"snn-fg: {message}", file=sys.stderr)


@dataclass(frozen=True, kw_only=True)
class NetworkOptions:
    """Which network runs (``owner``: the function whose options these are,
    named in errors).

    ``params`` and ``spiking`` build the default network (defaults: the
    paper's); ``network`` is a recipe name, a stored description or a
    :class:`~snn_fg.network.Network` instead (never both).
    ``feedback=False`` removes the feedback onto border-ownership cells
    (:meth:`Network.without_feedback`, the model's ablation); ``calibrate``
    scales the input gains to the input's actual mean rate; ``input_coding``
    (``None``: the network's own) sets how a recording's events become
    spikes (:attr:`~snn_fg.network.Network.input_coding`); ``maps_grid``
    (:data:`~snn_fg.frames.pool.MAPS_GRIDS`) where its maps are read out: on
    the sensor's pixels, or on the blocks of a network that pools its input.
    """

    params: ModelParams | None = None
    spiking: SpikingParams | None = None
    network: Network | str | Path | None = None
    feedback: bool = True
    calibrate: bool = True
    input_coding: str | None = None
    maps_grid: str = "sensor"
    owner: InitVar[str] = "run_spiking"

    def __post_init__(self, owner):
        check.choice(owner, "maps_grid", self.maps_grid, MAPS_GRIDS)
        if self.network is not None and (self.params is not None or self.spiking is not None):
            check.fail(owner, None, None, "give either a network or params/spiking to build one, not both")
        check.flag(owner, "feedback", self.feedback)
        if self.input_coding is not None:
            check.choice(owner, "input_coding", self.input_coding, INPUT_CODINGS)

    def resolve(self, shape) -> tuple[Network, dict]:
        """The description to run for a sensor of ``shape`` (rows, cols), and
        how it was obtained (for the record): built, or ``network`` through
        :func:`~snn_fg.network.recipes.network_for`. Its frame is the pooled
        sensor when its ``params.input_pool > 1``."""
        if self.network is None:
            params = ModelParams() if self.params is None else self.params
            spiking = SpikingParams() if self.spiking is None else self.spiking
            network = build_network(params, pooled_shape(shape, params.input_pool), spiking)
            origin = {"origin": "built", "spiking_params": spiking.to_dict()}
        else:
            network, origin = network_for(self.network, shape)
        origin["feedback"] = self.feedback
        if self.input_coding is not None and self.input_coding != network.input_coding:
            origin["input_coding"] = self.input_coding
            network = dataclasses.replace(network, input_coding=self.input_coding)
        return (network if self.feedback else network.without_feedback()), origin


@dataclass(frozen=True, kw_only=True)
class SimulatorOptions:
    """On which backend and how the network is simulated.

    ``backend`` is a name or a :class:`~snn_fg.backends.Backend` object (one
    object serves many runs: what it prepares is kept), ``backend_options``
    the name's constructor options; ``dt_ms`` the time step (``None``: the
    network's own, :attr:`~snn_fg.network.Network.dt_ms`); ``instantiate``
    the cells to create (``None``: :meth:`cells_for`); ``record_spikes``
    keeps spike times; ``progress`` prints stage messages and a progress bar
    on stderr, ``log`` receives the messages instead.
    """

    backend: str | Backend = DEFAULT_BACKEND
    backend_options: dict | None = None
    dt_ms: float | None = None
    instantiate: str | None = None
    record_spikes: bool = True
    progress: bool = True
    log: Callable | None = None
    owner: InitVar[str] = "run_spiking"

    def __post_init__(self, owner):
        if not isinstance(self.backend, Backend):  # (a name: refused here, not when the first run starts)
            check.choice(owner, "backend", self.backend, tuple(backend_names()))
        if self.dt_ms is not None:
            object.__setattr__(self, "dt_ms", check.number(owner, "dt_ms", self.dt_ms, lo=0, lo_open=True))
        if self.instantiate is not None:
            check.choice(owner, "instantiate", self.instantiate, INSTANTIATE)

    def step_for(self, network: Network) -> float:
        """The time step of a run of ``network``: ``dt_ms``, or the network's own."""
        return network.time_step(self.dt_ms)

    def backend_object(self) -> Backend:
        return as_backend(self.backend, self.backend_options)

    @property
    def say(self) -> Callable | None:
        """Where stage messages go: ``log``, stderr with ``progress``, or nowhere."""
        return self.log if self.log is not None else (stderr_log if self.progress else None)

    def cells_for(self, backend: Backend, inp) -> str:
        """The cells to create: ``instantiate`` if given; for an event frame
        presented as regular trains, those the populations' hints choose
        (``"input"``), on every backend; otherwise the backend's own default.

        The hints judge a cell by the nominal input rate, which regular trains
        keep exactly: on an event frame the maps with them are those with every
        cell, in less time. Timed events and Poisson trains come in bursts, where
        a cell the hints leave out can fire, so there each backend keeps its
        default (the measurements: ``docs/spiking-network.md``)."""
        if self.instantiate is not None:
            return self.instantiate
        return "input" if inp.kind == "frame-regular" else backend.default_instantiate


@dataclass(frozen=True, kw_only=True)
class FrameOptions:
    """One frame (or window) presented for ``duration_ms``, its spikes
    counted from ``settle_ms`` (default: half of it). An event frame's
    pixels fire at ``rate_hz`` as ``input_process`` trains (``regular``,
    with a random phase from ``seed``, or ``poisson``); timed events repeat
    until the end with ``replay``. ``record_state`` and ``sites``: see
    :class:`~snn_fg.backends.RunSettings`."""

    duration_ms: float = FRAME_DURATION_MS
    settle_ms: float | None = None
    seed: int = 0
    rate_hz: float = INPUT_RATE_HZ
    input_process: str = "regular"
    replay: bool = True
    record_state: tuple = ()
    sites: dict | None = None
    owner: InitVar[str] = "run_spiking"

    def __post_init__(self, owner):
        duration = check.number(owner, "duration_ms", self.duration_ms, lo=0, lo_open=True)
        object.__setattr__(self, "duration_ms", duration)
        object.__setattr__(
            self,
            "settle_ms",
            duration / 2
            if self.settle_ms is None
            else check.number(owner, "settle_ms", self.settle_ms, lo=0, hi=duration, hi_open=True),
        )
        check.seed(owner, self.seed)
        object.__setattr__(self, "rate_hz", check_trains(owner, self.rate_hz, self.input_process))
        object.__setattr__(self, "record_state", tuple(self.record_state))


@dataclass(frozen=True, kw_only=True)
class RecordingOptions:
    """A recording run as one network: each window is read from the spikes
    ``readout_lag_ms`` later than its own span, counted over the last
    ``readout_ms`` of it (``None``: the whole span); ``window_clock`` fires the
    network's window clock (if it has one) as each window starts, or where
    windows overlap once every window length (see
    :class:`~snn_fg.models.spiking.stream_input.StreamLayout`); ``seed``
    draws the held sources' phases of the ``window`` input coding
    (:attr:`~snn_fg.network.Network.input_coding`)."""

    readout_lag_ms: float = READOUT_LAG_MS
    readout_ms: float | None = None
    window_clock: bool = True
    seed: int = 0
    owner: InitVar[str] = "run_spiking_windows"

    def __post_init__(self, owner):
        object.__setattr__(self, "readout_lag_ms", check.number(owner, "readout_lag_ms", self.readout_lag_ms, lo=0))
        if self.readout_ms is not None:
            object.__setattr__(
                self, "readout_ms", check.number(owner, "readout_ms", self.readout_ms, lo=0, lo_open=True)
            )
        check.flag(owner, "window_clock", self.window_clock)
        check.seed(owner, self.seed)


@dataclass(frozen=True)
class SpikingOptions:
    """Every option of a spiking run, in its parts (the defaults: the paper's
    network on the default backend)."""

    network: NetworkOptions = field(default_factory=NetworkOptions)
    simulator: SimulatorOptions = field(default_factory=SimulatorOptions)
    frame: FrameOptions = field(default_factory=FrameOptions)
    recording: RecordingOptions = field(default_factory=RecordingOptions)

    @classmethod
    def from_keywords(cls, owner: str, keywords: dict, *, frame: bool = True, recording: bool = True) -> SpikingOptions:
        """The keyword options of ``owner`` as parts; the frame or recording
        part only where ``owner`` takes it. A keyword no part has is a
        ``TypeError`` naming it."""
        kinds = {"network": NetworkOptions, "simulator": SimulatorOptions}
        if frame:
            kinds["frame"] = FrameOptions
        if recording:
            kinds["recording"] = RecordingOptions
        names = {part: {f.name for f in dataclasses.fields(kind)} for part, kind in kinds.items()}
        for k in keywords:
            if not any(k in n for n in names.values()):
                raise TypeError(f"{owner}() got an unexpected keyword argument {k!r}")
        return cls(
            **{
                part: kind(owner=owner, **{k: v for k, v in keywords.items() if k in names[part]})
                for part, kind in kinds.items()
            }
        )
