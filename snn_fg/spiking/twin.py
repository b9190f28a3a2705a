"""Rate twin: the unrolled network run as the rate model's iteration.

It uses the unrolled connectivity (the same cells, kernel taps, lattices and
interpolations that Brian2 gets) but replaces the spiking dynamics by the
reference's synchronous iteration of stages 4-8:

* S: the unrolled DoG drive (in kernel units) thresholded at
  ``edge_threshold``, arg-max over directions, index = direction + n/2; cells
  without any response above threshold take index n/2 (the untuned rule);
* B = S * f(z) with the reference's ``f`` (each pair sums to 2 per S);
* G = rectified von Mises sums of B through the unrolled projections
  (opposite family left out on the first iteration), light/dark winner-take-all;
* z = (z+ - z-) through the unrolled G -> Z projections and the top-down
  pooling, read at the B cells through the unrolled Z -> B interpolation.

Comparing the twin with the reference measures what the network's structure
(pruning, lattices, site rules, pooling) changes; comparing the spiking run
with the twin measures what the spiking dynamics change.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..network.description import FAMILIES, ZPAIRS
from .decode import decode
from .unroll import Unrolled


def _matrix(un: Unrolled, conn) -> sp.csr_matrix:
    """Connection matrix (targets x sources) in kernel units (weight / gain, signed by the kernel)."""
    pr = conn.projection
    n_t = un.n_cells(pr.target)
    n_s = un.n_cells(pr.source)
    k = conn.w / (pr.sign * pr.gain_mv) if pr.gain_mv else conn.w * 0
    return sp.csr_matrix((k, (conn.post, conn.pre)), shape=(n_t, n_s))


def run_twin(un: Unrolled, iterations: int | None = None, relax: float = 1.0, uninhibited: int = 1,
             s_index: dict | None = None, z_gain: float = 1.0, untuned_scale: float = 1.0,
             g_transfer=None):
    """Iterate the reference's stages 4-8 on the unrolled network.

    ``relax`` < 1 turns the synchronous update into a damped one
    (``x <- (1 - relax) x + relax * update``), closer to continuous-time
    dynamics; ``uninhibited`` is the number of first iterations without the
    opposite-family inhibition. ``s_index`` (level -> index per ``U`` site,
    -1 for none) replaces the S stage's winners, e.g. by a spiking run's.

    Returns ``(fg_x, fg_y, grouping, rates)`` where ``rates`` maps population
    names to per-cell activities (B, G in the reference's units).
    """
    net = un.network
    p = net.params
    n = p.n_ori
    n_dir = p.n_dir
    iterations = p.iterations if iterations is None else iterations
    by = {}
    for c in un.connections:
        by.setdefault((c.projection.source, c.projection.target, c.projection.sign), []).append(c)

    def mat(src, tgt, sign=None):
        cs = [c for (s, t, g), lst in by.items() for c in lst if s == src and t == tgt and (sign is None or g == sign)]
        if not cs:
            return sp.csr_matrix((un.n_cells(tgt), un.n_cells(src)))
        return sum(_matrix(un, c) for c in cs)

    levels = range(1, p.levels + 1)
    act = {"on": un.active["on"].ravel().astype(float), "off": un.active["off"].ravel().astype(float)}
    rates = {}
    # ---- S cells: drive, threshold, arg-max ----------------------------------
    s_onehot = {}
    for l in levels:
        if l == 1:
            x_on, x_off = act["on"], act["off"]
            src_on, src_off = "on", "off"
        else:
            src_on, src_off = f"ron_{l}", f"roff_{l}"
            x_on = np.clip(mat("on", src_on) @ act["on"], 0, None)
            x_off = np.clip(mat("off", src_off) @ act["off"], 0, None)
            rates[src_on], rates[src_off] = x_on, x_off
        s_name = f"S_{l}"
        drive = mat(src_on, s_name) @ x_on + mat(src_off, s_name) @ x_off
        drive[drive < p.edge_threshold] = 0
        pop = net.population(s_name)
        sites = un.sites[s_name]
        c, r, col = np.unravel_index(sites, pop.shape)
        pos_idx = r * pop.shape[2] + col
        # support positions (U sites) and best direction per position
        u_sites = un.sites[f"U_{l}"]
        best = np.full(u_sites.size, -1)
        best_val = np.zeros(u_sites.size)
        where = np.searchsorted(u_sites, pos_idx)
        order = np.lexsort((c, -drive))      # strongest first; ties -> lowest direction
        seen = np.zeros(u_sites.size, bool)
        for i in order:
            w = where[i]
            if w < u_sites.size and u_sites[w] == pos_idx[i] and not seen[w] and drive[i] > 0:
                best[w] = c[i]
                best_val[w] = drive[i]
                seen[w] = True
        index = np.where(best >= 0, (best + n // 2) % n_dir, n // 2)
        if s_index is not None and l in s_index:
            index = np.asarray(s_index[l])
        s_onehot[l] = (u_sites, index, best < 0)
        rates[s_name] = (best[np.clip(where, 0, u_sites.size - 1)] == c).astype(float)
    # ---- B / G / z iteration ----------------------------------------------------
    b_s = {}     # S value feeding each B cell
    for l in levels:
        u_sites, index, untuned = s_onehot[l]
        for f in FAMILIES:
            name = f"B{f}_{l}"
            pop = net.population(name)
            c, r, col = np.unravel_index(un.sites[name], pop.shape)
            pos_idx = r * pop.shape[2] + col
            w = np.searchsorted(u_sites, pos_idx)
            off = 0 if f in ("L1", "D2") else n
            b_s[name] = (index[w] == c + off) * np.where(untuned[w], untuned_scale, 1.0)
    B = {k: v.copy() for k, v in b_s.items()}
    mats = {}
    for l in levels:
        for f in FAMILIES:
            for g in ("GL", "GD"):
                for sign in (1, -1):
                    mats[(f"B{f}_{l}", f"{g}_{l}", sign)] = mat(f"B{f}_{l}", f"{g}_{l}", sign)
        for k in ZPAIRS:
            for g in ("GL", "GD"):
                for sign in (1, -1):
                    mats[(f"{g}_{l}", f"Z{k}_{l}", sign)] = mat(f"{g}_{l}", f"Z{k}_{l}", sign)
            if l < p.levels:
                for k2 in ZPAIRS:
                    for sign in (1, -1):
                        mats[(f"Z{k2}_{l + 1}", f"Z{k}_{l}", sign)] = mat(f"Z{k2}_{l + 1}", f"Z{k}_{l}", sign)
        for f in FAMILIES:
            for k in ZPAIRS:
                mats[(f"Z{k}_{l}", f"B{f}_{l}")] = mat(f"Z{k}_{l}", f"B{f}_{l}")
    w_inh = p.w_inh
    G = {}
    for it in range(iterations):
        first = it < uninhibited
        for l in levels:
            for g in ("GL", "GD"):
                tot = np.zeros(un.n_cells(f"{g}_{l}"))
                for f in FAMILIES:
                    tot += mats[(f"B{f}_{l}", f"{g}_{l}", 1)] @ B[f"B{f}_{l}"]
                    if not first:
                        tot -= w_inh * mats[(f"B{f}_{l}", f"{g}_{l}", -1)] @ B[f"B{f}_{l}"]
                new = np.maximum(tot, 0) if g_transfer is None else g_transfer(np.maximum(tot, 0))
                old = G.get(f"{g}_{l}")
                G[f"{g}_{l}"] = new if old is None else (1 - relax) * old + relax * new
            # light/dark winner-take-all per grid point (the two may have different sites)
            full = {}
            for g in ("GL", "GD"):
                a = np.zeros(net.population(f"{g}_{l}").size)
                a[un.sites[f"{g}_{l}"]] = G[f"{g}_{l}"]
                full[g] = a
            win_l = full["GL"] > full["GD"]
            win_d = full["GD"] > full["GL"]
            G[f"GL_{l}"] = np.where(win_l, full["GL"], 0.0)[un.sites[f"GL_{l}"]]
            G[f"GD_{l}"] = np.where(win_d, full["GD"], 0.0)[un.sites[f"GD_{l}"]]
        # z, top-down: z_l = x_l + decay * resize(z_{l+1}) (kernel units; the
        # pooling matrices carry the interpolation, decay applied here)
        z = {}
        for l in reversed(list(levels)):
            for k in ("1", "2"):
                zs = np.zeros(un.n_cells(f"Z{k}p_{l}"))
                zs += mats[(f"GL_{l}", f"Z{k}p_{l}", 1)] @ G[f"GL_{l}"] + mats[(f"GD_{l}", f"Z{k}p_{l}", 1)] @ G[f"GD_{l}"]
                zs -= mats[(f"GL_{l}", f"Z{k}p_{l}", -1)] @ G[f"GL_{l}"] + mats[(f"GD_{l}", f"Z{k}p_{l}", -1)] @ G[f"GD_{l}"]
                zs = zs * net.population(f"Z{k}p_{l}").stride ** 2
                if l < p.levels:
                    zs += p.pyramid_decay * (mats[(f"Z{k}p_{l + 1}", f"Z{k}p_{l}", 1)] @ z[(k, l + 1)])
                z[(k, l)] = zs
        for l in levels:
            for f, (k, sgn) in {"L1": ("1", 1), "D2": ("1", -1), "L2": ("2", 1), "D1": ("2", -1)}.items():
                name = f"B{f}_{l}"
                # both halves of a pair reach a B cell with the same interpolation weights
                zb = _interp_to_b(mats, k, l, name, z[(k, l)])
                with np.errstate(over="ignore"):
                    fz = 1.0 + p.alpha * (1.0 / (1.0 + np.exp(-sgn * zb * z_gain)) - 0.5)
                B[name] = (1 - relax) * B[name] + relax * np.maximum(b_s[name] * fz, 0.0)
    rates.update(B)
    rates.update(G)
    fg_x, fg_y, grouping, _ = decode(net, un.sites, rates)
    return fg_x, fg_y, grouping, rates


def _interp_to_b(mats, k, l, name, zval):
    """Interpolate a z lattice value onto B cells with whichever Z -> B matrix exists."""
    for half in ("p", "n"):
        m = mats.get((f"Z{k}{half}_{l}", name))
        if m is not None and m.nnz:
            return np.asarray(np.abs(m) @ zval).ravel()
    return np.zeros(m.shape[0]) if m is not None else 0.0
