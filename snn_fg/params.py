"""The one parameter object shared by every model, simulator and exporter.

Defaults are the paper's Table T1 values (see ``../shared/docs/model.md``).
"""
from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass

from .errors import ParameterError


@dataclass(frozen=True)
class ModelParams:
    """Parameters of the figure-ground model (rate and spiking forms).

    Attributes
    ----------
    levels: pyramid levels; level ``l`` (1-based) is scaled by ``(1/sqrt 2)**(l-1)``.
    n_ori: orientations per half-turn (border-ownership orientations); the
        simple cells have ``2 * n_ori`` directions.
    r0: radius in pixels of the von Mises grouping ring (object size grouped).
    iterations: grouping/feedback iterations (stages 7 and 8).
    alpha: feedback gain in ``f(z) = 1 + alpha * (sigmoid(z) - 0.5)``.
    w_inh: weight of the opposite border-ownership family's inhibition.
    dog_s1, dog_s2: diagonal covariances (row, column) of the two Gaussians of
        the oriented edge kernel ``N(S2) - N(S1)``.
    dog_half_width, dog_step: the DoG kernel is sampled on ``-half_width..+half_width``
        in steps of ``dog_step`` (31 samples by default).
    edge_threshold: oriented responses below this are zeroed.
    sum_threshold: after summing frames, responses below this are zeroed.
    pyramid_decay: weight ``decay**(k-l)`` of level ``k`` when pooling feedback at level ``l``.
    grouping_floor: FBFG only: normalised grouping values below this are zeroed.
    fbfg_edge_sigma: FBFG only: scale (px) of the Gaussian-derivative edge operator.
    fbfg_edge_floor: FBFG only: edge strengths below this fraction of the level-1
        maximum are zeroed.
    """

    levels: int = 10
    n_ori: int = 8
    r0: float = 8.0
    iterations: int = 10
    alpha: float = 2.0
    w_inh: float = 1.0
    dog_s1: tuple[float, float] = (0.8, 0.4)
    dog_s2: tuple[float, float] = (0.8, 0.3)
    dog_half_width: float = 3.0
    dog_step: float = 0.2
    edge_threshold: float = 0.3
    sum_threshold: float = 0.2
    pyramid_decay: float = 0.5
    grouping_floor: float = 0.1
    fbfg_edge_sigma: float = 1.0
    fbfg_edge_floor: float = 0.1

    def __post_init__(self):
        def bad(name, why):
            raise ParameterError(f"ModelParams.{name}={getattr(self, name)!r}: {why}")

        for name in ("levels", "n_ori", "iterations"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool):
                bad(name, "must be an integer")
        if self.levels < 1:
            bad("levels", "must be >= 1")
        if self.n_ori < 1:
            bad("n_ori", "must be >= 1")
        if self.iterations < 0:
            bad("iterations", "must be >= 0")
        for name in ("r0", "alpha", "w_inh", "dog_half_width", "dog_step", "edge_threshold",
                     "sum_threshold", "pyramid_decay", "grouping_floor", "fbfg_edge_sigma",
                     "fbfg_edge_floor"):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                bad(name, "must be a finite number")
        if self.r0 <= 0:
            bad("r0", "must be > 0")
        if self.alpha < 0:
            bad("alpha", "must be >= 0")
        if self.fbfg_edge_sigma <= 0:
            bad("fbfg_edge_sigma", "must be > 0")
        if self.dog_step <= 0 or self.dog_half_width <= 0:
            bad("dog_step", "DoG sampling step and half width must be > 0")
        for name in ("dog_s1", "dog_s2"):
            v = tuple(getattr(self, name))
            if len(v) != 2 or not all(isinstance(x, (int, float)) and x > 0 for x in v):
                bad(name, "must be two positive variances (row, column)")
            object.__setattr__(self, name, tuple(float(x) for x in v))

    @property
    def n_dir(self) -> int:
        """Number of simple-cell directions (a full turn)."""
        return 2 * self.n_ori

    @property
    def dog_size(self) -> int:
        """Side of the sampled DoG kernel (31 by default)."""
        return int(round(2 * self.dog_half_width / self.dog_step)) + 1

    def replace(self, **changes) -> "ModelParams":
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["dog_s1"] = list(self.dog_s1)
        d["dog_s2"] = list(self.dog_s2)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "ModelParams":
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = set(d) - names
        if unknown:
            raise ParameterError(f"ModelParams: unknown parameter(s) {sorted(unknown)}")
        d = dict(d)
        for k in ("dog_s1", "dog_s2"):
            if k in d:
                d[k] = tuple(d[k])
        return cls(**d)

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)
