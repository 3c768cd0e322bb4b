"""Followed belief periods: a holder that perceives every change of a self fact shares its rows.

``belief_follow`` keeps, per holder key, the periods ``[from_ns, to_ns)`` during which the
holder's belief follows the self agent's key. The readable views show the self's intervals
clipped to each period (confidence x ``pconf``) and its events stamped in
``[events_from_ns, events_to_ns]`` as the holder's own, so a robot change that every holder
perceives writes no holder row. The rule
statements of ``sql/0003`` replace those of 0002.

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-22
"""

from __future__ import annotations

from importlib import resources

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None

_KEY = ("k.agent_id, k.subject_id, k.subject_owner_id, k.property, k.property_type, "
        "k.sub_property, k.target_id, k.target_owner_id")
_OWN = (f"SELECT {_KEY}, f.value_text, f.value_num, f.confidence, f.observability, "
        "f.valid_from_ns, f.valid_to_ns, f.recorded_ns, f.source, f.id AS fact_id, "
        "k.id AS key_id FROM facts f JOIN fact_keys k ON k.id = f.key_id")
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
_EVENT_KEY = ("k.subject_id, k.subject_owner_id, k.property, k.property_type, k.sub_property, "
              "k.target_id, k.target_owner_id")
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
_FUNCTIONS = {"sqlite": {"lo": "MIN", "hi": "MAX"},
              "postgresql": {"lo": "LEAST", "hi": "GREATEST"}}


def views(backend: str) -> list[tuple[str, str]]:
    """The readable views of this revision for ``backend`` (frozen here)."""
    followed = _FOLLOWED.format(**_FUNCTIONS[backend])
    open_followed = " AND w.to_ns IS NULL AND f.valid_to_ns IS NULL"
    closed_followed = " AND (w.to_ns IS NOT NULL OR f.valid_to_ns IS NOT NULL)"
    return [
        ("fact_history", f"{_OWN} UNION ALL {followed}"),
        ("current_facts",
         f"{_OWN} WHERE f.valid_to_ns IS NULL UNION ALL {followed}{open_followed}"),
        ("memory",
         f"{_OWN} WHERE f.valid_to_ns IS NOT NULL UNION ALL {followed}{closed_followed}"),
        ("event_log",
         f"{_EVENTS} UNION ALL {_FOLLOWED_EVENTS.format(**_FUNCTIONS[backend])}"),
    ]


def _statements(revision: str, backend: str) -> list[tuple[str, str]]:
    folder = resources.files("toaster") / "migrations" / "sql" / revision
    prefix = backend + "-"
    files = sorted((p for p in folder.iterdir()
                    if p.name.startswith(prefix) and p.name.endswith(".sql")),
                   key=lambda p: p.name)
    return [(p.name[len(prefix):-4], p.read_text(encoding="utf-8")) for p in files]


def _replace_views(bind: sa.Connection, definitions: list[tuple[str, str]]) -> None:
    cursor = bind.connection.dbapi_connection.cursor()
    for name, body in definitions:
        if bind.dialect.name == "postgresql":  # keeps the per-agent views built on it
            cursor.execute(f"CREATE OR REPLACE VIEW {name} AS {body}")
        else:
            cursor.execute(f"DROP VIEW IF EXISTS {name}")
            cursor.execute(f"CREATE VIEW {name} AS {body}")


def _install_rules(bind: sa.Connection, revision: str) -> None:
    backend = bind.dialect.name
    bind.execute(sa.text("DELETE FROM belief_rules WHERE backend = :b"), {"b": backend})
    rules = sa.table("belief_rules", sa.column("backend"), sa.column("step"),
                     sa.column("sql_text"))
    op.bulk_insert(rules, [{"backend": backend, "step": step, "sql_text": body}
                           for step, body in _statements(revision, backend)])


