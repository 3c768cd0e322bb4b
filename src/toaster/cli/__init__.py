"""The ``toaster`` command: a thin client of the library (no SQL or rule lives here)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import click

from toaster.errors import ToasterError

if TYPE_CHECKING:
    from toaster.db import Database


class AppContext:
    """What every command gets: the database URL, opened on first use."""

    def __init__(self, url: str | None, debug: bool) -> None:
        self.url = url
        self.debug = debug
        self._db: Database | None = None

    @property
    def db(self) -> Database:
        """The database, created and migrated on first use when it is new."""
        if self._db is None:
            from toaster.session import connect

            self._db = connect(self.url)
        return self._db

    def close(self) -> None:
        if self._db is not None:
            self._db.close()


class ToasterGroup(click.Group):
    """Turns toaster's expected errors into one-line messages (exit 1); ``--debug`` shows them
    with their traceback."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except ToasterError as exc:
            obj = ctx.find_object(AppContext)
            if obj is not None and obj.debug:
                raise
            raise click.ClickException(str(exc)) from None
        except Exception as exc:  # a database error raised through a raw cursor (a lock
            error = _database_error(ctx, exc)  # held too long, a corrupted file...)
            obj = ctx.find_object(AppContext)
            if error is None or (obj is not None and obj.debug):
                raise
            raise click.ClickException(str(error)) from None


def _database_error(ctx: click.Context, exc: Exception) -> ToasterError | None:
    """The one-line error of a driver error the engine's own handler did not see (raw DBAPI
    cursors bypass it); None when ``exc`` is not the user's to fix (a bug)."""
    from toaster.db.engine import database_error, describe, lock_timeout, parse_url

    obj = ctx.find_object(AppContext)
    try:
        where = describe(parse_url(obj.url if obj is not None else None))
        return database_error(exc, where, lock_timeout())
    except ToasterError:
        return None


@click.group(cls=ToasterGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.option("--db", "url", envvar="TOASTER_DB", metavar="URL",
              help="sqlite:///FILE.db or postgresql://HOST/DB (env TOASTER_DB; default "
                   "sqlite:///toaster.db in the working directory, created on first use).")
@click.option("--debug", is_flag=True, help="Show tracebacks for errors.")
@click.version_option(package_name="toaster")
@click.pass_context
def cli(ctx: click.Context, url: str | None, debug: bool) -> None:
    """toaster: situation assessment for human-robot interaction.

    Facts about the world and each agent's beliefs, kept as intervals in a temporal SQL
    database (SQLite or PostgreSQL), with their events and memory.
    """
    app = AppContext(url, debug)
    ctx.obj = app
    ctx.call_on_close(app.close)


def _register() -> None:
    from toaster.cli.beliefs import beliefs, tell_cmd
    from toaster.cli.checks import guard
    from toaster.cli.control import entity, hand, monitor, pointing_cmd, relative_position, stream
    from toaster.cli.db import db_group
    from toaster.cli.demo import demo
    from toaster.cli.execute import execute
    from toaster.cli.export import export, record
    from toaster.cli.info import get_info, set_info
    from toaster.cli.plot import plot_facts
    from toaster.cli.run import area, relpos, run
    from toaster.cli.serve import serve
    from toaster.cli.tolerance import tolerance
    from toaster.cli.watch import watch

    for command in (area, beliefs, db_group, demo, entity, execute, export, get_info, hand,
                    monitor, plot_facts, pointing_cmd, record, relative_position, relpos, run,
                    serve, set_info, stream, tell_cmd, tolerance, watch):
        cli.add_command(command)
    guard(cli)


_register()


def main() -> None:
    """Entry point of the ``toaster`` script."""
    cli(prog_name="toaster")
