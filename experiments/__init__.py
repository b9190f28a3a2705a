"""Experiments in tiers, each run from the repository root as ``python -m experiments.<tier>.<name>``:

* :mod:`experiments.paper` - the paper's tables and figures, reproduced;
* :mod:`experiments.validation` - our models against references and against each other;
* :mod:`experiments.bench` - speed and memory.

:mod:`experiments.common` holds what they share (paths, result records, tables).
"""
