"""Alembic environment: runs on the connection handed over by :mod:`toaster.db.migrate`."""

from __future__ import annotations

from alembic import context
from sqlalchemy import create_engine

from toaster.db.schema import metadata

config = context.config


def _run(connection) -> None:
    context.configure(
        connection=connection,
        target_metadata=metadata,
        render_as_batch=connection.dialect.name == "sqlite",
        compare_type=True,
    )
    with context.begin_transaction():
        context.run_migrations()


connection = config.attributes.get("connection")
if connection is not None:
    _run(connection)
else:  # plain `alembic` command line, e.g. for autogenerate during development
    url = config.get_main_option("sqlalchemy.url")
    if not url:
        msg = "alembic: set sqlalchemy.url (toaster db upgrade needs none)"
        raise SystemExit(msg)
    engine = create_engine(url)
    with engine.begin() as conn:
        _run(conn)
