"""The fast engine's view of a network: flat arrays built once per
description and time step (:func:`build_tables`), never one per synapse.

* cells: every cell of every population gets a global number
  ``offset(population) + flat index`` (flat index into its
  ``(channels, rows, cols)`` grid); spike sources are numbered too, so that
  a spike is one integer whatever emits it;
* neuron types: one row of constants per distinct :class:`~snn_fg.network.Neuron`
  (per-step decay factors, potentials in volts, refractory steps) and the
  tables of the closed-form advance over ``k`` silent steps;
* projections: a Conv is its kept kernel taps per input channel (exactly
  those :func:`~snn_fg.lowering.connect.kernel_taps` keeps), a Resize its two
  interpolation matrices transposed (:func:`~snn_fg.lowering.connect.resize_factors`),
  the weight of a synapse being computed when a spike passes.

Potentials and weights are held in volts, as Brian2 holds them, so that the
two simulators round the same numbers the same way.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ...lowering.connect import kernel_taps, resize_factors, resize_kept_mass
from ...network.graph import Network
from ...network.projections import Conv
from ...pynn.cells import quantise
from ..base import receptor, receptor_weights

#: volts per millivolt (Brian2's ``mV``): weights and potentials are scaled
#: by it exactly as Brian2 scales them
MV = 1e-3
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
#: columns of the population table
P_OFF, P_CH, P_GR, P_GC, P_STRIDE, P_LR, P_LC, P_TYPE, P_SIZE = range(9)
#: columns of the projection table
(J_KIND, J_SRC, J_TGT, J_COL, J_DELAY, J_WRAP, J_BASE, J_COLBASE, J_PRUNE, J_INH, J_RADIUS, J_DENSE, J_KR, J_GBASE) = (
    range(14)
)
CONV, RESIZE = 0, 1


@dataclass
class EngineTables:
    """Everything the engine needs about one network at one time step."""

    network: Network
    dt_ms: float
    offsets: dict  # population name -> first global cell number
    pops: np.ndarray  # int64 (n_populations, 9), columns P_*
    n_cells: int
    nrn: np.ndarray  # float64 (n_types, N_NRN), columns DM..PEAK, volts
    ref_steps: np.ndarray  # int64 (n_types,)
    adv: np.ndarray  # float64 (n_types, 5, ADVANCE_STEPS + 1): d_m^k, d_e^k, d_i^k, P_e(k), P_i(k)
    prj: np.ndarray  # int64 (n_projections, 14), columns J_*
    prj_w: np.ndarray  # float64 (n_projections, 3): sign * gain (mV), prune threshold of a Resize,
    #                          and its quantisation step (interpolation products rounded to it; 0: exact)
    ch_ptr: np.ndarray  # int64: Conv taps of input channel c, residues (a, b) modulo the target
    tap_co: np.ndarray  #   stride s, of projection p are ch_ptr[i] .. ch_ptr[i + 1], i = base + (c s + a) s
    tap_qr: np.ndarray  #   + b, of tap_co (output channel), tap_qr, tap_qc (the target lattice point is
    tap_qc: np.ndarray  #   the source's level pixel // s - (qr, qc)), tap_w (volts added to the
    tap_w: np.ndarray  #   receptor) and tap_off (flat offset, for sources whose whole footprint lies
    tap_off: np.ndarray  #   inside the level)
    dense: np.ndarray  # float64: a Conv's weights by level offset, (C_out, C_in, 2R+1, 2R+1) from
    #                          dense[J_DENSE], R = J_KR (0 where there is no tap)
    pair_ptr: np.ndarray  # int64: the output channels input channel c reaches, with their row offset
    pair_co: np.ndarray  #   ranges: pair_ptr[J_GBASE + c] .. [+1] of pair_co, pair_rlo, pair_rhi
    pair_rlo: np.ndarray
    pair_rhi: np.ndarray
    csr_ptr: np.ndarray  # int64: Resize rows/cols: source index s of a factor starting at
    csr_idx: np.ndarray  #   base has targets csr_idx[csr_ptr[base + s]:csr_ptr[base + s + 1]]
    csr_val: np.ndarray  #   with interpolation weights csr_val
    grp_ptr: np.ndarray  # int64: projections feeding one (target population, current) are
    grp_prj: np.ndarray  #   grp_prj[grp_ptr[k]:grp_ptr[k + 1]] (their input is summed, then delivered)
    kept_mass: dict  # projection name -> kept fraction of its kernel mass
    taps: dict  # projection name -> kept taps (Conv) or interpolation weights (Resize)
    tap_k: np.ndarray  # float64: each tap's kernel value before the gain (tap_w is made from it)
    dense_k: np.ndarray  # float64: the same for ``dense``
    spans: np.ndarray  # int64 (n_projections, 4): a Conv's taps tap_*[a:b] and dense[c:d]

    def with_gains(self, network: Network) -> "EngineTables":
        """These tables for ``network``, which must differ from
        :attr:`network` in projection gains only (:func:`gains_only`), e.g.
        the same description calibrated for another input rate: the weights
        are made again from the kept kernel values, as :func:`build_tables`
        makes them, and nothing else is recomputed."""
        tap_w, dense, prj_w = self.tap_w.copy(), self.dense.copy(), self.prj_w.copy()
        for p, pr in enumerate(network.projections):
            prj_w[p, 0] = pr.sign * pr.gain_mv
            if isinstance(pr, Conv):
                a, b, c, d = self.spans[p]
                tap_w[a:b] = tap_weights(pr, self.tap_k[a:b])
                dense[c:d] = tap_weights(pr, self.dense_k[c:d])
        return dataclasses.replace(self, network=network, tap_w=tap_w, dense=dense, prj_w=prj_w)

    @property
    def taps_per_row(self) -> np.ndarray:
        """Per projection: the taps a spike follows (those of its stride
        residue class) per target row its kernel covers (0 for a Resize)."""
        out = np.zeros(self.prj.shape[0])
        for p, pr in enumerate(self.network.projections):
            if self.prj[p, J_KIND] != CONV:
                continue
            g0 = self.prj[p, J_GBASE]
            c_in, st = self.pops[self.prj[p, J_SRC], P_CH], self.pops[self.prj[p, J_TGT], P_STRIDE]
            rows = (
                self.pair_rhi[self.pair_ptr[g0] : self.pair_ptr[g0 + c_in]]
                - self.pair_rlo[self.pair_ptr[g0] : self.pair_ptr[g0 + c_in]]
                + 1
            )
            out[p] = self.taps[pr.name] / st**2 / max(rows.sum() / st, 1)
        return out

    @property
    def max_fanout(self) -> int:
        """Most synaptic events one spike can cause through one projection."""
        conv = int(np.diff(self.ch_ptr).max()) if self.ch_ptr.size > 1 else 0
        csr = int(np.diff(self.csr_ptr).max()) if self.csr_ptr.size > 1 else 0
        conv_out = [self.network.population(pr.target).channels for pr in self.network.projections]
        footprint = int(max(c * (2 * r + 1) ** 2 for c, r in zip(conv_out, self.prj[:, J_KR]))) if conv_out else 0
        return max(conv, csr * csr, footprint, 1)


def _neuron_types(network: Network, dt_ms: float):
    """One row per distinct neuron, as Brian2's backend sets its per-cell
    constants (the exact propagators of ``Neuron.propagators``, potentials
    times ``mV``)."""
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


def _populations(network: Network, neurons):
    rows, offsets, off = [], {}, 0
    for p in network.populations:
        offsets[p.name] = off
        kind = SOURCE_TYPE if p.is_source else neurons.index(p.neuron)
        rows.append([off, p.channels, *p.grid, p.stride, *p.level_shape, kind, p.size])
        off += p.size
    return offsets, np.array(rows, dtype=np.int64).reshape(-1, 9), off


def _transposed(a: np.ndarray):
    """CSR of ``a.T``: for each source index, its target indices and weights."""
    tgt, src = np.nonzero(a)
    order = np.lexsort((tgt, src))
    ptr = np.searchsorted(src[order], np.arange(a.shape[1] + 1))
    return ptr, tgt[order], a[tgt[order], src[order]]


class _Collector:
    """Concatenates the per-projection tap and CSR arrays."""

    def __init__(self):
        self.ch_ptr, self.taps, self.csr = [np.zeros(1, np.int64)], [], [[np.zeros(1, np.int64)], [], []]
        self.n_ch, self.n_taps, self.n_csr_rows, self.n_csr = 0, 0, 0, 0
        self.dense, self.dense_k, self.n_dense = [], [], 0
        self.pair_ptr, self.pairs, self.n_pair_ch, self.n_pairs = [np.zeros(1, np.int64)], [], 0, 0

    def dense_kernel(self, co, ci, dr, dc, k, pr, c_out: int, c_in: int):
        """The taps as a dense array by level offset, and per input channel
        the output channels it reaches with their row-offset range."""
        r = int(max(np.abs(dr).max(), np.abs(dc).max())) if dr.size else 0
        size = 2 * r + 1
        kd = np.zeros((c_out, c_in, size, size))
        kd[co, ci, dr + r, dc + r] = k
        base = self.n_dense
        self.dense_k.append(kd.ravel())
        self.dense.append(tap_weights(pr, kd.ravel()))
        self.n_dense += kd.size
        # (input, output) channel pairs in order, with the row-offset range of their taps
        key = np.asarray(ci, np.int64) * c_out + np.asarray(co, np.int64)
        uniq, inv = np.unique(key, return_inverse=True)
        lo = np.full(uniq.size, np.iinfo(np.int64).max)
        hi = np.full(uniq.size, np.iinfo(np.int64).min)
        np.minimum.at(lo, inv.ravel(), dr)
        np.maximum.at(hi, inv.ravel(), dr)
        pairs = len(uniq)
        counts = np.bincount(uniq // c_out, minlength=c_in)
        gbase = self.n_pair_ch
        self.pair_ptr.append(np.cumsum(counts) + self.n_pairs)
        self.pairs.append(np.stack([uniq % c_out, lo, hi], axis=1).astype(np.int64).reshape(-1, 3))
        self.n_pair_ch += c_in
        self.n_pairs += pairs
        return base, r, gbase

    def conv(self, ch_ptr, co, qr, qc, k, w, off):
        base = self.n_ch
        self.ch_ptr.append(ch_ptr[1:] + self.n_taps)
        self.taps.append((co, qr, qc, w, off, k))
        self.n_ch += ch_ptr.size - 1
        self.n_taps += co.size
        return base

    def factor(self, a: np.ndarray):
        ptr, idx, val = _transposed(a)
        base = self.n_csr_rows
        self.csr[0].append(ptr[1:] + self.n_csr)
        self.csr[1].append(idx)
        self.csr[2].append(val)
        self.n_csr_rows += ptr.size - 1
        self.n_csr += idx.size
        return base

    def arrays(self) -> dict:
        taps = [np.concatenate([t[i] for t in self.taps]) if self.taps else np.zeros(0) for i in range(6)]
        csr = [np.concatenate(x) if x else np.zeros(0) for x in self.csr]
        pairs = np.concatenate(self.pairs) if self.pairs else np.zeros((0, 3), np.int64)
        return {
            "ch_ptr": np.concatenate(self.ch_ptr).astype(np.int64),
            "tap_co": taps[0].astype(np.int32),
            "tap_qr": taps[1].astype(np.int32),
            "tap_qc": taps[2].astype(np.int32),
            "tap_w": taps[3].astype(np.float64),
            "tap_off": taps[4].astype(np.int64),
            "tap_k": taps[5].astype(np.float64),
            "dense": np.concatenate(self.dense) if self.dense else np.zeros(1),
            "dense_k": np.concatenate(self.dense_k) if self.dense_k else np.zeros(1),
            "pair_ptr": np.concatenate(self.pair_ptr).astype(np.int64),
            "pair_co": pairs[:, 0].copy(),
            "pair_rlo": pairs[:, 1].copy(),
            "pair_rhi": pairs[:, 2].copy(),
            "csr_ptr": csr[0].astype(np.int64),
            "csr_idx": csr[1].astype(np.int32),
            "csr_val": csr[2].astype(np.float64),
        }


def quantised_values(k: np.ndarray, peak: float, weight_bits: int | None) -> np.ndarray:
    """Kernel values as the ``weight_bits``-bit weights a board holds: one
    scale per projection, its largest |value| ``peak`` over ``2**(bits-1) - 1``
    (:func:`snn_fg.lowering.quantise.projection_scales`); unchanged for None."""
    if weight_bits is None:
        return k
    return quantise(k, weight_bits, peak / (2 ** (weight_bits - 1) - 1))


def _conv(network, pr, src, tgt, out: _Collector, weight_bits=None):
    """A Conv's kept taps, grouped by input channel and by the residues of
    the tap offset modulo the target's stride (a source at level pixel ``p``
    reaches the target lattice only through the taps with ``d = p (mod
    stride)``, and those land on lattice point ``p // stride - q`` with
    ``q = (d - d mod stride) / stride``), each group sorted by ``q`` (rows
    first) so that the taps landing inside the level form a range.

    A wrap-around kernel larger than the level folds onto it: its taps are
    taken modulo the level and those landing on the same cell add up, as
    the unrolled synapses do (:func:`~snn_fg.lowering.connect.conv_pairs`)."""
    co, ci, dr, dc, k, kept = kernel_taps(pr, network)
    if weight_bits is not None:
        k = quantised_values(k, float(np.abs(pr.kernel.array(network.params)).max()), weight_bits)
        co, ci, dr, dc, k = (a[k != 0] for a in (co, ci, dr, dc, k))
    dense = out.dense_kernel(co, ci, dr, dc, k, pr, tgt.channels, src.channels)
    st = tgt.stride
    gr, gc = tgt.grid
    rr, rc = dr % st, dc % st
    qr, qc = (dr - rr) // st, (dc - rc) // st
    cls = (ci * st + rr) * st + rc
    radius = int(max(np.abs(qr).max(), np.abs(qc).max())) if qr.size else 0
    if pr.padding == "wrap" and 2 * radius + 1 > min(gr, gc):  # (wrap-around: stride 1, cls = ci)
        co, cls, qr, qc, k = _fold(co, cls, qr % gr, qc % gc, k)
        radius = max(gr, gc)  # never entirely inside the level
    order = np.lexsort((qc, qr, cls))
    co, qr, qc, k, cls = co[order], qr[order], qc[order], k[order], cls[order]
    ch_ptr = np.searchsorted(cls, np.arange(src.channels * st * st + 1))
    off = co.astype(np.int64) * gr * gc - qr * gc - qc
    base = out.conv(ch_ptr, co, qr, qc, k, tap_weights(pr, k), off)
    return base, 0, kept, int(co.size), radius, dense


def tap_weights(pr, k: np.ndarray) -> np.ndarray:
    """What a Conv's taps with kernel values ``k`` add to their receptor (volts)."""
    return receptor_weights(pr.sign, pr.sign * pr.gain_mv * k) * MV


