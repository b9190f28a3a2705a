"""The rate model on the network's connectivity (the *twin*): the unrolled
network run as the rate model's iteration.

It uses the unrolled connectivity (the same cells, kernel taps, lattices and
interpolations a simulator gets) but replaces the spiking dynamics by the
reference's synchronous iteration of stages 4-8:

* simple cells: the unrolled DoG drive (in kernel units) thresholded at
  ``edge_threshold``, arg-max over directions, index = direction + n/2;
  pixels without a response above threshold take index n/2 (the untuned rule);
* border ownership B = S * f(z) with the reference's ``f`` (each pair sums to 2);
* grouping G = rectified von Mises sums of B through the unrolled projections,
  the rival family inhibiting as the network has it (through excess cells
  ``rect(B_rival - B_partner)``, zero on the first iteration; or directly,
  left out on the first ``uninhibited`` iterations), light/dark winner-take-all;
* z = (z+ - z-) through the unrolled grouping -> feedback projections and the
  top-down pooling, read at the border-ownership cells through the unrolled
  feedback -> border-ownership interpolation.

Comparing the twin with the reference measures what the network's structure
(pruning, lattices, site hints, pooling) changes; comparing a spiking run
with the twin measures what the spiking dynamics change.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ...lowering.unroll import Unrolled, to_grid
from ...network.wiring import FAMILIES, FEEDBACK_TO_FAMILY, PARTNER
from .decode import decode_rates


def _matrix(un: Unrolled, conn) -> sp.csr_matrix:
    """Connection matrix (targets x sources) in kernel units (weight / gain, signed by the kernel)."""
    pr = conn.projection
    k = conn.w / (pr.sign * pr.gain_mv) if pr.gain_mv else conn.w * 0
    return sp.csr_matrix((k, (conn.post, conn.pre)), shape=(un.n_cells(pr.target), un.n_cells(pr.source)))


class _Matrices:
    """Connection matrices between populations found by role and level."""

    def __init__(self, un: Unrolled):
        self.un = un
        self.by = {}
        for c in un.connections:
            self.by.setdefault((c.projection.source, c.projection.target, c.projection.sign), []).append(c)
        self.cache = {}

    def name(self, role, level):
        return self.un.network.one(role, level).name

    def __call__(self, src, tgt, sign=None, kernel=None) -> sp.csr_matrix:
        """Sum of the matrices from population ``src`` to ``tgt`` (names), of
        one sign or both, of projections with one kernel reference or all."""
        key = (src, tgt, sign, kernel)
        if key not in self.cache:
            cs = [
                c
                for s in ((1, -1) if sign is None else (sign,))
                for c in self.by.get((src, tgt, s), [])
                if kernel is None
                or getattr(c.projection, "kernel", None) is not None
                and c.projection.kernel.ref == kernel
            ]
            self.cache[key] = sum(
                (_matrix(self.un, c) for c in cs), sp.csr_matrix((self.un.n_cells(tgt), self.un.n_cells(src)))
            )
        return self.cache[key]


def _simple_stage(un, mats, level, s_index):
    """Index per untuned site (support pixel) and whether it is untuned; per-cell S activity."""
    net, p = un.network, un.network.params
    n, n_dir = p.n_ori, p.n_dir
    on, off = mats.name("input_on", 1), mats.name("input_off", 1)
    x_on = un.active[on].ravel().astype(float)
    x_off = un.active[off].ravel().astype(float)
    relays = {}
    if level > 1:
        r_on, r_off = mats.name("relay_on", level), mats.name("relay_off", level)
        x_on = np.clip(mats(on, r_on) @ x_on, 0, None)
        x_off = np.clip(mats(off, r_off) @ x_off, 0, None)
        relays = {r_on: x_on, r_off: x_off}
        on, off = r_on, r_off
    s_name, u_name = mats.name("simple", level), mats.name("untuned", level)
    drive = mats(on, s_name, kernel="dog") @ x_on + mats(off, s_name, kernel="dog") @ x_off
    drive[drive < p.edge_threshold] = 0
    pop = net.population(s_name)
    c, r, col = np.unravel_index(un.sites[s_name], pop.shape)
    pos_idx = r * pop.shape[2] + col
    u_sites = un.sites[u_name]
    best = np.full(u_sites.size, -1)
    where = np.searchsorted(u_sites, pos_idx)
    seen = np.zeros(u_sites.size, bool)
    for i in np.lexsort((c, -drive)):  # strongest first; ties -> lowest direction
        w = where[i]
        if w < u_sites.size and u_sites[w] == pos_idx[i] and not seen[w] and drive[i] > 0:
            best[w] = c[i]
            seen[w] = True
    index = np.where(best >= 0, (best + n // 2) % n_dir, n // 2)
    if s_index is not None and level in s_index:
        index = np.asarray(s_index[level])
    s_rate = (best[np.clip(where, 0, u_sites.size - 1)] == c).astype(float)
    return (u_sites, index, best < 0), {s_name: s_rate, **relays}


def run_twin(
    un: Unrolled,
    iterations: int | None = None,
    relax: float = 1.0,
    uninhibited: int = 1,
    s_index: dict | None = None,
    z_gain: float = 1.0,
    untuned_scale: float = 1.0,
    g_transfer=None,
):
    """Iterate the reference's stages 4-8 on the unrolled network.

    ``relax`` < 1 turns the synchronous update into a damped one
    (``x <- (1 - relax) x + relax * update``), closer to continuous-time
    dynamics; ``uninhibited`` is the number of first iterations without the
    opposite-family inhibition. ``s_index`` (level -> index per untuned
    site, -1 for none) replaces the simple stage's winners, e.g. by a
    spiking run's.

    Returns ``(fg_x, fg_y, grouping, rates)`` where ``rates`` maps population
    names to per-cell activities (B, G in the reference's units).
    """
    net = un.network
    p = net.params
    n = p.n_ori
    iterations = p.iterations if iterations is None else iterations
    mats = _Matrices(un)
    levels = range(1, p.levels + 1)
    rates = {}
    b_s = {}  # simple-cell value feeding each border-ownership cell
    for level in levels:
        (u_sites, index, untuned), level_rates = _simple_stage(un, mats, level, s_index)
        rates.update(level_rates)
        for f in FAMILIES:
            name = mats.name(f"bo_{f}", level)
            pop = net.population(name)
            c, r, col = np.unravel_index(un.sites[name], pop.shape)
            w = np.searchsorted(u_sites, r * pop.shape[2] + col)
            half = 0 if f in ("L1", "D2") else n
            b_s[name] = (index[w] == c + half) * np.where(untuned[w], untuned_scale, 1.0)
    B = {k: v.copy() for k, v in b_s.items()}
    G = {}
    for it in range(iterations):
        for level in levels:
            _grouping_step(un, mats, level, B, G, p.w_inh if it >= uninhibited else 0.0, relax, g_transfer)
        z = _feedback_signals(un, mats, levels, G)
        for level in levels:
            for f, (k_for, _) in FEEDBACK_TO_FAMILY.items():
                name = mats.name(f"bo_{f}", level)
                half, sgn = k_for[0], 1 if k_for[1] == "p" else -1  # z for L1/L2, -z for D2/D1
                zb = _interp_to_bo(mats, half, level, name, z[(half, level)])
                with np.errstate(over="ignore"):
                    fz = 1.0 + p.alpha * (1.0 / (1.0 + np.exp(-sgn * zb * z_gain)) - 0.5)
                B[name] = (1 - relax) * B[name] + relax * np.maximum(b_s[name] * fz, 0.0)
    rates.update(B)
    rates.update(G)
    fg_x, fg_y, grouping, _ = decode_rates(net, un.sites, rates)
    return fg_x, fg_y, grouping, rates


def _excess(un, mats, level, B) -> dict:
    """Excess cells' values ``rect(B_f - B_partner)`` (networks that have them)."""
    net = un.network
    out = {}
    for f in FAMILIES:
        found = net.by_role(f"excess_{f}", level)
        if not found:
            continue
        x = found[0].name
        own, rival = (mats.name(f"bo_{k}", level) for k in (f, PARTNER[f]))
        out[x] = np.maximum(to_grid(un, own, B[own]) - to_grid(un, rival, B[rival]), 0.0).ravel()[un.sites[x]]
    return out


def _grouping_step(un, mats, level, B, G, w_inh, relax, g_transfer):
    """Stage 7 at one level, then the light/dark winner-take-all per grid point.
    The rival family inhibits as the network has it: directly, or through
    its excess cells."""
    names = {pol: mats.name(f"group_{pol}", level) for pol in ("L", "D")}
    X = _excess(un, mats, level, B)
    rivals = X if X else {mats.name(f"bo_{f}", level): B[mats.name(f"bo_{f}", level)] for f in FAMILIES}
    for g in names.values():
        tot = np.zeros(un.n_cells(g))
        for f in FAMILIES:
            b = mats.name(f"bo_{f}", level)
            tot += mats(b, g, 1) @ B[b]
        if w_inh:
            for r, values in rivals.items():
                tot -= w_inh * (mats(r, g, -1) @ values)
        new = np.maximum(tot, 0) if g_transfer is None else g_transfer(np.maximum(tot, 0))
        G[g] = new if g not in G else (1 - relax) * G[g] + relax * new
    # the two may have different sites
    full = {pol: to_grid(un, g, G[g]).ravel() for pol, g in names.items()}
    G[names["L"]] = np.where(full["L"] > full["D"], full["L"], 0.0)[un.sites[names["L"]]]
    G[names["D"]] = np.where(full["D"] > full["L"], full["D"], 0.0)[un.sites[names["D"]]]


def _feedback_signals(un, mats, levels, G) -> dict:
    """z1 and z2 per level, top-down: z_l = x_l + decay * resize(z_{l+1})
    (kernel units; the pooling matrices carry the interpolation)."""
    p = un.network.params
    z = {}
    for level in reversed(list(levels)):
        gl, gd = mats.name("group_L", level), mats.name("group_D", level)
        for half in ("1", "2"):
            zp = mats.name(f"feedback_{half}p", level)
            zs = mats(gl, zp, 1) @ G[gl] + mats(gd, zp, 1) @ G[gd]
            zs = zs - (mats(gl, zp, -1) @ G[gl] + mats(gd, zp, -1) @ G[gd])
            zs = zs * un.network.population(zp).stride ** 2
            if level < p.levels:
                coarse = mats.name(f"feedback_{half}p", level + 1)
                zs = zs + p.pyramid_decay * (mats(coarse, zp, 1) @ z[(half, level + 1)])
            z[(half, level)] = zs
    return z


def _interp_to_bo(mats, half, level, name, zval):
    """Interpolate a z lattice value onto border-ownership cells with
    whichever feedback -> border-ownership matrix exists (both halves of a
    pair reach a cell with the same interpolation weights)."""
    for side in ("p", "n"):
        m = mats(mats.name(f"feedback_{half}{side}", level), name)
        if m.nnz:
            return np.asarray(np.abs(m) @ zval).ravel()
    return np.zeros(mats.un.n_cells(name))
