"""The one declaration of toaster's schema (SQLAlchemy Core). Alembic migrations create it.

Tables
------
``entities``    every thing toaster knows (text id, name, kind, owner for joints).
``agents``      the entities that hold beliefs; ``is_self`` marks robots whose perception is the
                world state. ``num`` is a small integer used to name the per-agent views.
``holders``     everyone whose beliefs are kept (revision 0008): each agent (``agent_id`` =
                ``id``, depth 1, added by a trigger when the agent is) and each nested holder
                ``A>B`` ("A's model of B's beliefs", ``agent_id`` NULL, depth = chain length),
                registered by the belief rule. Nested holders are neither entities nor agents.
``fact_keys``   one row per identity of a fact for a holder (``agent_id`` -> ``holders.id``):
                (holder, subject, subject owner, property, sub-property, target, target owner).
``facts``       validity intervals ``[valid_from_ns, valid_to_ns)`` of a key with its value,
                confidence and observability. ``valid_to_ns`` NULL = current. At most one open
                interval per key (partial unique index).
``events``      every change of any agent's beliefs (appeared / changed / ended) and user events.
``ontology``    class tree as an adjacency list (class, individual, instantiated).
``properties``  static properties of entities, open key/value.
``areas``       area definitions (a JSON spec) so that areas survive restarts.
``settings``    thresholds and rule configuration kept as data (JSON values by scope/key).
``belief_chain`` the chains of nested holders: ``A>B`` is A, B, one row per position (0003).
``belief_follow`` periods during which a holder's belief of a key *follows* the self agent's
                key (it perceives every change): the self's intervals clipped to
                ``[from_ns, to_ns)`` and its events stamped in ``[events_from_ns,
                events_to_ns]`` are the holder's, read through the views, confidence x
                ``pconf``; a robot change perceived by a following holder writes no row (0003).
``belief_groups`` holders that perceive alike and follow the same self keys, each with its
                group's representative (revision 0011): while no perception fact changes, the
                rule computes a group's perception once (step 96_regroup forms them).
``belief_perceived`` who perceives which entity (holder, confidence), kept between runs for
                the self agent ``store_state.perceived_for``: a run whose changes hold no
                perception input reuses it (revision 0023, step 21_remember).
``belief_settled`` self keys that every holder perceiving them follows (and no other): while
                the kept perception holds, their changes take no step (0023, 98_settle).
``fact_samples`` the numeric history inside an interval (revision 0004): when a number,
                confidence or observability changes beyond its tolerance, the open interval
                is refreshed in place and the values it held *until* then are kept here, so
                the value at any past time is known within the tolerance (first sample of the
                interval after t, else the interval's own values).
``fact_sample_blocks`` PostgreSQL: an open interval's older samples, packed by maintenance
                into rows of :data:`toaster.db.dialects.postgresql.BLOCK` samples (arrays, one
                per column; ``until_ns`` is the block's last): a row of ``fact_samples`` costs
                100 bytes there, a sample in a block 35 (revision 0025). Empty on SQLite.
``store_state`` one row; ``cache_epoch`` is bumped by writes that bypass snapshot sync so that
                every store process reloads what it remembers of the open facts;
                ``control_version`` by every change of what a running node must apply
                (areas, monitored agents, streams, held objects, commands; revision 0005).
``control_commands`` one-shot requests to a running node (set an entity's pose, pointing,
                relative positions) with their answers; pending ones wait for the next node
                (revision 0005, see :mod:`toaster.node.control`).
``rule_writer`` SQLite: the store's writer role for one transaction; the guard triggers of
                the tables above that only the store and the rule write refuse anyone else
                (revision 0006, :data:`toaster.db.dialects.GUARDED_TABLES`).
``fact_inbox``  the write surface of plain SQL clients: one inserted row is one write, applied
                by a trigger as the store applies it, then the belief rule (revision 0007).
``belief_runs`` inserting a row runs the belief rule over ``belief_changed``; ``belief_steps``
                (SQLite) the blocks of a run; ``belief_changed`` ... ``belief_new_chain`` the
                rule's scratch tables, empty between runs (:mod:`toaster.rules.pipeline`).

No foreign keys on ``facts`` and ``events``: they are the hot tables (thousands of rows per
second) and a per-row foreign-key check there cost more than the insert itself (PostgreSQL runs
one trigger per row). The store writes them only with key ids it just read or created, and
deletions go through :func:`toaster.db.catalog.empty_facts`, which removes events, intervals and
keys together.

Readable views (``current_facts``, ``memory``, ``fact_history``, ``event_log``) and one view
per real agent (``fact_table_<agent>``, ``memory_table_<agent>``, ``events_table_<agent>``; not
for nested holders) are created by migrations and by agent registration (see
:mod:`toaster.db.views`).
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import (
    ARRAY,
    BigInteger,
    Boolean,
    CheckConstraint,
    Column,
    Float,
    ForeignKey,
    Index,
    Integer,
    MetaData,
    PrimaryKeyConstraint,
    Table,
    Text,
    text,
)
from sqlalchemy.types import TypeEngine

NAMING = {
    "ix": "ix_%(table_name)s_%(column_0_N_name)s",
    "uq": "uq_%(table_name)s_%(column_0_N_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}

metadata = MetaData(naming_convention=NAMING)

#: 64-bit integer primary keys that are also SQLite rowid aliases (autoincrementing).
RowId = BigInteger().with_variant(Integer(), "sqlite")


def _text(name: str, **kwargs: object) -> Column[str]:
    return Column(name, Text, nullable=False, server_default=text("''"), **kwargs)  # type: ignore[arg-type]


entities = Table(
    "entities",
    metadata,
    Column("id", Text, primary_key=True),
    _text("name"),
    _text("kind"),
    _text("owner_id"),
    Column("created_ns", BigInteger, nullable=False),
    CheckConstraint("id <> ''", name="id_not_empty"),
)

agents = Table(
    "agents",
    metadata,
    Column("id", Text, ForeignKey("entities.id", ondelete="CASCADE"), primary_key=True),
    Column("num", Integer, nullable=False, unique=True),
    Column("is_self", Boolean, nullable=False, server_default=text("false")),
    Column("registered_ns", BigInteger, nullable=False),
)

holders = Table(
    "holders",
    metadata,
    Column("id", Text, primary_key=True),
    Column(
        "agent_id", Text, ForeignKey("agents.id", ondelete="CASCADE"), nullable=True, unique=True
    ),
    Column("depth", Integer, nullable=False),
    Column("registered_ns", BigInteger, nullable=False),
    # The rules' clock of this holder: the time of its last belief run (runs never go back in
    # time, whatever the clocks of the producers that start them), and the self agent whose run
    # set it (its next write at that time shares the instant, any other run at or before it
    # comes 1 ns later). PostgreSQL: a run locks its holders' rows, so that the runs sharing a
    # holder take turns and the others do not wait (revision 0028; before, one clock for all in
    # ``store_state``).
    Column("clock_ns", BigInteger, nullable=True),
    Column("clock_self", Text, nullable=True),
    CheckConstraint(
        "(depth = 1 AND agent_id = id) OR (depth >= 2 AND agent_id IS NULL)", name="agent_or_nested"
    ),
)

fact_keys = Table(
    "fact_keys",
    metadata,
    Column("id", RowId, primary_key=True, autoincrement=True),
    Column("agent_id", Text, ForeignKey("holders.id", ondelete="CASCADE"), nullable=False),
    Column("subject_id", Text, nullable=False),
    _text("subject_owner_id"),
    Column("property", Text, nullable=False),
    _text("sub_property"),
    _text("target_id"),
    _text("target_owner_id"),
    _text("property_type"),
    CheckConstraint("subject_id <> '' AND property <> ''", name="key_not_empty"),
    Index(
        "uq_fact_keys_identity",
        "agent_id",
        "subject_id",
        "subject_owner_id",
        "property",
        "sub_property",
        "target_id",
        "target_owner_id",
        unique=True,
    ),
    Index("ix_fact_keys_subject", "subject_id", "agent_id"),
    Index("ix_fact_keys_target", "target_id", "agent_id"),
    Index("ix_fact_keys_property", "agent_id", "property"),
    # As-of (revision 0022): an agent's keys in the order beliefs_at returns them, so that
    # SQLite merges its two halves without sorting.
    Index("ix_fact_keys_agent_order", "agent_id", "subject_id", "property", "target_id", "id"),
)

facts = Table(
    "facts",
    metadata,
    Column("id", RowId, primary_key=True, autoincrement=True),
    Column("key_id", BigInteger, nullable=False),  # -> fact_keys.id (see "No foreign keys")
    Column("value_text", Text, nullable=False),
    Column("value_num", Float, nullable=True),
    Column("confidence", Float, nullable=False),
    Column("observability", Float, nullable=False),
    Column("valid_from_ns", BigInteger, nullable=False),
    Column("valid_to_ns", BigInteger, nullable=True),
    Column("recorded_ns", BigInteger, nullable=False),
    Column("source", Text, nullable=False),
    CheckConstraint("valid_to_ns IS NULL OR valid_to_ns >= valid_from_ns", name="valid_interval"),
    CheckConstraint("confidence >= 0 AND confidence <= 1", name="confidence_range"),
    CheckConstraint("observability >= 0 AND observability <= 1", name="observability_range"),
    # One open interval per key; also the index used to close and refresh the open interval.
    Index(
        "uq_facts_open_key",
        "key_id",
        unique=True,
        sqlite_where=text("valid_to_ns IS NULL"),
        postgresql_where=text("valid_to_ns IS NULL"),
    ),
    # As-of: the last interval of a key starting at or before t.
    Index("ix_facts_key_from", "key_id", "valid_from_ns", "id"),
)

events = Table(
    "events",
    metadata,
    Column("id", RowId, primary_key=True, autoincrement=True),
    Column("key_id", BigInteger, nullable=False),  # -> fact_keys.id
    Column("agent_id", Text, nullable=False),  # -> agents.id
    Column("kind", Text, nullable=False),
    Column("stamp_ns", BigInteger, nullable=False),
    Column("value_text", Text, nullable=True),
    Column("value_num", Float, nullable=True),
    Column("confidence", Float, nullable=True),
    Column("observability", Float, nullable=True),
    Column("previous_text", Text, nullable=True),
    Column("source", Text, nullable=False),
    Column("recorded_ns", BigInteger, nullable=False),
    CheckConstraint("kind IN ('appeared', 'changed', 'ended', 'event')", name="kind_known"),
    Index("ix_events_agent_stamp", "agent_id", "stamp_ns"),
    Index("ix_events_stamp", "stamp_ns"),
    Index("ix_events_key_stamp", "key_id", "stamp_ns"),
)

ontology = Table(
    "ontology",
    metadata,
    Column("entity_class", Text, primary_key=True),
    Column("individual", Text, primary_key=True),
    Column("instantiated", Boolean, nullable=False, server_default=text("false")),
    CheckConstraint("entity_class <> '' AND individual <> ''", name="not_empty"),
    Index("ix_ontology_individual", "individual"),
)

properties = Table(
    "properties",
    metadata,
    Column("entity_id", Text, ForeignKey("entities.id", ondelete="CASCADE"), primary_key=True),
    Column("key", Text, primary_key=True),
    Column("value", Text, nullable=False),
    CheckConstraint("key <> ''", name="key_not_empty"),
    Index("ix_properties_key_value", "key", "value"),
)

areas = Table(
    "areas",
    metadata,
    Column("id", Text, primary_key=True),
    _text("owner_id"),
    Column("spec_json", Text, nullable=False),
    Column("updated_ns", BigInteger, nullable=False),
    CheckConstraint("id <> ''", name="id_not_empty"),
)

settings = Table(
    "settings",
    metadata,
    Column("scope", Text, primary_key=True),
    Column("key", Text, primary_key=True),
    Column("value_json", Text, nullable=False),
)

fact_samples = Table(
    "fact_samples",
    metadata,
    Column("fact_id", BigInteger, nullable=False),  # -> facts.id (see "No foreign keys")
    Column("until_ns", BigInteger, nullable=False),
    Column("value_num", Float, nullable=True),
    Column("confidence", Float, nullable=False),
    Column("observability", Float, nullable=False),
    PrimaryKeyConstraint("fact_id", "until_ns"),
    sqlite_with_rowid=False,  # the primary key is the table: one narrow row a sample
)


def _array(of: TypeEngine[Any]) -> TypeEngine[Any]:
    """A PostgreSQL array (TEXT on SQLite, where the table stays empty)."""
    return ARRAY(of).with_variant(Text(), "sqlite")


fact_sample_blocks = Table(  # PostgreSQL: older samples, packed by maintenance (0025)
    "fact_sample_blocks",
    metadata,
    Column("fact_id", BigInteger, nullable=False),  # -> facts.id
    Column("until_ns", BigInteger, nullable=False),  # its last sample's
    Column("untils_ns", _array(BigInteger()), nullable=False),  # increasing
    Column("value_nums", _array(Float()), nullable=False),
    Column("confidences", _array(Float()), nullable=False),
    Column("observabilities", _array(Float()), nullable=False),
    PrimaryKeyConstraint("fact_id", "until_ns"),
)

store_state = Table(
    "store_state",
    metadata,
    Column("id", Integer, primary_key=True),
    Column("cache_epoch", BigInteger, nullable=False, server_default=text("0")),
    Column("control_version", BigInteger, nullable=False, server_default=text("0")),
    # The agents and depth the nested holders were registered for (step holders).
    Column("holders_basis", Text, nullable=False, server_default=text("''")),
    # The self agent the groups of holders were formed for; NULL: none hold (revision 0011).
    Column("groups_for", Text, nullable=True),
    # Bumped by any write to ``agents`` (trigger): stores re-read their agents (0012).
    Column("agents_version", BigInteger, nullable=False, server_default=text("0")),
    # The self agent whose perception ``belief_perceived`` keeps, NULL: none (it ends with the
    # groups of holders), and the first run time it holds for (0023).
    Column("perceived_for", Text, nullable=True),
    Column("perceived_ns", BigInteger, nullable=True),
    CheckConstraint("id = 1", name="single_row"),
)

rule_writer = Table(  # SQLite's writer role (see toaster.db.dialects.GUARDED_TABLES)
    "rule_writer",
    metadata,
    Column("id", Integer, primary_key=True),
    Column("holder", Text, nullable=False),  # 'store' or 'inbox'
    CheckConstraint("id = 1", name="single_row"),
)

# -- The write surface and the rule's triggers (revision 0007, toaster.rules.triggers) ------
fact_inbox = Table(  # one inserted row = one write; the trigger applies it, the row is not kept
    "fact_inbox",
    metadata,
    Column("id", RowId, primary_key=True, autoincrement=True),
    Column("action", Text, nullable=False, server_default=text("'assert'")),
    Column("agent_id", Text, nullable=False),
    Column("subject_id", Text, nullable=True),
    Column("subject_owner_id", Text, nullable=True),
    Column("property", Text, nullable=False),
    Column("property_type", Text, nullable=True),
    Column("sub_property", Text, nullable=True),
    Column("target_id", Text, nullable=True),
    Column("target_owner_id", Text, nullable=True),
    Column("value_text", Text, nullable=False, server_default=text("'true'")),
    Column("value_num", Float, nullable=True),
    Column("confidence", Float, nullable=False, server_default=text("1.0")),
    Column("observability", Float, nullable=False, server_default=text("1.0")),
    Column("t_ns", BigInteger, nullable=False),
    Column("source", Text, nullable=False, server_default=text("'sql'")),
    Column("actor_id", Text, nullable=True),  # who made the change (revision 0009)
)

belief_runs = Table(  # inserting a row runs the belief rule over belief_changed
    "belief_runs",
    metadata,
    Column("id", RowId, primary_key=True, autoincrement=True),
    Column("self_id", Text, nullable=False),
    Column("t_ns", BigInteger, nullable=False),
    Column("recorded_ns", BigInteger, nullable=False),
)

belief_steps = Table(  # SQLite: the blocks of a run (a trigger each), emptied by the run
    "belief_steps",
    metadata,
    Column("id", RowId, primary_key=True, autoincrement=True),
    Column("block", Text, nullable=False),
    Column("self_id", Text, nullable=False),
    Column("t_ns", BigInteger, nullable=False),
    Column("recorded_ns", BigInteger, nullable=False),
)

# Scratch tables of one rule run, empty between runs. SQLite's triggers can only read tables of
# the main schema (one writer at a time); PostgreSQL sessions shadow the hot ones with temporary
# tables of the same name (step 00_temp), so concurrent writers never share rows.
belief_changed = Table(
    "belief_changed",
    metadata,
    Column("key_id", BigInteger, primary_key=True, autoincrement=False),
    Column("refreshed", Boolean, nullable=False),
    Column("prev_num", Float),
    Column("prev_conf", Float),
    Column("prev_obs", Float),
    Column("move", Text),  # a location key that ended ('before') or started ('after') (0009)
    Column("actor_id", Text),  # the agent who made the change, if known (0009)
)
belief_focus = Table("belief_focus", metadata, Column("entity_id", Text, primary_key=True))
belief_seen = Table(
    "belief_seen",
    metadata,
    Column("holder_id", Text),
    Column("entity_id", Text),
    Column("phase", Text),
    Column("pconf", Float),
    Index("ix_belief_seen_entity_holder", "entity_id", "phase", "holder_id"),
)
belief_in = Table(
    "belief_in",
    metadata,
    Column("holder_id", Text),
    Column("self_key", BigInteger),
    Column("hkey", BigInteger),
    Column("pconf", Float),
    Column("seen_again", Integer, nullable=False, server_default=text("0")),
    Index("ix_belief_in_key", "self_key", "holder_id"),
)
belief_todo = Table(
    "belief_todo",
    metadata,
    Column("holder_id", Text),
    Column("hkey", BigInteger),
    Column("self_key", BigInteger),
    Column("follow_id", BigInteger),
    Column("action", Text),
    Column("value_text", Text),
    Column("value_num", Float),
    Column("confidence", Float),
    Column("observability", Float),
    Column("previous_text", Text),
    Column("pconf", Float),
    Column("split_ns", BigInteger),
)
belief_freeze = Table(
    "belief_freeze",
    metadata,
    Column("follow_id", BigInteger, primary_key=True, autoincrement=False),
    Column("hkey", BigInteger),
    Column("from_ns", BigInteger),
    Column("cut_ns", BigInteger),
    Column("value_text", Text),
    Column("value_num", Float),
    Column("confidence", Float),
    Column("observability", Float),
)
belief_mat = Table(
    "belief_mat",
    metadata,
    Column("follow_id", BigInteger, primary_key=True, autoincrement=False),
)
belief_percepts = Table(  # SQLite: 20_perceive's self perception facts, one pass (0029)
    "belief_percepts",
    metadata,
    Column("subject_id", Text),
    Column("property", Text),
    Column("target_id", Text),
    Column("confidence", Float),
)
belief_new_chain = Table(  # nested holders being registered (step holders)
    "belief_new_chain",
    metadata,
    Column("holder_id", Text),
    Column("position", Integer),
    Column("member_id", Text),
)

control_commands = Table(
    "control_commands",
    metadata,
    Column("id", RowId, primary_key=True, autoincrement=True),
    Column("kind", Text, nullable=False),
    Column("args_json", Text, nullable=False),
    Column("created_ns", BigInteger, nullable=False),
    Column("state", Text, nullable=False, server_default=text("'pending'")),
    Column("answer_json", Text, nullable=True),
    Column("done_ns", BigInteger, nullable=True),
    CheckConstraint("state IN ('pending', 'done', 'failed')", name="state_known"),
    Index("ix_control_commands_pending", "state", "id"),
)

belief_groups = Table(  # holders that perceive alike and follow the same keys (0011)
    "belief_groups",
    metadata,
    Column("holder_id", Text, ForeignKey("holders.id", ondelete="CASCADE"), primary_key=True),
    Column("rep_id", Text, ForeignKey("holders.id", ondelete="CASCADE"), nullable=False),
    Index("ix_belief_groups_rep_id", "rep_id"),
)

belief_perceived = Table(  # who perceives which entity, kept between runs (0023)
    "belief_perceived",
    metadata,
    Column("entity_id", Text, primary_key=True),
    Column("holder_id", Text, primary_key=True),
    Column("pconf", Float, nullable=False),
)

belief_settled = Table(  # self keys whose steady changes need no step (0023)
    "belief_settled",
    metadata,
    Column("key_id", BigInteger, primary_key=True, autoincrement=False),
    Column("since_ns", BigInteger, nullable=False),
)

belief_chain = Table(
    "belief_chain",
    metadata,
    Column("holder_id", Text, ForeignKey("holders.id", ondelete="CASCADE"), primary_key=True),
    Column("position", Integer, primary_key=True),
    Column("member_id", Text, ForeignKey("agents.id", ondelete="CASCADE"), nullable=False),
    CheckConstraint("position >= 1", name="position_positive"),
    Index("ix_belief_chain_member_id", "member_id"),
)

belief_follow = Table(
    "belief_follow",
    metadata,
    Column("id", RowId, primary_key=True, autoincrement=True),
    Column("holder_id", Text, nullable=False),  # -> agents.id (the belief holder)
    Column("hkey", BigInteger, nullable=False),  # -> fact_keys.id of the holder
    Column("self_key", BigInteger, nullable=False),  # -> fact_keys.id of the self agent
    Column("from_ns", BigInteger, nullable=False),
    Column("to_ns", BigInteger, nullable=True),
    Column("events_from_ns", BigInteger, nullable=False),
    Column("events_to_ns", BigInteger, nullable=True),
    Column("pconf", Float, nullable=False),
    CheckConstraint("to_ns IS NULL OR to_ns >= from_ns", name="valid_period"),
    CheckConstraint("pconf >= 0", name="pconf_positive"),
    # One open period per holder key; the rule finds the followers of a changed self key.
    Index(
        "uq_belief_follow_open_hkey",
        "hkey",
        unique=True,
        sqlite_where=text("to_ns IS NULL"),
        postgresql_where=text("to_ns IS NULL"),
    ),
    Index("ix_belief_follow_hkey_from", "hkey", "from_ns"),
    Index("ix_belief_follow_self_holder", "self_key", "holder_id"),
)
