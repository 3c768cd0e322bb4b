"""``toaster db``: schema revision management and maintenance."""

from __future__ import annotations

from typing import TYPE_CHECKING

import click

from toaster.cli.output import say

if TYPE_CHECKING:
    from sqlalchemy import Engine

#: How many invariant violations and integrity problems ``db check`` lists.
_SHOWN = 10


def _engine(
    ctx: click.Context, *, create: bool = False, revision: str = "head"
) -> tuple[Engine, str | None]:
    """The engine on ``--db`` and its revision; refuses what is not a toaster database."""
    from toaster.db.database import open_engine

    return open_engine(ctx.obj.url, create=create, revision=revision)


@click.group("db")
def db_group() -> None:
    """Create, upgrade and check the database schema (Alembic migrations)."""


@db_group.command()
@click.argument("revision", default="head")
@click.pass_context
def upgrade(ctx: click.Context, revision: str) -> None:
    """Migrate the database up to REVISION (default: the newest); a new one is created."""
    from toaster.db import migrate

    engine, before = _engine(ctx, create=True, revision=revision)
    try:
        migrate.upgrade(engine, revision)
        after = migrate.current_revision(engine)
    finally:
        engine.dispose()
    say(f"database at revision {after}" + ("" if before == after else f" (was {before or 'none'})"))


@db_group.command()
@click.argument("revision")
@click.pass_context
def downgrade(ctx: click.Context, revision: str) -> None:
    """Migrate the database down to REVISION (``base`` removes every toaster table)."""
    from toaster.db import migrate

    engine, _ = _engine(ctx)
    try:
        migrate.downgrade(engine, revision)
        after = migrate.current_revision(engine)
    finally:
        engine.dispose()
    say(f"database at revision {after or 'base (empty)'}")


@db_group.command()
@click.pass_context
def current(ctx: click.Context) -> None:
    """Print the database's revision and the one this toaster expects."""
    from toaster.db import migrate

    engine, revision = _engine(ctx)
    engine.dispose()
    click.echo(f"database: {revision or 'none (empty)'}")
    click.echo(f"toaster:  {migrate.head_revision()}")


@db_group.command()
@click.pass_context
def check(ctx: click.Context) -> None:
    """Exit non-zero unless the database is intact (SQLite), at this toaster's revision, every
    agent's views exist and the stored intervals and events keep their invariants."""
    from sqlalchemy import inspect

    from toaster.db import migrate
    from toaster.db.invariants import violations
    from toaster.errors import DatabaseOpenError, InvariantViolationError
    from toaster.queries import agents

    engine, _ = _engine(ctx)
    try:
        if engine.dialect.name == "sqlite":
            with engine.connect() as conn:
                rows = conn.exec_driver_sql(f"PRAGMA quick_check({_SHOWN})").scalars().all()
            if rows != ["ok"]:
                msg = (
                    f"database {engine.url.database!r} is corrupted: {'; '.join(rows)}: "
                    "restore it from a backup"
                )
                raise DatabaseOpenError(msg)
        migrate.check_at_head(engine, url_hint=ctx.obj.url or "")
    finally:
        engine.dispose()
    db = ctx.obj.db
    views = set(inspect(db.connection).get_view_names())
    without = [
        agent.id
        for agent in agents(db)
        if not {agent.fact_view, agent.memory_view, agent.events_view} <= views
    ]
    with db.transaction() as conn:
        found = violations(conn, limit=_SHOWN)
    if found:
        lines = "\n".join(found[:_SHOWN]) + ("\n..." if len(found) > _SHOWN else "")
        msg = f"the temporal invariants do not hold (toaster.db.invariants):\n{lines}"
        raise InvariantViolationError(msg)
    say(f"ok: database at revision {migrate.head_revision()}, {len(views)} views, invariants hold")
    if without:  # recordings register their people without: not an error
        say(
            f"{len(without)} agent(s) have no per-agent views (such as {without[0]!r}): "
            "`toaster db views` creates them"
        )


@db_group.command()
@click.argument("agents", nargs=-1, metavar="[AGENT]...")
@click.pass_context
def views(ctx: click.Context, agents: tuple[str, ...]) -> None:
    """Create the per-agent views (fact_table_ID, memory_table_ID, events_table_ID) that do not
    exist, of the AGENTs given or of every agent (recordings register their people without
    them: thousands of views slow every statement down)."""
    from toaster.db.catalog import create_missing_views

    db = ctx.obj.db
    with db.store().transaction() as conn:
        created = create_missing_views(conn, list(agents) if agents else None)
    say(f"created the views of {len(created)} agent(s)")


@db_group.command()
@click.pass_context
def maintain(ctx: click.Context) -> None:
    """Reclaim dead rows (PostgreSQL VACUUM ANALYZE of the hot tables; SQLite: fold the WAL).

    `toaster run` does it every minute by itself; use this for databases that other writers
    fill, on servers whose autovacuum is off.
    """
    ctx.obj.db.maintain()
    say("maintained")
