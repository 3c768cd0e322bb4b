"""Every error toaster raises on purpose derives from :class:`ToasterError`.

The CLI turns these into a one-line message and a non-zero exit code; anything else is a bug
and keeps its traceback.
"""

from __future__ import annotations

import re
from typing import ClassVar

#: Line breaks and other control characters (C0, DEL, C1, Unicode line/paragraph separators)
_CONTROL = re.compile("[\x00-\x1f\x7f-\x9f\u2028\u2029]")


def one_line(message: str) -> str:
    """``message`` on one line: control characters (those of the values it names: ids with
    line breaks, escape sequences) shown as escapes such as ``\\n``, ``\\x1b``."""
    return _CONTROL.sub(lambda m: repr(m.group())[1:-1], message)


class ToasterError(Exception):
    """Base class of toaster's expected errors (bad input, bad state, missing extras).

    Its message is one line (:func:`one_line`), whatever the values it names, unless the
    class reports several lines (:attr:`multiline`)."""

    #: True for a report of several lines (``toaster db check``'s violations)
    multiline: ClassVar[bool] = False

    def __init__(self, *args: object) -> None:
        if not self.multiline and args and isinstance(args[0], str):
            args = (one_line(args[0]), *args[1:])
        super().__init__(*args)


class InvalidInputError(ToasterError, ValueError):
    """A value given by the user or a producer is not acceptable (empty id, NaN confidence...)."""


class UnknownAgentError(InvalidInputError):
    """A fact or query names an agent that was never registered."""


class UnknownEntityError(InvalidInputError):
    """A command names an entity that is not in the entities table."""


class TimeOrderError(InvalidInputError):
    """A write would end a fact before it started (snapshots must come in time order)."""


class FileFormatError(InvalidInputError):
    """A seed, batch or scenario file cannot be read."""


class SchemaOutdatedError(ToasterError):
    """The database is at an older (or unknown) schema revision than this toaster."""


class ReadOnlyError(ToasterError):
    """A statement tried to write through a read-only command."""


class MissingDependencyError(ToasterError, ImportError):
    """An optional dependency is not installed; the message names the extra to install."""

    def __init__(self, package: str, extra: str, feature: str) -> None:
        msg = f"{feature} needs {package}: pip install 'toaster[{extra}]'"
        super().__init__(msg)
        self.package = package
        self.extra = extra


class ConcurrentWriteError(ToasterError):
    """A write kept conflicting with concurrent writers and was abandoned (rolled back)."""


class DatabaseOpenError(ToasterError):
    """A database cannot be opened or used: unreachable server, a file that is not a SQLite
    database or is corrupted, another application's database."""


class DatabaseLockedError(ToasterError):
    """Another process held the database's lock longer than ``TOASTER_LOCK_TIMEOUT`` seconds
    (the statement was rolled back)."""


class InvariantViolationError(ToasterError):
    """``toaster db check`` found stored intervals or events that break the temporal
    invariants (:mod:`toaster.db.invariants`): one line per violation."""

    multiline = True
