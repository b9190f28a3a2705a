"""The fast engine's view of a network: flat arrays built once per
description and time step (:func:`build_tables`), never one per synapse.

* cells: every cell of every population gets a global number
  ``offset(population) + flat index`` (flat index into its
  ``(channels, rows, cols)`` grid); spike sources are numbered too, so that
  a spike is one integer whatever emits it;
* neuron types: :mod:`.neurons`;
* projections: a Conv is its stencil rows, a Resize its two interpolation
  matrices transposed (:mod:`.stencils`), the weight of a resize's synapse
  being computed when a spike passes.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ...lowering.connect import kernel_taps
from ...network.graph import Network
from ...network.projections import Conv
from ...pynn import tables as rule
from ...pynn.cells import quantise
from ..base import receptor
from .neurons import MS, SOURCE_TYPE, by_steps, neuron_types
from .stencils import StencilCollector, resize_factors_of, stencil_rows, tap_weights

#: columns of the population table
P_OFF, P_CH, P_GR, P_GC, P_STRIDE, P_LR, P_LC, P_TYPE, P_SIZE = range(9)
#: columns of the projection table: kind, source and target population,
#: current (1 exc, 2 inh), delay (steps), wrap-around, first stencil class
#: (Conv) or row factor (Resize), column factor, pruned, inhibitory, and a
#: Conv's reach in lattice points (a spike at least this far from the
#: grid's edges lands whole)
J_KIND, J_SRC, J_TGT, J_COL, J_DELAY, J_WRAP, J_BASE, J_COLBASE, J_PRUNE, J_INH, J_RADIUS = range(11)
N_J = 11
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
    adv_k: np.ndarray  # float64 (n_types, ADVANCE_STEPS + 1, 8): the same by k, one cache line each
    prj: np.ndarray  # int64 (n_projections, N_J), columns J_*
    prj_w: np.ndarray  # float64 (n_projections, 3): sign * gain (mV), prune threshold of a Resize,
    #                          and its quantisation step (interpolation products rounded to it; 0: exact)
    cls_ptr: np.ndarray  # int64: stencil rows of class c of Conv p: cls_ptr[J_BASE + c] .. [+ 1]
    row_tab: np.ndarray  # int64 (8 per stencil row, columns stencils.R_*): its output channel, lattice
    #                          offsets, columns, first value in st_w, which values are taps, its (channel, row) and
    #                          its first value's place in the summed input from lattice point (0, 0)
    st_w: np.ndarray  # float64: stencil values, volts added to the receptor (0 in gaps)
    st_k: np.ndarray  # float64: the same as kernel values before the gain (st_w is made from them)
    csr_ptr: np.ndarray  # int64: Resize rows/cols: source index s of a factor starting at
    csr_idx: np.ndarray  #   base has targets csr_idx[csr_ptr[base + s]:csr_ptr[base + s + 1]]
    csr_val: np.ndarray  #   with interpolation weights csr_val
    grp_ptr: np.ndarray  # int64: projections feeding one (target population, current) are
    grp_prj: np.ndarray  #   grp_prj[grp_ptr[k]:grp_ptr[k + 1]] (their input is summed, then delivered)
    kept_mass: dict  # projection name -> kept fraction of its kernel mass
    taps: dict  # projection name -> kept taps (Conv) or interpolation weights (Resize)
    spans: np.ndarray  # int64 (n_projections, 2): a Conv's values st_w[a:b]

    def with_gains(self, network: Network) -> EngineTables:
        """These tables for ``network``, which must differ from
        :attr:`network` in projection gains only (:func:`gains_only`), e.g.
        the same description calibrated for another input rate: the weights
        are made again from the kept kernel values, as :func:`build_tables`
        makes them, and nothing else is recomputed."""
        st_w, prj_w = self.st_w.copy(), self.prj_w.copy()
        for p, pr in enumerate(network.projections):
            prj_w[p, 0] = pr.sign * pr.gain_mv
            if isinstance(pr, Conv):
                a, b = self.spans[p]
                st_w[a:b] = tap_weights(pr, self.st_k[a:b])
        return dataclasses.replace(self, network=network, st_w=st_w, prj_w=prj_w)


def _populations(network: Network, neurons):
    rows, offsets, off = [], {}, 0
    for p in network.populations:
        offsets[p.name] = off
        kind = SOURCE_TYPE if p.is_source else neurons.index(p.neuron)
        rows.append([off, p.channels, *p.grid, p.stride, *p.level_shape, kind, p.size])
        off += p.size
    return offsets, np.array(rows, dtype=np.int64).reshape(-1, 9), off


def quantised_values(k: np.ndarray, peak: float, weight_bits: int | None) -> np.ndarray:
    """Kernel values as the ``weight_bits``-bit weights a board holds: one
    scale per projection, its largest |value| ``peak`` over ``2**(bits-1) - 1``
    (:func:`snn_fg.lowering.quantise.projection_scales`); unchanged for None."""
    if weight_bits is None:
        return k
    return quantise(k, weight_bits, peak / (2 ** (weight_bits - 1) - 1))


def conv_classes(network, pr, src, tgt, weight_bits=None):
    """A Conv's kept taps as the engine follows them from a spike:
    ``(co, cls, qr, qc, k, kept mass, n_cls, reach)``.

    A source at level pixel ``p`` reaches the target lattice only through
    the taps of its class (its input channel, and ``p`` modulo the target's
    stride), and those land on lattice point ``p // stride - q``
    (:func:`snn_fg.pynn.tables.conv_stencil`, the rule every backend's
    synapses follow). ``reach``: a spike at least this many lattice points
    from the grid's edges lands whole; a wrap-around kernel folded onto a
    smaller level never does."""
    co, ci, dr, dc, k, kept = kernel_taps(pr, network)
    if weight_bits is not None:
        k = quantised_values(k, float(np.abs(pr.kernel.array(network.params)).max()), weight_bits)
        co, ci, dr, dc, k = (a[k != 0] for a in (co, ci, dr, dc, k))
    st = tgt.stride
    if pr.padding == "wrap" and st != 1:
        raise ValueError(f"the fast engine wraps a Conv around its level at stride 1 only ({pr.name!r})")
    where = {"grid": tgt.grid, "stride": st, "level_shape": tgt.level_shape}
    taps = np.stack([co, ci, dr, dc], axis=1)
    co, cls, qr, qc, k, folded = rule.conv_stencil(taps, k, where, pr.padding == "wrap")
    reach = max(tgt.grid) if folded else (int(max(np.abs(qr).max(), np.abs(qc).max())) if qr.size else 0)
    return co, cls, qr, qc, k, kept, src.channels * st * st, reach


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
        and all(x is y or rest(x) == rest(y) for x, y in zip(a.projections, b.projections, strict=True))
    )


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
    neurons, nrn, ref, adv = neuron_types(network, dt_ms)
    offsets, pops, n_cells = _populations(network, neurons)
    index = {p.name: q for q, p in enumerate(network.populations)}
    out = StencilCollector()
    rows, wrow, kept, taps, spans = [], [], {}, {}, []
    for pr in network.projections:
        src, tgt = network.population(pr.source), network.population(pr.target)
        if isinstance(pr, Conv):
            co, cls, qr, qc, k, kept[pr.name], n_cls, radius = conv_classes(network, pr, src, tgt, weight_bits)
            taps[pr.name] = int(co.size)
            base, a, b = out.conv(pr, stencil_rows(co, cls, qr, qc, k, n_cls), tgt.grid)
            kind, colbase, wrap, thr, step = CONV, 0, int(pr.padding == "wrap"), 0.0, 0.0
            spans.append([a, b])
        else:
            base, colbase, kept[pr.name], taps[pr.name], thr, step = resize_factors_of(pr, src, tgt, out, weight_bits)
            kind, wrap, radius = RESIZE, 0, 0
            spans.append([0, 0])
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
            ]
        )
        wrow.append([pr.sign * pr.gain_mv, thr, step])
    prj = np.array(rows, dtype=np.int64).reshape(-1, N_J)
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
        adv_k=by_steps(adv),
        prj=prj,
        prj_w=np.array(wrow, dtype=np.float64).reshape(-1, 3),
        grp_ptr=grp_ptr,
        grp_prj=grp_prj,
        kept_mass=kept,
        taps=taps,
        spans=np.array(spans, dtype=np.int64).reshape(-1, 2),
        **out.arrays(),
    )
