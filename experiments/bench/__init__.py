"""Side-by-side speed benchmark of the figure-ground models (issue 13).

``python -m experiments.bench --help`` from the repository root; see
:mod:`experiments.bench.run`.
"""
