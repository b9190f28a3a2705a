"""The ``snn-fg`` command line: one module per command (:mod:`.run`,
:mod:`.compare`, :mod:`.events`, :mod:`.export`, :mod:`.decode`,
:mod:`.data`), the options they share (:mod:`.options`), and the parser and
entry point that join them (:mod:`.main`). A run of a model into an output
folder is :mod:`.runner`; several recordings in one run, :mod:`.batch`.
"""

from .main import build_parser, console, main

__all__ = ["build_parser", "console", "main"]
