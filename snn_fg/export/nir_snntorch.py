"""``snn-fg export --format nir --nir-profile snntorch``: the graph in the node kinds snnTorch imports, and its run.

snnTorch 1.0.0 (``snntorch.import_nir.import_from_nir``, executed by
nirtorch 2.6's interpreter, which carries a feedback edge over one step)
imports Affine, Linear, Conv2d, Flatten, AvgPool2d, IF, LIF and CubaLIF.
The exact graph (:mod:`.nir`) stops it at the first LIF node: ``v_leak``
must be 0 (``AssertionError: v_leak not supported``); past that it has no
mapping for ``LI`` (the synaptic currents) or ``Delay`` (``ValueError:
Unknown node type``), and nirtorch takes one ``Input`` node (ours has one
per spike source and one per cut between pyramid levels). This profile
writes instead:

* each population one ``CubaLIF`` (its one synaptic time constant; refused
  when a population's excitatory and inhibitory ones differ), ``v_leak = 0``
  and ``v_reset = 0``, its resting potential a constant current: the bias of
  a 1 x 1 ``Conv2d`` ``<pop>.rest`` of zero weights from the input (exact
  once the synaptic current has settled);
* each projection one ``Conv2d`` of signed weights straight into its target:
  **no delays** (inside a feedback loop the consumer's one step, elsewhere
  none);
* one ``Input`` node ``input`` of shape (2, H, W): ON and OFF pixels, and
  one ``Output`` node (nirtorch 2.6 loops for ever on two);
* **no refractory period** (NIR has none) and **zero padding** where ours
  wraps around;
* snnTorch reads a spike as a one-step pulse of unit height, a current of
  area ``dt`` (its fixed 1e-4 s) where NIR's spike is a unit impulse
  (measured: one spike into one cell moved snnTorch's membrane by 1e-4 of
  the NIR semantics' 0.5 mV), so ``w_in = tau_syn / tau_mem`` with
  ``r = tau_mem / dt``, ``1 / dt`` above what NIR's semantics ask;
* snnTorch's step is fixed at 1e-4 s; the graph is written for a step of
  the network's own (0.5 ms by default): every time constant is scaled by
  1e-4 s / step (``metadata["snn_fg"]["profile"]["time_scale"]``), so
  snnTorch's step stands for 0.5 ms, 5x fewer steps than at 0.1 ms.

Only one-level networks: no NIR node interpolates between pyramid levels.
The window clock (it fires only between the windows of a recording) is left
out. :func:`snntorch_network` is the same network for our own engines
(delays of one step, refractoriness of one step, zero padding, no clock),
so the encoding's cost is measured apart from the consumer's.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from ..network.graph import Network
from ..network.projections import Conv, Resize
from .nir import _graph_metadata, _nir, conv2d_drive, flat_network

#: snnTorch 1.0's fixed time step in its NIR import (s)
SNNTORCH_DT_S = 1e-4
PROFILE = "snntorch"


def snntorch_network(network: Network, dt_ms: float = 0.5) -> Network:
    """``network`` as the profile writes it, for our own engines at ``dt_ms``:
    flat (every population at stride 1), no clock, zero padding, every delay
    and refractory period one step. Refuses what the profile cannot write."""
    net = flat_network(network)
    bad = [pr.name for pr in net.projections if isinstance(pr, Resize)
           and not net.population(pr.source).role == "clock"]
    if bad:
        raise ParameterError(f"NIR profile {PROFILE}: no NIR node interpolates between pyramid levels "
                             f"({bad[0]}); export a one-level network (--levels 1)")
    two = [p.name for p in net.populations if p.neuron is not None and p.neuron.tau_exc_ms != p.neuron.tau_inh_ms]
    if two:
        raise ParameterError(f"NIR profile {PROFILE}: population {two[0]} has two synaptic time constants; "
                             "CubaLIF has one")
    reset = [p.name for p in net.populations if p.neuron is not None and p.neuron.v_reset_mv != 0]
    if reset:
        raise ParameterError(f"NIR profile {PROFILE}: population {reset[0]} resets to a potential other than 0; "
                             "snnTorch resets to 0")
    pops = tuple(p if p.neuron is None else dataclasses.replace(p, neuron=dataclasses.replace(p.neuron,
                 t_ref_ms=dt_ms)) for p in net.populations if p.role != "clock")
    prjs = tuple(dataclasses.replace(pr, delay_ms=dt_ms, padding="zero") for pr in net.projections
                 if isinstance(pr, Conv))
    return dataclasses.replace(net, populations=pops, projections=prjs,
                               notes=net.notes + (f"NIR profile {PROFILE}: delays and refractory periods one step, "
                                                  "zero padding, no window clock.",))


def _cuba(nir, p, step_s: float):
    n = p.neuron
    scale = SNNTORCH_DT_S / step_s          # snnTorch's 1e-4 s step stands for step_s of the network's time
    tau_m, tau_s = n.tau_m_ms * 1e-3 * scale, n.tau_exc_ms * 1e-3 * scale

    def full(v):
        return np.full(p.shape, v, dtype=np.float64)
    return nir.CubaLIF(tau_mem=full(tau_m), tau_syn=full(tau_s), r=full(tau_m / SNNTORCH_DT_S), v_leak=full(0.0),
                       v_threshold=full(n.v_th_mv), v_reset=full(0.0), w_in=full(tau_s / tau_m),
                       metadata={"snn_fg_population": p.name, "v_rest_mv": n.v_rest_mv})


def _rest(nir, p, sources: list, step_s: float):
    """The 1 x 1 Conv2d of zero weights from the input whose bias is the
    resting potential's constant current into ``p`` (r w_in b = v_rest, r w_in
    = tau_syn / step). It is also every population's first input: nirtorch
    2.6 gives an input from later in a loop a one-element zero tensor on the
    first step, which only adds up beside an input of the population's shape."""
    bias = np.full(p.channels, p.neuron.v_rest_mv * step_s / (p.neuron.tau_exc_ms * 1e-3), np.float32)
    return nir.Conv2d(input_shape=p.grid, weight=np.zeros((p.channels, len(sources), 1, 1), np.float32), stride=1,
                      padding=0, dilation=1, groups=1, bias=bias, metadata={"v_rest_mv": p.neuron.v_rest_mv})