def gains_only(a: Network, b: Network) -> bool:
    """Whether two networks differ at most in projection gains (and the
    input rate they are calibrated for): then the engine's tables of one
    serve the other after :meth:`EngineTables.with_gains`."""

    def rest(pr):
        return type(pr), {k: v for k, v in vars(pr).items() if k != "gain_mv"}

    return (
        a.params == b.params
        and a.frame_shape == b.frame_shape
        and a.populations == b.populations
        and len(a.projections) == len(b.projections)
        and all(x is y or rest(x) == rest(y) for x, y in zip(a.projections, b.projections))
    )


def _fold(co, ci, qr, qc, k):
    """Taps with the same channels and (folded) offset merged, their values summed."""
    key = np.stack([co, ci, qr, qc], axis=1)
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    total = np.bincount(inv.ravel(), weights=k, minlength=len(uniq))
    keep = total != 0
    return uniq[keep, 0], uniq[keep, 1], uniq[keep, 2], uniq[keep, 3], total[keep]


def _resize(pr, src, tgt, out: _Collector, weight_bits=None):
    ar, ac, peak = resize_factors(pr, src, tgt)
    base, colbase = out.factor(ar), out.factor(ac)
    taps = int(np.count_nonzero(ar)) * int(np.count_nonzero(ac))
    step = 0.0 if weight_bits is None else peak / (2 ** (weight_bits - 1) - 1)
    return base, colbase, resize_kept_mass(ar, ac, pr.prune, peak), taps, pr.prune * peak, step


