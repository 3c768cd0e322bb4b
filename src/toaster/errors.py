"""Every error toaster raises on purpose derives from :class:`ToasterError`.

The CLI turns these into a one-line message and a non-zero exit code; anything else is a bug
and keeps its traceback.
"""

from __future__ import annotations


class ToasterError(Exception):
    """Base class of toaster's expected errors (bad input, bad state, missing extras)."""


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
    invariants (:mod:`toaster.db.invariants`)."""
