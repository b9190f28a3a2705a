"""The ``snn-fg`` subcommands: each one's module and its line in ``snn-fg --help``.

A command's module (its parser and handler, with their imports: a model, a
simulator, matplotlib) is imported only when that command is asked for
(:func:`snn_fg.cli.main.build_parser`): ``snn-fg --help`` imports none (a tenth
of a second), ``snn-fg CMD --help`` only CMD's.
"""

from __future__ import annotations

from typing import NamedTuple


class Command(NamedTuple):
    """A subcommand ``NAME``: the module that defines it (its ``add_NAME_command(subparsers)``
    registers the parser and its handler) and its one-line help."""

    module: str
    help: str


#: every subcommand, in the order ``snn-fg --help`` lists them
COMMANDS = {
    "run": Command("snn_fg.cli.run", "run a figure-ground model on an input and write its maps"),
    "compare": Command("snn_fg.cli.compare", "compare two runs' maps (e.g. spiking vs rate)"),
    "plot": Command("snn_fg.cli.plot", "draw a recording's run: chosen windows, an animation, its overview"),
    "events": Command(
        "snn_fg.cli.events", "summarise an event recording or simulate one from an image; write event frames"
    ),
    "export": Command("snn_fg.cli.export", "export the network (PyNN, Lava, NIR, resource report)"),
    "decode": Command("snn_fg.cli.decode", "decode an exported network's spike counts into maps"),
    "data": Command("snn_fg.cli.data", "list, describe and fetch the datasets (recordings, BSDS references)"),
    "stream": Command("snn_fg.cli.stream", "replay a recording as a live event stream (for snn-fg live)"),
    "live": Command("snn_fg.cli.live", "run a model on a live event stream, writing maps as the windows complete"),
}
