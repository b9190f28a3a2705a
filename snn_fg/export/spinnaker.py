"""Which projections sPyNNaker's ``ConvolutionConnector`` can carry: :func:`spinnaker_plan`.

sPyNNaker's local-only convolution (``convolution_connector.py`` and
``local_only_conv_impl.c``) connects two 2-D populations through one 2-D
kernel with zero padding and a stride on the target; a spike of source pixel
``q`` reaches target ``p`` with weight ``w[q - p]`` counted from the kernel
centre, i.e. it *convolves* (our ``mode='conv'``; a ``corr`` kernel is passed
flipped). Positive and negative weights go to two receptors. A population
that receives convolutions is "local-only": it may receive nothing else
(sPyNNaker issue 1224), and its one delay comes from its synapse dynamics.

Our populations hold ``channels`` cells per grid point, so one of our Conv
projections becomes one ``ConvolutionConnector`` per non-zero
``(c_out, c_in)`` kernel plane between per-channel 2-D populations.
"""

from __future__ import annotations

import math

import numpy as np

from ..network.graph import Network
from ..network.projections import Conv
from ..pynn.spinnaker import CELLS_PER_CORE, core_tile, layout

#: time step below which sPyNNaker 1!7.4.1 gives the synapses of a population that takes explicit
#: lists cores of their own, one per core of cells here (``PopulationVertex.use_combined_core``: below
#: 1 ms it splits whenever a synapse core is needed; measured: 276 synapse cores beside 274 cores of
#: cells for a 32 x 24 export at 0.5 ms, none at 1 ms; experiments/results/export_spinnaker.md)
SPLIT_BELOW_MS = 1.0


