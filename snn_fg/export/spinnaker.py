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

import numpy as np

from ..network.graph import Network
from ..network.projections import Conv
from .report import resource_report


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


def spinnaker_plan(network: Network, *, estimate: bool = False, dt_ms: float | None = None) -> dict:
    """Per projection: ``ConvolutionConnector`` (with its kernels, strides
    and padding) or ``FromListConnector`` and why; with ``estimate`` also the
    resource report's SpiNNaker 1 figures (cores, chips, boards) for
    ``dt_ms`` steps, which ``run.py --virtual-board`` sets beside sPyNNaker's."""
    dt_ms = network.time_step(dt_ms, "spinnaker_plan")
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
    if estimate:
        out["estimate"] = {
            k: v
            for k, v in resource_report(network, dt_ms)["targets"]["spinnaker1"].items()
            if k in ("cores", "chips", "boards_spinn5", "note")
        }
    return out
