"""Hardware resource report of the whole network: :func:`resource_report`.

Neurons, synapses, fan-in and fan-out, delays in time steps, the weights'
dynamic range per receptor, and for SpiNNaker 1, SpiNNaker 2 and Loihi 2 the
cores, chips and boards the network needs and every documented limit it
breaks (:mod:`.hardware`). Counts are of the board network
(:func:`~snn_fg.export.board.board_network`: every cell, explicit synapses
as a PyNN connection list would hold them); on a chip with weight-shared
convolutions (Loihi 2, sPyNNaker's ``ConvolutionConnector``) the synaptic
memory is smaller, the neuron counts the same.
"""

from __future__ import annotations

import math
import textwrap

import numpy as np

from ..network.graph import Network
from ..pynn.cells import delay_steps, quantise, split_receptors
from .board import board_network, table, table_values
from .hardware import LOIHI2, SPINNAKER1, SPINNAKER2
from .spinn5 import (
    COUNTED,
    board_cores,
    boards_allocated,
    boards_needed,
    chips_estimate,
    network_cores,
    one_board_lines,
    widest_on_one_board,
)
from .synapses import projection_counts

SCHEMA = "snn-fg.resources/1"


def _weights(network: Network, pr, tab) -> dict:
    """Receptor -> (min, max) |weight| (mV = nA) the projection puts on it."""
    tgt = network.population(pr.target).neuron
    exc, mag = split_receptors(pr.sign * pr.gain_mv * table_values(tab), pr.sign, tgt.tau_exc_ms, tgt.tau_inh_ms)
    return {
        r: (float(mag[m].min()), float(mag[m].max())) for r, m in (("excitatory", exc), ("inhibitory", ~exc)) if m.any()
    }


def _lost_at(bits: int, network: Network, pr, tab) -> float:
    """Fraction of a projection's distinct weights that round to 0 at ``bits``
    bits with one scale for the projection."""
    w = pr.gain_mv * np.abs(table_values(tab))
    return float(np.mean(quantise(w, bits, w.max() / (2 ** (bits - 1) - 1)) == 0)) if w.size else 0.0


def _projection_rows(network: Network, dt_ms: float) -> list:
    rows = []
    for pr in network.projections:
        tab = table(network, pr)
        c = projection_counts(network, pr, tab)
        rows.append(
            {
                "name": pr.name,
                "type": pr.type_name,
                "source": pr.source,
                "target": pr.target,
                "synapses": c.synapses,
                "max_fan_in": c.max_fan_in,
                "max_fan_out": c.max_fan_out,
                "delay_ms": pr.delay_ms,
                "delay_steps": delay_steps(pr.delay_ms, dt_ms),
                "weights_mv": _weights(network, pr, tab),
                "lost_at_8_bits": _lost_at(8, network, pr, tab),
                "_fan_in": c.fan_in_by_channel,
                "_fan_out": c.fan_out_by_channel,
            }
        )
    return rows


def _population_rows(network: Network, prows: list) -> list:
    out = []
    for p in network.populations:
        fin = np.zeros(p.channels, np.int64)
        fout = np.zeros(p.channels, np.int64)
        weights: dict = {}
        for r in prows:
            if r["target"] == p.name:
                fin += r["_fan_in"]
                for rec, (lo, hi) in r["weights_mv"].items():
                    a, b = weights.get(rec, (math.inf, 0.0))
                    weights[rec] = (min(a, lo), max(b, hi))
            if r["source"] == p.name:
                fout += r["_fan_out"]
        out.append(
            {
                "name": p.name,
                "role": p.role,
                "level": p.level,
                "cells": p.size,
                "source": p.is_source,
                "max_fan_in": int(fin.max()),
                "max_fan_out": int(fout.max()),
                "weights_mv": {k: {"min": lo, "max": hi, "range": hi / lo} for k, (lo, hi) in weights.items()},
            }
        )
    return out


def _violation(what: str, value, limit, source: str) -> dict:
    return {"constraint": what, "value": value, "limit": limit, "source": source}


