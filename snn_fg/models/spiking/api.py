"""Python entry points of the spiking model: :func:`run_spiking` and
:func:`run_spiking_result`.

The flow is the package's: input spikes -> network description (built from
parameters, or a stored one) -> calibration to the input rate -> a backend
(by name) -> :class:`~snn_fg.backends.SimulationResult` -> rate decoding ->
:class:`~snn_fg.results.maps.Maps` with a :class:`~snn_fg.models.spiking.record.SpikingRecord`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ...backends import RunSettings, SimulationResult
from ...errors import InputError
from ...events.core import check_sensor_size
from ...events.frame import events_to_frame
from ...frames.check import event_frame
from ...frames.pool import pool_events, pool_frame, pooled_shape
from ...lowering.input_spikes import InputSpikes, event_spikes, frame_spikes
from ...network.graph import Network
from ...results.maps import CONFIDENCE, Maps
from .decode import decode_maps
from .options import FrameOptions, SpikingOptions
from .record import SpikingRecord, run_provenance


@dataclass
class SpikingResult:
    """One spiking run: the maps, the network that ran (calibrated to the
    input), the backend's result, the input spikes and the record."""

    maps: Maps
    network: Network
    result: SimulationResult
    inputs: InputSpikes
    record: SpikingRecord


def _sensor_shape(pos, neg, events, sensor_size) -> tuple[int, int]:
    """(rows, cols) of the input's sensor (the input is checked in full by :func:`_inputs`)."""
    if events is None:
        if pos is None and neg is None:
            raise InputError("<input>", "give events (with sensor_size) or both pos and neg")
        event_frame("run_spiking", pos, neg)
        return np.shape(pos)[:2]
    if sensor_size is None:
        raise InputError("<events>", "sensor_size (width, height) is needed with events")
    w, h, _ = check_sensor_size(sensor_size, "<events>")
    return h, w


def _pooled(pos, neg, events, sensor_size, pool: int):
    """The input on the block grid of ``ModelParams.input_pool``, and the
    sensor's event pixels (to bring the maps back to the sensor's size)."""
    if events is None:
        sensor = (np.asarray(pos) != 0) | (np.asarray(neg) != 0)
        return (*pool_frame(pos, neg, pool), None, None, sensor)
    on, off = events_to_frame(events, sensor_size, "<events>")
    sensor = (on != 0) | (off != 0)
    return None, None, pool_events(events, pool), pooled_shape(sensor.shape, pool)[::-1], sensor


def _inputs(pos, neg, events, sensor_size, frame: FrameOptions, dt_ms: float, net: Network):
    if events is not None:
        if pos is not None or neg is not None:
            raise InputError("<input>", "give either events or a frame (pos, neg), not both")
        if sensor_size is None:
            raise InputError("<events>", "sensor_size (width, height) is needed with events")
        inp = event_spikes(events, sensor_size, dt_ms, replay=frame.replay, refractory_ms=net.input_refractory_ms)
    else:
        if pos is None or neg is None:
            raise InputError("<input>", "give events (with sensor_size) or both pos and neg")
        inp = frame_spikes(pos, neg, frame.rate_hz, dt_ms, frame.duration_ms, frame.seed, frame.input_process)
    if not (inp.on.any() or inp.off.any()):
        raise InputError("<input>", "no pixel has an event: nothing to simulate")
    return inp


def run_spiking_result(pos=None, neg=None, *, events=None, sensor_size=None, **keywords) -> SpikingResult:
    """:func:`run_spiking`, returning a :class:`SpikingResult` with the
    internals. The options are :func:`run_spiking`'s keywords."""
    t_start = time.perf_counter()
    opts = SpikingOptions.from_keywords("run_spiking", keywords, recording=False)
    frame, sim = opts.frame, opts.simulator
    net, origin = opts.network.resolve(_sensor_shape(pos, neg, events, sensor_size))
    pool = net.params.input_pool
    sensor = None
    if pool > 1:
        pos, neg, events, sensor_size, sensor = _pooled(pos, neg, events, sensor_size, pool)
    dt_ms = sim.step_for(net)
    inp = _inputs(pos, neg, events, sensor_size, frame, dt_ms, net)
    if opts.network.calibrate and not np.isclose(net.input_rate_hz, inp.rate_hz, rtol=1e-12, atol=0):
        origin["calibrated"] = {"from_hz": net.input_rate_hz, "to_hz": inp.rate_hz}
        net = net.calibrated(inp.rate_hz)
    backend = sim.backend_object()
    instantiate = sim.cells_for(backend, inp)
    settings = RunSettings(
        duration_ms=frame.duration_ms,
        dt_ms=dt_ms,
        count_from_ms=frame.settle_ms,
        record_spikes=sim.record_spikes,
        record_state=frame.record_state,
        instantiate=instantiate,
        sites=frame.sites,
        log=sim.say,
        progress=sim.progress,
    )
    result = backend.simulate(net, inp, settings)
    unpooled = sensor is not None and opts.network.maps_grid == "sensor"
    fg_x, fg_y, grouping, conf = decode_maps(result, sensor, pool if unpooled else 1)
    rec = SpikingRecord.from_result(result, inp, frame.settle_ms)
    simulation = {
        **rec.timing(),
        "dt_ms": dt_ms,
        "seed": int(frame.seed),
        "input": inp.kind,
        "rate_hz_requested": float(frame.rate_hz),
        "rate_hz_used": inp.rate_hz,
        "input_process": frame.input_process if events is None else "events",
        "replay": bool(frame.replay) if events is not None else None,
        "merged_input_spikes": inp.merged,
        "instantiate": instantiate,
        "record_spikes": bool(sim.record_spikes),
    }
    record = run_provenance(net, origin, backend, result, rec.populations, simulation, t_start)
    extra = {**rec.arrays(), CONFIDENCE: conf.astype(np.float32)}
    maps = Maps(fg_x.astype(np.float32), fg_y.astype(np.float32), grouping.astype(np.float32), record, extra)
    return SpikingResult(maps, net, result, inp, rec)


