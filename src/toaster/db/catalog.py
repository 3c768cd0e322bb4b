"""Entities, agents, ontology, properties, areas and settings: the small tables around facts,
written here (and read here by the store).

Every function takes a connection inside the caller's transaction; :class:`toaster.db.Store`
wraps the writes in one transaction per call. The public reads (entities, agents, ontology,
descendants, properties) are :mod:`toaster.queries.catalog`'s.
"""

from __future__ import annotations

import json
import math
from typing import Any

from sqlalchemy import (
    BigInteger,
    Connection,
    bindparam,
    cast,
    delete,
    func,
    insert,
    select,
    update,
)

from toaster.db import schema as s
from toaster.db.dialects import backend_for, insert_with_conflicts
from toaster.db.views import agent_view_names, create_agent_views, drop_agent_views
from toaster.errors import InvalidInputError, UnknownEntityError
from toaster.model import (
    AGENT_KINDS,
    Fact,
    check_agent_id,
    check_id,
    check_optional_id,
    check_text,
    shown,
)
from toaster.timeutil import check_ns, now_ns

_PLURALS = {
    "humans": "human",
    "robots": "robot",
    "objects": "object",
    "joints": "joint",
    "areas": "area",
    "agents": "agent",
}


def normalise_kind(kind: object) -> str:
    """Lower-case, singular kind (``'Object'`` and ``'objects'`` both give ``'object'``)."""
    if not isinstance(kind, str):
        msg = f"invalid entity kind {kind!r}: give a word such as human, robot, object, joint"
        raise InvalidInputError(msg)
    word = kind.strip().strip("'").lower()
    return _PLURALS.get(word, word)


def _entity_values(entity_id: str, kind: str, name: str, owner_id: str) -> dict[str, str]:
    """An entity's checked columns (one-line errors naming the bad value)."""
    check_id(entity_id, "entity id")
    check_text(name, f"name of entity {entity_id!r}")
    check_optional_id(owner_id, f"owner id of entity {entity_id!r}")
    return {"name": name or entity_id, "kind": normalise_kind(kind), "owner_id": owner_id}


def _wants_agent(kind: str, agent: bool | None, is_self: bool | None = None) -> bool:
    return agent if agent is not None else (kind in AGENT_KINDS or kind == "agent" or bool(is_self))


def upsert_entity(
    conn: Connection,
    entity_id: str,
    kind: str,
    name: str,
    owner_id: str,
    *,
    is_self: bool | None,
    agent: bool | None,
    t_ns: int | None,
    views: bool = True,
) -> None:
    """Insert or update an entity; register it as an agent when it is one (with its
    per-agent views unless ``views`` is false: see :func:`register_agent`)."""
    values = _entity_values(entity_id, kind, name, owner_id)
    stamp = now_ns() if t_ns is None else check_ns(t_ns, f"registration time of {entity_id!r}")
    # One statement whoever registers the same entity at the same time (another process
    # waits for this transaction, then updates).
    conn.execute(upsert(conn, s.entities, ["id"], values, created_ns=stamp, id=entity_id))
    if _wants_agent(values["kind"], agent, is_self) or is_self:
        register_agent(conn, entity_id, is_self=is_self, t_ns=stamp, views=views)


def upsert_entities(
    conn: Connection, rows: list[tuple[str, str, str, str, bool | None]], *, t_ns: int, views: bool
) -> None:
    """:func:`upsert_entity` of many ``(id, kind, name, owner_id, agent)`` rows (none self)
    in a few statements, so that a recording's thousands of people register at once
    (docs/producers.md, "Belief holders")."""
    check_ns(t_ns, "registration time")
    checked = [
        (entity_id, _entity_values(entity_id, kind, name, owner), agent)
        for entity_id, kind, name, owner, agent in rows
    ]
    if not checked:
        return
    statement = insert_with_conflicts(conn.dialect.name)(s.entities)
    statement = statement.on_conflict_do_update(
        index_elements=["id"], set_={c: statement.excluded[c] for c in ("name", "kind", "owner_id")}
    )
    conn.execute(
        statement,
        [{"id": entity_id, "created_ns": t_ns, **values} for entity_id, values, _ in checked],
    )
    wanted = [
        entity_id for entity_id, values, agent in checked if _wants_agent(values["kind"], agent)
    ]
    if wanted:
        register_agents(conn, wanted, t_ns=t_ns, views=views)


