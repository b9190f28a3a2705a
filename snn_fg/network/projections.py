"""The projections of a network description: what every projection has, and
its two kinds, :class:`Conv` (a weight-shared kernel between populations of
one level) and :class:`Resize` (interpolation between grids), with a registry
that rebuilds a projection from its ``type`` name (:func:`projection_from_dict`).

Sign convention: a connection's weight is ``sign * gain_mv * K`` with ``K``
the kernel (or interpolation) value, so a kernel with negative lobes (the
DoG, bicubic interpolation) is split between the two currents while its
balance is kept.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from .. import validate as check
from .nodes import Kernel, Node, finite

#: projection type name -> class, filled by :class:`Projection` subclasses
PROJECTION_TYPES: dict[str, type] = {}


@dataclass(frozen=True, kw_only=True)
class Projection(Node):
    """What every projection has: its ends, the current it feeds (``sign``
    +1 excitatory, -1 inhibitory), ``gain_mv`` (the weight of a unit kernel
    value), ``delay_ms``, ``prune`` (kernel taps under this fraction of the
    largest |value| are left out) and ``calibrated``: the gain is set for the
    network's ``input_rate_hz`` and is rescaled when the network is
    calibrated to another input rate (:meth:`Network.calibrated`)."""

    type_name: ClassVar[str] = ""

    name: str
    source: str
    target: str
    sign: int = 1
    gain_mv: float = 1.0
    delay_ms: float = 1.0
    prune: float = 0.0
    calibrated: bool = False

    def __init_subclass__(cls, **kw):
        super().__init_subclass__(**kw)
        if cls.type_name:
            PROJECTION_TYPES[cls.type_name] = cls

    @property
    def _owner(self) -> str:
        return f"{type(self).__name__} '{self.name}'"

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            check.fail(type(self).__name__, "name", self.name, "must be a non-empty string")
        owner = self._owner
        check.choice(owner, "sign", self.sign, (1, -1))
        object.__setattr__(self, "gain_mv", finite(owner, "gain_mv", self.gain_mv, 0))
        object.__setattr__(self, "delay_ms", finite(owner, "delay_ms", self.delay_ms, 0))
        object.__setattr__(self, "prune", check.number(owner, "prune", self.prune, lo=0, hi=1, hi_open=True))
        check.flag(owner, "calibrated", self.calibrated)

    def to_dict(self) -> dict:
        return {"type": self.type_name, **super().to_dict()}

    #: what a stored projection must state: a key left out took its default silently (a description
    #: edited by hand with delay_ms deleted ran with 1 ms, where the export's run.py refuses it)
    STATED: ClassVar[tuple] = ("name", "source", "target", "sign", "gain_mv", "delay_ms")

    @classmethod
    def from_dict(cls, d: dict):
        if isinstance(d, dict):
            missing = [k for k in cls.STATED if k not in d]
            if missing:
                check.fail(
                    f"{cls.__name__} {d.get('name', '?')!r}", None, None,
                    f"has no {', '.join(missing)} (a key left out or misspelt? a stored projection states each)",
                )  # fmt: skip
        return super().from_dict(d)


def projection_from_dict(d: dict) -> Projection:
    """Rebuild a projection from :meth:`Projection.to_dict` output (by its ``type``)."""
    if not isinstance(d, dict):
        check.fail("projection", None, None, f"expected a mapping, got {type(d).__name__}")
    d = dict(d)
    kind = d.pop("type", None)
    if kind not in PROJECTION_TYPES:
        check.fail(f"projection {d.get('name')!r}", "type", kind, f"must be one of {sorted(PROJECTION_TYPES)}")
    return PROJECTION_TYPES[kind].from_dict(d)


@dataclass(frozen=True, kw_only=True)
class Conv(Projection):
    """Weight-shared projection between two populations of the same level.

    For a target cell at level pixel ``P`` and a kernel tap at offset ``d``
    (kernel index minus centre), the source cell sits at ``P + d`` for a
    correlation (``mode='corr'``) and at ``P - d`` for a convolution. With
    ``padding='wrap'`` positions are taken modulo the level shape (taps that
    fold onto the same source add up); with ``'zero'`` positions outside the
    level are dropped, as are positions off the source's stride lattice.
    """

    type_name: ClassVar[str] = "conv"
    _nested: ClassVar[dict] = {"kernel": Kernel}

    kernel: Kernel
    mode: str = "corr"
    padding: str = "zero"

    def __post_init__(self):
        super().__post_init__()
        owner = self._owner
        check.choice(owner, "mode", self.mode, ("conv", "corr"))
        check.choice(owner, "padding", self.padding, ("zero", "wrap"))
        if not isinstance(self.kernel, Kernel):
            check.fail(owner, "kernel", type(self.kernel).__name__, "must be a Kernel")


@dataclass(frozen=True, kw_only=True)
class Resize(Projection):
    """Interpolation from one population's grid onto another's, channel by channel.

    Target cell ``(c, i, j)`` receives from source cell ``(c, i', j')`` with
    weight ``A_r[i, i'] * A_c[j, j']``: the target grid point at level pixel
    ``x = stride_t * i`` maps to source level coordinate
    ``(x + 0.5) * N_src / N_tgt - 0.5`` (half-pixel centres), interpolated on
    the source lattice (``cubic``: Keys a = -0.75; ``linear``) with clamped
    indices. Between two stride-1 grids this is exactly OpenCV's resize
    (stages 2 and 8). Source and target may share a level (resampling
    between strides).
    """

    type_name: ClassVar[str] = "resize"

    interpolation: str = "cubic"

    def __post_init__(self):
        super().__post_init__()
        check.choice(self._owner, "interpolation", self.interpolation, ("cubic", "linear"))
