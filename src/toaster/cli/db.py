"""``toaster db``: schema revision management and maintenance."""

from __future__ import annotations

import click

from toaster.cli.output import say


def _engine(ctx: click.Context):
    from toaster.db.engine import default_url, make_engine

    return make_engine(ctx.obj.url or default_url())


@click.group("db")
def db_group() -> None:
    """Create, upgrade and check the database schema (Alembic migrations)."""


@db_group.command()
@click.argument("revision", default="head")
@click.pass_context
def upgrade(ctx: click.Context, revision: str) -> None:
    """Migrate the database up to REVISION (default: the newest)."""
    from toaster.db import migrate

    engine = _engine(ctx)
    before = migrate.current_revision(engine)
    migrate.upgrade(engine, revision)
    after = migrate.current_revision(engine)
    engine.dispose()
    say(f"database at revision {after}" + ("" if before == after else f" (was {before})"))


@db_group.command()
@click.argument("revision")
@click.pass_context
def downgrade(ctx: click.Context, revision: str) -> None:
    """Migrate the database down to REVISION (``base`` removes every toaster table)."""
    from toaster.db import migrate

    engine = _engine(ctx)
    migrate.downgrade(engine, revision)
    say(f"database at revision {migrate.current_revision(engine) or 'base (empty)'}")
    engine.dispose()


@db_group.command()
@click.pass_context
def current(ctx: click.Context) -> None:
    """Print the database's revision and the one this toaster expects."""
    from toaster.db import migrate

    engine = _engine(ctx)
    click.echo(f"database: {migrate.current_revision(engine) or 'none (empty)'}")
    click.echo(f"toaster:  {migrate.head_revision()}")
    engine.dispose()


@db_group.command()
@click.pass_context
def check(ctx: click.Context) -> None:
    """Exit non-zero unless the database is at this toaster's revision and every agent's
    views exist."""
    from sqlalchemy import inspect

    from toaster.db import migrate
    from toaster.errors import SchemaOutdatedError
    from toaster.queries import agents

    engine = _engine(ctx)
    try:
        migrate.check_at_head(engine, url_hint=ctx.obj.url or "")
    finally:
        engine.dispose()
    db = ctx.obj.db
    views = set(inspect(db.connection).get_view_names())
    missing = [name for agent in agents(db)
               for name in (agent.fact_view, agent.memory_view, agent.events_view)
               if name not in views]
    if missing:
        msg = f"missing per-agent views {missing}: re-register the agents with set-info ENTITY"
        raise SchemaOutdatedError(msg)
    say(f"ok: database at revision {migrate.head_revision()}, {len(views)} views")


@db_group.command()
@click.pass_context
def maintain(ctx: click.Context) -> None:
    """Reclaim dead rows (PostgreSQL VACUUM ANALYZE of the hot tables; SQLite: fold the WAL).

    `toaster run` does it every minute by itself; use this for databases that other writers
    fill, on servers whose autovacuum is off.
    """
    ctx.obj.db.maintain()
    say("maintained")