def upgrade() -> None:
    """Create ``belief_follow``, install the 0003 rule statements and the union views."""
    op.create_table(
        "belief_follow",
        sa.Column("id", sa.BigInteger().with_variant(sa.Integer(), "sqlite"),
                  autoincrement=True, nullable=False),
        sa.Column("holder_id", sa.Text(), nullable=False),
        sa.Column("hkey", sa.BigInteger(), nullable=False),
        sa.Column("self_key", sa.BigInteger(), nullable=False),
        sa.Column("from_ns", sa.BigInteger(), nullable=False),
        sa.Column("to_ns", sa.BigInteger(), nullable=True),
        sa.Column("events_from_ns", sa.BigInteger(), nullable=False),
        sa.Column("events_to_ns", sa.BigInteger(), nullable=True),
        sa.Column("pconf", sa.Float(), nullable=False),
        sa.CheckConstraint("to_ns IS NULL OR to_ns >= from_ns",
                           name=op.f("ck_belief_follow_valid_period")),
        sa.CheckConstraint("pconf >= 0", name=op.f("ck_belief_follow_pconf_positive")),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_belief_follow")),
    )
    with op.batch_alter_table("belief_follow", schema=None) as batch_op:
        batch_op.create_index("uq_belief_follow_open_hkey", ["hkey"], unique=True,
                              sqlite_where=sa.text("to_ns IS NULL"),
                              postgresql_where=sa.text("to_ns IS NULL"))
        batch_op.create_index("ix_belief_follow_hkey_from", ["hkey", "from_ns"], unique=False)
        batch_op.create_index("ix_belief_follow_self_holder", ["self_key", "holder_id"],
                              unique=False)
    bind = op.get_bind()
    _install_rules(bind, "0003")
    _replace_views(bind, views(bind.dialect.name))
    bind.execute(sa.text("INSERT INTO settings (scope, key, value_json) SELECT 'beliefs', "
                         "'share_rows', 'true' WHERE NOT EXISTS (SELECT 1 FROM settings "
                         "WHERE scope = 'beliefs' AND key = 'share_rows')"))


def downgrade() -> None:
    """Copy every followed period into the holders' own rows, then restore 0002."""
    bind = op.get_bind()
    # The followed rows are those the views show under a holder's key while the underlying
    # row belongs to the self's key: copy them as they are shown.
    bind.exec_driver_sql(
        "INSERT INTO facts (key_id, value_text, value_num, confidence, observability, "
        "valid_from_ns, valid_to_ns, recorded_ns, source) "
        "SELECT h.key_id, h.value_text, h.value_num, h.confidence, h.observability, "
        "h.valid_from_ns, h.valid_to_ns, h.recorded_ns, h.source "
        "FROM fact_history h JOIN facts f ON f.id = h.fact_id AND f.key_id <> h.key_id")
    bind.exec_driver_sql(
        "INSERT INTO events (key_id, agent_id, kind, stamp_ns, value_text, value_num, "
        "confidence, observability, previous_text, source, recorded_ns) "
        "SELECT h.key_id, h.agent_id, h.kind, h.stamp_ns, h.value_text, h.value_num, "
        "h.confidence, h.observability, h.previous_text, h.source, h.recorded_ns "
        "FROM event_log h JOIN events e ON e.id = h.id AND e.key_id <> h.key_id")
    _replace_views(bind, [("fact_history", _OWN),
                          ("current_facts", _OWN + " WHERE f.valid_to_ns IS NULL"),
                          ("memory", _OWN + " WHERE f.valid_to_ns IS NOT NULL"),
                          ("event_log", _EVENTS)])
    with op.batch_alter_table("belief_follow", schema=None) as batch_op:
        batch_op.drop_index("ix_belief_follow_self_holder")
        batch_op.drop_index("ix_belief_follow_hkey_from")
        batch_op.drop_index("uq_belief_follow_open_hkey")
    op.drop_table("belief_follow")
    _install_rules(bind, "0002")
    op.execute("DELETE FROM settings WHERE scope = 'beliefs' AND key = 'share_rows'")