def upsert(
    conn: Connection, table: Any, keys: list[str], values: dict[str, Any], **insert_only: Any
) -> Any:
    """``INSERT ... ON CONFLICT (keys) DO UPDATE SET values`` in ``conn``'s dialect (both
    backends spell it alike); ``insert_only`` columns are set by the insert alone."""
    statement = insert_with_conflicts(conn.dialect.name)(table).values(**insert_only, **values)
    return statement.on_conflict_do_update(index_elements=keys, set_=values)


def register_agent(
    conn: Connection, agent_id: str, *, is_self: bool | None, t_ns: int, views: bool = True
) -> None:
    """Make an entity an agent (idempotent, also against concurrent registrations) and
    create its per-agent views (``views``; a recording's thousands of people are registered
    without them: each view is DDL, which grows the schema every later statement parses;
    :func:`create_missing_views` makes them on demand).

    The agent's number is the next free one, taken under the backend's registration lock
    (PostgreSQL: an advisory lock held to the commit; SQLite has one writer), so processes
    registering agents at once wait for each other instead of taking the same number.
    """
    agents = s.agents.c
    known = conn.execute(select(agents.num).where(agents.id == agent_id)).first() is not None
    if not known and register_agents(
        conn, [agent_id], t_ns=t_ns, views=views, is_self=bool(is_self)
    ):
        return
    if is_self is not None:  # known, or registered by another process meanwhile
        conn.execute(update(s.agents).where(agents.id == agent_id).values(is_self=is_self))


def lock_registrations(conn: Connection) -> None:
    """Take, until the transaction ends, the lock under which agents are numbered
    (PostgreSQL). A transaction that registers agents after writing other tables takes it
    first: their triggers lock ``store_state``, which another registration holding this lock
    would wait for (a deadlock)."""
    backend_for(conn.dialect.name).lock_registrations(conn)


def register_agents(
    conn: Connection, agent_ids: list[str], *, t_ns: int, views: bool, is_self: bool = False
) -> list[str]:
    """:func:`register_agent` of many agents in a few statements; return those it
    registered (the others were agents already)."""
    agents = s.agents.c
    unique = [check_agent_id(a) for a in dict.fromkeys(agent_ids)]
    lock_registrations(conn)
    known: set[str] = set()
    for start in range(0, len(unique), 500):  # (SQLite's bound parameters are limited)
        chunk = unique[start : start + 500]
        known.update(conn.execute(select(agents.id).where(agents.id.in_(chunk))).scalars())
    new = [a for a in unique if a not in known]
    if not new:
        return new
    first = conn.execute(select(func.coalesce(func.max(agents.num), 0))).scalar_one() + 1
    conn.execute(
        insert(s.agents),
        [
            {"id": a, "num": first + i, "is_self": is_self, "registered_ns": t_ns}
            for i, a in enumerate(new)
        ],
    )
    if views:
        for i, agent_id in enumerate(new):
            create_agent_views(conn, agent_id, first + i)
    return new


def create_missing_views(conn: Connection, agent_ids: list[str] | None = None) -> list[str]:
    """Create the per-agent views that do not exist (of ``agent_ids``, default every agent);
    return the agents that got them."""
    from sqlalchemy import inspect

    existing = set(inspect(conn).get_view_names())
    query = select(s.agents.c.id, s.agents.c.num).order_by(s.agents.c.num)
    if agent_ids is not None:
        check_entities(conn, agent_ids)
        query = query.where(s.agents.c.id.in_(agent_ids))
    created = []
    for agent_id, num in conn.execute(query).all():
        if not set(agent_view_names(agent_id)) <= existing:
            create_agent_views(conn, agent_id, num)
            created.append(agent_id)
    return created


