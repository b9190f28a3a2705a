"""Python entry points of the spiking model: :func:`run_spiking` and
:func:`run_spiking_result`.

The flow is the package's: input spikes -> network description (built from
parameters, or a stored one) -> calibration to the input rate -> a backend
(by name) -> :class:`~snn_fg.backends.SimulationResult` -> rate decoding ->
:class:`~snn_fg.maps.Maps` with a :class:`~snn_fg.spiking.record.SpikingRecord`.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import validate as check
from ..backends import DEFAULT_BACKEND, RunSettings, SimulationResult, as_backend
from ..errors import InputError
from ..events.window import events_to_frame
from ..frames.pool import pool_events, pool_frame, pooled_shape, unpool_maps
from ..lowering.input_spikes import InputSpikes, event_spikes, frame_spikes
from ..maps import Maps
from ..network.builder import build_network
from ..network.graph import Network
from ..network.recipes import network_for
from ..network.spiking_params import SpikingParams
from ..params import ModelParams
from .decode import decode
from .record import SpikingRecord


@dataclass
class SpikingResult:
    """One spiking run: the maps, the network that ran (calibrated to the
    input), the backend's result, the input spikes and the record."""

    maps: Maps
    network: Network
    result: SimulationResult
    inputs: InputSpikes
    record: SpikingRecord


def stderr_log(message: str):
    print(f"snn-fg: {message}", file=sys.stderr, flush=True)


def resolve_network(network, params, spiking, shape, feedback: bool = True) -> tuple[Network, dict]:
    """The description to run for a sensor of ``shape`` (rows, cols), and
    how it was obtained (for the record): built from ``params`` and
    ``spiking``, or ``network``, a recipe name, a stored description or a
    :class:`Network` (:func:`~snn_fg.network.recipes.network_for`). Its frame
    is the pooled sensor when its ``params.input_pool > 1``.

    ``feedback=False`` removes the feedback onto border-ownership cells
    (:meth:`Network.without_feedback`), the model's ablation."""
    if network is None:
        params = ModelParams() if params is None else params
        spiking = SpikingParams() if spiking is None else spiking
        network = build_network(params, pooled_shape(shape, params.input_pool), spiking)
        origin = {"origin": "built", "spiking_params": spiking.to_dict()}
    else:
        if params is not None or spiking is not None:
            check.fail("run_spiking", None, None, "give either a network or params/spiking to build one, not both")
        network, origin = network_for(network, shape)
    origin["feedback"] = check.flag("run_spiking", "feedback", feedback)
    return (network if feedback else network.without_feedback()), origin


def _sensor_shape(pos, events, sensor_size) -> tuple[int, int]:
    """(rows, cols) of the input's sensor (the input is checked in full by :func:`_inputs`)."""
    if events is None:
        if pos is None:
            raise InputError("<input>", "give events (with sensor_size) or both pos and neg")
        return np.shape(pos)[:2]
    if sensor_size is None:
        raise InputError("<events>", "sensor_size (width, height) is needed with events")
    try:
        return int(sensor_size[1]), int(sensor_size[0])
    except (TypeError, ValueError, IndexError):
        raise InputError("<events>", f"sensor_size must be (width, height[, 2]), got {sensor_size!r}") from None


def _pooled(pos, neg, events, sensor_size, pool: int):
    """The input on the block grid of ``ModelParams.input_pool``, and the
    sensor's event pixels (to bring the maps back to the sensor's size)."""
    if events is None:
        sensor = (np.asarray(pos) != 0) | (np.asarray(neg) != 0)
        return (*pool_frame(pos, neg, pool), None, None, sensor)
    on, off = events_to_frame(events, sensor_size, "<events>")
    sensor = (on != 0) | (off != 0)
    return None, None, pool_events(events, pool), pooled_shape(sensor.shape, pool)[::-1], sensor


def _inputs(pos, neg, events, sensor_size, rate_hz, dt_ms, duration_ms, seed, input_process, replay,
            net: Network | None = None):
    if events is not None:
        if pos is not None or neg is not None:
            raise InputError("<input>", "give either events or a frame (pos, neg), not both")
        if sensor_size is None:
            raise InputError("<events>", "sensor_size (width, height) is needed with events")
        inp = event_spikes(events, sensor_size, dt_ms, replay=replay,
                           refractory_ms=0.0 if net is None else net.input_refractory_ms)
    else:
        if pos is None or neg is None:
            raise InputError("<input>", "give events (with sensor_size) or both pos and neg")
        inp = frame_spikes(pos, neg, rate_hz, dt_ms, duration_ms, seed, input_process)
    if not (inp.on.any() or inp.off.any()):
        raise InputError("<input>", "no pixel has an event: nothing to simulate")
    return inp


def default_instantiate(backend, inp) -> str:
    """The cells to create when the caller does not say: for an event frame
    presented as regular trains, those the populations' hints choose
    (``"input"``), on every backend; otherwise the backend's own default.

    The hints judge a cell by the nominal input rate, which regular trains
    keep exactly: on the six shared BSDS frames the fast engine's maps with
    them are bit for bit those with every cell, and take 1.2-2.4x less time
    (24 Nov). Timed events and Poisson trains come in bursts, where a cell
    the hints leave out can fire (a ``dvs.es`` window's feedback cells fire
    17 % fewer spikes with them), so there each backend keeps its default."""
    if inp.kind == "frame-regular":
        return "input"
    return backend.default_instantiate


