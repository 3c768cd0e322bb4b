"""Beliefs: nested belief holders and followed belief periods.

``belief_chain``: a nested holder ``A>B`` (an agent row) is the chain A, B ("A's model of B's
beliefs"), one row per position.

``belief_follow`` keeps, per holder key, the periods ``[from_ns, to_ns)`` during which the
holder's belief follows the self agent's key. The readable views show the self's intervals
clipped to each period (confidence x ``pconf``) and its events stamped in
``[events_from_ns, events_to_ns]`` as the holder's own, so a robot change that every holder
perceives writes no holder row.

The rule statements are not stored: every store renders them from the package's templates
(:mod:`toaster.rules.sqltext`); their settings' defaults are the view ``belief_settings``
(0006). This revision squashes the unreleased 0002 (which also stored the statements in a
table ``belief_rules`` and the defaults as ``settings`` rows) and 0003: a database stamped
0003 or later by them upgrades unchanged (0006 drops ``belief_rules``).

Revision ID: 0003
Revises: 0001
Create Date: 2026-11-23
"""

from __future__ import annotations

import hashlib
import importlib
from typing import Any

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0001"
branch_labels = None
depends_on = None

# The readable views of this revision, frozen (a revision never imports live view text; the
# followed period is defined in toaster.rules.sqltext, and tests/rules/test_sqltext.py
# checks that the views of a database at head are the ones it renders).
_KEY = (
    "k.agent_id, k.subject_id, k.subject_owner_id, k.property, k.property_type, "
    "k.sub_property, k.target_id, k.target_owner_id"
)
_OWN = (
    f"SELECT {_KEY}, f.value_text, f.value_num, f.confidence, f.observability, "
    "f.valid_from_ns, f.valid_to_ns, f.recorded_ns, f.source, f.id AS fact_id, "
    "k.id AS key_id FROM facts f JOIN fact_keys k ON k.id = f.key_id"
)
# The self's intervals of a followed key, clipped to the period ({lo}/{hi}: MIN/MAX or
# LEAST/GREATEST, the one difference between the backends).
_FOLLOWED = (
    f"SELECT {_KEY}, f.value_text, f.value_num, {{lo}}(1.0, f.confidence * w.pconf), "
    "f.observability, {hi}(f.valid_from_ns, w.from_ns), "
    "CASE WHEN w.to_ns IS NULL THEN f.valid_to_ns WHEN f.valid_to_ns IS NULL THEN w.to_ns "
    "ELSE {lo}(f.valid_to_ns, w.to_ns) END, f.recorded_ns, 'beliefs', f.id, k.id "
    "FROM belief_follow w JOIN fact_keys k ON k.id = w.hkey "
    "JOIN facts f ON f.key_id = w.self_key "
    "AND (w.to_ns IS NULL OR (f.valid_from_ns < w.to_ns AND w.to_ns > w.from_ns)) "
    "AND (f.valid_to_ns IS NULL OR f.valid_to_ns > w.from_ns)"
)
_EVENT_KEY = (
    "k.subject_id, k.subject_owner_id, k.property, k.property_type, k.sub_property, "
    "k.target_id, k.target_owner_id"
)
_EVENTS = (
    f"SELECT e.id, e.agent_id, e.kind, e.stamp_ns, {_EVENT_KEY}, e.value_text, e.value_num, "
    "e.confidence, e.observability, e.previous_text, e.source, e.recorded_ns, e.key_id "
    "FROM events e JOIN fact_keys k ON k.id = e.key_id"
)
_FOLLOWED_EVENTS = (
    f"SELECT e.id, k.agent_id, e.kind, e.stamp_ns, {_EVENT_KEY}, e.value_text, e.value_num, "
    "{lo}(1.0, e.confidence * w.pconf), e.observability, e.previous_text, 'beliefs', "
    "e.recorded_ns, k.id "
    "FROM belief_follow w JOIN fact_keys k ON k.id = w.hkey "
    "JOIN events e ON e.key_id = w.self_key AND e.kind <> 'event' "
    "AND e.stamp_ns >= w.events_from_ns "
    "AND (w.events_to_ns IS NULL OR e.stamp_ns <= w.events_to_ns)"
)
_FUNCTIONS = {"sqlite": {"lo": "MIN", "hi": "MAX"}, "postgresql": {"lo": "LEAST", "hi": "GREATEST"}}