def nested_holders_of(conn: Connection, agent_id: str) -> list[str]:
    """The nested holders whose chain names ``agent_id`` (``A>B`` for A and for B)."""
    chain = s.belief_chain.c
    return list(
        conn.execute(
            select(chain.holder_id)
            .distinct()
            .where(chain.member_id == agent_id)
            .order_by(chain.holder_id)
        ).scalars()
    )


def remove_entity(conn: Connection, entity_id: str) -> None:
    """Delete an entity; an agent's views, keys, facts and events go with it, and so do the
    nested holders whose chain names it."""
    check_entities(conn, [entity_id])
    if conn.execute(select(s.agents.c.id).where(s.agents.c.id == entity_id)).first():
        drop_agent_views(conn, entity_id)
        for holder in (*nested_holders_of(conn, entity_id), entity_id):
            empty_facts(conn, holder)
            conn.execute(delete(s.holders).where(s.holders.c.id == holder))
        conn.execute(delete(s.agents).where(s.agents.c.id == entity_id))
    conn.execute(delete(s.properties).where(s.properties.c.entity_id == entity_id))
    conn.execute(delete(s.entities).where(s.entities.c.id == entity_id))


def check_entities(conn: Connection, ids: list[str]) -> None:
    """Raise :class:`UnknownEntityError` for the first id (non-empty) not registered."""
    wanted = [i for i in ids if i]
    if not wanted:
        return
    found = set(
        conn.execute(
            select(s.entities.c.id).where(s.entities.c.id.in_(bindparam("ids", expanding=True))),
            {"ids": wanted},
        ).scalars()
    )
    for entity_id in wanted:
        if entity_id not in found:
            msg = (
                f"unknown entity {entity_id!r}: register it first with "
                f"`toaster set-info ENTITY --id {entity_id} --type object` (or human, robot...)"
            )
            raise UnknownEntityError(msg)


def open_facts_matching(
    conn: Connection, agent_id: str, prop: str, filters: dict[str, str | None]
) -> list[tuple[int, Fact, int]]:
    """Current facts of an agent with this property and the non-wildcard key fields."""
    k, f = s.fact_keys.c, s.facts.c
    query = (
        select(
            k.id,
            k.subject_id,
            k.property,
            k.target_id,
            f.value_text,
            f.value_num,
            f.confidence,
            f.observability,
            k.property_type,
            k.sub_property,
            k.subject_owner_id,
            k.target_owner_id,
            f.valid_from_ns,
        )
        .select_from(s.fact_keys.join(s.facts, s.facts.c.key_id == k.id))
        .where(k.agent_id == agent_id, k.property == prop, f.valid_to_ns.is_(None))
    )
    for column, value in filters.items():
        if value is not None and value != "NULL":
            query = query.where(k[column] == value)
    return [(row[0], Fact(*row[1:12]), row[12]) for row in conn.execute(query.order_by(k.id))]


def empty_facts(conn: Connection, agent_id: str | None) -> None:
    """Delete facts, memory and events of one agent or of all (keys included)."""
    if agent_id is None:
        for table in (s.events, s.fact_samples, s.fact_sample_blocks, s.facts, s.fact_keys):
            conn.execute(delete(table))
        # No belief run happened yet: the rules' clocks start again (a replay from 0).
        conn.execute(update(s.holders).values(clock_ns=None, clock_self=None))
        delete_setting(conn, "data", "start_ns")  # nor any data: the next run's start counts
        return
    keys = select(s.fact_keys.c.id).where(s.fact_keys.c.agent_id == agent_id)
    conn.execute(delete(s.events).where(s.events.c.agent_id == agent_id))
    facts = select(s.facts.c.id).where(s.facts.c.key_id.in_(keys))
    # rows first: a packing that moved some meanwhile committed its blocks before these go
    for table in (s.fact_samples, s.fact_sample_blocks):
        conn.execute(delete(table).where(table.c.fact_id.in_(facts)))
    conn.execute(delete(s.facts).where(s.facts.c.key_id.in_(keys)))
    conn.execute(delete(s.fact_keys).where(s.fact_keys.c.agent_id == agent_id))


