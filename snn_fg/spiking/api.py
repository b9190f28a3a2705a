"""Python entry points of the spiking model: :func:`run_spiking` and
:func:`save_spiking_figures`."""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError, ParameterError
from ..maps import Maps
from ..network.description import Network, NetworkParams, build_network
from ..params import ModelParams
from .brian import SimResult, simulate
from .decode import decode
from .inputs import InputSpikes, event_spikes, frame_spikes
from .unroll import Unrolled, unroll

#: roles in display order, for figures and summaries
ROLE_ORDER = ("relay_on", "relay_off", "simple", "untuned", "bo_L1", "bo_L2", "bo_D1", "bo_D2",
              "group_L", "group_D", "fb_z1p", "fb_z1n", "fb_z2p", "fb_z2n")
RASTER_CELLS_PER_ROLE = 30


@dataclass
class SpikingResult:
    """Everything one spiking run produced (the Maps plus the network internals)."""

    maps: Maps
    network: Network
    unrolled: Unrolled
    sim: SimResult
    inputs: InputSpikes
    rates: dict          # population -> rate (Hz) per instantiated cell


def _check_number(name, v, positive=True):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or (positive and v <= 0):
        raise ParameterError(f"{name}={v!r}: must be a {'positive' if positive else 'finite'} number")
    return float(v)


