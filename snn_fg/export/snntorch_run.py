"""A graph of the snnTorch profile (:mod:`snn_fg.export.nir_snntorch`) run by
snnTorch itself, through nirtorch: an independent NIR consumer, whose spike
counts are set beside our engines' on the same network
(:func:`~snn_fg.export.nir_snntorch.snntorch_network`). The stepping is the
code a NIR export folder's ``run.py`` runs (:mod:`.snntorch_loop.counting`)."""

from __future__ import annotations

from ..errors import ParameterError, install_hint
from ..network.graph import Network
from .nir_snntorch import snntorch_network
from .snntorch_loop.counting import count_spikes, first_counted_step


def check_snntorch() -> None:
    """One line saying how to install torch and snnTorch, unless both import."""
    # (torch and snnTorch are an optional extra, and torch takes seconds to import: only when a graph is run)
    try:
        import torch  # noqa: F401
        from snntorch.import_nir import import_from_nir  # noqa: F401
    except ImportError:
        raise ParameterError(
            f"running a NIR graph with snnTorch needs torch and snntorch: {install_hint('snntorch')}"
        ) from None


def run_snntorch(
    graph, network: Network, inputs, *, step_ms: float, duration_ms: float, count_from_ms: float, one_grid: bool = False
) -> dict:
    """Simulate a graph of this profile made from ``network`` for a step of
    ``step_ms`` with snnTorch (through nirtorch) on ``inputs``
    (:class:`~snn_fg.lowering.input_spikes.InputSpikes` on that step), counting
    every population's spikes from ``count_from_ms`` on: population name ->
    counts per cell (flat order); ``one_grid`` as the graph was written."""
    check_snntorch()
    net = snntorch_network(network, one_grid=one_grid)
    n_steps = int(round(duration_ms / step_ms))
    idx, st = inputs.spike_times_steps(n_steps)
    cells = [(p.name, p.size) for p in net.populations if p.neuron is not None]
    return count_spikes(
        graph,
        cells,
        idx,
        st,
        inputs.shape,
        n_steps=n_steps,
        count_from_step=first_counted_step(count_from_ms, step_ms),
    )