def _delay_steps(delay_ms: float, dt_ms: float) -> int:
    """A delay in steps, rounded as Brian2's spike queue rounds it (seconds
    over seconds, the delay first rounded to 1e-6 ms as our Brian2 backend
    groups synapses)."""
    return int(np.round(round(delay_ms, 6) * MS / (dt_ms * MS)))


def build_tables(network: Network, dt_ms: float, weight_bits: int | None = None) -> EngineTables:
    """The engine's arrays for ``network`` simulated at ``dt_ms``; with
    ``weight_bits`` every weight is the ``weight_bits``-bit integer times one
    scale per projection that a board holds (:func:`quantised_values`).

    Examples
    --------
    >>> from snn_fg.network import build_network
    >>> from snn_fg.params import ModelParams
    >>> tab = build_tables(build_network(ModelParams(levels=1), (20, 24)), 0.5)
    >>> tab.n_cells == sum(p.size for p in tab.network.populations)
    True
    """
    neurons, nrn, ref, adv = _neuron_types(network, dt_ms)
    offsets, pops, n_cells = _populations(network, neurons)
    index = {p.name: q for q, p in enumerate(network.populations)}
    out = _Collector()
    rows, wrow, kept, taps, spans = [], [], {}, {}, []
    for pr in network.projections:
        src, tgt = network.population(pr.source), network.population(pr.target)
        spans.append([out.n_taps, out.n_taps, out.n_dense, out.n_dense])
        if isinstance(pr, Conv):
            base, colbase, kept[pr.name], taps[pr.name], radius, dense = _conv(network, pr, src, tgt, out, weight_bits)
            kind, wrap, thr, step = CONV, int(pr.padding == "wrap"), 0.0, 0.0
        else:
            base, colbase, kept[pr.name], taps[pr.name], thr, step = _resize(pr, src, tgt, out, weight_bits)
            kind, wrap, radius, dense = RESIZE, 0, 0, (0, 0, 0)
        spans[-1][1], spans[-1][3] = out.n_taps, out.n_dense
        rows.append(
            [
                kind,
                index[src.name],
                index[tgt.name],
                1 if receptor(pr.sign) == "exc" else 2,
                _delay_steps(pr.delay_ms, dt_ms),
                wrap,
                base,
                colbase,
                int(pr.prune > 0),
                int(pr.sign < 0),
                radius,
                *dense,
            ]
        )
        wrow.append([pr.sign * pr.gain_mv, thr, step])
    arrays = out.arrays()
    prj = np.array(rows, dtype=np.int64).reshape(-1, 14)
    groups: dict = {}
    for p in range(prj.shape[0]):
        groups.setdefault((int(prj[p, J_TGT]), int(prj[p, J_COL])), []).append(p)
    grp_prj = np.array([p for members in groups.values() for p in members], dtype=np.int64)
    grp_ptr = np.cumsum([0] + [len(members) for members in groups.values()]).astype(np.int64)
    return EngineTables(
        network=network,
        dt_ms=float(dt_ms),
        offsets=offsets,
        pops=pops,
        n_cells=int(n_cells),
        nrn=nrn,
        ref_steps=ref,
        adv=adv,
        prj=prj,
        prj_w=np.array(wrow, dtype=np.float64).reshape(-1, 3),
        grp_ptr=grp_ptr,
        grp_prj=grp_prj,
        kept_mass=kept,
        taps=taps,
        spans=np.array(spans, dtype=np.int64).reshape(-1, 4),
        **arrays,
    )