def _conv_reason(network: Network, pr) -> str | None:
    """Why ``pr`` cannot be a ConvolutionConnector (None: it can)."""
    if not isinstance(pr, Conv):
        return "interpolation between pyramid levels (Resize) is no convolution"
    if pr.padding != "zero":
        return "wrap-around padding; sPyNNaker pads with zeros only"
    src, tgt = network.population(pr.source), network.population(pr.target)
    if tgt.stride % src.stride:
        return f"target lattice (stride {tgt.stride}) is not a sub-lattice of the source's (stride {src.stride})"
    k = pr.kernel.array(network.params)
    if (k.shape[2] // 2) % src.stride or (k.shape[3] // 2) % src.stride:
        return "kernel centre off the source lattice"
    post = spynnaker_post_shape(src.grid, k[:, :, :: src.stride, :: src.stride].shape[2:], tgt.stride // src.stride)
    if post != tgt.grid:
        return (
            f"sPyNNaker would give a {post[0]} x {post[1]} target (rows x cols) for the "
            f"{src.grid[0]} x {src.grid[1]} source, not the lattice's {tgt.grid[0]} x {tgt.grid[1]}: it counts "
            "(n + 2 pad - k + 1) // stride cells, one fewer than our lattice on an odd row or column count"
        )
    return None


def spynnaker_post_shape(grid: tuple[int, int], kernel: tuple[int, int], strides: int) -> tuple[int, int]:
    """The target shape sPyNNaker's ``ConvolutionConnector`` requires (its
    ``get_post_shape``: ``(n - (k - 1) + 2 pad) // stride``, at least 1) for
    a source ``grid`` and a lattice ``kernel`` padded by ``k // 2``, as the
    export pads it."""
    return tuple(max(1, (n - (k - 1) + 2 * (k // 2)) // strides) for n, k in zip(grid, kernel))


def _lattice_kernel(network: Network, pr: Conv) -> np.ndarray:
    """The kernel on the source lattice, pruned, oriented as sPyNNaker convolves."""
    k = pr.kernel.array(network.params)
    ab = np.abs(k)
    k = np.where(ab >= pr.prune * ab.max(), k, 0.0) if pr.prune > 0 else k
    s = network.population(pr.source).stride
    k = k[:, :, ::s, ::s]
    return k if pr.mode == "conv" else k[:, :, ::-1, ::-1]


def spinnaker_plan(network: Network) -> dict:
    """Per projection: ``ConvolutionConnector`` (with its kernels, strides
    and padding) or ``FromListConnector`` and why (the resource report's
    estimate beside it: :func:`~snn_fg.export.report.spinnaker_estimate`)."""
    reasons = {pr.name: _conv_reason(network, pr) for pr in network.projections}
    for name in {p.name for p in network.populations}:
        into = [pr for pr in network.incoming(name)]
        if any(reasons[pr.name] for pr in into):
            for pr in into:
                reasons[pr.name] = reasons[pr.name] or (
                    "its target also receives projections that are not "
                    "convolutions (a local-only population takes only "
                    "convolutions; sPyNNaker issue 1224)"
                )
        elif len({pr.delay_ms for pr in into}) > 1:
            for pr in into:
                reasons[pr.name] = (
                    "its target's convolutions have different delays (one delay per local-only population)"
                )
    entries = []
    for pr in network.projections:
        e = {"name": pr.name, "source": pr.source, "target": pr.target}
        if reasons[pr.name]:
            e.update(connector="FromListConnector", why=reasons[pr.name])
        else:
            k = _lattice_kernel(network, pr)
            planes = [(int(o), int(i)) for o, i in zip(*np.nonzero(np.abs(k).sum((2, 3))))]
            tgt, src = network.population(pr.target), network.population(pr.source)
            e.update(
                connector="ConvolutionConnector",
                strides=tgt.stride // src.stride,
                padding=[k.shape[2] // 2, k.shape[3] // 2],
                kernel_planes=len(planes),
                weight_scale_mv=pr.sign * pr.gain_mv,
                delay_ms=pr.delay_ms,
            )
        entries.append(e)
    conv = [e for e in entries if e["connector"] == "ConvolutionConnector"]
    out = {
        "schema": "snn-fg.spinnaker-plan/1",
        "convolution": len(conv),
        "connector_instances": sum(e["kernel_planes"] for e in conv),
        "from_list": len(entries) - len(conv),
        "projections": entries,
    }
    return out


def _tiles(cols: int, rows: int) -> int:
    """Cores of a 2-D population cut by :func:`~snn_fg.pynn.spinnaker.core_tile`."""
    a, b = core_tile(cols, rows)
    return (cols // a) * (rows // b)


def spinnaker_cores(network: Network, dt_ms: float | None = None) -> dict[str, int]:
    """The cores sPyNNaker gives each population of ``network`` (a board network) as the PyNN
    export's ``run.py`` builds it on SpiNNaker, for ``dt_ms`` steps (the network's own by default).

    Cells: 256 a core in a 1-D population; a population that a ConvolutionConnector joins is 2-D,
    one per channel where its kernels mix channels (:func:`~snn_fg.pynn.spinnaker.layout`), cut
    into tiles whose sides divide the grid's. Spike sources: one core, or the tiles of a 2-D one.
    Below :data:`SPLIT_BELOW_MS` a population that takes explicit lists gets one synapse core per
    core of cells; a local-only population (the target of convolutions) keeps its synapses on its
    own cores."""
    dt_ms = network.time_step(dt_ms, "spinnaker_cores")
    plan = spinnaker_plan(network)["projections"]
    by_name = {pr.name: pr for pr in network.projections}
    conv = [e for e in plan if e["connector"] == "ConvolutionConnector"]
    kinds = layout(
        {p.name: {"channels": p.channels} for p in network.populations},
        [(e["source"], e["target"], _lattice_kernel(network, by_name[e["name"]])) for e in conv],
    )
    local_only = {e["target"] for e in conv}
    lists = {e["target"] for e in plan if e["connector"] == "FromListConnector"}
    cores = {}
    for p in network.populations:
        rows, cols = p.grid
        kind = kinds.get(p.name)
        if kind is None:
            n = 1 if p.is_source else math.ceil(p.size / CELLS_PER_CORE)
        elif kind == "stacked":
            n = _tiles(cols, rows * p.channels)
        else:
            n = (p.channels if kind == "split" else 1) * _tiles(cols, rows)
        split = dt_ms < SPLIT_BELOW_MS and p.name in lists and p.name not in local_only
        cores[p.name] = 2 * n if split else n
    return cores
