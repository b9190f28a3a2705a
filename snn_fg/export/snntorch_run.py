"""A graph of the snnTorch profile (:mod:`snn_fg.export.nir_snntorch`) run by
snnTorch itself, through nirtorch: an independent NIR consumer, whose spike
counts are set beside our engines' on the same network
(:func:`~snn_fg.export.nir_snntorch.snntorch_network`)."""

from __future__ import annotations

import contextlib
import io

import numpy as np

from ..errors import ParameterError, install_hint
from ..network.graph import Network
from .nir_snntorch import snntorch_network


def _snntorch():
    # (torch and snnTorch are an optional extra, and torch takes seconds to import: only when a graph is run)
    try:
        import torch
        from snntorch.import_nir import import_from_nir
    except ImportError:
        raise ParameterError(
            f"running a NIR graph with snnTorch needs torch and snntorch: {install_hint('snntorch')}"
        ) from None
    return torch, import_from_nir


def run_snntorch(
    graph, network: Network, inputs, *, step_ms: float, duration_ms: float, count_from_ms: float, one_grid: bool = False
) -> dict:
    """Simulate a graph of this profile made from ``network`` for a step of
    ``step_ms`` with snnTorch (through nirtorch) on ``inputs``
    (:class:`~snn_fg.lowering.input_spikes.InputSpikes` on that step), counting
    every population's spikes from ``count_from_ms`` on: population name ->
    counts per cell (flat order); ``one_grid`` as the graph was written."""
    torch, import_from_nir = _snntorch()
    net = snntorch_network(network, one_grid=one_grid)
    with contextlib.redirect_stdout(io.StringIO()):  # snnTorch prints its weight-scaling notes
        module = import_from_nir(graph)
    mods = dict(module.named_modules())
    counts, live = {}, [False]

    def hook(name):
        def count(_mod, _inp, out):
            if live[0]:
                counts[name] += (out[0] if isinstance(out, tuple) else out).reshape(-1).numpy().astype(np.int64)

        return count

    for p in net.populations:
        if p.neuron is not None:
            counts[p.name] = np.zeros(p.size, np.int64)
            mods[p.name.replace(".", "_")].register_forward_hook(hook(p.name))
    n_steps = int(round(duration_ms / step_ms))
    idx, st = inputs.spike_times_steps(n_steps)
    order = np.argsort(st, kind="stable")
    idx, st = idx[order], st[order]
    bounds = np.searchsorted(st, np.arange(n_steps + 1))
    h, w = inputs.shape
    frame = np.zeros(2 * h * w, np.float32)
    state = None
    with torch.no_grad():
        for k in range(n_steps):
            frame[:] = 0
            frame[idx[bounds[k] : bounds[k + 1]]] = 1.0
            live[0] = k * step_ms >= count_from_ms - 1e-9
            _, state = module(torch.from_numpy(frame.reshape(1, 2, h, w)), state)
    return counts
