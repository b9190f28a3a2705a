"""What a spiking run keeps beside its maps: :class:`SpikingRecord`, and its
run provenance (:func:`run_provenance`).

Per simulated population the spike count of every cell that fired and
where that cell sits (a silent cell is only counted, in the summary: a
recording's network has millions of cells, most of them silent in any
window), a raster sample, the input masks and a summary (cells, rates,
synapses). :meth:`SpikingRecord.arrays` is its part of ``maps.npz``;
:meth:`SpikingRecord.from_maps` reads it back (for a recording, one window's
part), strictly: a missing key is an error, not a default.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numba import njit

from ...backends.base import SimulationResult
from ...errors import InputError
from ...network.graph import Network
from ...network.roles import ROLE_ORDER
from ...results.maps import window_part
from ...validate import integer

#: cells of each role whose spike times the raster sample keeps
RASTER_CELLS_PER_ROLE = 30
_NAMES = "population_names"
_RASTER = ("raster_cell", "raster_t_ms", "raster_role")


@dataclass
class Raster:
    """Spikes of up to :data:`RASTER_CELLS_PER_ROLE` cells per role: row of
    the sampled cell, time (ms) and role (index into
    :data:`~snn_fg.network.roles.ROLE_ORDER`)."""

    row: np.ndarray
    t_ms: np.ndarray
    role: np.ndarray


@dataclass
class SpikingRecord:
    """Spike counts and cells of one spiking run (or one window of a recording)."""

    names: list
    counts: dict  # population -> int32 spikes of each cell that fired (maps saved by
    #                            earlier versions hold every instantiated cell, silent ones with 0)
    sites: dict  # population -> int64 flat index of each in its (channels, rows, cols)
    raster: Raster | None
    input_on: np.ndarray  # uint8 (H, W): pixels that received ON input
    input_off: np.ndarray
    count_window_ms: float
    duration_ms: float
    settle_ms: float
    populations: dict  # population -> summary (role, level, cells, rates, synapses)

    def rates(self, name: str) -> np.ndarray:
        """Firing rate (Hz) of each cell in :attr:`counts`."""
        return self.counts[name] / (self.count_window_ms / 1000.0)

    def all_rates(self, name: str) -> np.ndarray:
        """Firing rates of every instantiated cell, the silent ones as 0
        (in no particular order: for distributions)."""
        r = self.rates(name)
        silent = max(int(self.populations[name]["cells"]) - int(np.count_nonzero(r)), 0)
        return np.concatenate([r[r > 0], np.zeros(silent)])

    @classmethod
    def from_result(cls, result, inputs, settle_ms: float, cells: bool = True) -> SpikingRecord:
        """Summarise a :class:`~snn_fg.backends.SimulationResult` fed by
        ``inputs``; ``cells=False`` leaves the per-cell counts out (a
        recording's windows whose counts are not kept), the summary in."""
        names = result.populations
        syn = result.stats.get("synapses_in", {})
        per_s = 1000.0 / result.count_window_ms
        summary = {}
        for name, (size, total, active, most) in zip(names, count_summary(result.counts, names), strict=True):
            p = result.network.population(name)
            summary[name] = {
                "role": p.role,
                "level": p.level,
                "cells": size,
                "mean_rate_hz": float(total) / size * per_s if size else 0.0,
                "active_frac": active / size if size else 0.0,
                "max_rate_hz": float(most) * per_s if size else 0.0,
                "refractory_max_hz": p.neuron.max_rate_hz,
                "synapses_in": int(syn.get(name, 0)) if syn else None,
            }
        fired = {n: np.flatnonzero(result.counts[n]) for n in names} if cells else {}
        return cls(
            names=names,
            counts={n: result.counts[n][f].astype(np.int32) for n, f in fired.items()},
            sites={n: result.sites[n][f].astype(np.int64) for n, f in fired.items()},
            raster=_sample_raster(result) if result.spikes is not None else None,
            input_on=inputs.on.astype(np.uint8),
            input_off=inputs.off.astype(np.uint8),
            count_window_ms=result.count_window_ms,
            duration_ms=result.simulated_ms,
            settle_ms=settle_ms,
            populations=summary,
        )

    def arrays(self) -> dict:
        """The record's part of ``maps.npz`` (none where the cells were left out)."""
        if self.names and not self.counts:
            return {}
        out = {_NAMES: np.array(self.names), "input_on": self.input_on, "input_off": self.input_off}
        for n in self.names:
            out[f"spikes_{n}"] = self.counts[n]
            out[f"sites_{n}"] = self.sites[n]
        if self.raster is not None:
            out.update(zip(_RASTER, (self.raster.row, self.raster.t_ms, self.raster.role)))
        return out

    def timing(self) -> dict:
        """The record's entries of ``params["simulation"]``."""
        return {"duration_ms": self.duration_ms, "settle_ms": self.settle_ms, "count_window_ms": self.count_window_ms}

    @classmethod
    def from_maps(cls, maps, window: int | None = None) -> tuple[SpikingRecord, int | None]:
        """The record stored with ``maps`` and the window it belongs to.

        For one frame ``window`` is ``None``. For a recording's maps (shape
        ``(n_windows, H, W)``) it is that window's record; by default the
        window with the most spikes.
        """
        ex = maps.extra
        if _NAMES not in ex:
            raise InputError("<maps>", "holds no spiking record (was it made by the spiking model?)")
        params = maps.params
        if maps.fg_x.ndim == 3:
            n = maps.fg_x.shape[0]
            names = [str(x) for x in np.atleast_1d(window_part(ex, _NAMES, 0))]
            if window is None:
                totals = [sum(int(window_part(ex, f"spikes_{p}", i).sum()) for p in names) for i in range(n)]
                window = int(np.argmax(totals))
            integer("SpikingRecord.from_maps", "window", window, lo=0, hi=n - 1)
            ex = {k: window_part(ex, k, window) for k in ex if not k.endswith("_offsets")}
            params = {**params, **params.get("windows", [{}] * n)[window]}
        try:
            sim = params["simulation"]
            names = [str(x) for x in np.atleast_1d(ex[_NAMES])]
            raster = Raster(*(np.asarray(ex[k]) for k in _RASTER)) if _RASTER[0] in ex else None
            rec = cls(
                names=names,
                counts={n: np.asarray(ex[f"spikes_{n}"]) for n in names},
                sites={n: np.asarray(ex[f"sites_{n}"]) for n in names},
                raster=raster,
                input_on=np.asarray(ex["input_on"]),
                input_off=np.asarray(ex["input_off"]),
                count_window_ms=float(sim["count_window_ms"]),
                duration_ms=float(sim["duration_ms"]),
                settle_ms=float(sim["settle_ms"]),
                populations=params["populations"],
            )
        except KeyError as exc:
            raise InputError("<maps>", f"spiking record is incomplete: {exc.args[0]!r} is missing") from None
        return rec, (window if maps.fg_x.ndim == 3 else None)


def _sample_raster(result) -> Raster:
    """Up to RASTER_CELLS_PER_ROLE cells per role (level 1 first), chosen evenly
    among the cells that fired (the first cells where none did)."""
    rows, times, roles = [], [], []
    row0 = 0
    for ri, role in enumerate(ROLE_ORDER):
        names = sorted(result.of_role(role), key=lambda n: result.network.population(n).level)
        taken = 0
        for name in names:
            need = RASTER_CELLS_PER_ROLE - taken
            if need <= 0:
                break
            counts = result.counts[name]
            fired = np.flatnonzero(counts > 0)
            if fired.size == 0:
                fired = np.arange(min(counts.size, RASTER_CELLS_PER_ROLE))
            cells = (
                np.unique(fired[np.linspace(0, fired.size - 1, min(need, fired.size)).astype(int)])
                if fired.size
                else fired
            )
            cell, t_ms = result.spikes[name]
            keep = np.isin(cell, cells)
            rows.append(row0 + taken + np.searchsorted(cells, cell[keep]))
            times.append(t_ms[keep])
            roles.append(np.full(int(keep.sum()), ri))
            taken += cells.size
        row0 += taken
    if not rows:
        return Raster(np.zeros(0, np.int32), np.zeros(0, np.float32), np.zeros(0, np.int16))
    return Raster(
        np.concatenate(rows).astype(np.int32),
        np.concatenate(times).astype(np.float32),
        np.concatenate(roles).astype(np.int16),
    )


def run_provenance(
    net: Network, origin: dict, backend, result: SimulationResult, populations: dict, simulation: dict, t_start: float
) -> dict:
    """The run provenance (``Maps.params``) of a spiking run: model
    parameters, where the network came from, the backend, the simulation settings, cell and synapse counts,
    per-population summaries, timings and the network's notes."""
    syn = result.stats.get("synapses_in", {})
    return {
        "model": "spiking",
        **net.params.to_dict(),
        "network": {**origin, "frame_shape": list(net.frame_shape), "input_rate_hz": net.input_rate_hz},
        "backend": backend.describe(),
        "simulation": simulation,
        "counts": {
            "cells": {n: int(s.size) for n, s in result.sites.items()},
            # (None where the backend makes no synapses: the fast engine follows shared kernels)
            "synapses_in": {n: int(syn.get(n, 0)) if syn else None for n in result.sites},
            "total_cells": result.total_cells,
            "total_synapses": int(sum(syn.values())) if syn else None,
            "backend_objects": result.stats.get("backend_objects", {}),
        },
        "kept_kernel_mass": result.stats.get("kept_kernel_mass", {}),
        # the backend's own counters (fast: synaptic events, spikes, cells updated)
        "backend_stats": {k: v for k, v in result.stats.items() if isinstance(v, (int, float))},
        "populations": populations,
        "timings_s": {**result.timings_s, "total": time.perf_counter() - t_start},
        "notes": list(net.notes),
    }


def count_summary(counts, names) -> list[tuple[int, int, int, int]]:
    """For each population of ``names``: its cells, their spikes, the cells
    that fired and the most spikes of one cell (``counts``: population -> the
    spikes of each cell, integers), in one compiled pass over every cell. The
    counts of a window read as a run goes are slices of one array
    (:class:`~snn_fg.models.spiking.window_reader.WindowCounts`), read there."""
    flat = getattr(counts, "flat", None)
    if flat is None:
        arrays = [np.asarray(counts[n]).reshape(-1) for n in names]
        stops = np.cumsum([a.size for a in arrays], dtype=np.int64)
        starts = stops - np.array([a.size for a in arrays], np.int64)
        flat = np.concatenate(arrays) if arrays else np.zeros(0, np.int64)
    else:
        starts = np.array([counts.parts[n].start for n in names], np.int64)
        stops = np.array([counts.parts[n].stop for n in names], np.int64)
    out = np.zeros((len(names), 3), np.int64)
    _segment_summary(flat, starts, stops, out)
    return [(int(b - a), int(t), int(k), int(m)) for a, b, (t, k, m) in zip(starts, stops, out, strict=True)]


@njit(cache=True, nogil=True)
def _segment_summary(flat, starts, stops, out):
    """``out[q]``: the sum, the non-zero values and the largest value of ``flat[starts[q]:stops[q]]``."""
    for q in range(starts.size):
        # (a slice walked from 0, with no branch: it runs over ~1e6 cells a window and
        # compiles to vector code, 0.16 ms in place of 1.1 ms)
        seg = flat[starts[q] : stops[q]]
        total, active, most = 0, 0, 0
        if seg.size:
            most = seg[0]
        for x in range(seg.size):
            v = seg[x]
            total += v
            active += v != 0
            most = max(most, v)
        out[q, 0], out[q, 1], out[q, 2] = total, active, most
