"""The one parameter object shared by every model, simulator and exporter.

Defaults are the paper's Table T1 values (see ``docs/model.md``, "Default parameters").
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass

from . import validate as check

#: How grouping cells treat the two contrast polarities (``ModelParams.grouping_polarity``).
GROUPING_POLARITIES = ("compete", "pool")
#: The lower bound of each model parameter that has one, and whether it is excluded: the one home of
#: the ranges, which :class:`ModelParams` and the command line's options (``--levels``...) both check.
#: Two orientations at least: one gives edges of one orientation only; one iteration at least: none
#: gives no vector and no grouping; ``w_inh`` inhibits, so it is not negative.
LOWER = {
    "levels": (1, False),
    "levels_per_octave": (1, False),
    "input_pool": (1, False),
    "n_ori": (2, False),
    "iterations": (1, False),
    "side_cue_level": (1, False),
    "r0": (0, True),
    "alpha": (0, False),
    "w_inh": (0, False),
    "dog_half_width": (0, True),
    "dog_step": (0, True),
    "fbfg_edge_sigma": (0, True),
    "side_cue": (0, False),
    "side_cue_radius": (0, True),
}
#: the parameters ``snn-fg run`` takes as options (``--levels``...) and ``get_model`` as keywords
RUN_PARAMS = ("levels", "n_ori", "r0", "iterations", "alpha", "w_inh", "side_cue")
#: the whole-number parameters, and the real-valued ones that are checked
INTEGERS = ("levels", "levels_per_octave", "input_pool", "n_ori", "iterations", "side_cue_level")
NUMBERS = (
    "r0",
    "alpha",
    "w_inh",
    "dog_half_width",
    "dog_step",
    "edge_threshold",
    "sum_threshold",
    "pyramid_decay",
    "grouping_floor",
    "fbfg_edge_sigma",
    "fbfg_edge_floor",
    "side_cue",
    "side_cue_radius",
)


@dataclass(frozen=True, kw_only=True)
class ModelParams:
    """Parameters of the figure-ground model (rate and spiking forms).

    Attributes
    ----------
    levels: pyramid levels; level ``l`` (1-based) is scaled by ``(1/sqrt 2)**(l-1)``
        (``2 ** (-(l-1) / levels_per_octave)`` in general).
    levels_per_octave: pyramid levels per halving of the scale: 2 (the paper's
        ``1/sqrt 2`` steps) or 1 (octaves: half the cells and synapses of the
        coarse levels, for the compact network).
    input_pool: stage 0: blocks of ``input_pool x input_pool`` sensor pixels
        become one pixel of the event frame the model sees (1: none); the
        maps come back at the sensor's size (:mod:`snn_fg.frames.pool`).
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
    grouping_polarity: ``"compete"`` (the paper's): light-figure and
        dark-figure grouping cells compete per pixel, winner takes all;
        ``"pool"``: no competition, and the feedback reads the sum of both,
        so that a figure is grouped whatever the sign of its contrast along
        the outline (the natural-scene variant, :mod:`snn_fg.models.rate.natural`).
    side_cue: gain of the side cue (0: none; the natural-scene variant,
        :mod:`snn_fg.models.rate.side_cue`): at level 1, each border-ownership pair's
        feedback signal ``z`` gains ``side_cue`` times the event density in
        the half disc on its side minus that on the other side.
    side_cue_radius: radius (level-1 pixels) of the side cue's half discs.
    side_cue_level: the pyramid level whose event density the side cue reads
        (the coarsest level if there are fewer).
    """

    levels: int = 10
    levels_per_octave: int = 2
    input_pool: int = 1
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
    grouping_polarity: str = "compete"
    side_cue: float = 0.0
    side_cue_radius: float = 160.0
    side_cue_level: int = 9

    def __post_init__(self):
        owner = "ModelParams"
        for name in INTEGERS:
            check.integer(owner, name, getattr(self, name), lo=LOWER[name][0])
        for name in NUMBERS:
            lo, strict = LOWER.get(name, (None, False))
            object.__setattr__(self, name, check.number(owner, name, getattr(self, name), lo=lo, lo_open=strict))
        check.choice(owner, "grouping_polarity", self.grouping_polarity, GROUPING_POLARITIES)
        for name in ("dog_s1", "dog_s2"):
            v = getattr(self, name)
            try:
                pair = tuple(check.number(owner, name, x, lo=0, lo_open=True) for x in v)
            except TypeError:
                pair = ()
            if len(pair) != 2:
                check.fail(owner, name, v, "must be two positive variances (row, column)")
            object.__setattr__(self, name, pair)

    @property
    def n_dir(self) -> int:
        """Number of simple-cell directions (a full turn)."""
        return 2 * self.n_ori

    @property
    def cue_level(self) -> int:
        """The level the side cue reads: ``side_cue_level``, or the coarsest if there are fewer."""
        return min(self.side_cue_level, self.levels)

    @property
    def dog_size(self) -> int:
        """Side of the sampled DoG kernel (31 by default)."""
        return int(round(2 * self.dog_half_width / self.dog_step)) + 1

    def replace(self, **changes) -> ModelParams:
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["dog_s1"] = list(self.dog_s1)
        d["dog_s2"] = list(self.dog_s2)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> ModelParams:
        check.known_keys("ModelParams", d, [f.name for f in dataclasses.fields(cls)])
        d = dict(d)
        for k in ("dog_s1", "dog_s2"):
            if k in d:
                d[k] = tuple(d[k])
        return cls(**d)

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)


#: The natural-scene variant's parameters (:mod:`snn_fg.models.rate.natural`,
#: ``--model natural``): the paper's, with the grouping polarities pooled, no
#: rival inhibition, a grouping radius of 4 px and the side cue. Here rather
#: than there, so that naming the models does not load the rate model's code.
NATURAL_PARAMS = ModelParams(grouping_polarity="pool", w_inh=0.0, r0=4.0, side_cue=3e3)

#: The frame-based model's edge operators for its simple cells (:mod:`snn_fg.models.rate.fbfg`, ``--edge-operator``).
EDGE_OPERATORS = ("gaussian", "corf")