def _as_bool(value: object, what: str) -> bool:
    if isinstance(value, bool):
        return value
    word = str(value).strip().strip("'").lower()
    if word in {"true", "1", "yes"}:
        return True
    if word in {"false", "0", "no", ""}:
        return False
    msg = f"invalid {what} {value!r}: use true or false"
    raise InvalidInputError(msg)


def upsert_ontology(
    conn: Connection, entity_class: str, individual: str, instantiated: object
) -> None:
    """Insert or update one class-tree edge."""
    check_id(entity_class, "ontology class")
    check_id(individual, "ontology individual")
    flag = _as_bool(instantiated, "instantiated flag")
    table = s.ontology
    conn.execute(
        upsert(
            conn,
            table,
            ["entity_class", "individual"],
            {"instantiated": flag},
            entity_class=entity_class,
            individual=individual,
        )
    )


def delete_ontology(conn: Connection, entity_class: str, individual: str | None) -> int:
    """Delete one edge or all edges of a class."""
    query = delete(s.ontology).where(
        s.ontology.c.entity_class == check_id(entity_class, "ontology class")
    )
    if individual is not None:
        query = query.where(s.ontology.c.individual == check_id(individual, "ontology individual"))
    return conn.execute(query).rowcount


def upsert_property(conn: Connection, entity_id: str, key: str, value: object) -> None:
    """Set one static property of a registered entity."""
    check_id(key, "property key")
    check_entities(conn, [check_id(entity_id, "entity id")])
    if not isinstance(value, str | int | float) or (
        isinstance(value, float) and not math.isfinite(value)
    ):
        msg = (
            f"invalid value {shown(value)} for property {key!r} of {entity_id!r}: "
            "give text or a finite number"
        )
        raise InvalidInputError(msg)
    table = s.properties
    stored = str(value).lower() if isinstance(value, bool) else str(value)
    check_text(stored, f"value of property {key!r} of {entity_id!r}")
    conn.execute(
        upsert(conn, table, ["entity_id", "key"], {"value": stored}, entity_id=entity_id, key=key)
    )


def delete_property(conn: Connection, entity_id: str, key: str | None) -> int:
    """Delete one property or all properties of an entity."""
    query = delete(s.properties).where(s.properties.c.entity_id == check_id(entity_id, "entity id"))
    if key is not None:
        query = query.where(s.properties.c.key == check_id(key, "property key"))
    return conn.execute(query).rowcount


def put_area(conn: Connection, area_id: str, spec: dict[str, Any], owner_id: str) -> None:
    """Insert or replace an area definition."""
    check_id(area_id, "area id")
    check_optional_id(owner_id, f"owner of area {area_id!r}")
    body = to_json(spec, f"spec for area {area_id!r}", sort_keys=True)
    conn.execute(
        upsert(
            conn,
            s.areas,
            ["id"],
            {"owner_id": owner_id or "", "spec_json": body, "updated_ns": now_ns()},
            id=area_id,
        )
    )
    bump_control(conn)


def remove_area(conn: Connection, area_id: str) -> bool:
    """Delete an area; False when it did not exist."""
    found = bool(
        conn.execute(delete(s.areas).where(s.areas.c.id == check_id(area_id, "area id"))).rowcount
    )
    if found:
        bump_control(conn)
    return found


def remove_all_areas(conn: Connection) -> int:
    """Delete every area; return how many there were."""
    count = int(conn.execute(delete(s.areas)).rowcount or 0)
    if count:
        bump_control(conn)
    return count


def areas(conn: Connection) -> dict[str, dict[str, Any]]:
    """Every stored area spec by id."""
    rows = conn.execute(select(s.areas.c.id, s.areas.c.spec_json).order_by(s.areas.c.id))
    return {row[0]: json.loads(row[1]) for row in rows}


