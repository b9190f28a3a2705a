"""How maps are judged: against each other window by window (:mod:`.metrics`,
with the figure of both, :mod:`.compare_figure`), along object outlines
(:mod:`.outline`), against human figure/ground labels (:mod:`.groundtruth`),
and the paper's evaluation on BSDS images (:mod:`.evaluation`) with its
sweeps (:mod:`.sweep`)."""
