"""Intervals for the scores against human labels, from resampling the images: since 30 Nov in
:mod:`snn_fg.scoring.bootstrap`, so that ``snn-fg compare RUN LABELS`` gives the experiment pages'
interval by the same code; handed on here for the experiments that import them from this module."""

from snn_fg.scoring.bootstrap import bootstrap_difference, bootstrap_scores

__all__ = ["bootstrap_difference", "bootstrap_scores"]