def run_spiking_result(pos=None, neg=None, events=None, sensor_size=None, params: ModelParams = ModelParams(),
                       duration_ms: float = 400.0, dt_ms: float = 0.5, seed: int = 0, rate_hz: float = 200.0,
                       progress: bool = True, network: NetworkParams | None = None, settle_ms: float | None = None,
                       input_process: str = "regular", replay: bool = True, codegen: str = "auto",
                       record_spikes: bool = True, keep_connections: bool = False, log=None) -> SpikingResult:
    """:func:`run_spiking`, returning the full :class:`SpikingResult`."""
    t_start = time.perf_counter()
    if not isinstance(params, ModelParams):
        raise ParameterError(f"params: expected a ModelParams, got {type(params).__name__}")
    net_params = NetworkParams() if network is None else network
    if not isinstance(net_params, NetworkParams):
        raise ParameterError(f"network: expected a NetworkParams, got {type(net_params).__name__}")
    duration_ms = _check_number("duration_ms", duration_ms)
    dt_ms = _check_number("dt_ms", dt_ms)
    settle_ms = duration_ms / 2 if settle_ms is None else _check_number("settle_ms", settle_ms, positive=False)
    if not 0 <= settle_ms < duration_ms:
        raise ParameterError(f"settle_ms={settle_ms}: must lie in [0, duration_ms={duration_ms})")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise ParameterError(f"seed={seed!r}: must be an integer")
    if log is None and progress:
        def log(msg):
            print(msg, file=sys.stderr, flush=True)
    say = log or (lambda msg: None)

    # ---- input -----------------------------------------------------------
    if events is not None:
        if pos is not None or neg is not None:
            raise InputError("<input>", "give either events or a frame (pos, neg), not both")
        if sensor_size is None:
            raise InputError("<events>", "sensor_size (width, height) is needed with events")
        inp = event_spikes(events, sensor_size, dt_ms, replay=replay)
    else:
        if pos is None or neg is None:
            raise InputError("<input>", "give events (with sensor_size) or both pos and neg")
        inp = frame_spikes(pos, neg, rate_hz, dt_ms, duration_ms, seed, input_process)
    if not (inp.on.any() or inp.off.any()):
        raise InputError("<input>", "no pixel has an event: nothing to simulate")

    # ---- network ---------------------------------------------------------
    net_params = net_params.replace(input_rate_hz=inp.rate_hz)
    net = build_network(params, inp.shape, net_params)
    t0 = time.perf_counter()
    un = unroll(net, {"on": inp.on, "off": inp.off})
    t_unroll = time.perf_counter() - t0
    counts = un.counts()
    say(f"spiking network: {sum(counts['cells'].values()):,} cells, "
        f"{sum(counts['synapses_in'].values()):,} synapses (unrolled in {t_unroll:.1f} s)")
    if progress:
        say(un.table())
    kept = {c.projection.name: round(c.kept_mass, 4) for c in un.connections}
    syn_in = counts["synapses_in"]
    sim = simulate(un, inp, duration_ms, dt_ms, settle_ms, codegen=codegen, record_spikes=record_spikes,
                   progress=progress, free=not keep_connections, log=say if progress else None)

    # ---- decode ----------------------------------------------------------
    lay = sim.layout
    window_s = sim.count_window_ms / 1000.0
    rates = {}
    spikes = {}
    for name in lay.names:
        a, k = lay.offsets[name], lay.sizes[name]
        spikes[name] = sim.counts[a:a + k]
        rates[name] = spikes[name] / window_s
    fg_x, fg_y, grouping, _ = decode(net, un.sites, rates)

    pops = {p.name: p for p in net.populations}
    summary = {}
    for name in lay.names:
        r = rates[name]
        p = pops[name]
        summary[name] = {"role": p.role, "level": p.level, "cells": int(r.size),
                         "mean_rate_hz": float(r.mean()) if r.size else 0.0,
                         "active_frac": float((r > 0).mean()) if r.size else 0.0,
                         "max_rate_hz": float(r.max()) if r.size else 0.0,
                         "refractory_max_hz": p.neuron.max_rate_hz,
                         "synapses_in": int(syn_in[name])}
    extra = {"population_names": np.array(lay.names)}
    for name in lay.names:
        extra[f"spikes_{name}"] = spikes[name].astype(np.int32)
        extra[f"sites_{name}"] = un.sites[name].astype(np.int64)
    if sim.spike_i is not None:
        ri, rt, rp = _raster_sample(sim, lay, pops)
        extra["raster_cell"] = ri
        extra["raster_t_ms"] = rt
        extra["raster_role"] = rp
    extra["input_on"] = inp.on.astype(np.uint8)
    extra["input_off"] = inp.off.astype(np.uint8)
    record = {
        "model": "spiking",
        **params.to_dict(),
        "network": net_params.to_dict(),
        "simulation": {"duration_ms": duration_ms, "dt_ms": dt_ms, "settle_ms": settle_ms,
                       "count_window_ms": sim.count_window_ms, "seed": int(seed), "input": inp.kind,
                       "rate_hz_requested": float(rate_hz), "rate_hz_used": inp.rate_hz,
                       "input_process": input_process if events is None else "events",
                       "replay": bool(replay) if events is not None else None,
                       "merged_input_spikes": inp.merged, "codegen": sim.codegen,
                       "record_spikes": bool(record_spikes)},
        "counts": {"cells": counts["cells"], "synapses_in": syn_in,
                   "total_cells": int(sum(counts["cells"].values())),
                   "total_synapses": int(sum(syn_in.values())),
                   "brian2_synapse_objects": sim.n_synapses},
        "kept_kernel_mass": kept,
        "populations": summary,
        "timings_s": {"unroll": t_unroll, **sim.timings, "total": time.perf_counter() - t_start},
        "notes": list(net.notes),
    }
    maps = Maps(fg_x.astype(np.float32), fg_y.astype(np.float32), grouping.astype(np.float32), record, extra)
    return SpikingResult(maps, net, un, sim, inp, rates)


