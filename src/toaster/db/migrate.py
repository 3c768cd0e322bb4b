"""Alembic, driven from Python on a given connection (one code path for CLI, tests, library)."""

from __future__ import annotations

from importlib import resources

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Connection, Engine

from toaster.db.schema import metadata
from toaster.errors import SchemaOutdatedError


def alembic_config(connection: Connection | None = None) -> Config:
    """An Alembic config pointing at the migrations shipped in the package."""
    config = Config()
    config.set_main_option("script_location", str(resources.files("toaster") / "migrations"))
    if connection is not None:
        config.attributes["connection"] = connection
    return config


def head_revision() -> str:
    """The newest revision this toaster knows."""
    head = ScriptDirectory.from_config(alembic_config()).get_current_head()
    assert head is not None
    return head


def current_revision(engine: Engine) -> str | None:
    """The database's revision, or None for a database toaster never touched."""
    with engine.connect() as conn:
        return MigrationContext.configure(conn).get_current_revision()


def upgrade(engine: Engine, revision: str = "head") -> None:
    """Migrate the database up to ``revision`` (one transaction)."""
    with engine.begin() as conn:
        conn.info["write"] = True
        command.upgrade(alembic_config(conn), revision)
    _analyze(engine)


def downgrade(engine: Engine, revision: str) -> None:
    """Migrate the database down to ``revision`` (``base`` removes everything)."""
    with engine.begin() as conn:
        command.downgrade(alembic_config(conn), revision)


def _analyze(engine: Engine) -> None:
    # Fresh statistics so that PostgreSQL plans sensibly on tables that started empty: toaster's
    # own tables only (a bare ANALYZE would also sample every other schema of a shared server,
    # and record another writer's uncommitted first tick as empty tables).
    if engine.dialect.name == "postgresql":
        with engine.begin() as conn:
            present = set(conn.dialect.get_table_names(conn))
            names = [t.name for t in metadata.sorted_tables if t.name in present]
            if names:
                conn.exec_driver_sql("ANALYZE " + ", ".join(f'"{n}"' for n in names))


def is_empty(engine: Engine) -> bool:
    """True when the database holds no table at all (a new file, a new PostgreSQL database)."""
    with engine.connect() as conn:
        return not conn.dialect.get_table_names(conn)


def check_at_head(engine: Engine, *, url_hint: str = "") -> None:
    """Raise :class:`SchemaOutdatedError` with the fix when the database is not at head."""
    current = current_revision(engine)
    head = head_revision()
    if current == head:
        return
    where = f" --db {url_hint}" if url_hint else ""
    if current is None:
        msg = (f"database has no toaster schema (this toaster expects revision {head}): "
               f"run `toaster db upgrade{where}`")
    elif current in _known_revisions():
        msg = (f"database is at revision {current}, this toaster expects {head}: "
               f"run `toaster db upgrade{where}`")
    else:
        msg = (f"database is at revision {current}, which this toaster does not know "
               f"(it expects {head}): it was written by a newer toaster; upgrade toaster")
    raise SchemaOutdatedError(msg)


def _known_revisions() -> set[str]:
    script = ScriptDirectory.from_config(alembic_config())
    return {rev.revision for rev in script.walk_revisions()}
