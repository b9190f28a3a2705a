"""Rate decoding: spike counts -> the rate model's readout (stage 9).

Rates (spikes per second over the counting window) of the border-ownership
and grouping cells fill a :class:`snn_fg.rate.edfg.GroupingResult`, and the
rate model's own :func:`~snn_fg.rate.edfg.readout` turns it into ``fg_x``,
``fg_y`` and the grouping map. Grouping cells on a strided lattice are first
interpolated (bilinear) onto their level's full grid.
"""
from __future__ import annotations

import numpy as np

from ..network.description import FAMILIES, Network
from ..rate.edfg import GroupingResult, readout
from .unroll import interp_matrix


def population_rates(network: Network, sites: dict, rates_by_pop: dict, name: str) -> np.ndarray:
    """Rates of population ``name`` on its full (channels, rows, cols) grid (0 where no cell)."""
    p = network.population(name)
    out = np.zeros(p.size)
    out[sites[name]] = rates_by_pop[name]
    return out.reshape(p.shape)


def to_level_grid(network: Network, name: str, grid: np.ndarray) -> np.ndarray:
    """Interpolate a strided population's (channels, rows, cols) map onto its level grid."""
    p = network.population(name)
    if p.stride == 1:
        return grid
    ar = interp_matrix(p.level_shape[0], p.level_shape[0], p.stride, 1, "linear")
    ac = interp_matrix(p.level_shape[1], p.level_shape[1], p.stride, 1, "linear")
    return np.einsum("ri,cij,sj->crs", ar, grid, ac, optimize=True)


def grouping_result(network: Network, sites: dict, rates_by_pop: dict) -> GroupingResult:
    """A GroupingResult filled with decoded rates, level by level."""
    params = network.params
    fam = {f: [] for f in FAMILIES}
    s_l, gl_l, gd_l = [], [], []
    for level in range(1, params.levels + 1):
        def one(role):
            pops = network.by_role(role, level)
            if len(pops) != 1:
                raise ValueError(f"Network: level {level} has {len(pops)} populations of role {role!r}, need 1")
            return pops[0].name
        for f in FAMILIES:
            fam[f].append(population_rates(network, sites, rates_by_pop, one(f"bo_{f}")))
        s_l.append(population_rates(network, sites, rates_by_pop, one("simple")))
        for role, acc in (("group_L", gl_l), ("group_D", gd_l)):
            name = one(role)
            acc.append(to_level_grid(network, name, population_rates(network, sites, rates_by_pop, name))[0])
    return GroupingResult(s_l, fam["L1"], fam["L2"], fam["D1"], fam["D2"], gl_l, gd_l)


def decode(network: Network, sites: dict, rates_by_pop: dict):
    """``(fg_x, fg_y, grouping, GroupingResult)`` from per-population rates (Hz)."""
    g = grouping_result(network, sites, rates_by_pop)
    fg_x, fg_y, grouping = readout(g, network.params, network.frame_shape)
    return fg_x, fg_y, grouping, g
