"""The ``snn-fg`` command: its parser, made of one module's parser per
subcommand, and how a command ends.

Bad input ends with one line ``snn-fg: error: <file>: <problem>`` and exit
status 2; an interrupted run (Ctrl-C, SIGTERM) exits 130 or 143 and leaves
the output folder as it was (a frame), or with the windows completed so far
(a recording, which ``--resume`` continues). Ctrl-C while the command's
modules are still being imported ends the same way, in one line.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import signal
import sys
import warnings
from pathlib import Path

from ..errors import InputWarning, SnnFgError
from .commands import COMMANDS

#: the exit status of bad input, a usage error included
EXIT_INPUT = 2


class UsageParser(argparse.ArgumentParser):
    """A usage error is one line naming the command, the problem and where help is (no usage block)."""

    def error(self, message):
        self.exit(EXIT_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser(commands=None) -> tuple[argparse.ArgumentParser, dict]:
    """The parser and its subcommand parsers by name. ``commands``: the subcommands
    whose modules are imported and parsers made whole (default: all); the others
    are listed by name and help only (:data:`~.commands.COMMANDS`)."""
    from .. import __version__

    parser = UsageParser(
        prog="snn-fg",
        allow_abbrev=False,
        description="Event-driven figure-ground organisation as a spiking neural network: run the "
        "model on events or images, compare maps, inspect event recordings, export the "
        "network.",
    )
    parser.add_argument("--version", action="version", version=f"snn-fg {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    subs = {}
    for name, command in COMMANDS.items():
        if commands is None or name in commands:
            subs[name] = getattr(importlib.import_module(command.module), f"add_{name}_command")(sub)
        else:
            subs[name] = sub.add_parser(name, help=command.help)
    return parser, subs


def asked_for(argv) -> tuple[str, ...]:
    """The subcommand an ``snn-fg`` command line names (its first word that is not an option),
    as :func:`build_parser`'s ``commands``: none for ``snn-fg --help`` or a word that names none."""
    words = [w for w in (sys.argv[1:] if argv is None else argv) if not w.startswith("-")]
    return tuple(words[:1]) if words and words[0] in COMMANDS else ()


@contextlib.contextmanager
def warnings_as_lines():
    """While a command runs, an :class:`~snn_fg.errors.InputWarning` is one
    ``snn-fg: warning:`` line (not Python's file:line form), above a progress bar
    if one is drawn; others as usual."""
    with warnings.catch_warnings():
        shown = warnings.showwarning

        def show(message, category, *rest, **kw):
            if issubclass(category, InputWarning):
                from tqdm import tqdm  # (a line of its own above a progress bar, which print glued it to)

                tqdm.write(f"snn-fg: warning: {message}", file=sys.stderr)
            else:
                shown(message, category, *rest, **kw)

        warnings.showwarning = show
        yield


def main(argv=None, *, exit_on_interrupt: bool = False) -> int:
    """Run one ``snn-fg`` command; returns the exit status.

    ``exit_on_interrupt``: after Ctrl-C or SIGTERM (and the one-line message)
    end the process at once with 130 or 143, without unwinding: what an
    interrupt cut short in library code (a half-loaded compiled module, say)
    can crash the interpreter while it is torn down, or make it end itself by
    the signal. The output folder has been restored by then."""
    args, received = argparse.Namespace(), []
    try:
        # (only the command asked for is imported, and its heavy imports may be interrupted too: an
        # import can swallow the KeyboardInterrupt, so a Ctrl-C there is also noted and raised again)
        with _noted(signal.SIGINT) as early:
            parser, subs = build_parser(asked_for(argv))
            args, extra = parser.parse_known_args(argv)
            if extra:  # report an unknown option under the subcommand's own usage
                subs[args.command].error(f"unrecognized arguments: {' '.join(extra)}")
            from ..backends import cancel
        if early:
            raise KeyboardInterrupt(early[-1])

        with cancel.Signals() as signals, warnings_as_lines():
            received = signals.received
            args.interrupted = lambda: bool(signals.received)
            try:
                return args.handler(args)
            except Exception as exc:
                # after an interrupt that a library swallowed, whatever fails
                # next is its consequence: report the interrupt, not the error
                if signals.received:
                    raise KeyboardInterrupt(signals.received[-1]) from None
                if isinstance(exc, OSError) and exc.filename is not None:
                    # a file that cannot be read or written (a full disk part way through a run, say):
                    # the file and the system's reason in one line
                    exc = f"{exc.filename}: {exc.strerror or type(exc).__name__}"
                elif isinstance(exc, MemoryError):
                    exc = out_of_memory(exc, getattr(args, "input", None), args.command)
                elif not isinstance(exc, SnnFgError):
                    raise
                print(f"snn-fg: error: {exc if isinstance(exc, str) else exc.for_command_line()}", file=sys.stderr)
                return EXIT_INPUT
    except KeyboardInterrupt:
        term = "SIGTERM" in received
        note = getattr(args, "interrupt_note", "the output was left as it was before the run")
        print(f"snn-fg: interrupted ({'SIGTERM' if term else 'Ctrl-C'}); {note}", file=sys.stderr)
        code = 143 if term else 130
        if exit_on_interrupt:
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(code)
        return code


#: the commands that run a model (an out-of-memory line says what needs less memory for them)
MODEL_COMMANDS = ("run", "live", "decode")


def out_of_memory(exc: MemoryError, spec=None, command: str = "run") -> str:
    """The one line for a command that ran out of memory: what it could not have (numpy's
    ``Unable to allocate 5.03 GiB``, without the array's shape and type) and, for a command that
    runs a model, what needs less for its input ``spec``: a smaller image (an image file), or a
    smaller network."""
    from ..events.images import IMAGE_SUFFIXES

    what = str(exc).split(" for an array")[0].strip()
    if command not in MODEL_COMMANDS:
        return f"out of memory{f' ({what})' if what else ''}: snn-fg {command} needs more than this machine gives it"
    if spec is not None and Path(str(spec)).suffix.lower() in IMAGE_SUFFIXES:
        less = "a smaller image needs less (--image-scale F; a large image's note says which F)"
    else:
        less = (
            "a smaller network needs less (--network compact; the default network on a 1280 x 720 sensor "
            "makes 167 M cells: docs/performance.md, 'Memory')"
        )
    return f"out of memory{f' ({what})' if what else ''}: the model needs more than this machine gives it; {less}"


@contextlib.contextmanager
def _noted(signum):
    """While the command's modules load: ``signum`` raises KeyboardInterrupt as Python's own
    Ctrl-C does and is noted in the list yielded, which outlives an import that swallows the
    interrupt (:class:`~snn_fg.backends.cancel.Signals` takes over once they are loaded)."""
    noted: list[str] = []

    def handler(sig, frame):  # noqa: ARG001 - signal handler signature
        noted.append(signal.Signals(sig).name)
        raise KeyboardInterrupt(noted[-1])

    previous = signal.signal(signum, handler)
    try:
        yield noted
    finally:
        signal.signal(signum, previous)


def console():
    """The ``snn-fg`` entry point: :func:`main`, exiting with its status (at
    once after an interrupt). Output piped into a reader that stops early
    (``snn-fg events REC | head``) ends the command quietly."""
    try:
        sys.exit(main(exit_on_interrupt=True))
    except BrokenPipeError:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # (no error when Python flushes it)
        sys.exit(1)