def views(backend: str) -> list[tuple[str, str]]:
    """The readable views of this revision for ``backend``."""
    followed = _FOLLOWED.format(**_FUNCTIONS[backend])
    return [
        ("fact_history", f"{_OWN} UNION ALL {followed}"),
        (
            "current_facts",
            f"{_OWN} WHERE f.valid_to_ns IS NULL UNION ALL {followed} "
            "AND w.to_ns IS NULL AND f.valid_to_ns IS NULL",
        ),
        (
            "memory",
            f"{_OWN} WHERE f.valid_to_ns IS NOT NULL UNION ALL {followed} "
            "AND (w.to_ns IS NOT NULL OR f.valid_to_ns IS NOT NULL)",
        ),
        ("event_log", f"{_EVENTS} UNION ALL {_FOLLOWED_EVENTS.format(**_FUNCTIONS[backend])}"),
    ]


def _previous_views() -> list[tuple[str, str]]:
    """The views this revision replaces: those of 0001 (restored by the downgrade)."""
    return list(importlib.import_module("toaster.migrations.versions.0001_initial_schema").VIEWS)


def _cursor(bind: sa.Connection) -> Any:
    """The driver's cursor: no ':name' or '%' placeholder parsing in view text or identifiers."""
    dbapi = bind.connection.dbapi_connection
    assert dbapi is not None
    return dbapi.cursor()


def _replace_views(bind: sa.Connection, definitions: list[tuple[str, str]]) -> None:
    cursor = _cursor(bind)
    for name, body in definitions:
        if bind.dialect.name == "postgresql":  # keeps the per-agent views built on it
            cursor.execute(f"CREATE OR REPLACE VIEW {name} AS {body}")
        else:
            cursor.execute(f"DROP VIEW IF EXISTS {name}")
            cursor.execute(f"CREATE VIEW {name} AS {body}")


def upgrade() -> None:
    """Create ``belief_chain``, ``belief_follow`` and the union views."""
    op.create_table(
        "belief_chain",
        sa.Column("holder_id", sa.Text(), nullable=False),
        sa.Column("position", sa.Integer(), nullable=False),
        sa.Column("member_id", sa.Text(), nullable=False),
        sa.CheckConstraint("position >= 1", name=op.f("ck_belief_chain_position_positive")),
        sa.ForeignKeyConstraint(
            ["holder_id"],
            ["agents.id"],
            ondelete="CASCADE",
            name=op.f("fk_belief_chain_holder_id_agents"),
        ),
        sa.ForeignKeyConstraint(
            ["member_id"],
            ["agents.id"],
            ondelete="CASCADE",
            name=op.f("fk_belief_chain_member_id_agents"),
        ),
        sa.PrimaryKeyConstraint("holder_id", "position", name=op.f("pk_belief_chain")),
    )
    with op.batch_alter_table("belief_chain", schema=None) as batch_op:
        batch_op.create_index("ix_belief_chain_member_id", ["member_id"], unique=False)
    op.create_table(
        "belief_follow",
        sa.Column(
            "id",
            sa.BigInteger().with_variant(sa.Integer(), "sqlite"),
            autoincrement=True,
            nullable=False,
        ),
        sa.Column("holder_id", sa.Text(), nullable=False),
        sa.Column("hkey", sa.BigInteger(), nullable=False),
        sa.Column("self_key", sa.BigInteger(), nullable=False),
        sa.Column("from_ns", sa.BigInteger(), nullable=False),
        sa.Column("to_ns", sa.BigInteger(), nullable=True),
        sa.Column("events_from_ns", sa.BigInteger(), nullable=False),
        sa.Column("events_to_ns", sa.BigInteger(), nullable=True),
        sa.Column("pconf", sa.Float(), nullable=False),
        sa.CheckConstraint(
            "to_ns IS NULL OR to_ns >= from_ns", name=op.f("ck_belief_follow_valid_period")
        ),
        sa.CheckConstraint("pconf >= 0", name=op.f("ck_belief_follow_pconf_positive")),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_belief_follow")),
    )
    with op.batch_alter_table("belief_follow", schema=None) as batch_op:
        batch_op.create_index(
            "uq_belief_follow_open_hkey",
            ["hkey"],
            unique=True,
            sqlite_where=sa.text("to_ns IS NULL"),
            postgresql_where=sa.text("to_ns IS NULL"),
        )
        batch_op.create_index("ix_belief_follow_hkey_from", ["hkey", "from_ns"], unique=False)
        batch_op.create_index(
            "ix_belief_follow_self_holder", ["self_key", "holder_id"], unique=False
        )
    bind = op.get_bind()
    _replace_views(bind, views(bind.dialect.name))


