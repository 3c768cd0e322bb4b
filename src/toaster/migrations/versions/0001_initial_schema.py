"""Initial schema: entities, agents, fact keys and intervals, events, ontology, properties,
areas, settings, and the readable views over facts and events.

Revision ID: 0001
Revises:
Create Date: 2026-11-22
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None

_FACT_COLUMNS = (
    "k.agent_id, k.subject_id, k.subject_owner_id, k.property, k.property_type, k.sub_property, "
    "k.target_id, k.target_owner_id, f.value_text, f.value_num, f.confidence, f.observability, "
    "f.valid_from_ns, f.valid_to_ns, f.recorded_ns, f.source, f.id AS fact_id, k.id AS key_id"
)
_FACTS = f"SELECT {_FACT_COLUMNS} FROM facts f JOIN fact_keys k ON k.id = f.key_id"

#: Readable views, frozen as of this revision (never import live view text into a migration).
VIEWS = [
    ("fact_history", _FACTS),
    ("current_facts", _FACTS + " WHERE f.valid_to_ns IS NULL"),
    ("memory", _FACTS + " WHERE f.valid_to_ns IS NOT NULL"),
    (
        "event_log",
        "SELECT e.id, e.agent_id, e.kind, e.stamp_ns, k.subject_id, k.subject_owner_id, k.property, "
        "k.property_type, k.sub_property, k.target_id, k.target_owner_id, e.value_text, e.value_num, "
        "e.confidence, e.observability, e.previous_text, e.source, e.recorded_ns, e.key_id "
        "FROM events e JOIN fact_keys k ON k.id = e.key_id",
    ),
]


def upgrade() -> None:
    """Create every table, index and readable view of the first schema."""
    op.create_table(
        "areas",
        sa.Column("id", sa.Text(), nullable=False),
        sa.Column("owner_id", sa.Text(), server_default=sa.text("('')"), nullable=False),
        sa.Column("spec_json", sa.Text(), nullable=False),
        sa.Column("updated_ns", sa.BigInteger(), nullable=False),
        sa.CheckConstraint("id <> ''", name=op.f("ck_areas_id_not_empty")),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_areas")),
    )
    op.create_table(
        "entities",
        sa.Column("id", sa.Text(), nullable=False),
        sa.Column("name", sa.Text(), server_default=sa.text("('')"), nullable=False),
        sa.Column("kind", sa.Text(), server_default=sa.text("('')"), nullable=False),
        sa.Column("owner_id", sa.Text(), server_default=sa.text("('')"), nullable=False),
        sa.Column("created_ns", sa.BigInteger(), nullable=False),
        sa.CheckConstraint("id <> ''", name=op.f("ck_entities_id_not_empty")),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_entities")),
    )
    op.create_table(
        "ontology",
        sa.Column("entity_class", sa.Text(), nullable=False),
        sa.Column("individual", sa.Text(), nullable=False),
        sa.Column("instantiated", sa.Boolean(), server_default=sa.text("(false)"), nullable=False),
        sa.CheckConstraint(
            "entity_class <> '' AND individual <> ''", name=op.f("ck_ontology_not_empty")
        ),
        sa.PrimaryKeyConstraint("entity_class", "individual", name=op.f("pk_ontology")),
    )
    with op.batch_alter_table("ontology", schema=None) as batch_op:
        batch_op.create_index("ix_ontology_individual", ["individual"], unique=False)

    op.create_table(
        "settings",
        sa.Column("scope", sa.Text(), nullable=False),
        sa.Column("key", sa.Text(), nullable=False),
        sa.Column("value_json", sa.Text(), nullable=False),
        sa.PrimaryKeyConstraint("scope", "key", name=op.f("pk_settings")),
    )
    op.create_table(
        "store_state",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("cache_epoch", sa.BigInteger(), server_default=sa.text("0"), nullable=False),
        sa.CheckConstraint("id = 1", name=op.f("ck_store_state_single_row")),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_store_state")),
    )
    op.create_table(
        "agents",
        sa.Column("id", sa.Text(), nullable=False),
        sa.Column("num", sa.Integer(), nullable=False),
        sa.Column("is_self", sa.Boolean(), server_default=sa.text("(false)"), nullable=False),
        sa.Column("registered_ns", sa.BigInteger(), nullable=False),
        sa.ForeignKeyConstraint(
            ["id"], ["entities.id"], name=op.f("fk_agents_id_entities"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_agents")),
        sa.UniqueConstraint("num", name=op.f("uq_agents_num")),
    )
    op.create_table(
        "properties",
        sa.Column("entity_id", sa.Text(), nullable=False),
        sa.Column("key", sa.Text(), nullable=False),
        sa.Column("value", sa.Text(), nullable=False),
        sa.CheckConstraint("key <> ''", name=op.f("ck_properties_key_not_empty")),
        sa.ForeignKeyConstraint(
            ["entity_id"],
            ["entities.id"],
            name=op.f("fk_properties_entity_id_entities"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("entity_id", "key", name=op.f("pk_properties")),
    )
    with op.batch_alter_table("properties", schema=None) as batch_op:
        batch_op.create_index("ix_properties_key_value", ["key", "value"], unique=False)

    op.create_table(
        "fact_keys",
        sa.Column(
            "id",
            sa.BigInteger().with_variant(sa.Integer(), "sqlite"),
            autoincrement=True,
            nullable=False,
        ),
        sa.Column("agent_id", sa.Text(), nullable=False),
        sa.Column("subject_id", sa.Text(), nullable=False),
        sa.Column("subject_owner_id", sa.Text(), server_default=sa.text("('')"), nullable=False),
        sa.Column("property", sa.Text(), nullable=False),
        sa.Column("sub_property", sa.Text(), server_default=sa.text("('')"), nullable=False),
        sa.Column("target_id", sa.Text(), server_default=sa.text("('')"), nullable=False),
        sa.Column("target_owner_id", sa.Text(), server_default=sa.text("('')"), nullable=False),
        sa.Column("property_type", sa.Text(), server_default=sa.text("('')"), nullable=False),
        sa.CheckConstraint(
            "subject_id <> '' AND property <> ''", name=op.f("ck_fact_keys_key_not_empty")
        ),
        sa.ForeignKeyConstraint(
            ["agent_id"],
            ["agents.id"],
            name=op.f("fk_fact_keys_agent_id_agents"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_fact_keys")),
    )
    with op.batch_alter_table("fact_keys", schema=None) as batch_op:
        batch_op.create_index("ix_fact_keys_property", ["agent_id", "property"], unique=False)
        batch_op.create_index("ix_fact_keys_subject", ["subject_id", "agent_id"], unique=False)
        batch_op.create_index("ix_fact_keys_target", ["target_id", "agent_id"], unique=False)
        batch_op.create_index(
            "uq_fact_keys_identity",
            [
                "agent_id",
                "subject_id",
                "subject_owner_id",
                "property",
                "sub_property",
                "target_id",
                "target_owner_id",
            ],
            unique=True,
        )

    op.create_table(
        "events",
        sa.Column(
            "id",
            sa.BigInteger().with_variant(sa.Integer(), "sqlite"),
            autoincrement=True,
            nullable=False,
        ),
        sa.Column("key_id", sa.BigInteger(), nullable=False),
        sa.Column("agent_id", sa.Text(), nullable=False),
        sa.Column("kind", sa.Text(), nullable=False),
        sa.Column("stamp_ns", sa.BigInteger(), nullable=False),
        sa.Column("value_text", sa.Text(), nullable=True),
        sa.Column("value_num", sa.Float(), nullable=True),
        sa.Column("confidence", sa.Float(), nullable=True),
        sa.Column("observability", sa.Float(), nullable=True),
        sa.Column("previous_text", sa.Text(), nullable=True),
        sa.Column("source", sa.Text(), nullable=False),
        sa.Column("recorded_ns", sa.BigInteger(), nullable=False),
        sa.CheckConstraint(
            "kind IN ('appeared', 'changed', 'ended', 'event')", name=op.f("ck_events_kind_known")
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_events")),
    )
    with op.batch_alter_table("events", schema=None) as batch_op:
        batch_op.create_index("ix_events_agent_stamp", ["agent_id", "stamp_ns"], unique=False)
        batch_op.create_index("ix_events_key_stamp", ["key_id", "stamp_ns"], unique=False)
        batch_op.create_index("ix_events_stamp", ["stamp_ns"], unique=False)

    op.create_table(
        "facts",
        sa.Column(
            "id",
            sa.BigInteger().with_variant(sa.Integer(), "sqlite"),
            autoincrement=True,
            nullable=False,
        ),
        sa.Column("key_id", sa.BigInteger(), nullable=False),
        sa.Column("value_text", sa.Text(), nullable=False),
        sa.Column("value_num", sa.Float(), nullable=True),
        sa.Column("confidence", sa.Float(), nullable=False),
        sa.Column("observability", sa.Float(), nullable=False),
        sa.Column("valid_from_ns", sa.BigInteger(), nullable=False),
        sa.Column("valid_to_ns", sa.BigInteger(), nullable=True),
        sa.Column("recorded_ns", sa.BigInteger(), nullable=False),
        sa.Column("source", sa.Text(), nullable=False),
        sa.CheckConstraint(
            "confidence >= 0 AND confidence <= 1", name=op.f("ck_facts_confidence_range")
        ),
        sa.CheckConstraint(
            "observability >= 0 AND observability <= 1", name=op.f("ck_facts_observability_range")
        ),
        sa.CheckConstraint(
            "valid_to_ns IS NULL OR valid_to_ns >= valid_from_ns",
            name=op.f("ck_facts_valid_interval"),
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_facts")),
    )
    with op.batch_alter_table("facts", schema=None) as batch_op:
        batch_op.create_index("ix_facts_key_from", ["key_id", "valid_from_ns", "id"], unique=False)
        batch_op.create_index(
            "uq_facts_open_key",
            ["key_id"],
            unique=True,
            sqlite_where=sa.text("valid_to_ns IS NULL"),
            postgresql_where=sa.text("valid_to_ns IS NULL"),
        )

    op.execute("INSERT INTO store_state (id, cache_epoch) VALUES (1, 0)")
    for name, body in VIEWS:
        op.execute(f"CREATE VIEW {name} AS {body}")


def downgrade() -> None:
    """Drop everything, per-agent views first (they depend on the readable views)."""
    bind = op.get_bind()
    readable = {name for name, _ in VIEWS}
    # No placeholder parsing in identifiers: the driver's own cursor.
    cursor = bind.connection.dbapi_connection.cursor()  # type: ignore[union-attr]
    for view in sa.inspect(bind).get_view_names():
        if view not in readable:
            quoted = '"' + view.replace('"', '""') + '"'
            cursor.execute(f"DROP VIEW IF EXISTS {quoted}")
    for name, _ in reversed(VIEWS):
        op.execute(f"DROP VIEW IF EXISTS {name}")
    with op.batch_alter_table("facts", schema=None) as batch_op:
        batch_op.drop_index(
            "uq_facts_open_key",
            sqlite_where=sa.text("valid_to_ns IS NULL"),
            postgresql_where=sa.text("valid_to_ns IS NULL"),
        )
        batch_op.drop_index("ix_facts_key_from")

    op.drop_table("facts")
    with op.batch_alter_table("events", schema=None) as batch_op:
        batch_op.drop_index("ix_events_stamp")
        batch_op.drop_index("ix_events_key_stamp")
        batch_op.drop_index("ix_events_agent_stamp")

    op.drop_table("events")
    with op.batch_alter_table("fact_keys", schema=None) as batch_op:
        batch_op.drop_index("uq_fact_keys_identity")
        batch_op.drop_index("ix_fact_keys_target")
        batch_op.drop_index("ix_fact_keys_subject")
        batch_op.drop_index("ix_fact_keys_property")

    op.drop_table("fact_keys")
    with op.batch_alter_table("properties", schema=None) as batch_op:
        batch_op.drop_index("ix_properties_key_value")

    op.drop_table("properties")
    op.drop_table("agents")
    op.drop_table("store_state")
    op.drop_table("settings")
    with op.batch_alter_table("ontology", schema=None) as batch_op:
        batch_op.drop_index("ix_ontology_individual")

    op.drop_table("ontology")
    op.drop_table("entities")
    op.drop_table("areas")
