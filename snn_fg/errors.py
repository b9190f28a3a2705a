"""Error types of snn-fg.

Every problem with a user's input is raised as :class:`InputError` (or a
subclass), which names the file, the problem and, where it applies, the place
in the file (byte offset or event index).  The CLI prints ``str(error)`` as one
line and exits non-zero; nothing else should escape to the user.
"""

from __future__ import annotations


class SnnFgError(Exception):
    """Base class of every error this package raises on purpose."""


class InputError(SnnFgError, ValueError):
    """A user-supplied file or array is unusable.

    Parameters
    ----------
    source:
        The file (or a description such as ``"<array>"``) at fault.
    problem:
        What is wrong, in words a user understands.
    where:
        Optional location: ``"byte offset 1024"``, ``"event 17"``...
    """

    def __init__(self, source, problem: str, where: str | None = None):
        self.source = str(source)
        self.problem = problem
        self.where = where
        loc = f" (at {where})" if where else ""
        super().__init__(f"{self.source}: {problem}{loc}")


class InputWarning(UserWarning):
    """Input that can be read but looks wrong (a file cut short at an event
    boundary, say); the message names the file. The command line prints it as
    one ``snn-fg: warning:`` line (:func:`snn_fg.cli.main.warnings_as_lines`)."""


class ParameterError(SnnFgError, ValueError):
    """A model parameter is out of its valid range; names the parameter."""


def install_hint(extra: str) -> str:
    """What to run for an optional extra: snn-fg is installed from its
    folder (the README's setup), not from a package index, so the extra is
    named the way ``pip`` finds it there."""
    return f'pip install -e ".[{extra}]" in the snn-fg folder'
