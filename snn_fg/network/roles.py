"""The roles of the network's populations: what each population's cells compute.

The decoder, every backend and the figures find populations by role (and
level), never by name; a role's cells are described once, here.
"""

#: What a population computes.
ROLES = (
    "input_on",
    "input_off",  # spike sources, one per pixel and polarity (level 1)
    "relay_on",
    "relay_off",  # the event frame resized to a coarser level (stage 2)
    "simple",  # oriented simple cells, 2 * n_ori directions (stages 3-4)
    "untuned",  # event pixels without an oriented response (stage 4)
    "bo_L1",
    "bo_L2",
    "bo_D1",
    "bo_D2",  # border-ownership cells, n_ori orientations (stage 5)
    "excess_L1",
    "excess_L2",
    "excess_D1",
    "excess_D2",  # a family's excess over its rival (stage 7)
    "group_L",
    "group_D",  # grouping cells (stage 7)
    "feedback_1p",
    "feedback_1n",  # feedback cells: the signal z1 = VL1 - VD2 as a rectified pair
    "feedback_2p",
    "feedback_2n",  # and z2 = VL2 - VD1 (stage 8)
    "side_p",
    "side_n",  # the side cue of the natural-scene variant, a rectified pair (stage 8)
    "clock",  # one spike source marking where each window of a recording starts
)
SOURCE_ROLES = ("input_on", "input_off", "clock")
#: the roles the decoder reads at every level, one population each
#: (:func:`snn_fg.models.spiking.decode.grouping_result`)
READOUT_ROLES = ("simple", "bo_L1", "bo_L2", "bo_D1", "bo_D2", "group_L", "group_D")

#: non-source roles in display order (figures, summaries)
ROLE_ORDER = tuple(r for r in ROLES if r not in SOURCE_ROLES)
#: what the cells of each role do, for figure captions: (roles, meaning), in ROLE_ORDER
ROLE_MEANINGS = (
    (("relay_on", "relay_off"), "the ON and OFF event frame resized to a coarser pyramid level (stage 2)"),
    (("simple",), "oriented edge cells, 16 directions per pixel (stages 3-4)"),
    (("untuned",), "event pixels without an oriented response (stage 4)"),
    (
        ("bo_L1", "bo_L2", "bo_D1", "bo_D2"),
        "border-ownership cells: a light (L) or dark (D) figure on side 1 or 2 of the edge (stage 5)",
    ),
    (
        ("excess_L1", "excess_L2", "excess_D1", "excess_D2"),
        "a border-ownership family's excess over its rival, which inhibits the rival's grouping (stage 7)",
    ),
    (("group_L", "group_D"), "grouping cells of light and dark figures: proto-object centres (stage 7)"),
    (
        ("feedback_1p", "feedback_1n", "feedback_2p", "feedback_2n"),
        "feedback cells: z1 = VL1 - VD2 and z2 = VL2 - VD1 as positive (p) and negative (n) halves (stage 8). "
        "They carry z as a rate and have a refractory period of one time step so that the rate stays "
        "proportional to z; where z is strong they fire a spike every step by design (up to 2 kHz at the "
        "default network's 0.5 ms step, 1 kHz at the compact one's 1 ms; docs/spiking-network.md)",
    ),
    (
        ("side_p", "side_n"),
        "side-cue cells: the event density on side 1 of an orientation's border minus side 2, "
        "within a wide half disc, as positive (p) and negative (n) halves; they feed the "
        "level-1 feedback cells (the natural-scene variant)",
    ),
)
