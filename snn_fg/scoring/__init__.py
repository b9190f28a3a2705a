"""How maps are judged: against each other window by window (:mod:`.metrics`,
with the figure of both, :mod:`.compare_figure`; a board's maps cut to meet the
reference, :mod:`.align`), along object outlines
(:mod:`.outline`) and against human figure/ground labels (:mod:`.groundtruth`: labels and their directions;
:mod:`.label_scores`: the scores, pooled over labellers and images; :mod:`.labels_figure`).
The paper's evaluation on BSDS images and its sweeps are the experiments'
(``experiments/evaluation.py``, ``experiments/sweep.py``)."""