def run_spiking(pos=None, neg=None, **keywords) -> Maps:
    """Run the spiking figure-ground network on one frame or window of input.

    Parameters
    ----------
    pos, neg : array (H, W), optional
        An event frame without timing (uint8 0/1): each pixel with an event
        fires at ``rate_hz`` for ``duration_ms`` (regular trains with a
        random phase from ``seed``, or Poisson with ``input_process``).
    events : structured array, optional
        Timed events instead (fields x, y, t in microseconds, p), with
        ``sensor_size`` (W, H[, 2]); they keep their timestamps, and with
        ``replay`` the window repeats until ``duration_ms``.
    input_coding : str, optional
        How a recording's events become input spikes (default: the
        network's own, :attr:`~snn_fg.network.Network.input_coding`).
    params : ModelParams, optional
        Model parameters to build the default network from (default: the
        paper's); with ``spiking`` (:class:`~snn_fg.network.SpikingParams`).
    network : Network or path, optional
        A description to run instead (e.g. ``networks/default_321x481.json``,
        possibly edited); resized to the input's frame shape if needed.
    backend : str or Backend
        Simulator (``snn_fg.backends.backend_names()``); ``backend_options``
        are passed to it (Brian2: ``codegen``, ``free``). A backend object
        (``get_backend(name)``) serves many calls: what it prepares for a
        network (the fast engine's tables and cell arrays) is kept.
    duration_ms, dt_ms, settle_ms : float
        Simulated time, time step, and the start of the counting window
        (default: half of ``duration_ms``).
    calibrate : bool
        Scale the input gains to the input's actual mean rate (recorded in
        ``params["network"]["calibrated"]``).
    feedback : bool
        ``False`` removes the feedback onto border-ownership cells (the
        ablation: both sides of every border stay equal, the figure-ground
        map loses its direction).
    instantiate : {"input", "all"}, optional
        Create only the cells this input can use, or every cell (default:
        :meth:`~snn_fg.models.spiking.options.SimulatorOptions.cells_for`, ``"input"``
        for an event frame's regular trains, else the backend's
        ``default_instantiate``; recorded in ``params``).
    record_spikes : bool
        Keep spike times for the raster figure.
    record_state, sites
        Final state variables to keep, and the cells to make per population
        (:class:`~snn_fg.backends.RunSettings`).
    maps_grid : {"sensor", "blocks"}
        Where the maps of a network that pools its input are read out: on
        the sensor's pixels (default), or on its blocks
        (:data:`~snn_fg.frames.pool.MAPS_GRIDS`).
    progress, log
        ``progress`` prints one-line stage messages and a progress bar on
        stderr; ``log`` receives the messages instead.

    Returns
    -------
    Maps
        ``fg_x``, ``fg_y``, ``grouping`` decoded from spike counts by the rate
        model's own readout; ``params`` records every parameter, the
        backend, cell and synapse counts, rates and timings; the spike
        counts per population are the :class:`SpikingRecord`
        (``SpikingRecord.from_maps(maps)``).

    Raises
    ------
    TypeError
        An unknown keyword (the keywords are checked once, as
        :class:`~snn_fg.models.spiking.options.SpikingOptions`, and passed on whole).

    Examples
    --------
    >>> from snn_fg.events import image_to_frame
    >>> from snn_fg.frames.scenes import disc
    >>> from snn_fg.params import ModelParams
    >>> pos, neg = image_to_frame(disc(radius=12).image)
    >>> maps = run_spiking(pos, neg, params=ModelParams(levels=2), duration_ms=60, progress=False)
    >>> maps.fg_x.shape == pos.shape
    True
    """
    return run_spiking_result(pos, neg, **keywords).maps
