"""Rate decoding: firing rates -> the rate model's readout (stage 9).

Rates (spikes per second in the counting window) of the border-ownership
and grouping cells fill a :class:`snn_fg.models.rate.edfg.GroupingResult`, and the
rate model's own :func:`~snn_fg.models.rate.edfg.readout` turns it into ``fg_x``,
``fg_y`` and the grouping map. Grouping cells on a strided lattice are first
interpolated (bilinear) onto their level's whole grid. Populations are found
by role, so this works for any backend and any network with the model's roles.
"""

from __future__ import annotations

import numpy as np

from ...frames.pool import event_pixels, unpool_maps
from ...lowering.interp import interp_matrix
from ...network.graph import Network
from ...network.wiring import FAMILIES
from ..rate.edfg import GroupingResult, readout


def _grid(network: Network, sites: dict, rates: dict, name: str) -> np.ndarray:
    pop = network.population(name)
    if sites[name].size == pop.size:  # every cell instantiated (sites are sorted): the rates are the grid
        return np.asarray(rates[name], dtype=np.float64).reshape(pop.shape)
    out = np.zeros(pop.size)
    out[sites[name]] = rates[name]
    return out.reshape(pop.shape)


def read_out(role: str, level: int) -> bool:
    """Whether the maps read a population of ``role`` at ``level``: the grouping
    cells of every level and the border-ownership cells of level 1
    (:func:`~snn_fg.models.rate.edfg.readout`, :func:`vector_confidence`)."""
    return role.startswith("group_") or (role.startswith("bo_") and level == 1)


def to_level_grid(network: Network, name: str, grid: np.ndarray) -> np.ndarray:
    """Interpolate a strided population's (channels, rows, cols) map onto its level grid."""
    p = network.population(name)
    if p.stride == 1:
        return grid
    ar = interp_matrix(p.level_shape[0], p.level_shape[0], p.stride, 1, "linear")
    ac = interp_matrix(p.level_shape[1], p.level_shape[1], p.stride, 1, "linear")
    # (einsum("ri,cij,sj->crs", optimize=True)'s two contractions, without its path search each call)
    return np.tensordot(ar, np.tensordot(grid, ac, axes=([2], [1])), axes=([1], [1])).transpose(1, 0, 2)


def grouping_result(network: Network, sites: dict, rates: dict, maps_only: bool = False) -> GroupingResult:
    """A GroupingResult filled with per-cell rates (population name -> values
    over its ``sites``), level by level; ``maps_only``: only what the maps
    read (:func:`read_out`; ``rates`` may hold only those), the simple cells
    and the border-ownership cells of the higher levels left out (empty lists)."""
    fam = {f: [] for f in FAMILIES}
    s_l, gl_l, gd_l = [], [], []
    for level in range(1, network.params.levels + 1):
        for f in FAMILIES:
            if not maps_only or read_out(f"bo_{f}", level):
                fam[f].append(_grid(network, sites, rates, network.one(f"bo_{f}", level).name))
        if not maps_only or read_out("simple", level):
            s_l.append(_grid(network, sites, rates, network.one("simple", level).name))
        for role, acc in (("group_L", gl_l), ("group_D", gd_l)):
            name = network.one(role, level).name
            acc.append(to_level_grid(network, name, _grid(network, sites, rates, name))[0])
    return GroupingResult(s_l, fam["L1"], fam["L2"], fam["D1"], fam["D2"], gl_l, gd_l)


def decode_rates(network: Network, sites: dict, rates: dict, maps_only: bool = False):
    """``(fg_x, fg_y, grouping, GroupingResult)`` from per-cell rates by
    population (``maps_only``: see :func:`grouping_result`)."""
    g = grouping_result(network, sites, rates, maps_only)
    fg_x, fg_y, grouping = readout(g, network.params, network.frame_shape)
    return fg_x, fg_y, grouping, g


def decode(result, maps_only: bool = False):
    """``(fg_x, fg_y, grouping, GroupingResult)`` of a
    :class:`~snn_fg.backends.SimulationResult` (``maps_only``: see
    :func:`grouping_result`)."""
    return decode_rates(result.network, result.sites, decoded_rates(result, maps_only), maps_only)


def vector_confidence(g: GroupingResult, count_window_ms: float) -> np.ndarray:
    """How many standard errors of its own spike counts each level-1
    figure-ground vector is long.

    The vector is ``sum_o u_o (B2[o] - B1[o])`` (stage 9, ``u_o`` the unit
    normal of orientation ``o``), from the counts ``n = rate * window`` of the
    border-ownership cells. If the counts were Poisson, each component of
    the vector would have variance ``sum_o u_o**2 (n1[o] + n2[o])``, so
    ``|sum_o u_o (n2 - n1)| / sqrt(sum_o (n1 + n2))`` is the vector's length
    in standard errors: about 1 where a couple of spikes decide the side,
    4.5 where 20 spikes all fall on one side. 0 where no cell fired.
    """
    t = count_window_ms / 1000.0
    b1, b2 = g.bl1[0] + g.bd1[0], g.bl2[0] + g.bd2[0]
    n = b1.shape[0]
    ang = 2 * np.pi * np.arange(n) / (2 * n) - np.pi / 2
    diff = (b2 - b1) * t
    length = np.hypot(np.tensordot(np.cos(ang), diff, axes=1), np.tensordot(np.sin(ang), diff, axes=1))
    total = (b1 + b2).sum(axis=0) * t
    return np.divide(length, np.sqrt(total), out=np.zeros_like(length), where=total > 0)


def decode_maps(result, edges: np.ndarray | None = None, pool: int = 1):
    """``(fg_x, fg_y, grouping, confidence)`` of a result at the sensor's
    size: a network that pools its input (``pool`` > 1) hands each of the
    sensor's event pixels (``edges``) its block's vector
    (:func:`~snn_fg.frames.pool.unpool_maps`) and confidence
    (:func:`vector_confidence`)."""
    fg_x, fg_y, grouping, g = decode(result, maps_only=True)
    conf = vector_confidence(g, result.count_window_ms)
    if pool > 1:
        rows, cols = at = event_pixels(edges)
        fg_x, fg_y, grouping = unpool_maps(fg_x, fg_y, grouping, edges, pool, at)
        block = np.zeros(np.shape(edges), conf.dtype)
        block[at] = conf[rows // pool, cols // pool]
        conf = block
    return fg_x, fg_y, grouping, conf


#: the roles whose rates the read-out uses
DECODED_ROLES = ("simple", "group_L", "group_D", *(f"bo_{f}" for f in FAMILIES))


def decoded_rates(result, maps_only: bool = False) -> dict:
    """Per-cell rates of the populations the read-out uses (the others,
    most of a network's cells, are not needed); ``maps_only``: of those the
    maps read (:func:`read_out`)."""
    return {
        p.name: result.rates(p.name)
        for role in DECODED_ROLES
        for p in result.network.by_role(role)
        if p.name in result.counts and (not maps_only or read_out(role, p.level))
    }
