"""The ``toaster`` command: a thin client of the library (no SQL or rule lives here)."""

from __future__ import annotations

from typing import Any

import click

from toaster.cli.context import AppContext, add_db_option, app_of, one_line
from toaster.timeutil import TIME_STYLES

__all__ = ["AppContext", "cli", "main"]


class ToasterGroup(click.Group):
    """Turns toaster's expected errors into one-line messages (exit 1); ``--debug`` shows them
    with their traceback (:func:`toaster.cli.context.one_line`)."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except Exception as exc:
            error = one_line(ctx, exc)
            if error is None:
                raise
            raise error from None


@click.group(cls=ToasterGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.option(
    "--time",
    "time_style",
    envvar="TOASTER_TIME",
    default="auto",
    show_default=True,
    type=click.Choice(TIME_STYLES, case_sensitive=False),
    help="Show times as seconds since the data's start (+12.500 s), as UTC dates, "
    "or auto: elapsed for simulated data (starting in 1970), dates otherwise "
    "(env TOASTER_TIME; docs/time.md).",
)
@click.option("--debug", is_flag=True, help="Show tracebacks for errors.")
@click.version_option(package_name="toaster")
@click.pass_context
def cli(ctx: click.Context, time_style: str, debug: bool) -> None:
    """toaster: situation assessment for human-robot interaction.

    Facts about the world and each agent's beliefs, kept as intervals in a temporal SQL
    database (SQLite or PostgreSQL), with their events and memory. Every command takes
    --db URL, before or after its name (it wins over $TOASTER_DB); listings take --limit,
    --json and --csv, and print tab-separated lines when piped. Reference: docs/cli.md.
    """
    app = app_of(ctx)  # made by --db (eager) if given
    app.debug = debug
    app.time_style = time_style.lower()


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
    from toaster.cli.ros1 import ros1_group
    from toaster.cli.run import area, relpos, run
    from toaster.cli.serve import serve
    from toaster.cli.tolerance import tolerance
    from toaster.cli.watch import watch

    for command in (
        area,
        beliefs,
        db_group,
        demo,
        entity,
        execute,
        export,
        get_info,
        hand,
        monitor,
        plot_facts,
        pointing_cmd,
        record,
        relative_position,
        relpos,
        ros1_group,
        run,
        serve,
        set_info,
        stream,
        tell_cmd,
        tolerance,
        watch,
    ):
        cli.add_command(command)
    add_db_option(cli)
    guard(cli)


_register()


def main() -> None:
    """Entry point of the ``toaster`` script."""
    cli(prog_name="toaster")