def _view_names(agent_id: str) -> list[str]:
    """The per-agent view names (frozen copy of toaster.db.views.view_name)."""
    names = []
    for prefix in ("fact_table_", "memory_table_", "events_table_"):
        name = prefix + agent_id
        if len(name.encode()) > 63:
            digest = hashlib.sha1(agent_id.encode()).hexdigest()[:10]
            room = 63 - len(prefix) - len(digest) - 1
            name = f"{prefix}{agent_id.encode()[:room].decode(errors='ignore')}_{digest}"
        names.append(name)
    return names


def _copy_followed_periods(bind: sa.Connection) -> None:
    """Copy every followed period into the holders' own rows. The followed rows are those the
    views show under a holder's key while the underlying row belongs to the self's key: they
    are copied as they are shown."""
    bind.exec_driver_sql(
        "INSERT INTO facts (key_id, value_text, value_num, confidence, observability, "
        "valid_from_ns, valid_to_ns, recorded_ns, source) "
        "SELECT h.key_id, h.value_text, h.value_num, h.confidence, h.observability, "
        "h.valid_from_ns, h.valid_to_ns, h.recorded_ns, h.source "
        "FROM fact_history h JOIN facts f ON f.id = h.fact_id AND f.key_id <> h.key_id"
    )
    bind.exec_driver_sql(
        "INSERT INTO events (key_id, agent_id, kind, stamp_ns, value_text, value_num, "
        "confidence, observability, previous_text, source, recorded_ns) "
        "SELECT h.key_id, h.agent_id, h.kind, h.stamp_ns, h.value_text, h.value_num, "
        "h.confidence, h.observability, h.previous_text, h.source, h.recorded_ns "
        "FROM event_log h JOIN events e ON e.id = h.id AND e.key_id <> h.key_id"
    )


def _remove_nested_holders(bind: sa.Connection) -> None:
    """Remove the nested holders: their views, beliefs, chains and agent rows."""
    cursor = _cursor(bind)  # and standard quoting
    holders = [
        row[0] for row in bind.execute(sa.text("SELECT DISTINCT holder_id FROM belief_chain"))
    ]
    for holder in holders:
        for name in _view_names(holder):
            quoted = '"' + name.replace('"', '""') + '"'
            cursor.execute(f"DROP VIEW IF EXISTS {quoted}")
        for table in ("events", "facts", "fact_keys"):
            if table == "facts":
                bind.execute(
                    sa.text(
                        "DELETE FROM facts WHERE key_id IN "
                        "(SELECT id FROM fact_keys WHERE agent_id = :h)"
                    ),
                    {"h": holder},
                )
            else:
                bind.execute(sa.text(f"DELETE FROM {table} WHERE agent_id = :h"), {"h": holder})
        bind.execute(sa.text("DELETE FROM belief_chain WHERE holder_id = :h"), {"h": holder})
        bind.execute(sa.text("DELETE FROM agents WHERE id = :h"), {"h": holder})
        bind.execute(sa.text("DELETE FROM entities WHERE id = :h"), {"h": holder})


def downgrade() -> None:
    """Copy every followed period into own rows, restore 0001's views, remove the nested
    holders (their beliefs and views), the tables and the beliefs settings."""
    bind = op.get_bind()
    _copy_followed_periods(bind)
    _replace_views(bind, _previous_views())
    with op.batch_alter_table("belief_follow", schema=None) as batch_op:
        batch_op.drop_index("ix_belief_follow_self_holder")
        batch_op.drop_index("ix_belief_follow_hkey_from")
        batch_op.drop_index("uq_belief_follow_open_hkey")
    op.drop_table("belief_follow")
    _remove_nested_holders(bind)
    with op.batch_alter_table("belief_chain", schema=None) as batch_op:
        batch_op.drop_index("ix_belief_chain_member_id")
    op.drop_table("belief_chain")
    op.execute("DROP TABLE IF EXISTS belief_rules")  # a database stamped by the old 0002-0005
    op.execute("DELETE FROM settings WHERE scope = 'beliefs'")
