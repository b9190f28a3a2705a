"""Which cells read which, as the model's stages 5, 7 and 8 say: the four
border-ownership families and their partners, the inputs of the grouping and
feedback cells, the feedback half for and against each family; and the
kernels the stages wire them with. The builder's stages (:mod:`.stages`), the
read-out (:mod:`snn_fg.models.spiking.decode`) and the twin
(:mod:`snn_fg.models.spiking.twin`) share these tables.
"""

from __future__ import annotations

from .nodes import Kernel

FAMILIES = ("L1", "L2", "D1", "D2")
#: Stage 5: the half of the simple cells each family reads (0: directions
#: ``o``, 1: directions ``o + n_ori``): BL1[o] = S[o], BL2[o] = S[o+n],
#: BD1[o] = S[o+n], BD2[o] = S[o].
FAMILY_HALF = {"L1": 0, "L2": 1, "D1": 1, "D2": 0}
#: The family sharing a simple cell with each family (the two compete).
PARTNER = {"L1": "D2", "D2": "L1", "L2": "D1", "D1": "L2"}
#: The feedback signals z1 = VL1 - VD2 and z2 = VL2 - VD1, each carried by a
#: rectified pair of feedback cells (``p``: positive part, ``n``: negative).
FEEDBACK_HALVES = ("1p", "1n", "2p", "2n")
OPPOSITE_HALF = {"1p": "1n", "1n": "1p", "2p": "2n", "2n": "2p"}
#: Stage 7: (border-ownership family, grouping polarity, von Mises half,
#: sign): gL1 = (BL1 - w BD2) (*) m2, gL2 = (BL2 - w BD1) (*) m1,
#: gD1 = (BD1 - w BL2) (*) m2, gD2 = (BD2 - w BL1) (*) m1.
GROUPING_INPUTS = (
    ("L1", "L", 2, 1),
    ("L2", "L", 1, 1),
    ("D2", "L", 2, -1),
    ("D1", "L", 1, -1),
    ("D1", "D", 2, 1),
    ("D2", "D", 1, 1),
    ("L2", "D", 2, -1),
    ("L1", "D", 1, -1),
)
#: Stage 8: each feedback half as (grouping polarity, half) excitatory minus
#: (grouping polarity, half) inhibitory: z1 = GL (*) m1 - GD (*) m2,
#: z2 = GL (*) m2 - GD (*) m1, and their negatives.
FEEDBACK_INPUTS = {
    "1p": (("L", 1), ("D", 2)),
    "1n": (("D", 2), ("L", 1)),
    "2p": (("L", 2), ("D", 1)),
    "2n": (("D", 1), ("L", 2)),
}
#: Stage 8: the feedback half (for, against) each border-ownership family:
#: z1 favours BL1 and opposes BD2, z2 favours BL2 and opposes BD1.
FEEDBACK_TO_FAMILY = {"L1": ("1p", "1n"), "D2": ("1n", "1p"), "L2": ("2p", "2n"), "D1": ("2n", "2p")}


def channel_map(n_out: int, n_in: int, pairs, weight: float = 1.0) -> Kernel:
    """A kernel that only maps channels: ``(out, in)`` ``pairs`` of weight ``weight`` at the same pixel."""
    return Kernel(ref="channel_map", args={"n_out": n_out, "n_in": n_in, "entries": [[o, i, weight] for o, i in pairs]})


def dog_half(polarity: int, n: int) -> Kernel:
    """DoG kernels from one input polarity to all ``2n`` directions; only the
    polarity's own half (ON: ``0..n-1``, OFF: ``n..2n-1``) is non-zero."""
    return Kernel(
        ref="dog", args={"directions": [k if polarity * n <= k < (polarity + 1) * n else None for k in range(2 * n)]}
    )


def von_mises(half: int, layout: str) -> Kernel:
    """The von Mises half ``half`` (1 or 2) of stage 7, read in ``layout`` (``gather`` or ``scatter``)."""
    return Kernel(ref="von_mises", args={"half": half, "layout": layout})