def run_spiking_result(pos=None, neg=None, *, events=None, sensor_size=None, params: ModelParams | None = None,
                       spiking: SpikingParams | None = None, network: Network | str | Path | None = None,
                       backend=DEFAULT_BACKEND, backend_options: dict | None = None,
                       duration_ms: float = 400.0, dt_ms: float = 0.5, settle_ms: float | None = None,
                       seed: int = 0, rate_hz: float = 200.0, input_process: str = "regular",
                       replay: bool = True, calibrate: bool = True, instantiate: str | None = None, feedback: bool = True,
                       record_spikes: bool = True, record_state: tuple = (), sites: dict | None = None,
                       progress: bool = True, log=None) -> SpikingResult:
    """:func:`run_spiking`, returning a :class:`SpikingResult` with the internals."""
    t_start = time.perf_counter()
    duration_ms = check.number("run_spiking", "duration_ms", duration_ms, lo=0, lo_open=True)
    dt_ms = check.number("run_spiking", "dt_ms", dt_ms, lo=0, lo_open=True)
    settle_ms = duration_ms / 2 if settle_ms is None else check.number(
        "run_spiking", "settle_ms", settle_ms, lo=0, hi=duration_ms, hi_open=True)
    check.integer("run_spiking", "seed", seed)
    net, origin = resolve_network(network, params, spiking, _sensor_shape(pos, events, sensor_size), feedback)
    pool = net.params.input_pool
    sensor = None
    if pool > 1:
        pos, neg, events, sensor_size, sensor = _pooled(pos, neg, events, sensor_size, pool)
    inp = _inputs(pos, neg, events, sensor_size, rate_hz, dt_ms, duration_ms, seed, input_process, replay, net)
    if calibrate and not np.isclose(net.input_rate_hz, inp.rate_hz, rtol=1e-12, atol=0):
        origin["calibrated"] = {"from_hz": net.input_rate_hz, "to_hz": inp.rate_hz}
        net = net.calibrated(inp.rate_hz)
    sim_backend = as_backend(backend, backend_options)
    instantiate = instantiate or default_instantiate(sim_backend, inp)
    say = log if log is not None else (stderr_log if progress else None)
    settings = RunSettings(duration_ms=duration_ms, dt_ms=dt_ms, count_from_ms=settle_ms,
                           record_spikes=record_spikes, record_state=tuple(record_state),
                           instantiate=instantiate, sites=sites, log=say, progress=progress)
    result = sim_backend.simulate(net, inp, settings)
    fg_x, fg_y, grouping, _ = decode(result)
    if sensor is not None:
        fg_x, fg_y, grouping = unpool_maps(fg_x, fg_y, grouping, sensor, pool)
    rec = SpikingRecord.from_result(result, inp, settle_ms)
    simulation = {**rec.timing(), "dt_ms": dt_ms, "seed": int(seed), "input": inp.kind,
                  "rate_hz_requested": float(rate_hz), "rate_hz_used": inp.rate_hz,
                  "input_process": input_process if events is None else "events",
                  "replay": bool(replay) if events is not None else None,
                  "merged_input_spikes": inp.merged, "instantiate": instantiate,
                  "record_spikes": bool(record_spikes)}
    record = run_params(net, origin, sim_backend, result, rec.populations, simulation, t_start)
    maps = Maps(fg_x.astype(np.float32), fg_y.astype(np.float32), grouping.astype(np.float32), record,
                rec.arrays())
    return SpikingResult(maps, net, result, inp, rec)


def run_params(net: Network, origin: dict, backend, result: SimulationResult, populations: dict,
               simulation: dict, t_start: float) -> dict:
    """``Maps.params`` of a spiking run: model parameters, where the network
    came from, the backend, the simulation settings, cell and synapse counts,
    per-population summaries, timings and the network's notes."""
    syn = result.stats.get("synapses_in", {})
    return {
        "model": "spiking",
        **net.params.to_dict(),
        "network": {**origin, "frame_shape": list(net.frame_shape), "input_rate_hz": net.input_rate_hz},
        "backend": backend.describe(),
        "simulation": simulation,
        "counts": {"cells": {n: int(s.size) for n, s in result.sites.items()},
                   "synapses_in": {n: int(syn.get(n, 0)) for n in result.sites},
                   "total_cells": result.total_cells, "total_synapses": int(sum(syn.values())),
                   "backend_objects": result.stats.get("brian2_synapse_objects", {})},
        "kept_kernel_mass": result.stats.get("kept_kernel_mass", {}),
        # the backend's own counters (fast: synaptic events, spikes, cells updated)
        "backend_stats": {k: v for k, v in result.stats.items() if isinstance(v, (int, float))},
        "populations": populations,
        "timings_s": {**result.timings_s, "total": time.perf_counter() - t_start},
        "notes": list(net.notes),
    }


def run_spiking(pos=None, neg=None, **options) -> Maps:
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
        :func:`default_instantiate`, ``"input"`` for an event frame's regular
        trains, else the backend's ``default_instantiate``; recorded in
        ``params``).
    record_spikes : bool
        Keep spike times for the raster figure.
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

    Examples
    --------
    >>> from snn_fg.events import image_to_frame
    >>> from snn_fg.scenes import disc
    >>> from snn_fg.params import ModelParams
    >>> pos, neg = image_to_frame(disc(radius=12).image)
    >>> maps = run_spiking(pos, neg, params=ModelParams(levels=2), duration_ms=60, progress=False)
    >>> maps.fg_x.shape == pos.shape
    True
    """
    return run_spiking_result(pos, neg, **options).maps