def _conv(nir, net: Network, pr: Conv, sources: list):
    """One Conv2d of signed weights (the inhibitory receptor's charge kept) into ``pr``'s target."""
    src = net.population(pr.source)
    k, exc, mag = conv2d_drive(net, pr)
    w = np.where(exc, mag, -mag)
    if src.is_source:           # the one Input node stacks the spike sources as channels
        full = np.zeros((w.shape[0], len(sources), *w.shape[2:]))
        full[:, sources.index(src.name)] = w[:, 0]
        w = full
    return nir.Conv2d(input_shape=src.grid, weight=w.astype(np.float32), stride=1,
                      padding=(k.shape[2] // 2, k.shape[3] // 2), dilation=1, groups=1,
                      bias=np.zeros(w.shape[0], np.float32), metadata={"projection": pr.name})


def to_nir_snntorch(network: Network, *, step_ms: float = 0.5):
    """The NIR graph of ``network`` in this profile (module docstring), for
    a consumer step of ``step_ms`` of the network's time."""
    step_s = step_ms * 1e-3
    nir = _nir()
    net = snntorch_network(network)
    sources = [p.name for p in net.populations if p.is_source]
    h, w = net.frame_shape
    nodes = {"input": nir.Input(input_type={"input": np.array([len(sources), h, w])},
                                metadata={"channels": json.dumps(sources)})}
    edges = []
    for p in net.populations:
        if not p.is_source:
            nodes[p.name] = _cuba(nir, p, step_s)
            nodes[f"{p.name}.rest"] = _rest(nir, p, sources, step_s)
            edges += [("input", f"{p.name}.rest"), (f"{p.name}.rest", p.name)]
    # nirtorch 2.6 takes one Output node (with two, its graph builder re-queues them for ever); a consumer
    # reads the other populations' spikes from their modules (run_snntorch)
    out = net.one("group_L", 1)
    nodes["output"] = nir.Output(output_type={"output": np.array(out.shape)})
    edges.append((out.name, "output"))
    for pr in net.projections:
        nodes[pr.name] = _conv(nir, net, pr, sources)
        edges += [("input" if pr.source in sources else pr.source, pr.name), (pr.name, pr.target)]
    meta = json.loads(_graph_metadata(network, net, None)["snn_fg"])
    meta["profile"] = {"name": PROFILE, "step_s": step_s, "time_scale": SNNTORCH_DT_S / step_s,
                       "input_channels": sources}
    return nir.NIRGraph(nodes=nodes, edges=edges, metadata={"snn_fg": json.dumps(meta)})


def export_nir_snntorch(network: Network, out, *, step_ms: float = 0.5) -> Path:
    """Write the graph of this profile to ``out`` (atomically)."""
    from ..atomic import atomic_path

    graph = to_nir_snntorch(network, step_ms=step_ms)
    with atomic_path(out, suffix=".nir") as tmp:
        _nir().write(tmp, graph)
    return Path(out)


def _snntorch():
    try:
        import torch
        from snntorch.import_nir import import_from_nir
    except ImportError:
        raise ParameterError('running a NIR graph with snnTorch needs torch and snntorch: pip install '
                             '"snn-fg[snntorch]"') from None
    return torch, import_from_nir


def run_snntorch(graph, network: Network, inputs, *, step_ms: float, duration_ms: float,
                 count_from_ms: float) -> dict:
    """Simulate a graph of this profile made from ``network`` for a step of
    ``step_ms`` with snnTorch (through nirtorch) on ``inputs``
    (:class:`~snn_fg.lowering.input_spikes.InputSpikes` on that step), counting
    every population's spikes from ``count_from_ms`` on: population name ->
    counts per cell (flat order)."""
    import contextlib
    import io

    torch, import_from_nir = _snntorch()
    net = snntorch_network(network)
    with contextlib.redirect_stdout(io.StringIO()):        # snnTorch prints its weight-scaling notes
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
            frame[idx[bounds[k]:bounds[k + 1]]] = 1.0
            live[0] = k * step_ms >= count_from_ms - 1e-9
            _, state = module(torch.from_numpy(frame.reshape(1, 2, h, w)), state)
    return counts
