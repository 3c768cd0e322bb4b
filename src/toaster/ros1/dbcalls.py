"""Database side of the services: the library calls behind database_manager's execute,
get_info and set_info, the original's numeric area ids, and node commands waited for.

Plain toaster code (no rospy): results are dicts of toaster_msgs fields.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sqlalchemy import text

from toaster import queries as q
from toaster.db import catalog
from toaster.errors import InvalidInputError
from toaster.model import Entity, EventRow, Fact, FactRow
from toaster.node import control
from toaster.world.rosmsg import fact_fields, fact_from_msg

if TYPE_CHECKING:
    from toaster.db.database import Database

AREA_SCOPE, AREA_KEY = "ros1", "area_ids"  # {area name: the original's numeric id}
KEYBOARD_SCOPE, KEYBOARD_KEY = "keyboard", "entity"  # set_entity_keyboard's choice


def control_state(db: Database) -> control.ControlState:
    """The stored control state (monitored agents, streams, held objects)."""
    with db.transaction() as conn:
        return control.read_state(conn)


def entity_kind(db: Database, entity_id: str) -> str | None:
    """The kind of a registered entity (human, robot, object, joint...), None if unknown."""
    with db.transaction() as conn:
        kind = conn.execute(
            text("SELECT kind FROM entities WHERE id = :id"), {"id": entity_id}
        ).scalar_one_or_none()
    return None if kind is None else str(kind)


def run_command(db: Database, kind: str, args: dict[str, Any], wait_s: float) -> str | None:
    """Queue a node command; wait up to ``wait_s`` for it. The node's error, else None (also
    when no node took it in time: it stays queued for the next node)."""
    command_id = control.submit(db, kind, args)
    deadline = time.monotonic() + wait_s
    while time.monotonic() < deadline:
        with db.transaction() as conn:
            row = conn.execute(
                text("SELECT state, answer_json FROM control_commands WHERE id = :id"),
                {"id": command_id},
            ).one_or_none()
        if row is None or row.state == "done":
            return None
        if row.state == "failed":
            return str(json.loads(row.answer_json or '""'))
        time.sleep(0.01)
    return None


# -- the original's numeric area ids -----------------------------------------------------------
def area_numbers(db: Database) -> dict[str, int]:
    """{area name: number} for every stored area (areas made elsewhere get the first free
    numbers, kept from then on)."""
    with db.transaction(write=True) as conn:
        numbers = dict(catalog.get_setting(conn, AREA_SCOPE, AREA_KEY, {}) or {})
        names = set(catalog.areas(conn))
        numbers = {name: int(n) for name, n in numbers.items() if name in names}
        for name in sorted(names - set(numbers)):
            numbers[name] = _first_free(numbers.values())
        catalog.put_setting(conn, AREA_SCOPE, AREA_KEY, numbers)
    return numbers


def _first_free(used: Iterable[int]) -> int:
    taken, n = set(used), 1
    while n in taken:
        n += 1
    return n


def area_number(db: Database, requested: int, name: str) -> int:
    """The number an added area gets: the one asked for, the one its name has, else the first
    free one (the original's id 0)."""
    numbers = area_numbers(db)
    if requested > 0:
        return requested
    return numbers.get(name) or _first_free(numbers.values())


def area_name(db: Database, number: int) -> str | None:
    """The name of the area with that number."""
    return next((name for name, n in area_numbers(db).items() if n == number), None)


def put_area(db: Database, name: str, spec: dict[str, Any], number: int) -> None:
    """Store an area under its name; an area that had the same number is replaced (as the
    original's add_area with an existing id)."""
    numbers = area_numbers(db)
    with db.transaction(write=True) as conn:
        for other, n in list(numbers.items()):
            if n == number and other != name:
                catalog.remove_area(conn, other)
                del numbers[other]
        catalog.put_area(conn, name, spec, spec.get("owner", ""))
        numbers[name] = number
        catalog.put_setting(conn, AREA_SCOPE, AREA_KEY, numbers)


def forget_area(db: Database, name: str | None) -> None:
    """Drop one area's number (None: all of them)."""
    with db.transaction(write=True) as conn:
        numbers = dict(catalog.get_setting(conn, AREA_SCOPE, AREA_KEY, {}) or {})
        numbers = {} if name is None else {k: v for k, v in numbers.items() if k != name}
        catalog.put_setting(conn, AREA_SCOPE, AREA_KEY, numbers)


def set_keyboard_entity(db: Database, entity_id: str) -> None:
    """toaster_simu's set_entity_keyboard: the keyboard-controlled entity, kept as the
    setting ``keyboard.entity`` (one at a time, as the original)."""
    with db.transaction(write=True) as conn:
        catalog.put_setting(conn, KEYBOARD_SCOPE, KEYBOARD_KEY, entity_id)


def keyboard_entity(db: Database) -> str | None:
    """The entity set_entity_keyboard chose last (None: none)."""
    with db.transaction() as conn:
        found = catalog.get_setting(conn, KEYBOARD_SCOPE, KEYBOARD_KEY, None)
    return found if isinstance(found, str) else None


# -- rows as message fields ---------------------------------------------------------------------
def row_fields(row: FactRow) -> dict[str, Any]:
    """toaster_msgs/Fact fields of a stored interval (timeEnd 0 while it holds)."""
    out = fact_fields(row.to_fact(), row.valid_from_ns)
    out["timeEnd"] = row.valid_to_ns or 0
    return out


def event_fields(row: EventRow) -> dict[str, Any]:
    """toaster_msgs/Event fields; an ended fact is "!property", as the original wrote it."""
    fact = Fact(
        row.subject_id,
        row.property,
        row.target_id,
        row.value_text or "",
        row.value_num,
        row.confidence if row.confidence is not None else 1.0,
        row.observability if row.observability is not None else 1.0,
        row.property_type,
        row.sub_property,
        row.subject_owner_id,
        row.target_owner_id,
    )
    out = fact_fields(fact, row.stamp_ns)
    if row.kind == "ended":
        out["property"] = "!" + row.property
    for key in ("timeStart", "timeEnd"):
        del out[key]
    return out


def id_fields(entity: Entity) -> dict[str, Any]:
    return {"id": entity.id, "name": entity.name, "type": entity.kind, "owner_id": entity.owner_id}


def _number(value: str) -> int:
    return int(value) if value.isdigit() and int(value) < 2**32 else 0


def property_fields(db: Database, entity_id: str | None) -> list[dict[str, Any]]:
    """Static properties as toaster_msgs/Property (one per entity; known keys only)."""
    grouped: dict[str, dict[str, str]] = {}
    for row in q.properties(db, entity_id):
        grouped.setdefault(row.entity_id, {})[row.key] = str(row.value)
    return [
        {
            "id": _number(eid),
            "color": p.get("color", ""),
            "height": p.get("height", ""),
            "linkedToId": _number(p.get("linkedToId", "")),
            "linkType": p.get("linkType", ""),
        }
        for eid, p in grouped.items()
    ]


# -- database_manager ---------------------------------------------------------------------------
def _agent(db: Database, agent: str) -> str:
    store = db.store()
    return (
        store.check_agent(agent)
        if agent
        else store.self_agent("give agentId (no single self agent)")
    )


def _facts(db: Database, req: Any, sub: str) -> list[dict[str, Any]]:
    agent = _agent(db, req.agentId)
    if sub == "VALUE":
        f = req.reqFact
        row = q.fact_value(
            db,
            agent,
            f.subjectId,
            f.property,
            f.targetId,
            sub_property=f.subProperty or None,
            subject_owner=f.subjectOwnerId or None,
            target_owner=f.targetOwnerId or None,
        )
        return [row_fields(row)] if row else []
    reader = {"ALL": q.history, "CURRENT": q.current_facts, "OLD": q.memory}.get(sub)
    if reader is None:
        msg = f"get_info FACT {sub}: use ALL, CURRENT, OLD or VALUE"
        raise InvalidInputError(msg)
    return [row_fields(r) for r in reader(db, agent)]


def _events(db: Database, req: Any, sub: str) -> list[dict[str, Any]]:
    agent = req.agentId or None
    if sub == "VALUE":
        e = req.reqEvent
        rows = q.events(
            db,
            agent,
            subject=e.subjectId or None,
            target=e.targetId or None,
            property=e.property.lstrip("!") or None,
            limit=1,
        )
    else:
        rows = q.events(db, agent)
    return [event_fields(r) for r in rows]


def _ontology(db: Database, req: Any, sub: str) -> list[dict[str, Any]]:
    if sub == "LEAVE":
        rows = q.descendants(db, req.entityClass)
    else:
        rows = q.ontology(db, req.entityClass if sub == "VALUE" else None)
    return [
        {"entityClass": r.entity_class, "individual": r.individual, "instantiated": r.instantiated}
        for r in rows
    ]


def _ids(db: Database, req: Any, sub: str) -> list[dict[str, Any]]:
    if sub == "VALUE":
        return [id_fields(e) for e in q.entities(db, req.idString or None, name=req.name or None)]
    return [id_fields(e) for e in q.entities(db)]


def get_info(db: Database, req: Any) -> dict[str, list[dict[str, Any]]]:
    """The original's get_info by type and subType (FACT, EVENT, ONTOLOGY, ID/ENTITY, AGENT,
    PROPERTY)."""
    kind, sub = str(req.type).upper(), (str(req.subType).upper() or "ALL")
    if kind == "FACT":
        return {"facts": _facts(db, req, sub)}
    if kind == "EVENT":
        return {"events": _events(db, req, sub)}
    if kind == "ONTOLOGY":
        return {"ontology": _ontology(db, req, sub)}
    if kind in ("ID", "ENTITY"):
        return {"ids": _ids(db, req, sub)}
    if kind == "AGENT":
        agents = {a.id for a in q.agents(db)}
        return {"ids": [id_fields(e) for e in q.entities(db) if e.id in agents]}
    if kind == "PROPERTY":
        wanted = (req.idString or (str(req.id) if req.id else None)) if sub == "VALUE" else None
        return {"properties": property_fields(db, wanted)}
    msg = f"get_info type {req.type!r}: use FACT, EVENT, ONTOLOGY, ID, AGENT or PROPERTY"
    raise InvalidInputError(msg)


def set_info(db: Database, req: Any) -> None:
    """The original's set_info: ENTITY, FACT (add or remove; "NULL" wildcards), EVENT."""
    store = db.store()
    kind = str(req.infoType).upper()
    if kind == "ENTITY":
        store.add_entity(req.id, req.type or "object", req.name, req.ownerId)
        return
    if kind not in ("FACT", "EVENT"):
        msg = f"set_info {req.infoType!r}: use ENTITY, FACT or EVENT"
        raise InvalidInputError(msg)
    if req.agentId == "PLANNING":
        msg = "set_info: the PLANNING table is not kept by toaster"
        raise InvalidInputError(msg)
    agent = _agent(db, req.agentId)
    if kind == "EVENT":
        store.record_event(agent, fact_from_msg(req.event), t_ns=int(req.event.time) or None)
        return
    for f in req.facts:
        if req.add:
            store.assert_fact(
                agent, fact_from_msg(f), t_ns=int(f.time) or None, source="ros", strict=False
            )
        else:
            store.retract_facts(
                agent,
                f.property,
                f.subjectId or None,
                f.targetId or None,
                sub_property=f.subProperty or None,
                subject_owner_id=f.subjectOwnerId or None,
                target_owner_id=f.targetOwnerId or None,
                source="ros",
            )


def execute(db: Database, req: Any) -> tuple[bool, list[str]]:
    """The original's execute: SQL (read-only here), ARE_IN_TABLE, EMPTY, PRINT."""
    command = str(req.command).upper()
    if command == "SQL":
        result = q.execute(db, req.order)
        return True, ["NULL" if v is None else str(v) for row in result.rows for v in row]
    if command == "ARE_IN_TABLE":
        facts = [
            Fact(
                f.subjectId,
                f.property,
                f.targetId,
                sub_property=f.subProperty,
                property_type=f.propertyType,
            )
            for f in req.facts
        ]
        answers = q.are_in_table(db, _agent(db, req.agent), facts)
        if str(req.type).upper() == "INDIV":
            return True, ["true" if a else "false" for a in answers]
        return all(answers), []
    if command == "EMPTY":
        scope = str(req.type).upper()
        if scope not in ("ALL", "AGENT"):
            msg = f"execute EMPTY {req.type!r}: use ALL or AGENT"
            raise InvalidInputError(msg)
        db.store().empty(_agent(db, req.agent) if scope == "AGENT" else None)
        return True, []
    if command == "PRINT":
        agent = _agent(db, req.agent) if str(req.type).upper() == "AGENT" else None
        return True, [
            f"{r.agent_id} {r.subject_id} {r.property} {r.target_id} {r.value_text}"
            for r in q.current_facts(db, agent)
        ]
    msg = (
        f"execute {req.command!r}: use SQL, ARE_IN_TABLE, EMPTY or PRINT (toaster stores "
        "every producer's facts, so SET_TOPICS and RESET_TABLES have no equivalent)"
    )
    raise InvalidInputError(msg)


PLOT_DIR = "plot_fact"  # the original's <package dir>/plot_fact, here under the working directory


def plot_facts(db: Database, req: Any, directory: str | Path = PLOT_DIR) -> Path:
    """The original's plot_facts: ``reqFact``'s timeline between ``subjectID`` and ``targetID``
    written as gnuplot data to ``directory/<reqFact>.dat`` (script ``.gp`` beside it).

    Fixes the original's defects: the directory is created, no matching fact is a clear error
    (not a crash), and the level plotted after each change is the fact's, not its inverse.
    """
    from toaster.outputs.plotting import plot_facts as plot

    fact = str(req.reqFact).lstrip("!")
    if not fact or "/" in fact or fact.startswith("."):
        msg = f"plot_facts reqFact {req.reqFact!r}: give a fact name such as IsLookingToward"
        raise InvalidInputError(msg)
    since, until = (None, None) if req.fullTime else (int(req.timeStart), int(req.timeEnd))
    if until is not None and since is not None and until <= since:
        msg = f"plot_facts timeEnd {until} is not after timeStart {since}: or set fullTime"
        raise InvalidInputError(msg)
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{fact}.dat"
    plot(
        db,
        path,
        subject=req.subjectID or None,
        property=fact,
        target=req.targetID or None,
        since=since,
        until=until,
    )
    return path


# -- load_save ----------------------------------------------------------------------------------
SQLITE_OK, SQLITE_ERROR, SQLITE_CANTOPEN = 0, 1, 14  # the status codes load_save answers
_SQLITE_MAGIC = b"SQLite format 3\0"
_VERSIONS = ("cache_epoch", "control_version", "agents_version")


def _sqlite_file(path: Path) -> bool:
    with path.open("rb") as f:
        return f.read(16) == _SQLITE_MAGIC


def _revision(conn: Any, what: str) -> str:
    import sqlite3

    try:
        return str(conn.execute("SELECT version_num FROM alembic_version").fetchone()[0])
    except (sqlite3.Error, TypeError):
        msg = f"load_save: {what} is not a toaster database (no schema revision)"
        raise InvalidInputError(msg) from None


def load_save(db: Database, file_name: str, to_save: bool) -> None:
    """The original's load_save, with SQLite's online-backup API between the live database
    and ``file_name``: ``to_save`` copies the live database into the file (made or replaced;
    an existing file must be an SQLite database), else the file, a toaster database at the
    live one's schema revision, replaces the live database. After a load every store and a
    running node re-read what they cache (cache epoch, control and agent versions moved past
    both). PostgreSQL: refused (pg_dump / pg_restore do it on the server's side)."""
    import sqlite3

    if db.dialect_name != "sqlite":
        msg = (
            "load_save: the database is PostgreSQL, which keeps no in-memory copy to save: "
            "use pg_dump / pg_restore on the server"
        )
        raise InvalidInputError(msg)
    from sqlalchemy.engine import make_url

    live_path = make_url(db.url).database
    path = Path(str(file_name)).expanduser()
    if not file_name or live_path is None or path.resolve() == Path(live_path).resolve():
        msg = f"load_save: fileName {str(file_name)!r} must name another file than the live one"
        raise InvalidInputError(msg)
    if (path.exists() or not to_save) and not (path.is_file() and _sqlite_file(path)):
        what = "is no SQLite file to replace" if to_save else "is no SQLite database to load"
        msg = f"load_save: {str(path)!r} {what}"
        raise InvalidInputError(msg)
    live = sqlite3.connect(live_path, timeout=30)
    other = sqlite3.connect(path, timeout=30)
    try:
        if to_save:
            live.backup(other)
            return
        if _revision(other, repr(str(path))) != _revision(live, "the live database"):
            msg = f"load_save: {str(path)!r} is at another schema revision than the live database"
            raise InvalidInputError(msg)
        columns = ", ".join(_VERSIONS)
        before = live.execute(f"SELECT {columns} FROM store_state WHERE id = 1").fetchone()
        loaded = other.execute(f"SELECT {columns} FROM store_state WHERE id = 1").fetchone()
        other.backup(live)
        moved = [max(a, b) + 1 for a, b in zip(before, loaded, strict=True)]
        with live:
            live.execute(
                "UPDATE store_state SET cache_epoch = ?, control_version = ?, agents_version = ? "
                "WHERE id = 1",
                moved,
            )
    finally:
        live.close()
        other.close()