def _spinnaker1(pops, totals, cores: dict) -> dict:
    lim = SPINNAKER1
    mem_chips = math.ceil(totals["synapses"] * lim["bytes_per_synapse"].value / lim["sdram_per_chip"].value)
    boards = boards_needed(cores["cores"], mem_chips)
    bad = []
    top = lim["delay_slots"].value * lim["delay_extension"].value
    if totals["max_delay_steps"] > top:
        bad.append(_violation("delay", totals["max_delay_steps"], top, lim["delay_extension"].source))
    top16 = 2 ** lim["weight_bits"].value - 1
    wide = sorted(
        ((w["range"], f"{p['name']} {rec}") for p in pops for rec, w in p["weights_mv"].items() if w["range"] > top16),
        reverse=True,
    )
    if wide:
        bad.append(
            _violation(
                f"weight range (largest/smallest |w|) on one receptor, {len(wide)} receptors (widest: {wide[0][1]})",
                f"{wide[0][0]:.3g}",
                top16,
                lim["weight_bits"].source,
            )
        )
    return {
        "cores": cores["cores"],
        "chips": chips_estimate(cores["cores"], mem_chips, boards),
        "boards_spinn5": boards,
        "boards_allocated": boards_allocated(boards),
        "board_cores": board_cores(),
        "delay_extension_sources": cores["delay_extension_sources"],
        "violations": bad,
        "cores_by_population": cores["by_population"],
        "note": "cores: each population cut as the PyNN export builds it on sPyNNaker (256 cells a core; "
        "a population joined by convolutions in tiles whose sides divide its grid; below a 1 ms step "
        "one synapse core per core of a population that takes explicit lists), plus one "
        "delay-extension core per 256 sources of delays over 32 steps; "
        + COUNTED.removeprefix("counted: ")
        + "; synaptic memory at 4 bytes per synapse counts too (chips of 123 MB)",
    }


def _spinnaker2(pops, prows, totals) -> dict:
    lim = SPINNAKER2
    mem = totals["synapses"] * lim["bytes_per_synapse"].value + totals["neurons"] * lim["bytes_per_neuron"].value
    cores = math.ceil(mem / lim["memory_per_core"].value)
    bad = []
    if totals["distinct_delays"] > 1:
        bad.append(_violation("distinct delays", totals["distinct_delays"], 1, lim["delays"].source))
    bad += _eight_bit(prows, lim["weight_bits"].source)
    return {
        "cores": cores,
        "chips": math.ceil(cores / lim["cores_per_chip"].value),
        "violations": bad,
        "note": "cores from memory: 4 bytes per explicit synapse and 32 per neuron in 128 KB (assumed figures)",
    }


def _eight_bit(prows, source: str) -> list:
    lossy = sorted(((r["lost_at_8_bits"], r["name"]) for r in prows if r["lost_at_8_bits"] > 0), reverse=True)
    if not lossy:
        return []
    return [
        _violation(
            f"8-bit weights (one scale per projection): {len(lossy)} projections lose weights (worst: {lossy[0][1]})",
            f"{100 * lossy[0][0]:.0f} % of its distinct weights round to 0",
            "none lost",
            source,
        )
    ]


def _loihi2(pops, prows, totals, two_taus: list) -> dict:
    lim = LOIHI2
    cores = sum(math.ceil(p["cells"] / lim["neurons_per_core"].value) for p in pops if not p["source"])
    chips = max(
        math.ceil(totals["neurons"] / lim["neurons_per_chip"].value),
        math.ceil(totals["synapses"] / lim["synapses_per_chip"].value),
        math.ceil(cores / lim["cores_per_chip"].value),
    )
    bad = []
    if totals["max_delay_steps"] > lim["delay_steps"].value:
        long = sorted({r["name"] for r in prows if r["delay_steps"] > lim["delay_steps"].value})
        bad.append(
            _violation(
                f"delay ({', '.join(long[:4])}{'...' if len(long) > 4 else ''})",
                totals["max_delay_steps"],
                lim["delay_steps"].value,
                lim["delay_steps"].source,
            )
        )
    if two_taus:
        bad.append(
            _violation(
                "two synaptic time constants", f"{len(two_taus)} populations", 1, lim["synaptic_time_constants"].source
            )
        )
    bad += _eight_bit(prows, lim["weight_bits"].source)
    return {
        "cores": cores,
        "chips": chips,
        "violations": bad,
        "note": "chips: the largest of neurons/1 M, explicit synapses/120 M and cores/128 (8 k neurons per "
        "core); weight-shared convolutions need less synaptic memory",
    }


