"""Batch files: the original's XML seeds and their JSON/YAML equivalents, in one transaction.

XML (the original's ``database_manager/database/*.xml``): one element per row; the kind of file
is told by its attributes (``entityClass`` → ontology, ``color``/``linkType`` → static
properties, ``id``+``type`` → entities). Values may carry the single quotes the original pasted
into SQL; they are stripped. Entities named by static properties but not declared (the
original's numeric ids) are registered with kind ''. When the database has no *self* agent, the
first robot of an id list becomes self (the original's ``mainAgent``).

JSON / YAML::

    base_time: 2026-01-01T12:00:00Z     # durations below ("5s") count from here; default 0
    entities:   [{id: PR2_ROBOT, kind: robot, self: true}, {id: MUG, kind: object}]
    ontology:   [{class: agent, individual: human, instantiated: false}]
    properties: [{entity: MUG, key: color, value: red}]
    facts:      [{agent: PR2_ROBOT, subject: MUG, property: IsOn, target: TABLE, at: 0s}]
    retract:    [{agent: PR2_ROBOT, subject: MUG, property: IsOn, target: NULL, at: 5s}]
    events:     [{agent: PR2_ROBOT, subject: BOB, property: PickedUp, target: MUG, at: 5s}]
    timeline:                            # steps in time order; agent defaults to the self agent
      - {at: 5s, retract: [...], facts: [...], events: [...]}

A file is read and checked whole (syntax, types, ids, times) before the one transaction that
writes it; a row the database then refuses (an unknown agent...) rolls the file back. Either
way the database is as it was, and the error names the file, the row and the fix.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from toaster.db.catalog import entity_exists, note_data_start
from toaster.documents import read_document
from toaster.errors import FileFormatError, InvalidInputError
from toaster.model import MAX_ID_BYTES, Fact, check_fact, check_id, check_text, shown, utf8_size
from toaster.timeutil import parse_time, start_from_first

if TYPE_CHECKING:
    from toaster.db.writer.store import Store

_FACT_FIELDS = {
    "subject": "subject_id",
    "subject_id": "subject_id",
    "property": "property",
    "predicate": "property",
    "target": "target_id",
    "target_id": "target_id",
    "value": "value_text",
    "value_text": "value_text",
    "num": "value_num",
    "value_num": "value_num",
    "confidence": "confidence",
    "observability": "observability",
    "property_type": "property_type",
    "sub_property": "sub_property",
    "subject_owner": "subject_owner_id",
    "subject_owner_id": "subject_owner_id",
    "target_owner": "target_owner_id",
    "target_owner_id": "target_owner_id",
}
_NUMBERS = {"value_num", "confidence", "observability"}
_SECTIONS = {
    "base_time",
    "entities",
    "ontology",
    "properties",
    "facts",
    "retract",
    "events",
    "timeline",
}
T = TypeVar("T")
_STEP_KEYS = {"at", "retract", "facts", "assert", "events"}
_BOOL_WORDS = {
    "true": True,
    "1": True,
    "yes": True,
    "false": False,
    "0": False,
    "no": False,
    "": False,
}


class BatchReport(dict[str, int]):
    """Counts of rows written per kind (``entities``, ``facts``...)."""

    def add(self, kind: str, n: int = 1) -> None:
        self[kind] = self.get(kind, 0) + n


@dataclass
class Plan:
    """A batch read and checked, ready to write: ``(where, kind, write)`` per row."""

    origin: str
    writes: list[tuple[str, str, Callable[[Store], object]]] = field(default_factory=list)
    #: when the batch's data starts (recorded as the database's data start); None: untimed
    start_ns: int | None = None

    def add(self, where: str, kind: str, write: Callable[[Store], object]) -> None:
        self.writes.append((where, kind, write))

    def apply(self, store: Store) -> BatchReport:
        """Write every row (inside the caller's transaction); errors name the row."""
        report = BatchReport()
        if self.start_ns is not None:
            with store.transaction() as conn:
                note_data_start(conn, self.start_ns)
        for where, kind, write in self.writes:
            try:
                write(store)
            except InvalidInputError as exc:
                msg = f"{self.origin}: {where}: {exc}"
                raise type(exc)(msg) from None
            if kind:
                report.add(kind)
        return report


def load_file(store: Store, path: str | Path) -> BatchReport:
    """Import one XML, JSON or YAML file into the store, all or nothing: the file is read and
    checked whole before the one transaction that writes it."""
    path = Path(path)
    if not path.is_file():
        msg = f"cannot read {str(path)!r}: no such file"
        raise FileFormatError(msg)
    if path.suffix.lower() == ".xml":
        plan = plan_xml(path)
    else:
        data = read_document(path, "batch file")
        if not isinstance(data, dict):
            msg = (
                f"cannot read {str(path)!r}: the top level must be a mapping with sections "
                f"{', '.join(sorted(_SECTIONS))}"
            )
            raise FileFormatError(msg)
        plan = plan_document(data, origin=str(path))
    with store.transaction():
        return plan.apply(store)


def apply_document(store: Store, data: dict[str, Any], *, origin: str = "batch") -> BatchReport:
    """Check then apply a parsed JSON/YAML batch (inside the caller's transaction)."""
    return plan_document(data, origin=origin).apply(store)


def plan_document(data: dict[str, Any], *, origin: str = "batch") -> Plan:
    """Check a parsed JSON/YAML batch whole (one-line errors naming the row and the field)."""
    if not isinstance(data, dict):
        msg = f"{origin}: a batch is a mapping with sections {', '.join(sorted(_SECTIONS))}"
        raise FileFormatError(msg)
    unknown = set(data) - _SECTIONS
    if unknown:
        msg = (
            f"{origin}: unknown section(s) {', '.join(sorted(map(str, unknown)))}; "
            f"expected {', '.join(sorted(_SECTIONS))}"
        )
        raise FileFormatError(msg)
    plan = Plan(origin)
    base = _time(data.get("base_time", 0), 0, origin, "base_time")
    for index, row in _rows(data, "entities", origin):
        where = f"entities[{index}]"
        plan.add(where, "entities", _checked(origin, where, partial(_entity, row, base)))
    for index, row in _rows(data, "ontology", origin):
        where = f"ontology[{index}]"
        plan.add(where, "ontology", _checked(origin, where, partial(_edge, row)))
    for index, row in _rows(data, "properties", origin):
        where = f"properties[{index}]"
        plan.add(where, "properties", _checked(origin, where, partial(_property, row)))
    steps = [
        (
            f"{section}[{index}]",
            {
                "at": row.get("at", 0),  # the row's time, once
                section: [{k: v for k, v in row.items() if k != "at"}],
            },
        )
        for section in ("facts", "retract", "events")
        for index, row in _rows(data, section, origin)
    ]
    steps += [(f"timeline[{index}]", step) for index, step in _rows(data, "timeline", origin)]
    for where, step in steps:
        unknown_keys = set(step) - _STEP_KEYS
        if unknown_keys:
            msg = (
                f"{origin}: {where}: unknown key(s) {', '.join(sorted(map(str, unknown_keys)))}"
                f"; a step has {', '.join(sorted(_STEP_KEYS))}"
            )
            raise FileFormatError(msg)
        t_ns = _time(step.get("at", 0), base, origin, f"{where} 'at'")
        first = _plan_step(plan, step, t_ns, origin, where)
        plan.start_ns = first if plan.start_ns is None else min(plan.start_ns, first)
    if "base_time" in data:  # what its durations count from
        plan.start_ns = base
    elif plan.start_ns is not None:
        plan.start_ns = start_from_first(plan.start_ns)
    return plan


def _checked(origin: str, where: str, make: Callable[[], T]) -> T:
    """``make()`` (which checks a row and returns its write), errors named by the row."""
    try:
        return make()
    except InvalidInputError as exc:
        if isinstance(exc, FileFormatError) and str(exc).startswith(origin):
            raise
        msg = f"{origin}: {where}: {exc}"
        raise FileFormatError(msg) from None


def _entity(row: dict[str, Any], base: int) -> Callable[[Store], object]:
    entity_id = _req(row, "id")
    kind = _word(row, "object", "kind", "type")
    name = _word(row, "", "name")
    owner = _opt(row, "owner", "owner_id") or ""
    is_self, agent = _flag(row, "self"), _flag(row, "agent")
    return lambda store: store.add_entity(
        entity_id, kind, name, owner, is_self=is_self, agent=agent, t_ns=base
    )


def _edge(row: dict[str, Any]) -> Callable[[Store], object]:
    entity_class, individual = _req(row, "class", "entity_class"), _req(row, "individual")
    instantiated = bool(_flag(row, "instantiated"))
    return lambda store: store.add_ontology(entity_class, individual, instantiated)


def _property(row: dict[str, Any]) -> Callable[[Store], object]:
    entity_id, key = _req(row, "entity", "id", "entity_id"), _req(row, "key")
    value = property_value(row.get("value"), key)
    return lambda store: store.set_property(entity_id, key, value)


def property_value(value: object, key: str) -> str:
    """A static property's value as stored: text (numbers and booleans written as text) of at
    most :data:`toaster.model.MAX_ID_BYTES` bytes (the database indexes it with its key)."""
    if isinstance(value, bool):
        value = str(value).lower()
    elif isinstance(value, int | float):
        value = str(value)
    if not isinstance(value, str):
        msg = f"invalid value {shown(value)} for property {key!r}: give text or a number"
        raise InvalidInputError(msg)
    check_text(value, f"value of property {key!r}")
    if utf8_size(value) > MAX_ID_BYTES:
        msg = (
            f"invalid value {shown(value)} for property {key!r}: values are at most "
            f"{MAX_ID_BYTES} bytes of UTF-8, not {utf8_size(value)}"
        )
        raise InvalidInputError(msg)
    return value


def _plan_step(plan: Plan, step: dict[str, Any], t_ns: int, origin: str, where: str) -> int:
    """Plan a step's rows; return its earliest time."""
    first = t_ns
    for section, kind in (
        ("retract", "retracted"),
        ("facts", "facts"),
        ("assert", "facts"),
        ("events", "events"),
    ):
        rows = step.get(section) or []
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            msg = f"{origin}: {where}: {section!r} must be a list of mappings"
            raise FileFormatError(msg)
        for index, row in enumerate(rows):
            label = where if where.startswith(section) else f"{where}: {section}[{index}]"
            at = _time(row.get("at", t_ns), t_ns, origin, f"{label} 'at'")
            first = min(first, at)
            plan.add(label, kind, _checked(origin, label, partial(_write, row, section, at)))
    return first


def _write(row: dict[str, Any], section: str, t_ns: int) -> Callable[[Store], object]:
    agent = _opt(row, "agent")
    if section == "retract":
        prop = _req(row, "property", "predicate")
        filters = {
            name: _opt(row, *names)
            for name, names in (  # 'NULL' or absent: any
                ("subject_id", ("subject", "subject_id")),
                ("target_id", ("target", "target_id")),
                ("sub_property", ("sub_property",)),
            )
        }
        return lambda store: store.retract_facts(
            _agent(store, agent),
            prop,
            filters["subject_id"],
            filters["target_id"],
            sub_property=filters["sub_property"],
            t_ns=t_ns,
        )
    fact = check_fact(fact_from_mapping(row))
    if section == "events":
        return lambda store: store.record_event(_agent(store, agent), fact, t_ns=t_ns)
    source = _opt(row, "source") or "user"
    return lambda store: store.assert_fact(_agent(store, agent), fact, t_ns=t_ns, source=source)


def fact_from_mapping(row: dict[str, Any]) -> Fact:
    """A checked :class:`Fact` from a mapping with user-facing names (subject, property,
    target...): texts, numbers or booleans, not lists or mappings."""
    values: dict[str, Any] = {}
    for name, value in row.items():
        field_name = _FACT_FIELDS.get(name)
        if field_name is None or value is None:
            continue
        if isinstance(value, list | dict):
            msg = f"invalid {name} {shown(value)}: give text or a number"
            raise InvalidInputError(msg)
        if field_name in _NUMBERS:
            values[field_name] = value
        else:
            values[field_name] = str(value).lower() if isinstance(value, bool) else str(value)
    if "subject_id" not in values or "property" not in values:
        msg = f"fact {shown(row)} needs at least 'subject' and 'property'"
        raise InvalidInputError(msg)
    return check_fact(Fact(**values))


def _agent(store: Store, agent: str | None) -> str:
    return agent if agent else store.self_agent()


def _text_of(value: object) -> str | None:
    """Text of a scalar (numbers as written); None for lists, mappings and None."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, str | int | float):
        return str(value)
    return None


def _req(row: dict[str, Any], *names: str) -> str:
    for name in names:
        if row.get(name) not in (None, ""):
            text = _text_of(row[name])
            if text is None:
                msg = f"invalid {name} {shown(row[name])}: give an id (text)"
                raise InvalidInputError(msg)
            return check_id(text, name)
    msg = f"row {shown(row)} lacks {names[0]!r}"
    raise InvalidInputError(msg)


def _opt(row: dict[str, Any], *names: str) -> str | None:
    for name in names:
        if row.get(name) not in (None, ""):
            return _req(row, name)
    return None


def _word(row: dict[str, Any], default: str, *names: str) -> str:
    for name in names:
        value = row.get(name)
        if value is not None:
            text = _text_of(value)
            if text is None:
                msg = f"invalid {name} {shown(value)}: give text"
                raise InvalidInputError(msg)
            return check_text(text, name)
    return default


def _flag(row: dict[str, Any], name: str) -> bool | None:
    value = row.get(name)
    if value is None or isinstance(value, bool):
        return value
    word = _text_of(value)
    if word is None or word.strip().strip("'").lower() not in _BOOL_WORDS:
        msg = f"invalid {name} {shown(value)}: use true or false"
        raise InvalidInputError(msg)
    return _BOOL_WORDS[word.strip().strip("'").lower()]


def _time(value: Any, base: int, origin: str, what: str) -> int:
    try:
        if isinstance(value, bool) or not isinstance(value, int | str):
            msg = f"invalid time {shown(value)}: give nanoseconds, an ISO date or 12.5s"
            raise InvalidInputError(msg)
        return parse_time(value, start_ns=base)
    except InvalidInputError as exc:
        msg = f"{origin}: {what}: {exc}"
        raise FileFormatError(msg) from None


def _rows(data: dict[str, Any], section: str, origin: str) -> list[tuple[int, dict[str, Any]]]:
    rows = data.get(section) or []
    if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
        msg = f"{origin}: section {section!r} must be a list of mappings"
        raise FileFormatError(msg)
    return list(enumerate(rows))


# ---------------------------------------------------------------------------- original XML
def _read_xml(path: Path) -> list[dict[str, str]]:
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError, ValueError, RecursionError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        msg = f"cannot read {str(path)!r}: {reason} (expected one of the original's seed XML files)"
        raise FileFormatError(msg) from None
    return [{k: _unquote(v) for k, v in child.attrib.items()} for child in root]


def _unquote(value: str) -> str:
    value = value.strip()
    if len(value) >= 2 and value[0] == value[-1] == "'":
        value = value[1:-1]
    return value.strip()


def plan_xml(path: Path) -> Plan:
    """Read and check one of the original's seed XML files whole."""
    origin = str(path)
    plan = Plan(origin)
    state: dict[str, bool] = {}  # had_self: the database has a self agent (read when writing)

    def has_self(store: Store) -> bool:
        if "had_self" not in state:
            state["had_self"] = any(store.agents().values())
        return state["had_self"]

    for index, row in enumerate(_read_xml(path)):
        where = f"element {index + 1}"
        if "entityClass" in row:
            plan.add(
                where,
                "ontology",
                _checked(
                    origin,
                    where,
                    partial(
                        _edge,
                        {
                            "class": row["entityClass"],
                            "individual": row.get("individual"),
                            "instantiated": row.get("instantiated", "false"),
                        },
                    ),
                ),
            )
        elif "color" in row or "linkType" in row:
            entity_id = _checked(origin, where, partial(_req, row, "id"))

            def declare(store: Store, entity_id: str = entity_id) -> None:
                with store.db.transaction() as conn:
                    known = entity_exists(conn, entity_id)
                if not known:  # properties of undeclared entities
                    store.add_entity(entity_id, "", entity_id)

            plan.writes.append((where, "", declare))
            for key in ("color", "height", "linkedToId", "linkType"):
                if key in row:
                    plan.add(
                        where,
                        "properties",
                        _checked(
                            origin,
                            where,
                            partial(
                                _property, {"entity": row["id"], "key": key, "value": row[key]}
                            ),
                        ),
                    )
        elif "id" in row and "type" in row:

            def entity(row: dict[str, str] = row) -> Callable[[Store], object]:
                entity_id, kind = _req(row, "id"), _word(row, "", "type")
                name, owner = _word(row, "", "name"), _opt(row, "owner_id") or ""

                def write(store: Store) -> None:
                    make_self = kind.lower() == "robot" and not has_self(store)
                    store.add_entity(
                        entity_id, kind, name, owner, is_self=True if make_self else None
                    )
                    if make_self:
                        state["had_self"] = True

                return write

            plan.add(where, "entities", _checked(origin, where, entity))
        else:
            msg = (
                f"{origin}: element {index + 1} has attributes {sorted(row)}; expected an "
                "id list (id, type), ontology (entityClass, individual) or static properties"
            )
            raise FileFormatError(msg)
    return plan
