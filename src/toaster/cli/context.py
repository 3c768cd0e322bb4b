"""What every command shares: the database named by ``--db`` (declared once, here), opened on
first use.

``--db URL`` is accepted by the ``toaster`` group and by every command and subcommand, before or
after the command's name; the one precedence rule is *flag over environment over default*:
``--db`` wherever it is given, else ``$TOASTER_DB``, else ``sqlite:///toaster.db`` in the
working directory. Two different ``--db`` on one line are refused.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import click

from toaster.errors import InvalidInputError, ToasterError

if TYPE_CHECKING:
    from toaster.db import Database

#: The environment variable naming the database (same name as :data:`toaster.db.engine.ENV_VAR`,
#: not imported: ``toaster --help`` does not load SQLAlchemy).
ENV_VAR = "TOASTER_DB"
DB_HELP = (
    "Database: sqlite:///FILE.db or postgresql://USER@HOST/DB. Accepted before or after "
    f"any command; it wins over ${ENV_VAR}; without either, sqlite:///toaster.db in the "
    "working directory (created on first use)."
)


class AppContext:
    """What every command gets: the database URL (``--db``, else ``$TOASTER_DB``), the
    database, opened on first use, and how times are shown (``time_style``, ``--time``:
    :func:`toaster.cli.checks.command_frame`)."""

    def __init__(self, debug: bool = False, time_style: str = "auto") -> None:
        self.flag_url: str | None = None
        self.debug = debug
        self.time_style = time_style
        self._db: Database | None = None

    @property
    def url(self) -> str | None:
        """``--db`` if given (an empty one is refused when the database is opened), else
        ``$TOASTER_DB``, else None (the default file)."""
        if self.flag_url is not None:
            return self.flag_url
        return os.environ.get(ENV_VAR) or None

    def name(self, url: str) -> None:
        """Take ``--db URL``; a second, different one on the same line is refused."""
        if self.flag_url is not None and self.flag_url != url:
            msg = f"--db given twice ({self.flag_url!r} and {url!r}): give it once"
            raise click.UsageError(msg)
        if self._db is not None and self.flag_url != url:  # not reached from the command line
            msg = f"--db {url!r} came after the database {self.url!r} was opened"
            raise InvalidInputError(msg)
        self.flag_url = url

    @property
    def db(self) -> Database:
        """The database, created and migrated on first use when it is new."""
        if self._db is None:
            from toaster.app.session import connect

            self._db = connect(self.url)
        return self._db

    def close(self) -> None:
        if self._db is not None:
            self._db.close()
            self._db = None


def app_of(ctx: click.Context) -> AppContext:
    """The context's :class:`AppContext`, made (and closed with ``ctx``) when a command runs
    without the ``toaster`` group (``CliRunner().invoke(plot_facts, ...)``)."""
    app = ctx.find_object(AppContext)
    if app is None:
        app = AppContext()
        ctx.obj = app
        ctx.call_on_close(app.close)
    return app


def _take_db(ctx: click.Context, _param: click.Parameter, value: str | None) -> None:
    app = app_of(ctx)
    if value is not None:
        app.name(value)


def db_option() -> click.Option:
    """The one ``--db`` declaration (a fresh Option per command; see :func:`add_db_option`)."""
    return click.Option(
        ["--db"], metavar="URL", expose_value=False, is_eager=True, callback=_take_db, help=DB_HELP
    )


def add_db_option(command: click.Command) -> None:
    """Give ``command`` and all its subcommands ``--db`` (once each)."""
    if not any(param.name == "db" for param in command.params):
        command.params.insert(0, db_option())
    if isinstance(command, click.Group):
        for sub in command.commands.values():
            add_db_option(sub)


def one_line(ctx: click.Context, exc: Exception) -> click.ClickException | None:
    """The one-line message (exit 1) of an expected error: toaster's own, or a database error
    raised through a raw cursor (a lock held too long, a corrupted file...) that the engine's
    handler did not see. None: let it through (a bug, ``--debug``, click's own exits)."""
    app = ctx.find_object(AppContext)
    if isinstance(exc, click.ClickException | click.exceptions.Exit | click.Abort) or (
        app is not None and app.debug
    ):
        return None
    if isinstance(exc, ToasterError):
        return click.ClickException(str(exc))
    if isinstance(exc, OSError) and exc.filename is not None:
        return click.ClickException(_file_error(exc))
    from toaster.db.engine import database_error, describe, lock_timeout, parse_url

    try:
        where = describe(parse_url(app.url if app is not None else None))
        error = database_error(exc, where, lock_timeout())
    except ToasterError:
        return None
    return None if error is None else click.ClickException(str(error))


#: What to do about a file the command could not open, by the system's reason.
_FILE_FIXES = {
    FileNotFoundError: "create its folder or give another path",
    PermissionError: "give a path this user may use",
    IsADirectoryError: "name a file, not a folder",
    NotADirectoryError: "a part of the path is a file, not a folder",
}


def _file_error(exc: OSError) -> str:
    """``'PATH': reason: fix`` for a file a command could not read or write."""
    fix = next((f for kind, f in _FILE_FIXES.items() if isinstance(exc, kind)), "check the path")
    return f"{str(exc.filename)!r}: {exc.strerror or exc}: {fix}"