def run_spiking(pos=None, neg=None, events=None, sensor_size=None, params: ModelParams = ModelParams(),
                duration_ms: float = 400.0, dt_ms: float = 0.5, seed: int = 0, rate_hz: float = 200.0,
                progress: bool = True, **options) -> Maps:
    """Run the spiking figure-ground network on one window of input.

    Give either an event frame (``pos``, ``neg``: uint8 H x W, no timing; each
    pixel with an event fires at ``rate_hz`` for ``duration_ms``) or timed
    ``events`` (tonic-style structured array x, y, t [us], p) with
    ``sensor_size`` (W, H[, 2]); events keep their own timestamps and the
    window replays until ``duration_ms``.

    Returns :class:`~snn_fg.maps.Maps` (``fg_x``, ``fg_y``, ``grouping``) decoded
    from spike counts in ``[settle_ms, duration_ms)`` by the rate model's own
    readout. ``Maps.extra`` holds per population ``spikes_<pop>`` (counts per
    instantiated cell) and ``sites_<pop>`` (their flat indices into the
    population's (channels, rows, cols) grid), a raster sample
    (``raster_cell``, ``raster_t_ms``, ``raster_role``) and ``population_names``;
    ``Maps.params`` records every model, network and simulation parameter,
    cell and synapse counts, kept kernel mass, mean rates and timings.

    Options (keywords): ``network`` (:class:`NetworkParams`), ``settle_ms``
    (default: half of ``duration_ms``), ``input_process`` ('regular' | 'poisson'), ``replay`` (True),
    ``codegen`` ('auto' | 'cython' | 'numpy'), ``record_spikes`` (True),
    ``keep_connections`` (False: the unrolled synapse arrays are dropped once
    Brian2 holds them), ``log``.
    """
    return run_spiking_result(pos, neg, events, sensor_size, params, duration_ms, dt_ms, seed, rate_hz,
                              progress, **options).maps


def _raster_sample(sim: SimResult, lay, pops):
    """Spikes of up to RASTER_CELLS_PER_ROLE cells per role (level 1 first),
    chosen evenly among the cells that fired. Returns (row, t_ms, role index)."""
    chosen = []
    for ri, role in enumerate(ROLE_ORDER):
        names = sorted((n for n in lay.names if pops[n].role == role), key=lambda n: pops[n].level)
        cells = []
        for n in names:
            a, k = lay.offsets[n], lay.sizes[n]
            fired = a + np.flatnonzero(sim.counts[a:a + k] > 0)
            if fired.size == 0:
                fired = np.arange(a, a + min(k, RASTER_CELLS_PER_ROLE))
            need = RASTER_CELLS_PER_ROLE - len(cells)
            if need <= 0:
                break
            take = fired[np.linspace(0, fired.size - 1, min(need, fired.size)).astype(int)] if fired.size else fired
            cells.extend(np.unique(take).tolist())
        chosen.extend((c, ri) for c in cells[:RASTER_CELLS_PER_ROLE])
    if not chosen:
        return np.zeros(0, np.int32), np.zeros(0, np.float32), np.zeros(0, np.int16)
    cell_ids = np.array([c for c, _ in chosen])
    role_of = np.array([r for _, r in chosen])
    row_of = {c: i for i, c in enumerate(cell_ids)}
    m = np.isin(sim.spike_i, cell_ids)
    rows = np.array([row_of[c] for c in sim.spike_i[m]], dtype=np.int32)
    return rows, sim.spike_t[m].astype(np.float32), role_of[rows].astype(np.int16) if rows.size else \
        np.zeros(0, np.int16)


def spiking_window(maps: Maps, window: int | None = None) -> tuple[dict, dict, int | None]:
    """The spiking data of one frame: ``(extra, params, window)``.

    For a single frame the Maps' own ``extra`` and ``params``. For a
    recording (maps of shape ``(n_windows, H, W)``, written window by window
    by ``snn-fg run RECORDING --model spiking``) window ``window``'s part of
    every per-window array and its own parameters (cell counts, rates); by
    default the window with the most spikes.
    """
    from ..maps import window_part

    ex = maps.extra
    if "population_names" not in ex:
        raise InputError("<maps>", "no spiking data in Maps.extra (was it made by run_spiking?)")
    if maps.fg_x.ndim == 2:
        return ex, maps.params, None
    n = maps.fg_x.shape[0]
    names = [k[len("spikes_"):] for k in ex if k.startswith("spikes_") and not k.endswith("_offsets")]
    if window is None:
        totals = [sum(int(window_part(ex, f"spikes_{p}", i).sum()) for p in names) for i in range(n)]
        window = int(np.argmax(totals))
    if not 0 <= window < n:
        raise ParameterError(f"window={window}: the maps hold windows 0..{n - 1}")
    keys = {k for k in ex if not k.endswith("_offsets")}
    one = {k: window_part(ex, k, window) for k in keys}
    params = {k: v for k, v in maps.params.items() if k != "windows"}
    params.update(maps.params.get("windows", [{}] * n)[window])
    return one, params, window