def resource_report(network: Network, dt_ms: float | None = None, sensor_shape=None) -> dict:
    """What the whole network needs and which documented limits it breaks.

    Parameters
    ----------
    network : Network
        A description (the report is of its board network).
    dt_ms : float, optional
        The time step delays are counted in (default: the network's own).
    sensor_shape : (int, int), optional
        The sensor (rows, cols) the network was made for, recorded beside
        its frame (they differ where the network pools its input).

    Returns
    -------
    dict
        ``totals``, ``populations``, ``projections`` and ``targets``
        (``spinnaker1``, ``spinnaker2``, ``loihi2``: cores, chips, boards,
        ``violations`` with limit and source); JSON data.

    Examples
    --------
    >>> from snn_fg.network import build_network
    >>> from snn_fg.params import ModelParams
    >>> rep = resource_report(build_network(ModelParams(levels=2), (40, 52)))
    >>> rep["totals"]["neurons"] > 0 and rep["targets"]["spinnaker1"]["chips"] >= 1
    True
    """
    dt_ms = network.time_step(dt_ms, "resource_report")
    net = board_network(network)
    prows = _projection_rows(net, dt_ms)
    pops = _population_rows(net, prows)
    lif = [p for p in pops if not p["source"]]
    steps = sorted({r["delay_steps"] for r in prows})
    totals = {
        "neurons": sum(p["cells"] for p in lif),
        "sources": sum(p["cells"] for p in pops if p["source"]),
        "synapses": sum(r["synapses"] for r in prows),
        "max_fan_in": max((p["max_fan_in"] for p in lif), default=0),
        "max_fan_out": max((p["max_fan_out"] for p in pops), default=0),
        "delay_steps": steps,
        "max_delay_steps": max(steps, default=0),
        "distinct_delays": len(steps),
        "weights_mv": _global_weights(lif),
    }
    two_taus = [p.name for p in net.populations if p.neuron is not None and p.neuron.tau_exc_ms != p.neuron.tau_inh_ms]
    for r in prows:
        del r["_fan_in"], r["_fan_out"]
    return {
        "schema": SCHEMA,
        "frame_shape": list(net.frame_shape),
        "sensor_shape": None if sensor_shape is None else [int(v) for v in sensor_shape],
        "input_pool": net.params.input_pool,
        "levels": net.params.levels,
        "n_ori": net.params.n_ori,
        "dt_ms": dt_ms,
        "notes": list(net.notes[-1:]),
        "totals": totals,
        "targets": {
            "spinnaker1": _spinnaker1(pops, totals, network_cores(net, dt_ms)),
            "spinnaker2": _spinnaker2(pops, prows, totals),
            "loihi2": _loihi2(pops, prows, totals, two_taus),
        },
        "populations": pops,
        "projections": prows,
    }


def largest_sensor(make, sensor_shape, dt_ms: float | None = None) -> dict | None:
    """The widest sensor of ``sensor_shape``'s aspect (rows, cols) whose network (``make(shape)``)
    fits one SpiNN-5 board, the same whatever size was asked (:func:`~.spinn5.widest_on_one_board`,
    each candidate checked by its whole report)."""
    return widest_on_one_board(make, sensor_shape, dt_ms, lambda net: resource_report(net, dt_ms)["targets"])


