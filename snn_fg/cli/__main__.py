"""``python -m snn_fg.cli``: the ``snn-fg`` command."""

from .main import console

console()
