"""Belief settings with their defaults in one place; the rule text out of the database; the
internal tables guarded against direct writes.

``belief_settings`` (view): one row per belief-rule setting, the stored value or else the
default. It is the one declaration of the defaults: the rule statements and Python
(:mod:`toaster.rules.settings`) both read it, so a missing ``settings`` row means the
default everywhere. A later revision that changes a default replaces the view.

``belief_rules`` is dropped: the statements are rendered from the package's templates.

Guard triggers on the tables only the store and the rules write (keys, intervals, samples,
events, followed periods, nested holders): any other write fails with one line naming the way
to write facts, so that no client can corrupt the timelines silently. The store takes the
writer role per transaction (:meth:`toaster.db.dialects.Backend.begin_writes`): PostgreSQL a
transaction-local setting ``toaster.writer``, SQLite a row in ``rule_writer`` deleted before
the commit (SQLite has one writer at a time, so no other connection ever sees it).

Revision ID: 0006
Revises: 0005
Create Date: 2026-11-23
"""

from __future__ import annotations

import json

import sqlalchemy as sa
from alembic import op

from toaster.db.dialects import GUARD_MESSAGE

revision = "0006"
down_revision = "0005"
branch_labels = None
depends_on = None

#: The defaults of this revision (frozen: a change of default is a new revision).
DEFAULTS = {
    "enabled": True,
    "depth": 2,
    "copresence": ["IsInRoom"],
    "containment": ["IsIn", "IsOn"],
    "visibility": {"IsVisibleBy": "target", "CanSee": "subject", "IsLookingToward": "subject"},
    "closed": "IsClosed",
    "refute_by_target": ["IsOn"],
    "self_perception": False,
    "share_rows": True,
}


def _literal(value: object) -> str:
    return "'" + json.dumps(value).replace("'", "''") + "'"


def settings_view(defaults: dict[str, object]) -> str:
    """``belief_settings``: the stored value of each setting, else its default."""
    rows = ", ".join(f"('{key}', {_literal(value)})" for key, value in defaults.items())
    return (
        "CREATE VIEW belief_settings AS WITH defaults (key, value_json) AS "
        f"(VALUES {rows}) SELECT d.key, COALESCE(s.value_json, d.value_json) AS value_json, "
        "CASE WHEN s.value_json IS NULL THEN 1 ELSE 0 END AS is_default "
        "FROM defaults d LEFT JOIN settings s ON s.scope = 'beliefs' AND s.key = d.key"
    )


#: The tables this revision guards (later revisions guard their own new tables).
GUARDED_TABLES = ("fact_keys", "facts", "events", "fact_samples", "belief_follow", "belief_chain")


def _quoted(message: str) -> str:
    return "'" + message.replace("'", "''") + "'"


def guard_tables(backend: str, tables: tuple[str, ...]) -> None:
    """Refuse writes to ``tables`` outside the store and the rules (the function
    ``toaster_guard()`` exists on PostgreSQL from this revision on)."""
    for table in tables:
        if backend == "postgresql":
            op.execute(
                f"CREATE TRIGGER {table}_guard BEFORE INSERT OR UPDATE OR DELETE OR "
                f"TRUNCATE ON {table} FOR EACH STATEMENT EXECUTE FUNCTION toaster_guard()"
            )
            continue
        message = _quoted(GUARD_MESSAGE.format(table=table))
        for action in ("insert", "update", "delete"):
            op.execute(
                f"CREATE TRIGGER {table}_guard_{action} BEFORE {action.upper()} ON "
                f"{table} WHEN NOT EXISTS (SELECT 1 FROM rule_writer) "
                f"BEGIN SELECT RAISE(ABORT, {message}); END"
            )


def unguard_tables(backend: str, tables: tuple[str, ...]) -> None:
    """Undo :func:`guard_tables`."""
    for table in tables:
        if backend == "postgresql":
            op.execute(f"DROP TRIGGER {table}_guard ON {table}")
            continue
        for action in ("insert", "update", "delete"):
            op.execute(f"DROP TRIGGER {table}_guard_{action}")


def _create_guards(backend: str) -> None:
    if backend == "postgresql":
        message = _quoted(GUARD_MESSAGE.replace("{table}", "%s"))
        op.execute(
            "CREATE FUNCTION toaster_guard() RETURNS trigger LANGUAGE plpgsql AS $$ BEGIN "
            "IF current_setting('toaster.writer', true) IS DISTINCT FROM 'rules' THEN "
            f"RAISE EXCEPTION USING MESSAGE = format({message}, TG_TABLE_NAME), "
            "ERRCODE = 'insufficient_privilege'; END IF; RETURN NULL; END $$"
        )
    guard_tables(backend, GUARDED_TABLES)


def _drop_guards(backend: str) -> None:
    unguard_tables(backend, GUARDED_TABLES)
    if backend == "postgresql":
        op.execute("DROP FUNCTION toaster_guard()")


def upgrade() -> None:
    op.execute("DROP TABLE IF EXISTS belief_rules")
    op.execute(settings_view(DEFAULTS))
    op.create_table(
        "rule_writer",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("holder", sa.Text(), nullable=False),
        sa.CheckConstraint("id = 1", name=op.f("ck_rule_writer_single_row")),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_rule_writer")),
    )
    _create_guards(op.get_bind().dialect.name)


def downgrade() -> None:
    """Store the defaults as rows again (what 0005 read); the rule text is not restored."""
    _drop_guards(op.get_bind().dialect.name)
    op.drop_table("rule_writer")
    op.execute(
        "INSERT INTO settings (scope, key, value_json) SELECT 'beliefs', key, value_json "
        "FROM belief_settings WHERE is_default = 1"
    )
    op.execute("DROP VIEW belief_settings")