def _global_weights(lif) -> dict:
    out = {}
    for rec in ("excitatory", "inhibitory"):
        ws = [p["weights_mv"][rec] for p in lif if rec in p["weights_mv"]]
        if ws:
            lo, hi = min(w["min"] for w in ws), max(w["max"] for w in ws)
            out[rec] = {
                "min": lo,
                "max": hi,
                "range": hi / lo,
                "max_range_on_one_population": max(w["range"] for w in ws),
            }
    return out


#: the report table's width, in characters
TABLE_WIDTH = 100


def readable(v: float) -> str:
    """A number as a reader takes it in: ``3,000``, ``399``, ``0.00215``, ``8.72e-05``, ``4.57e+06``."""
    if 100 <= abs(v) < 1e6:
        return f"{v:,.0f}"
    return f"{v:.3g}"


def _wrapped(line: str) -> str:
    return textwrap.fill(line, TABLE_WIDTH, initial_indent="  ", subsequent_indent="      ", break_on_hyphens=False)


def report_table(rep: dict) -> str:
    """The report's headline figures as text, at most :data:`TABLE_WIDTH` characters wide."""
    t = rep["totals"]
    h, w = rep["frame_shape"]
    pool = rep.get("input_pool", 1)
    if rep.get("sensor_shape"):
        h, w = rep["sensor_shape"]
    what = f"a {w} x {h} sensor" if pool == 1 or rep.get("sensor_shape") else f"{w} x {h} blocks of a sensor"
    lines = [
        f"Whole network for {what} (width x height), {rep['levels']} levels, "
        f"{rep['n_ori']} orientations, dt {rep['dt_ms']:g} ms"
    ]
    if pool > 1:
        lines.append(
            f"  the sensor seen in {pool} x {pool} blocks: a {rep['frame_shape'][1]} x {rep['frame_shape'][0]} frame"
        )
    lines += [
        f"  neurons {t['neurons']:,}   spike sources {t['sources']:,}   synapses {t['synapses']:,}",
        f"  max fan-in {t['max_fan_in']:,}   max fan-out {t['max_fan_out']:,}   delays (steps) "
        f"{', '.join(str(d) for d in t['delay_steps'])}",
    ]
    for rec, wr in t["weights_mv"].items():
        lines.append(
            f"  {rec} weights {readable(wr['min'])} to {readable(wr['max'])} mV: range "
            f"{readable(wr['range'])} ({readable(wr['max_range_on_one_population'])} on one population)"
        )
    for name, tg in rep["targets"].items():
        size = f"cores {tg['cores']:,}   chips {tg['chips']:,}"
        if "boards_spinn5" in tg:
            size += f"   SpiNN-5 boards {tg['boards_spinn5']:,}"
            if tg["boards_allocated"] != tg["boards_spinn5"]:
                size += f" (a machine of {tg['boards_allocated']:,})"
        if not tg["violations"]:
            size += "   no limit broken"
        lines.append(f"{name:11s} {size}")
        for v in tg["violations"]:
            value, limit = (readable(x) if isinstance(x, (int, float)) else x for x in (v["value"], v["limit"]))
            lines.append(_wrapped(f"violates {v['constraint']}: {value} (limit {limit}; {v['source']})"))
        notes = [COUNTED] if "boards_spinn5" in tg else []
        if tg.get("largest_sensor_one_board"):
            notes += one_board_lines(tg["largest_sensor_one_board"])
        lines += [_wrapped(n) for n in notes]
    return "\n".join(lines)


def spinnaker_estimate(network: Network, dt_ms: float | None = None) -> dict:
    """The report's SpiNNaker 1 figures for ``network`` at ``dt_ms`` steps (cores, chips, boards,
    cores per population, how they were counted): what an export's ``spinnaker.json`` holds beside
    :func:`~snn_fg.export.spinnaker.spinnaker_plan`, and ``run.py --virtual-board`` sets beside
    sPyNNaker's own mapping."""
    sp = resource_report(network, dt_ms)["targets"]["spinnaker1"]
    return {k: v for k, v in sp.items() if k in ("cores", "chips", "boards_spinn5", "cores_by_population", "note")}
