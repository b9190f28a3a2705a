"""Simulator backends, chosen by name.

A backend turns a network description and input spikes into a
:class:`~snn_fg.backends.base.SimulationResult`. To add one (NEST through
PyNN, a fast event-driven engine...), write a module here with a subclass of
:class:`~snn_fg.backends.base.Backend` and add it to :data:`BACKENDS`; the
decoder, the figures, the command line and the backend-agnostic tests then
use it without change. Exporters (PyNN scripts, NIR files) consume the same
description from :mod:`snn_fg.export`.

>>> from snn_fg.backends import DEFAULT_BACKEND, backend_names, get_backend
>>> backend_names()
['brian2', 'fast', 'nest', 'loihi2']
>>> get_backend("brian2").name
'brian2'
>>> DEFAULT_BACKEND
'fast'
"""

from __future__ import annotations

import importlib

from .. import validate as check
from ..errors import SnnFgError
from .base import Backend, RunSettings, SimulationResult

#: name -> "module:Class", imported only when the backend is asked for, so
#: that a missing optional simulator costs nothing until it is used.
BACKENDS = {
    "brian2": "snn_fg.backends.brian2:Brian2Backend",
    "fast": "snn_fg.backends.fast:FastBackend",
    "nest": "snn_fg.backends.nest:NestBackend",
    "loihi2": "snn_fg.backends.loihi2:Loihi2Backend",
}
#: the backend runs use unless told otherwise: the fastest one verified against
#: Brian2 (identical spike trains, tests/test_fast_engine.py; identical spike
#: counts on every synthetic scene, experiments/results/spiking_fidelity_fast_vs_brian2.md)
DEFAULT_BACKEND = "fast"


def backend_names() -> list[str]:
    return list(BACKENDS)


def backend_class(name: str) -> type[Backend]:
    check.choice("backend", "name", name, tuple(BACKENDS))
    module, cls = BACKENDS[name].split(":")
    return getattr(importlib.import_module(module), cls)


def get_backend(name: str = DEFAULT_BACKEND, **options) -> Backend:
    """The backend ``name``, constructed with its ``options``.

    Raises :class:`~snn_fg.errors.SnnFgError` with one line saying what to
    install when the simulator it needs is missing.
    """
    cls = backend_class(name)
    ok, why = cls.available()
    if not ok:
        raise SnnFgError(f"backend {name!r} is not available: {why}")
    return cls(**options)


def as_backend(backend: str | Backend = DEFAULT_BACKEND, options: dict | None = None) -> Backend:
    """``backend`` itself if it is a :class:`Backend` (kept by a caller
    that runs many inputs, so that what it prepares, like the fast engine's
    tables and cell arrays, serves them all), else :func:`get_backend`
    of that name with ``options``."""
    if isinstance(backend, Backend):
        if options:
            raise SnnFgError(
                f"backend options {sorted(options)} were given with a backend object: set them when constructing it"
            )
        return backend
    return get_backend(backend, **(options or {}))


def available_backends() -> dict[str, tuple[bool, str]]:
    """name -> (usable here, what to install if not)."""
    return {name: backend_class(name).available() for name in BACKENDS}


__all__ = [
    "BACKENDS",
    "DEFAULT_BACKEND",
    "Backend",
    "RunSettings",
    "SimulationResult",
    "as_backend",
    "available_backends",
    "backend_class",
    "backend_names",
    "get_backend",
]
