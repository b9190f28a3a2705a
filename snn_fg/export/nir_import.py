"""The NIR import: a graph written by :func:`snn_fg.export.nir.export_nir`
read back into a runnable :class:`~snn_fg.network.Network` (NIR semantics:
stride-1 lattices, receptors split, array kernels; the representation is
described in :mod:`snn_fg.export.nir`), so that a round trip can be
simulated and measured, and ``snn-fg export --network FILE.nir`` reads one.
"""

from __future__ import annotations

import gzip
import json
import shutil
import tempfile
from pathlib import Path

import numpy as np

from ..errors import InputError, ParameterError
from ..network.graph import SETTINGS, Network
from ..network.nodes import Kernel, Neuron, Population
from ..network.projections import Conv, Resize
from ..params import ModelParams
from .nir import MS, SCHEMA, nir_package


def read_nir(path) -> Network:
    """A runnable :class:`~snn_fg.network.Network` from a NIR file written by
    :func:`~snn_fg.export.nir.export_nir` (NIR semantics: stride-1 lattices, receptors split,
    array kernels). A file that is not NIR, or not one of ours, is an
    :class:`~snn_fg.errors.InputError` naming it."""
    nir = nir_package()
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "no such file")
    try:
        g = read_graph(nir, path)
        meta = json.loads(g.metadata["snn_fg"])
    except (OSError, EOFError, KeyError, ValueError, TypeError) as exc:
        raise InputError(path, f"not a NIR graph written by snn-fg ({type(exc).__name__}: {exc})") from None
    if meta.get("schema") != SCHEMA:
        raise InputError(path, f"NIR graph of schema {meta.get('schema')!r}, not {SCHEMA!r}")
    try:
        return _network_from(g, meta)
    except (KeyError, ValueError, TypeError, ParameterError) as exc:
        raise InputError(path, f"inconsistent snn-fg NIR graph: {exc}") from None


def read_graph(nir, path: Path):
    """``nir.read``, also of a gzipped file (``.nir.gz``, as networks/ keeps it)."""
    if path.suffix != ".gz":
        return nir.read(path)
    with tempfile.TemporaryDirectory() as tmp, gzip.open(path, "rb") as src:
        raw = Path(tmp) / path.stem
        with open(raw, "wb") as dst:
            shutil.copyfileobj(src, dst)
        return nir.read(raw)


def _network_from(g, meta) -> Network:
    pops, prjs = [], []
    into = {dst: src for src, dst in g.edges}  # a Conv2d has one source
    for name, node in g.nodes.items():
        m = getattr(node, "metadata", None) or {}
        if "snn_fg_population" not in m:
            continue
        d = json.loads(m["snn_fg_population"])
        if type(node).__name__ == "LIF":
            exc, inh = g.nodes[f"{name}.exc"], g.nodes[f"{name}.inh"]
            d["neuron"] = Neuron(
                tau_m_ms=float(node.tau.flat[0]) / MS,
                tau_exc_ms=float(exc.tau.flat[0]) / MS,
                tau_inh_ms=float(inh.tau.flat[0]) / MS,
                v_rest_mv=float(node.v_leak.flat[0]),
                v_reset_mv=float(node.v_reset.flat[0]),
                v_th_mv=float(node.v_threshold.flat[0]),
                t_ref_ms=float(m["t_ref_s"]) / MS,
            ).to_dict()
        d["stride"], d["edge_mask"] = 1, False
        pops.append(Population.from_dict(d))
    for name, node in g.nodes.items():
        m = getattr(node, "metadata", None) or {}
        if type(node).__name__ == "Conv2d" and "projection" in m:
            delay = g.nodes[f"{name}.delay"].delay.flat[0] / MS
            sign = 1 if m["receptor"] == "exc" else -1
            w = np.asarray(node.weight, np.float64)
            synapse = next(dst for src, dst in g.edges if src == f"{name}.delay")
            prjs.append(
                Conv(
                    name=name.replace(".", "_"),
                    source=into[name],
                    target=synapse.rsplit(".", 1)[0],
                    kernel=Kernel(ref="array", args={"data": np.abs(w)}),
                    mode="corr",
                    padding=m["padding"],
                    sign=sign,
                    gain_mv=1.0,
                    delay_ms=float(delay),
                )
            )
        elif type(node).__name__ == "Input" and "snn_fg_projection" in m:
            d = json.loads(m["snn_fg_projection"])
            d.pop("type")
            prjs.append(Resize.from_dict(d))
    return Network(
        params=ModelParams.from_dict(meta["params"]),
        frame_shape=tuple(meta["frame_shape"]),
        populations=tuple(pops),
        projections=tuple(prjs),
        # (a graph written before 1 Dec 2026 carries only the input rate and the step: the rest are the defaults)
        **{k: meta[k] for k in SETTINGS if k in meta},
        notes=tuple(meta["notes"])
        + ("Read from NIR: " + "; ".join(f"{k}: {v}" for k, v in meta["approximations"].items()),),
    )
