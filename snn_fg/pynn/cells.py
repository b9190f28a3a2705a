"""Our cells and synapses in PyNN's terms: a neuron's ``IF_curr_exp``
parameters, the receptor and magnitude of each signed weight, weights rounded
to a board's bits, delays on the time grid, sPyNNaker's list rows, and spike
counts from what a simulator recorded.

Neuron mapping (PyNN ``IF_curr_exp``, ``cm dv/dt = cm (v_rest - v)/tau_m +
I``): ``cm`` in nF is set numerically equal to ``tau_m`` in ms, so the
membrane resistance is 1 MOhm and a synaptic weight of ``w`` nA moves the
membrane like our ``w`` mV (``tau_m dv/dt = v_rest - v + I_exc - I_inh``).

Receptors: a synapse's *drive* is ``sign * gain_mv * K`` (positive:
depolarising). PyNN's current synapses take only positive weights per
receptor, so a positive drive goes to the excitatory receptor and a negative
one to the inhibitory receptor. Where that is not the projection's own
receptor (the negative lobes of a DoG or bicubic kernel on an excitatory
projection), the magnitude is scaled by ``tau_own / tau_other`` so that the
synapse delivers the same charge (the same mean current) through the other
time constant.

Refractoriness: in our description a cell that fires in step ``n`` may fire
again in step ``n + R`` (``R = t_ref / dt``; the rate ceiling is
``1 / t_ref``, as in Brian2). NEST and sPyNNaker hold the membrane for
``tau_refrac / dt`` whole steps after the step of the spike, so the earliest
next spike is one step later than ours; ``tau_refrac`` is therefore
``t_ref - dt`` (:func:`cell_parameters`).

STANDALONE, as the rest of :mod:`snn_fg.pynn`: numpy and the standard library
only; an export carries it as ``fg_cells.py``.
"""

from __future__ import annotations

import numpy as np


def cell_parameters(neuron: dict, dt_ms: float) -> dict:
    """PyNN ``IF_curr_exp`` parameters of one of our CUBA LIF neurons
    (``tau_m_ms``, ``tau_exc_ms``, ``tau_inh_ms``, ``v_rest_mv``,
    ``v_reset_mv``, ``v_th_mv``, ``t_ref_ms``) simulated with time step
    ``dt_ms`` (the refractory period is one step shorter: module docstring)."""
    ref_steps = max(int(round(float(neuron["t_ref_ms"]) / dt_ms)) - 1, 0)
    return {
        "cm": float(neuron["tau_m_ms"]),
        "tau_m": float(neuron["tau_m_ms"]),
        "tau_syn_E": float(neuron["tau_exc_ms"]),
        "tau_syn_I": float(neuron["tau_inh_ms"]),
        "v_rest": float(neuron["v_rest_mv"]),
        "v_reset": float(neuron["v_reset_mv"]),
        "v_thresh": float(neuron["v_th_mv"]),
        "tau_refrac": ref_steps * dt_ms,
        "i_offset": 0.0,
    }


def split_receptors(drive: np.ndarray, sign: int, tau_exc_ms: float, tau_inh_ms: float):
    """Receptor and weight of each synapse: ``(excitatory mask, |weight|)``.

    ``drive`` is the signed weight in mV (positive depolarises). A synapse
    whose drive opposes its projection's ``sign`` moves to the other receptor
    with its magnitude scaled by ``tau_own / tau_other`` (same charge).
    """
    drive = np.asarray(drive, dtype=np.float64)
    exc = drive > 0
    mag = np.abs(drive)
    if sign > 0:
        mag = np.where(exc, mag, mag * tau_exc_ms / tau_inh_ms)
    else:
        mag = np.where(exc, mag * tau_inh_ms / tau_exc_ms, mag)
    return exc, mag


def quantise(values: np.ndarray, bits: int | None, scale: float) -> np.ndarray:
    """``values`` rounded to signed ``bits``-bit integers times ``scale``
    (``scale``: the projection's largest |value| over ``2**(bits-1) - 1``);
    unchanged for ``bits=None``."""
    if bits is None or scale <= 0:
        return np.asarray(values, dtype=np.float64)
    top = 2 ** (int(bits) - 1) - 1
    return np.clip(np.round(np.asarray(values) / scale), -top, top) * scale


def grid_delay(delay_ms: float, dt_ms: float) -> float:
    """A delay on the simulation grid, at least one step (NEST's rule)."""
    return delay_steps(delay_ms, dt_ms) * dt_ms


def delay_steps(delay_ms: float, dt_ms: float) -> int:
    """A delay in whole time steps, at least one (:func:`grid_delay` in steps)."""
    return max(1, int(round(delay_ms / dt_ms)))


def list_rows(pre, post, w, delay) -> np.ndarray:
    """``FromListConnector`` rows ``(pre, post, weight, delay)`` sorted by
    source, then target: sPyNNaker 7.4.1 sizes its synaptic rows by grouping
    the list by source and target, and splits the list as given at the group
    boundaries of the sorted one (``FromListConnector.__numpy_group``), so an
    unsorted list gets wrong row lengths (846 synapses in a row of at most
    152 on a 32 x 24 export, refused as over sPyNNaker's 256)."""
    pre, post = np.asarray(pre, np.int64), np.asarray(post, np.int64)
    order = np.lexsort((post, pre))
    return np.column_stack([pre[order], post[order], np.asarray(w)[order], np.full(pre.size, delay)])


def population_spikes(pop):
    """``(cell, t_ms)`` of every spike a PyNN population recorded, as the simulator stamped them."""
    trains = pop.get_data("spikes").segments[0].spiketrains
    cell = np.concatenate([np.full(len(s), i, np.int64) for i, s in enumerate(trains)] or [np.zeros(0, np.int64)])
    t = np.concatenate([np.asarray(s.magnitude, np.float64) for s in trains] or [np.zeros(0)])
    return cell, t


def counts_in(cell: np.ndarray, t_ms: np.ndarray, size: int, start_ms: float, end_ms: float) -> np.ndarray:
    """Spikes per cell with ``start_ms <= t < end_ms``."""
    inside = (t_ms >= start_ms - 1e-9) & (t_ms < end_ms - 1e-9)
    return np.bincount(cell[inside], minlength=size).astype(np.int64)
