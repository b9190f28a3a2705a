"""The ``snn-fg`` command line: one module per command
(:mod:`~snn_fg.cli.run`, :mod:`~snn_fg.cli.compare`, :mod:`~snn_fg.cli.plot`, :mod:`~snn_fg.cli.events`,
:mod:`~snn_fg.cli.export`, :mod:`~snn_fg.cli.decode`, :mod:`~snn_fg.cli.data`, :mod:`~snn_fg.cli.live`,
:mod:`~snn_fg.cli.stream`), with the parts some of them split off: ``run``'s model options
(:mod:`~snn_fg.cli.run_options`), ``compare``'s pairs of maps (:mod:`~snn_fg.cli.compare_maps`) and its verdict
(:mod:`~snn_fg.cli.compare_verdict`), runs
pooled by image (:mod:`~snn_fg.cli.compare_pooled`) and human labels (:mod:`~snn_fg.cli.compare_labels`),
and ``events --write-spikes`` (:mod:`~snn_fg.cli.spikes`); the options they share
(:mod:`~snn_fg.cli.options`), the list of commands
(:mod:`~snn_fg.cli.commands`: a command's module is imported only when it is
asked for), and the parser and entry point that join them (:mod:`~snn_fg.cli.main`). A run of a model into an output
folder is :mod:`~snn_fg.cli.runner`; several recordings in one run,
:mod:`~snn_fg.cli.batch`.
"""

from .main import build_parser, console, main

__all__ = ["build_parser", "console", "main"]
