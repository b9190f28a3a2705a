"""The fast engine's neuron types: one row of constants per distinct
:class:`~snn_fg.network.nodes.Neuron` (per-step decay factors, potentials
in volts, refractory steps) and the tables of the closed-form advance over
``k`` silent steps (:func:`advance_tables`).

Potentials are held in volts, as Brian2 holds them, so that the two
simulators round the same numbers the same way.
"""

from __future__ import annotations

import numpy as np

from .stencils import MV

#: seconds per millisecond
MS = 1e-3
#: neuron-type code of spike sources (cells without LIF state)
SOURCE_TYPE = 254
#: columns of the neuron-type table: the propagators of
#: :meth:`~snn_fg.network.nodes.Neuron.propagators` (DM, DE, DI, PE, PI),
#: potentials (volts), GAP (how far above rest a parked cell may be bounded),
#: TIGHT (the inhibitory current decays no faster than the excitatory one) and
#: PEAK (the largest response of ``v`` to a unit excitatory current, ``max_k P_e(k)``)
DM, DE, DI, PE, PI, V_REST, V_RESET, V_TH, GAP, TIGHT, PEAK = range(11)
N_NRN = 11
#: a parked cell's potential bound must stay this far (V) below threshold
#: (covers rounding between the closed-form advance and step-by-step updates)
PARK_MARGIN_V = 1e-12
#: relative margin on the computed peak response (rounding of the tables)
PEAK_MARGIN = 1e-9
#: silent steps covered by one row of the advance tables (longer gaps loop)
ADVANCE_STEPS = 512


def neuron_types(network, dt_ms: float):
    """One row per distinct neuron, as Brian2's backend sets its per-cell
    constants (the exact propagators of ``Neuron.propagators``, potentials
    times ``mV``): ``(neurons, nrn, refractory steps, advance tables)``."""
    neurons = []
    for p in network.populations:
        if p.neuron is not None and p.neuron not in neurons:
            neurons.append(p.neuron)
    n = len(neurons)
    if n >= SOURCE_TYPE:
        raise ValueError(f"the fast engine handles at most {SOURCE_TYPE - 1} distinct neurons, this network has {n}")
    nrn = np.zeros((n, N_NRN))
    for t, x in enumerate(neurons):
        f = x.propagators(dt_ms)
        nrn[t, [DM, DE, DI, PE, PI]] = [f["d_m"], f["d_exc"], f["d_inh"], f["p_exc"], f["p_inh"]]
        nrn[t, V_REST : V_TH + 1] = np.array([x.v_rest_mv, x.v_reset_mv, x.v_th_mv]) * MV
    nrn[:, GAP] = nrn[:, V_TH] - nrn[:, V_REST] - PARK_MARGIN_V
    adv = advance_tables(nrn)
    nrn[:, TIGHT] = nrn[:, DI] >= nrn[:, DE]
    p_e = adv[:, 3]
    # the peak must lie inside the table (P_e falls after it); else only P_e <= 1 holds
    inside = p_e.argmax(axis=1) < p_e.shape[1] - 1
    nrn[:, PEAK] = np.where(inside, p_e.max(axis=1) * (1 + PEAK_MARGIN), 1.0)
    dt_s = dt_ms * MS
    # Brian2's refractoriness: not refractory once timestep(t - lastspike) >= timestep(t_ref)
    ref = np.array([int((x.t_ref_ms * MS + 1e-3 * dt_s) / dt_s) for x in neurons], dtype=np.int64)
    return neurons, nrn, ref, adv


def advance_tables(nrn: np.ndarray) -> np.ndarray:
    """Closed form of ``k`` silent steps of the update: with ``u = v - v_rest``,
    ``u_k = d_m^k u + I_exc P_e(k) - I_inh P_i(k)``, ``I_k = d^k I``, where
    ``P_x(k) = p_x sum_j d_m^(k-1-j) d_x^j`` (the recurrence, iterated; the
    exact propagators make ``P_x(k)`` the membrane's response at ``k dt`` to a
    unit current, hence ``0 <= P_x(k) <= 1 - d_m^k``)."""
    adv = np.zeros((nrn.shape[0], 5, ADVANCE_STEPS + 1))
    adv[:, 0:3, 0] = 1.0
    d_m = nrn[:, DM]
    for k in range(ADVANCE_STEPS):
        adv[:, 0:3, k + 1] = adv[:, 0:3, k] * nrn[:, DM : DI + 1]
        # P_x(k+1) = d_m P_x(k) + p_x d_x^k, for x = exc (rows 1, 3) and inh (rows 2, 4)
        adv[:, 3:5, k + 1] = d_m[:, None] * adv[:, 3:5, k] + nrn[:, PE : PI + 1] * adv[:, 1:3, k]
    return adv


def by_steps(adv: np.ndarray) -> np.ndarray:
    """The advance tables ordered by ``k`` (``(n_types, ADVANCE_STEPS + 1, 8)``,
    columns as the rows of :func:`advance_tables`, 3 columns of padding):
    bringing a cell ``k`` steps forward then reads one cache line, not five."""
    out = np.zeros((adv.shape[0], adv.shape[2], 8))
    out[:, :, :5] = adv.transpose(0, 2, 1)
    return out