def save_spiking_figures(maps_or_result, out_dir, window: int | None = None) -> list[Path]:
    """Write ``spike_raster.png`` and ``rate_histograms.png`` into ``out_dir``.

    Accepts the :class:`Maps` of :func:`run_spiking` (or a saved one loaded
    with ``Maps.load``) or a :class:`SpikingResult`. For a recording's maps
    the figures show one window (``window``; default: the one with the most
    spikes, see :func:`spiking_window`).
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..atomic import save_figure

    maps = maps_or_result.maps if isinstance(maps_or_result, SpikingResult) else maps_or_result
    if not isinstance(maps, Maps):
        raise ParameterError(f"save_spiking_figures: expected Maps or SpikingResult, got {type(maps).__name__}")
    ex, params, window = spiking_window(maps, window)
    where = "" if window is None else f" (window {window})"
    out_dir = Path(out_dir)
    names = [str(n) for n in ex["population_names"]]
    pops = params.get("populations", {})
    window_s = params.get("simulation", {}).get("count_window_ms", 1000.0) / 1000.0
    duration = params.get("simulation", {}).get("duration_ms", None)
    settle = params.get("simulation", {}).get("settle_ms", None)
    written = []

    # -- raster --------------------------------------------------------------
    fig, ax = plt.subplots(figsize=(10, 7))
    if "raster_cell" in ex and np.size(ex["raster_cell"]):
        rows = np.asarray(ex["raster_cell"])
        roles = np.asarray(ex["raster_role"])
        cmap = plt.get_cmap("tab20")
        for ri in np.unique(roles):
            m = roles == ri
            ax.scatter(np.asarray(ex["raster_t_ms"])[m], rows[m], s=1.5, color=cmap(int(ri) % 20),
                       label=ROLE_ORDER[int(ri)], marker="|")
        # role labels at the centre of each block
        for ri in np.unique(roles):
            r = rows[roles == ri]
            ax.text(1.01, (r.min() + r.max()) / 2, ROLE_ORDER[int(ri)], transform=ax.get_yaxis_transform(),
                    fontsize=7, va="center")
        ax.set_ylim(rows.max() + 1, -1)
    else:
        ax.text(0.5, 0.5, "spikes were not recorded (record_spikes=False)", ha="center", transform=ax.transAxes)
    if settle is not None:
        ax.axvline(settle, color="k", lw=0.8, ls="--")
    if duration is not None:
        ax.set_xlim(0, duration)
    ax.set_xlabel("time (ms)  [dashed: start of the counting window]")
    ax.set_ylabel(f"sampled cells (up to {RASTER_CELLS_PER_ROLE} per role, level 1 first)")
    ax.set_title(f"Spike raster by population role{where}")
    fig.tight_layout()
    written.append(save_figure(fig, out_dir / "spike_raster.png", dpi=120))
    plt.close(fig)

    # -- rate histograms per role ------------------------------------------------
    by_role: dict = {}
    for n in names:
        role = pops.get(n, {}).get("role", n)
        by_role.setdefault(role, []).append(np.asarray(ex[f"spikes_{n}"]) / window_s)
    roles = [r for r in ROLE_ORDER if r in by_role] + [r for r in by_role if r not in ROLE_ORDER]
    ncol = 4
    nrow = -(-len(roles) // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(12, 2.4 * nrow), squeeze=False)
    for ax, role in zip(axes.ravel(), roles):
        r = np.concatenate(by_role[role])
        ax.hist(r, bins=40, color="C0")
        ax.set_yscale("log")
        ax.set_title(f"{role}: mean {r.mean():.1f} Hz, {100 * (r > 0).mean():.0f}% active", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.set_xlabel("rate (Hz)", fontsize=7)
    for ax in axes.ravel()[len(roles):]:
        ax.axis("off")
    fig.suptitle(f"Firing rates per population role (all levels, counting window){where}")
    fig.tight_layout()
    written.append(save_figure(fig, out_dir / "rate_histograms.png", dpi=110))
    plt.close(fig)
    return written
