"""Weight quantisation: every projection's weights as signed ``bits``-bit
integers times one scale factor per projection.

The scale is a property of the input-independent description: the largest
|weight| the projection can have anywhere (``gain_mv`` times the largest
kept |kernel value|, or times the largest interpolation product of a
Resize) over ``2**(bits-1) - 1``. Weights that round to 0 are dropped.
"""

from __future__ import annotations

import numpy as np

from .. import validate as check
from ..network.graph import Network
from ..network.projections import Conv, Projection
from ..pynn.cells import quantise
from .interp import interp_matrix

BITS_RANGE = (2, 32)


def check_bits(bits, owner="weight quantisation") -> int:
    return check.integer(owner, "weight_bits", bits, lo=BITS_RANGE[0], hi=BITS_RANGE[1])


def peak_weight(network: Network, pr: Projection) -> float:
    """Largest |weight| (mV) of projection ``pr`` anywhere in the network."""
    if isinstance(pr, Conv):
        k = np.abs(pr.kernel.array(network.params))
        return float(pr.gain_mv * k.max())
    src, tgt = network.population(pr.source), network.population(pr.target)
    peak = 1.0
    for axis in (0, 1):
        a = interp_matrix(src.level_shape[axis], tgt.level_shape[axis], src.stride, tgt.stride, pr.interpolation)
        peak *= float(np.abs(a).max())
    return pr.gain_mv * peak


def projection_scales(network: Network, bits: int) -> dict:
    """Projection name -> scale (mV per integer step) for ``bits``-bit weights."""
    bits = check_bits(bits)
    top = 2 ** (bits - 1) - 1
    return {pr.name: peak_weight(network, pr) / top for pr in network.projections}


def quantise_unrolled(un, bits: int):
    """Quantise the weights of an :class:`~snn_fg.lowering.unroll.Unrolled`
    network in place (synapses rounded to 0 are removed)."""
    scales = projection_scales(un.network, bits)
    for conn in un.connections:
        w = quantise(conn.w, bits, scales[conn.projection.name])
        keep = w != 0
        conn.pre, conn.post, conn.w = conn.pre[keep], conn.post[keep], w[keep]
        conn.n = int(keep.sum())
    return un
