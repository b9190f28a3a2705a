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
* **no refractory period** (NIR has none; a cell may fire again on the
  step after it spikes) and **zero padding** where ours wraps around; with
  ``deeper_reset`` (``--nir-refractory-as-deeper-reset``) a cell's reset
  stands in for its refractory period instead (:func:`reset_depth_mv`);
  snnTorch resets to 0, so every potential is written relative to the
  reset (threshold ``v_th - v_reset``, resting current for ``v_rest -
  v_reset``), which a current-based membrane computes alike;
* snnTorch reads a spike as a one-step pulse of unit height, a current of
  area ``dt`` (its fixed 1e-4 s) where NIR's spike is a unit impulse
  (measured: one spike into one cell moved snnTorch's membrane by 1e-4 of
  the NIR semantics' 0.5 mV), so ``w_in = tau_syn / tau_mem`` with
  ``r = tau_mem / dt``, ``1 / dt`` above what NIR's semantics ask;
* snnTorch's step is fixed at 1e-4 s; the graph is written for a step of
  the network's own (0.5 ms by default): every time constant is scaled by
  1e-4 s / step (``metadata["snn_fg"]["profile"]["time_scale"]``), so
  snnTorch's step stands for 0.5 ms, 5x fewer steps than at 0.1 ms.

No NIR node interpolates between pyramid levels, so a network of several
levels goes through only on one grid (``one_grid``, ``--nir-one-grid``;
:func:`one_grid_network`): every level's cells at every pixel of the frame,
a level's kernels dilated by its scale (2 for level 2 of octave levels, 4
for level 3), and each interpolation between levels the identity (a cell
reads the other level's cell at its own pixel). Cells of a coarse level
then stand at every pixel instead of every 2nd or 4th; each one still
reads its inputs at the level's spacing. Levels must be octaves apart
(``--network compact``). Each ``Conv2d`` keeps only the taps that reach a
cell of the frame, read with the ``dilation`` that skips the zeros between
them (:func:`reaching_taps`; the same sums, 14x fewer weights for the
compact network at 64 x 64). The window clock (it fires only between the
windows of a recording) is left out. :func:`snntorch_network` is the same
network for our own engines (delays of one step, refractoriness of one
step, zero padding, no clock), so the encoding's cost is measured apart
from the consumer's.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from ..frames.pyramid import level_scale
from ..network.graph import Network
from ..network.nodes import Kernel
from ..network.projections import Conv, Resize
from ..results.atomic import atomic_path
from .nir import conv2d_drive, flat_network, graph_metadata, identity_conv, nir_package

#: snnTorch 1.0's fixed time step in its NIR import (s)
SNNTORCH_DT_S = 1e-4
#: the drive (in multiples of a cell's threshold above its reset) at which a
#: deeper reset holds a cell for its refractory period (reset_depth_mv): of
#: 1, 2, 4, 8 and 16, the one closest to the exported network (fast engine)
#: over a disc and three dvs.es windows, two of them not the acceptance
#: crop's (experiments/results/nir_consumer.md)
RESET_DRIVE = 4.0
PROFILE = "snntorch"


def _dilated(k: np.ndarray, f: int) -> np.ndarray:
    """Kernel ``k`` (c_out, c_in, odd, odd) with its taps ``f`` pixels apart."""
    if f == 1:
        return k
    out = np.zeros((*k.shape[:2], (k.shape[2] - 1) * f + 1, (k.shape[3] - 1) * f + 1))
    out[:, :, ::f, ::f] = k
    return out


def level_spacing(network: Network, level: int) -> int:
    """Frame pixels between two pixels of pyramid ``level`` (1, 2, 4, ... for
    octave levels); refused for levels that are not an integer scale apart."""
    f = 1.0 / level_scale(level, network.params.levels_per_octave)
    if abs(f - round(f)) > 1e-9:
        raise ParameterError(
            f"NIR profile {PROFILE}, one grid: level {level} is {f:.3f} frame pixels per pixel; "
            "only levels an integer scale apart (octaves: levels_per_octave 1, --network compact) "
            "lie on the frame's grid"
        )
    return int(round(f))


def one_grid_network(network: Network) -> Network:
    """A flat network (:func:`~.nir.flat_network`) with every pyramid level on
    the frame's grid: each Conv's kernel (pruned) dilated by its level's
    spacing (:func:`level_spacing`), each Resize between two levels the
    identity of its channels (the module docstring says what this changes)."""
    prjs = []
    for pr in network.projections:
        src = network.population(pr.source)
        if src.role == "clock":
            prjs.append(pr)
        elif isinstance(pr, Resize):
            prjs.append(identity_conv(pr, src.channels))
        else:
            k = pr.kernel.array(network.params)
            if k.shape[2] % 2 == 0 or k.shape[3] % 2 == 0:
                raise ParameterError(f"NIR profile {PROFILE}, one grid: {pr.name} has a kernel of even size")
            k = np.where(np.abs(k) >= pr.prune * np.abs(k).max(), k, 0.0) if pr.prune > 0 else k
            prjs.append(
                dataclasses.replace(
                    pr,
                    prune=0.0,
                    kernel=Kernel(ref="array", args={"data": _dilated(k, level_spacing(network, src.level))}),
                )
            )
    shape = tuple(network.frame_shape)
    pops = tuple(p if p.role == "clock" else dataclasses.replace(p, level_shape=shape) for p in network.populations)
    return dataclasses.replace(
        network,
        one_grid=True,
        populations=pops,
        projections=tuple(prjs),
        notes=network.notes
        + (
            f"NIR profile {PROFILE}, one grid: every level on the "
            "frame's grid, kernels dilated, identity between levels.",
        ),
    )


def reset_depth_mv(neuron, step_ms: float, drive: float = RESET_DRIVE) -> float:
    """How far below its reset level a cell must reset so that, driven
    towards ``drive`` times its threshold's height above the reset, it takes
    its refractory period to climb back to the reset level:
    ``drive * (v_th - v_reset) * (exp((t_ref - step) / tau_m) - 1)`` (the
    consumer already holds it for one step). A cell driven harder climbs
    back sooner, one driven less later: a relative refractory period in
    place of an absolute one, which no NIR neuron node has."""
    hold = max(neuron.t_ref_ms - step_ms, 0.0)
    return float(drive * (neuron.v_th_mv - neuron.v_reset_mv) * np.expm1(hold / neuron.tau_m_ms))


def snntorch_network(
    network: Network,
    dt_ms: float | None = None,
    *,
    one_grid: bool = False,
    deeper_reset: bool = False,
    reset_drive: float = RESET_DRIVE,
) -> Network:
    """``network`` as the profile writes it, for our own engines at ``dt_ms``:
    flat (every population at stride 1), no clock, zero padding, every delay
    and refractory period one step; with ``one_grid`` every level on the
    frame's grid (:func:`one_grid_network`); with ``deeper_reset`` each
    cell resets :func:`reset_depth_mv` (at ``reset_drive``) lower instead of
    its refractory period. Refuses what the profile cannot write."""
    dt_ms = network.time_step(dt_ms, "snntorch_network")
    net = flat_network(network)
    if one_grid:
        net = one_grid_network(net)
    bad = [
        pr.name for pr in net.projections if isinstance(pr, Resize) and not net.population(pr.source).role == "clock"
    ]
    if bad:
        raise ParameterError(
            f"NIR profile {PROFILE}: no NIR node interpolates between pyramid levels "
            f"({bad[0]}); export a one-level network (--levels 1) or the levels on one "
            "grid (--nir-one-grid)"
        )
    two = [p.name for p in net.populations if p.neuron is not None and p.neuron.tau_exc_ms != p.neuron.tau_inh_ms]
    if two:
        raise ParameterError(
            f"NIR profile {PROFILE}: population {two[0]} has two synaptic time constants; CubaLIF has one"
        )
    reset = [p.name for p in net.populations if p.neuron is not None and p.neuron.v_reset_mv != 0]
    if reset:
        raise ParameterError(
            f"NIR profile {PROFILE}: population {reset[0]} resets to a potential other than 0; snnTorch resets to 0"
        )

    def neuron(n):
        return dataclasses.replace(
            n,
            t_ref_ms=dt_ms,
            v_reset_mv=n.v_reset_mv - (reset_depth_mv(n, dt_ms, reset_drive) if deeper_reset else 0.0),
        )

    pops = tuple(
        p if p.neuron is None else dataclasses.replace(p, neuron=neuron(p.neuron))
        for p in net.populations
        if p.role != "clock"
    )
    prjs = tuple(
        dataclasses.replace(pr, delay_ms=dt_ms, padding="zero") for pr in net.projections if isinstance(pr, Conv)
    )
    return dataclasses.replace(
        net,
        populations=pops,
        projections=prjs,
        notes=net.notes
        + (
            f"NIR profile {PROFILE}: delays and refractory periods one step"
            + (", resets deeper for the rest" if deeper_reset else "")
            + ", zero padding, no window clock.",
        ),
    )


def _cuba(nir, p, step_s: float):
    n = p.neuron
    scale = SNNTORCH_DT_S / step_s  # snnTorch's 1e-4 s step stands for step_s of the network's time
    tau_m, tau_s = n.tau_m_ms * 1e-3 * scale, n.tau_exc_ms * 1e-3 * scale

    def full(v):
        return np.full(p.shape, v, dtype=np.float64)

    return nir.CubaLIF(
        tau_mem=full(tau_m),
        tau_syn=full(tau_s),
        r=full(tau_m / SNNTORCH_DT_S),
        v_leak=full(0.0),
        v_threshold=full(n.v_th_mv - n.v_reset_mv),
        v_reset=full(0.0),
        w_in=full(tau_s / tau_m),
        metadata={"snn_fg_population": p.name, "v_rest_mv": n.v_rest_mv, "v_reset_mv": n.v_reset_mv},
    )


def _rest(nir, p, sources: list, step_s: float):
    """The 1 x 1 Conv2d of zero weights from the input whose bias is the
    resting potential's constant current into ``p`` (r w_in b = v_rest -
    v_reset, r w_in = tau_syn / step). It is also every population's first
    input: nirtorch 2.6 gives an input from later in a loop a one-element
    zero tensor on the first step, which only adds up beside an input of the
    population's shape."""
    rest = p.neuron.v_rest_mv - p.neuron.v_reset_mv  # relative to the reset, as _cuba writes it
    bias = np.full(p.channels, rest * step_s / (p.neuron.tau_exc_ms * 1e-3), np.float32)
    return nir.Conv2d(
        input_shape=p.grid,
        weight=np.zeros((p.channels, len(sources), 1, 1), np.float32),
        stride=1,
        padding=0,
        dilation=1,
        groups=1,
        bias=bias,
        metadata={"v_rest_mv": p.neuron.v_rest_mv},
    )


def reaching_taps(w: np.ndarray, grid) -> tuple[np.ndarray, int, tuple[int, int]]:
    """``(weight, dilation, padding)`` of a Conv2d that computes what the
    centred kernel ``w`` (c_out, c_in, odd, odd) computes on a ``grid``
    (rows, cols) with zero padding: only the taps that can reach a cell (an
    offset under the grid's longer side: NIR 1.0.8 infers a Conv2d's output
    shape from a square kernel), read every ``dilation`` pixels (the largest
    spacing that holds every non-zero tap, as on one grid)."""
    c = np.array(w.shape[2:]) // 2
    reach = np.minimum(c, max(grid) - 1)
    w = w[:, :, c[0] - reach[0] : c[0] + reach[0] + 1, c[1] - reach[1] : c[1] + reach[1] + 1]
    offsets = np.nonzero(np.abs(w).sum((0, 1)))
    spacing = int(np.gcd.reduce(np.concatenate([offsets[0] - reach[0], offsets[1] - reach[1], [0]])))
    if spacing > 1:
        reach = reach // spacing * spacing
        c = np.array(w.shape[2:]) // 2
        w = w[:, :, c[0] - reach[0] : c[0] + reach[0] + 1 : spacing, c[1] - reach[1] : c[1] + reach[1] + 1 : spacing]
    return w, max(spacing, 1), (int(reach[0]), int(reach[1]))


def _conv(nir, net: Network, pr: Conv, sources: list):
    """One Conv2d of signed weights (the inhibitory receptor's charge kept) into ``pr``'s target."""
    src = net.population(pr.source)
    _, exc, mag = conv2d_drive(net, pr)
    w, dilation, padding = reaching_taps(np.where(exc, mag, -mag), net.population(pr.target).grid)
    if src.is_source:  # the one Input node stacks the spike sources as channels
        full = np.zeros((w.shape[0], len(sources), *w.shape[2:]))
        full[:, sources.index(src.name)] = w[:, 0]
        w = full
    return nir.Conv2d(
        input_shape=src.grid,
        weight=w.astype(np.float32),
        stride=1,
        padding=padding,
        dilation=dilation,
        groups=1,
        bias=np.zeros(w.shape[0], np.float32),
        metadata={"projection": pr.name},
    )


def to_nir_snntorch(
    network: Network,
    *,
    step_ms: float | None = None,
    one_grid: bool = False,
    deeper_reset: bool = False,
    reset_drive: float = RESET_DRIVE,
):
    """The NIR graph of ``network`` in this profile (module docstring), for
    a consumer step of ``step_ms`` of the network's time."""
    step_ms = network.time_step(step_ms, "to_nir_snntorch")
    step_s = step_ms * 1e-3
    nir = nir_package()
    net = snntorch_network(network, step_ms, one_grid=one_grid, deeper_reset=deeper_reset, reset_drive=reset_drive)
    sources = [p.name for p in net.populations if p.is_source]
    h, w = net.frame_shape
    nodes = {
        "input": nir.Input(
            input_type={"input": np.array([len(sources), h, w])}, metadata={"channels": json.dumps(sources)}
        )
    }
    edges = []
    for p in net.populations:
        if not p.is_source:
            nodes[p.name] = _cuba(nir, p, step_s)
            nodes[f"{p.name}.rest"] = _rest(nir, p, sources, step_s)
            edges += [("input", f"{p.name}.rest"), (f"{p.name}.rest", p.name)]
    # nirtorch 2.6 takes one Output node (with two, its graph builder re-queues them for ever); a consumer
    # reads the other populations' spikes from their modules (snn_fg.export.snntorch_run.run_snntorch)
    out = net.one("group_L", 1)
    nodes["output"] = nir.Output(output_type={"output": np.array(out.shape)})
    edges.append((out.name, "output"))
    for pr in net.projections:
        nodes[pr.name] = _conv(nir, net, pr, sources)
        edges += [("input" if pr.source in sources else pr.source, pr.name), (pr.name, pr.target)]
    meta = json.loads(graph_metadata(network, net, None)["snn_fg"])
    meta["profile"] = {
        "name": PROFILE,
        "step_s": step_s,
        "time_scale": SNNTORCH_DT_S / step_s,
        "input_channels": sources,
        "one_grid": one_grid,
        "refractory": f"deeper reset, drive {reset_drive:g}" if deeper_reset else "one step",
    }
    return nir.NIRGraph(nodes=nodes, edges=edges, metadata={"snn_fg": json.dumps(meta)})


def export_nir_snntorch(
    network: Network, out, *, step_ms: float | None = None, one_grid: bool = False, deeper_reset: bool = False
) -> Path:
    """Write the graph of this profile (levels on one grid with ``one_grid``,
    refractory periods as deeper resets with ``deeper_reset``) to ``out`` (atomically)."""
    graph = to_nir_snntorch(network, step_ms=step_ms, one_grid=one_grid, deeper_reset=deeper_reset)
    with atomic_path(out, suffix=".nir") as tmp:
        nir_package().write(tmp, graph)
    return Path(out)