def to_json(value: object, what: str, *, sort_keys: bool = False) -> str:
    """``value`` as JSON text for a ``*_json`` column; a one-line error naming ``what`` when
    it has no JSON form (NaN and infinities included) or holds text that is not UTF-8."""
    try:
        body = json.dumps(value, sort_keys=sort_keys, allow_nan=False)
    except (TypeError, ValueError) as exc:
        msg = f"invalid {what}: {exc} (give JSON values: text, finite numbers, lists, objects)"
        raise InvalidInputError(msg) from None
    if "\\u" in body:  # non-ASCII text, escaped: lone surrogates are not text
        check_text(json.dumps(value, ensure_ascii=False), what)
    return body


def put_setting(conn: Connection, scope: str, key: str, value: object) -> None:
    """Insert or replace one JSON-able setting."""
    check_id(scope, "setting scope")
    check_id(key, "setting key")
    body = to_json(value, f"value for setting {scope}.{key}")
    table = s.settings
    conn.execute(upsert(conn, table, ["scope", "key"], {"value_json": body}, scope=scope, key=key))


def delete_setting(conn: Connection, scope: str, key: str | None = None) -> int:
    """Delete one setting, or every setting of a scope; return how many there were."""
    table = s.settings
    query = delete(table).where(table.c.scope == check_id(scope, "setting scope"))
    if key is not None:
        query = query.where(table.c.key == check_id(key, "setting key"))
    return int(conn.execute(query).rowcount or 0)


def get_setting(conn: Connection, scope: str, key: str, default: object) -> Any:
    """One setting's value, or ``default``."""
    table = s.settings
    row = conn.execute(
        select(table.c.value_json).where(
            table.c.scope == check_id(scope, "setting scope"),
            table.c.key == check_id(key, "setting key"),
        )
    ).first()
    return default if row is None else json.loads(row[0])


def settings(conn: Connection, scope: str) -> dict[str, Any]:
    """Every setting of a scope."""
    table = s.settings
    rows = conn.execute(select(table.c.key, table.c.value_json).where(table.c.scope == scope))
    return {row[0]: json.loads(row[1]) for row in rows}


def data_start_ns(conn: Connection) -> int | None:
    """When the database's data starts (the earliest scenario, recording or batch start
    recorded by :func:`note_data_start`); None when nothing recorded one."""
    value = get_setting(conn, "data", "start_ns", None)
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def note_data_start(conn: Connection, t_ns: int) -> None:
    """Record that data starts at ``t_ns``: keeps the earliest (writes only to lower it; one
    statement, so that concurrent runs keep the earliest too)."""
    table = s.settings
    statement = insert_with_conflicts(conn.dialect.name)(table).values(
        scope="data", key="start_ns", value_json=json.dumps(int(t_ns))
    )
    conn.execute(
        statement.on_conflict_do_update(
            index_elements=["scope", "key"],
            set_={"value_json": statement.excluded.value_json},
            where=cast(table.c.value_json, BigInteger) > int(t_ns),
        )
    )


def entity_exists(conn: Connection, entity_id: str) -> bool:
    """Whether ``entity_id`` is a registered entity (in the caller's transaction)."""
    table = s.entities
    query = select(table.c.id).where(table.c.id == check_text(entity_id, "entity id filter"))
    return conn.execute(query).first() is not None


# -- control plane (revision 0005; see toaster.node.control) ---------------------------------
CONTROL_CHANNEL = "toaster_control"


def bump_control(conn: Connection) -> None:
    """Mark a change a running node must apply, in this transaction (PostgreSQL also sends
    ``NOTIFY toaster_control`` on commit)."""
    state = s.store_state
    conn.execute(
        update(state).where(state.c.id == 1).values(control_version=state.c.control_version + 1)
    )
    if conn.dialect.name == "postgresql":
        conn.execute(select(func.pg_notify(CONTROL_CHANNEL, "")))


def control_version(conn: Connection) -> int:
    """The number bumped by every control change."""
    state = s.store_state
    return int(conn.execute(select(state.c.control_version).where(state.c.id == 1)).scalar_one())
