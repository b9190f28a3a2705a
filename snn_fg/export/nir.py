"""``snn-fg export --format nir``: the network as a NIR 1.0.8 graph, and back.

Representation (NIR lacks several of the model's mechanisms; each choice is
named in the graph's ``metadata["approximations"]``):

* **Units**: time in seconds, potentials in mV, currents in mV (nA through
  1 MOhm). A spike is a Dirac impulse of unit area: an edge weight ``w``
  into a synapse node adds ``w`` to its current.
* **Neurons**: each population is a ``LIF`` node (``tau = tau_m``,
  ``r = 1``, ``v_leak = v_rest``, threshold, reset) fed by two ``LI``
  synapse nodes ``<pop>.exc`` (``tau = tau_exc``, ``r = tau_exc``) and
  ``<pop>.inh`` (``tau = tau_inh``, ``r = -tau_inh``): the two exponential
  currents are exact. The **refractory period** is not in NIR: it is
  ``metadata["t_ref_s"]`` on the LIF node (membrane clamped at reset,
  currents decaying).
* **Weight-shared projections** (Conv) are ``Conv2d`` nodes (PyTorch
  cross-correlation; a ``conv``-mode kernel is flipped), split by the sign
  of their drive into ``<proj>.exc`` and ``<proj>.inh`` (the magnitude moved
  to the other receptor scaled by ``tau_own / tau_other``, as on PyNN),
  each followed by a ``Delay`` node (uniform per projection).
  **Wrap-around padding** is written as NIR's zero padding with
  ``metadata["padding"] = "wrap"``.
* **Stride-2 lattices**: NIR ``Conv2d`` cannot upsample, so populations on a
  coarser lattice are written on their level's full grid (stride 1; 4x the
  cells). A kernel read from a strided source keeps only its taps at
  lattice offsets (so each cell receives what a lattice cell did), and an
  interpolation between two lattices of one level becomes the identity.
* **Resize between pyramid levels** (non-integer scale): no NIR node can
  express it compactly; the graph is cut there. The source feeds an
  ``Output`` node ``<proj>.out``, the target's synapse is fed by an
  ``Input`` node ``<proj>.in`` through a ``Delay``; ``metadata`` holds the
  interpolation, gain, sign and pruning, and a consumer must connect the
  pair itself (:func:`~snn_fg.export.nir_import.read_nir` does).
* **Outputs**: the border-ownership and grouping populations (what the maps
  are decoded from) each feed an ``Output`` node ``<pop>.spikes``.
* **Input-dependent edge mask**: dropped (the board network, see
  :mod:`.board`).

:func:`~snn_fg.export.nir_import.read_nir` turns such a file back into a
runnable :class:`~snn_fg.network.Network` (NIR semantics: stride-1 lattices,
split receptors, array kernels), so a round trip can be simulated and measured.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from .. import __version__
from ..backends import cancel
from ..errors import ParameterError, install_hint
from ..lowering.quantise import projection_scales
from ..network.graph import Network
from ..network.nodes import Kernel, Population
from ..network.projections import Conv, Resize
from ..pynn.cells import quantise, split_receptors
from ..results.atomic import atomic_path
from ..results.outputs import check_output_file
from .board import board_network, fingerprint

MS = 1e-3
SCHEMA = "snn-fg.nir/1"
APPROXIMATIONS = {
    "refractory_period": "not in NIR: metadata t_ref_s on each LIF node",
    "two_synaptic_time_constants": "exact: two LI synapse nodes per population (<pop>.exc, <pop>.inh)",
    "negative_kernel_lobes": "moved to the other receptor, magnitude scaled by tau_own/tau_other (same charge)",
    "wrap_padding": "written as zero padding with metadata padding='wrap'",
    "stride_2_lattices": "written at stride 1 (4x the cells); kernels from a strided source keep their lattice "
    "taps; interpolation between lattices of one level becomes the identity",
    "resize_between_levels": "graph cut: Output <proj>.out and Input <proj>.in with the interpolation in metadata",
    "edge_mask": "dropped: every cell of every population (a fixed network)",
    "delays": "one Delay node per projection (uniform), seconds",
    "spike_convention": "a spike is a unit-area impulse; LI synapse r = tau so weight w adds w (mV) to the current",
}


def nir_package():
    """The ``nir`` package, or one line saying how to install it."""
    try:
        import nir
    except ImportError:
        raise ParameterError(f"NIR export needs the nir package: {install_hint('nir')}") from None
    return nir


def flat_network(network: Network) -> Network:
    """The network NIR can hold: the board network with every population at
    stride 1 (kernels from strided sources keep only their lattice taps)."""
    net = board_network(network)
    strides = {p.name: p.stride for p in net.populations}
    pops = tuple(dataclasses.replace(p, stride=1) for p in net.populations)
    prjs = []
    for pr in net.projections:
        s = strides[pr.source]
        src, tgt = net.population(pr.source), net.population(pr.target)
        if isinstance(pr, Resize) and src.level_shape == tgt.level_shape:
            # between two lattices of one level: at stride 1 the interpolation is the identity
            pr = identity_conv(pr, src.channels)
        if isinstance(pr, Conv) and s > 1:
            k = pr.kernel.array(net.params)
            keep = np.abs(k) >= pr.prune * np.abs(k).max() if pr.prune > 0 else k != 0
            pr = dataclasses.replace(
                pr, kernel=Kernel(ref="array", args={"data": _dilate(np.where(keep, k, 0.0), s)}), prune=0.0
            )
        prjs.append(pr)
    return dataclasses.replace(net, populations=pops, projections=tuple(prjs))


def identity_conv(pr: Resize, channels: int) -> Conv:
    """Resize ``pr`` as a Conv passing each of ``channels`` on at the same pixel (same gain and delay)."""
    ident = Kernel(
        ref="channel_map", args={"n_out": channels, "n_in": channels, "entries": [[c, c, 1.0] for c in range(channels)]}
    )
    return Conv(
        name=pr.name,
        source=pr.source,
        target=pr.target,
        kernel=ident,
        sign=pr.sign,
        gain_mv=pr.gain_mv,
        delay_ms=pr.delay_ms,
        calibrated=pr.calibrated,
    )


def _dilate(k: np.ndarray, s: int) -> np.ndarray:
    """A kernel read on a stride-``s`` lattice, written on the full grid: its
    taps are already at level-pixel offsets, only those on the lattice count."""
    out = np.zeros_like(k)
    c0, c1 = k.shape[2] // 2, k.shape[3] // 2
    out[:, :, c0 % s :: s, c1 % s :: s] = k[:, :, c0 % s :: s, c1 % s :: s]
    return out


def _js(d: dict) -> str:
    """Node metadata as one JSON string (HDF5 cannot store None or nested lists)."""
    return json.dumps(d)


def _population_nodes(nir, p: Population) -> dict:
    shape = p.shape
    n = p.neuron

    def full(v):  # float64: the values read back exactly (constant arrays compress to nothing)
        return np.full(shape, v, dtype=np.float64)

    meta = {
        "snn_fg_population": _js({k: v for k, v in p.to_dict().items() if k != "neuron"}),
        "t_ref_s": n.t_ref_ms * MS,
        "refractory": "membrane held at v_reset; currents keep decaying",
    }
    return {
        p.name: nir.LIF(
            tau=full(n.tau_m_ms * MS),
            r=full(1.0),
            v_leak=full(n.v_rest_mv),
            v_threshold=full(n.v_th_mv),
            v_reset=full(n.v_reset_mv),
            metadata=meta,
        ),
        f"{p.name}.exc": nir.LI(tau=full(n.tau_exc_ms * MS), r=full(n.tau_exc_ms * MS), v_leak=full(0.0)),
        f"{p.name}.inh": nir.LI(tau=full(n.tau_inh_ms * MS), r=full(-n.tau_inh_ms * MS), v_leak=full(0.0)),
    }


def conv2d_drive(net: Network, pr: Conv, bits=None, scale: float = 0.0):
    """The signed drive ``sign * gain * K`` (mV) of a Conv as a NIR ``Conv2d``
    weight (pruned, cross-correlation as in PyTorch), quantised to ``bits``,
    and how it splits between the receptors: ``(drive, excitatory mask, |weight|)``."""
    k = pr.kernel.array(net.params)
    if pr.prune > 0:
        k = np.where(np.abs(k) >= pr.prune * np.abs(k).max(), k, 0.0)
    if pr.mode == "conv":
        k = k[:, :, ::-1, ::-1]
    drive = quantise(pr.sign * pr.gain_mv * k, bits, scale)
    n = net.population(pr.target).neuron
    return (drive, *split_receptors(drive, pr.sign, n.tau_exc_ms, n.tau_inh_ms))


def _conv_nodes(nir, net: Network, pr: Conv, scale: float | None, bits) -> tuple[dict, list]:
    src, tgt = net.population(pr.source), net.population(pr.target)
    k, exc, mag = conv2d_drive(net, pr, bits, scale or 0.0)
    nodes, edges = {}, []
    pad = "wrap" if pr.padding == "wrap" else "zero"
    for rec, sel, sgn in (("exc", exc, 1.0), ("inh", ~exc & (mag > 0), 1.0)):
        w = np.where(sel & (mag > 0), sgn * mag, 0.0).astype(np.float32)
        if not w.any():
            continue
        conv = f"{pr.name}.{rec}"
        nodes[conv] = nir.Conv2d(
            input_shape=src.grid,
            weight=w,
            stride=1,
            padding=(k.shape[2] // 2, k.shape[3] // 2),
            dilation=1,
            groups=1,
            bias=np.zeros(w.shape[0], np.float32),
            metadata={
                "padding": pad,
                "projection": pr.name,
                "receptor": rec,
                "sign": pr.sign,
                "scale_mv": scale or 0.0,
            },
        )
        nodes[f"{conv}.delay"] = nir.Delay(delay=np.full(tgt.shape, pr.delay_ms * MS, np.float32))
        edges += [(pr.source, conv), (conv, f"{conv}.delay"), (f"{conv}.delay", f"{pr.target}.{rec}")]
    return nodes, edges


def _resize_nodes(nir, net: Network, pr: Resize) -> tuple[dict, list]:
    src, tgt = net.population(pr.source), net.population(pr.target)
    rec = "exc" if pr.sign > 0 else "inh"
    meta = {
        "snn_fg_projection": _js(pr.to_dict()),
        "receptor": rec,
        "semantics": "target(c,i,j) += sign*gain_mv*sum A_r[i,i'] A_c[j,j'] spikes(c,i',j') (half-pixel "
        "centres, OpenCV interpolation, clamped); see snn_fg.lowering.interp",
    }
    nodes = {
        f"{pr.name}.out": nir.Output(output_type={"output": np.array(src.shape)}, metadata=meta),
        f"{pr.name}.in": nir.Input(input_type={"input": np.array(tgt.shape)}, metadata=meta),
        f"{pr.name}.delay": nir.Delay(delay=np.full(tgt.shape, pr.delay_ms * MS, np.float32)),
    }
    if src.is_source:  # the spike source's own Input node feeds the cut
        nodes.pop(f"{pr.name}.out")
        edges = []
    else:
        edges = [(pr.source, f"{pr.name}.out")]
    edges += [(f"{pr.name}.in", f"{pr.name}.delay"), (f"{pr.name}.delay", f"{pr.target}.{rec}")]
    return nodes, edges


def _parts(nir, network: Network, net: Network, weight_bits, edges: list):
    """The graph's nodes ``(name, node)``, made one at a time (each
    population and projection when its turn comes), appending their edges
    to ``edges``."""
    scales = projection_scales(net, weight_bits) if weight_bits else {}
    for p in net.populations:
        if p.is_source:
            yield (
                p.name,
                nir.Input(input_type={"input": np.array(p.shape)}, metadata={"snn_fg_population": _js(p.to_dict())}),
            )
            continue
        yield from _population_nodes(nir, p).items()
        edges += [(f"{p.name}.exc", p.name), (f"{p.name}.inh", p.name)]
        if p.role.startswith(("bo_", "group_")):  # what the maps are decoded from
            yield f"{p.name}.spikes", nir.Output(output_type={"output": np.array(p.shape)})
            edges.append((p.name, f"{p.name}.spikes"))
    for pr in net.projections:
        n, e = (
            _conv_nodes(nir, net, pr, scales.get(pr.name), weight_bits)
            if isinstance(pr, Conv)
            else _resize_nodes(nir, net, pr)
        )
        edges += e
        yield from n.items()


def graph_metadata(network: Network, net: Network, weight_bits) -> dict:
    meta = {
        "schema": SCHEMA,
        "model": "snn-fg figure-ground network (D'Angelo et al. 2025)",
        "snn_fg_version": __version__,
        "network_sha256": fingerprint(network),
        "frame_shape": list(net.frame_shape),
        "params": net.params.to_dict(),
        **net.settings(),  # (every one: read back, the graph gives the same network)
        "weight_bits": weight_bits or 0,
        "time_unit": "s",
        "approximations": APPROXIMATIONS,
        "notes": list(net.notes),
    }
    return {"snn_fg": json.dumps(meta)}


def to_nir(network: Network, *, weight_bits: int | None = None):
    """The NIR graph of ``network`` (see the module docstring), whole in memory."""
    nir = nir_package()
    net = flat_network(network)
    edges: list = []
    nodes = dict(_parts(nir, network, net, weight_bits, edges))
    return nir.NIRGraph(nodes=nodes, edges=edges, metadata=graph_metadata(network, net, weight_bits))


def _write_hdf5(group, d: dict):
    """A node's dictionary into an HDF5 group, laid out as ``nir.write`` lays
    it out (strings as string datasets, arrays gzipped, dicts as groups,
    empty metadata left out), so that ``nir.read`` reads it."""
    import h5py  # (comes with the nir extra, as nir itself: imported only when NIR is written or read)

    for k, v in d.items():
        if k == "metadata" and v == {}:
            continue
        if isinstance(v, dict):
            _write_hdf5(group.create_group(str(k)), v)
        elif isinstance(v, str):
            group.create_dataset(k, data=v, dtype=h5py.string_dtype())
        elif isinstance(v, np.ndarray):
            group.create_dataset(k, data=v, dtype=v.dtype, compression="gzip")
        else:
            group.create_dataset(k, data=v)


def write_streaming(path, network: Network, *, weight_bits: int | None = None) -> Path:
    """Write the NIR file of ``network`` node by node: each node's arrays
    exist only while it is written. ``nir.write`` of the whole graph copies
    every array twice over (``dataclasses.asdict`` of the graph, then of each
    node), 5.5 GB for the default 304 x 240 network."""
    import h5py

    nir = nir_package()
    net = flat_network(network)
    edges: list = []
    with h5py.File(path, "w") as f:
        f.create_dataset("version", data=nir.version, dtype=h5py.string_dtype())
        root = f.create_group("node")
        nodes = root.create_group("nodes")
        for name, node in _parts(nir, network, net, weight_bits, edges):
            cancel.check()  # (Ctrl-C and SIGTERM stop the export between nodes: tens of seconds for a network)
            _write_hdf5(nodes.create_group(name), node.to_dict())
        _write_hdf5(root, {"type": "NIRGraph", "edges": edges, "metadata": graph_metadata(network, net, weight_bits)})
    return Path(path)


def export_nir(network: Network, out, *, weight_bits: int | None = None, force: bool = False) -> Path:
    """Write the NIR graph of ``network`` to ``out`` (atomically, node by
    node: :func:`write_streaming`).

    Examples
    --------
    >>> import tempfile, pathlib, nir
    >>> from snn_fg.network import build_network
    >>> from snn_fg.params import ModelParams
    >>> path = export_nir(build_network(ModelParams(levels=2), (24, 24)), pathlib.Path(tempfile.mkdtemp()) / "n.nir")
    >>> g = nir.read(path)
    >>> sorted({type(n).__name__ for n in g.nodes.values()})
    ['Conv2d', 'Delay', 'Input', 'LI', 'LIF', 'Output']
    """
    out = check_output_file(out, force, "export_nir", (".nir",))  # (the CLI's rule: a user's other file is kept)
    with atomic_path(out, suffix=".nir") as tmp:
        write_streaming(tmp, network, weight_bits=weight_bits)
    return out


def node_kinds(path) -> dict[str, int]:
    """How many nodes of each kind a NIR file holds (``{"LIF": 52, ...}``,
    most first), read from each node's ``type`` without loading its arrays:
    what a consumer must accept, said when the file is written."""
    import h5py

    kinds: dict[str, int] = {}
    with h5py.File(path, "r") as f:
        for node in f["node/nodes"].values():
            kind = node["type"][()]
            kind = kind.decode() if isinstance(kind, bytes) else str(kind)
            kinds[kind] = kinds.get(kind, 0) + 1
    return dict(sorted(kinds.items(), key=lambda kv: (-kv[1], kv[0])))


def describe_nir(path) -> str:
    """``5.6 MB; 553 nodes: 180 Delay, 154 Conv2d, ...``: the file's size and nodes, for the export's last line."""
    kinds = node_kinds(path)
    listed = ", ".join(f"{n} {k}" for k, n in kinds.items())
    return f"{Path(path).stat().st_size / 1e6:.1f} MB; {sum(kinds.values())} nodes: {listed}"
