"""Error types of snn-fg.

Every problem with a user's input is raised as :class:`InputError` (or a
subclass), which names the file, the problem and, where it applies, the place
in the file (byte offset or event index).  The CLI prints ``str(error)`` as one
line and exits non-zero; nothing else should escape to the user.
"""

from __future__ import annotations

from typing import NamedTuple


class SnnFgError(Exception):
    """Base class of every error this package raises on purpose."""

    def for_command_line(self) -> str:
        """The message as the command line prints it (the same unless the error says
        otherwise: an :class:`InputError` with a :class:`Remedy` names the option)."""
        return str(self)


class Remedy(NamedTuple):
    """What a user gives to make an input usable, as each front door spells it:
    the keyword of the Python API (``"sensor_size=(W, H)"``) and the option of the
    command line (``"--sensor-size WxH"``)."""

    keyword: str
    option: str


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
    remedy:
        Optional :class:`Remedy`: what fixes it, said as ``pass KEYWORD`` in
        ``str(error)`` (the API's message) and as ``give OPTION`` in
        :meth:`for_command_line`. ``problem`` then ends where the remedy is
        added (``"...; pass sensor_size=(W, H)"``), ``note`` after it (after
        the problem, without a remedy).
    """

    def __init__(self, source, problem: str, where: str | None = None, *, remedy: Remedy | None = None, note: str = ""):
        self.source = str(source)
        self.problem = problem
        self.where = where
        self.remedy, self.note = remedy, note
        super().__init__(self._message(None if remedy is None else f"pass {remedy.keyword}"))

    def _message(self, fix: str | None) -> str:
        loc = f" (at {self.where})" if self.where else ""
        fix = f"; {fix}" if fix else ""
        return f"{self.source}: {self.problem}{fix}{self.note}{loc}"

    def for_command_line(self) -> str:
        return str(self) if self.remedy is None else self._message(f"give {self.remedy.option}")

    def but(self, **changes) -> InputError:
        """This error with ``changes`` made (``problem``, ``where``, ``note``): a caller that knows
        more of the place, or what follows it, says so, and each front door keeps its remedy."""
        was = {"source": self.source, "problem": self.problem, "where": self.where}
        fields = {**was, "remedy": self.remedy, "note": self.note, **changes}
        return InputError(fields.pop("source"), fields.pop("problem"), fields.pop("where"), **fields)


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
