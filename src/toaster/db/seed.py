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

Every write of a file happens in one transaction: a bad row anywhere leaves the database as it
was, and the error names the file, the row and the fix.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

from toaster.db.catalog import entities
from toaster.documents import read_document
from toaster.errors import FileFormatError, InvalidInputError
from toaster.model import Fact
from toaster.timeutil import parse_time

if TYPE_CHECKING:
    from toaster.db.store import Store

_FACT_FIELDS = {"subject": "subject_id", "subject_id": "subject_id", "property": "property",
                "predicate": "property", "target": "target_id", "target_id": "target_id",
                "value": "value_text", "value_text": "value_text", "num": "value_num",
                "value_num": "value_num", "confidence": "confidence",
                "observability": "observability", "property_type": "property_type",
                "sub_property": "sub_property", "subject_owner": "subject_owner_id",
                "subject_owner_id": "subject_owner_id", "target_owner": "target_owner_id",
                "target_owner_id": "target_owner_id"}
_SECTIONS = {"base_time", "entities", "ontology", "properties", "facts", "retract", "events",
             "timeline"}


class BatchReport(dict[str, int]):
    """Counts of rows written per kind (``entities``, ``facts``...)."""

    def add(self, kind: str, n: int = 1) -> None:
        self[kind] = self.get(kind, 0) + n


def load_file(store: Store, path: str | Path) -> BatchReport:
    """Import one XML, JSON or YAML file into the store, all or nothing."""
    path = Path(path)
    if not path.is_file():
        msg = f"cannot read {str(path)!r}: no such file"
        raise FileFormatError(msg)
    suffix = path.suffix.lower()
    if suffix == ".xml":
        rows = _read_xml(path)
        with store.transaction():
            return _apply_xml(store, path, rows)
    data = read_document(path, "batch file")
    if not isinstance(data, dict):
        msg = (f"cannot read {str(path)!r}: the top level must be a mapping with sections "
               f"{', '.join(sorted(_SECTIONS))}")
        raise FileFormatError(msg)
    with store.transaction():
        return apply_document(store, data, origin=str(path))


def apply_document(store: Store, data: dict[str, Any], *, origin: str = "batch") -> BatchReport:
    """Apply a parsed JSON/YAML batch (inside the caller's transaction)."""
    unknown = set(data) - _SECTIONS
    if unknown:
        msg = (f"{origin}: unknown section(s) {', '.join(sorted(map(str, unknown)))}; "
               f"expected {', '.join(sorted(_SECTIONS))}")
        raise FileFormatError(msg)
    report = BatchReport()
    base = _time(data.get("base_time", 0), 0, origin, "base_time")
    for index, row in _rows(data, "entities", origin):
        def entity(row: dict[str, Any] = row) -> None:
            store.add_entity(
                _req(row, "id"), str(row.get("kind", row.get("type", "object"))),
                str(row.get("name", "")), str(row.get("owner", row.get("owner_id", "")) or ""),
                is_self=row.get("self"), agent=row.get("agent"), t_ns=base)
        _wrap(origin, "entities", index, entity)
        report.add("entities")
    for index, row in _rows(data, "ontology", origin):
        def edge(row: dict[str, Any] = row) -> None:
            store.add_ontology(_req(row, "class", "entity_class"), _req(row, "individual"),
                               row.get("instantiated", False))
        _wrap(origin, "ontology", index, edge)
        report.add("ontology")
    for index, row in _rows(data, "properties", origin):
        def prop(row: dict[str, Any] = row) -> None:
            store.set_property(_req(row, "entity", "id", "entity_id"), _req(row, "key"),
                               row.get("value"))
        _wrap(origin, "properties", index, prop)
        report.add("properties")
    steps = [{"at": row.get("at", 0), section: [row]}
             for section in ("facts", "retract", "events")
             for _, row in _rows(data, section, origin)]
    steps += [step for _, step in _rows(data, "timeline", origin)]
    for index, step in enumerate(steps):
        t_ns = _time(step.get("at", 0), base, origin, f"step {index + 1} 'at'")
        _apply_step(store, step, t_ns, origin, report)
    return report


def _apply_step(store: Store, step: dict[str, Any], t_ns: int, origin: str,
                report: BatchReport) -> None:
    for index, row in enumerate(step.get("retract") or []):
        def retract(row: dict[str, Any] = row) -> None:
            store.retract_facts(_agent(store, row), _req(row, "property", "predicate"),
                                _opt(row, "subject", "subject_id"),
                                _opt(row, "target", "target_id"),
                                sub_property=_opt(row, "sub_property"),
                                t_ns=_time(row.get("at", t_ns), t_ns, origin, "at"))
        _wrap(origin, "retract", index, retract)
        report.add("retracted")
    for index, row in enumerate(step.get("facts") or step.get("assert") or []):
        def assert_(row: dict[str, Any] = row) -> None:
            store.assert_fact(_agent(store, row), fact_from_mapping(row),
                              t_ns=_time(row.get("at", t_ns), t_ns, origin, "at"),
                              source=str(row.get("source", "user")))
        _wrap(origin, "facts", index, assert_)
        report.add("facts")
    for index, row in enumerate(step.get("events") or []):
        def event(row: dict[str, Any] = row) -> None:
            store.record_event(_agent(store, row), fact_from_mapping(row),
                               t_ns=_time(row.get("at", t_ns), t_ns, origin, "at"))
        _wrap(origin, "events", index, event)
        report.add("events")


def fact_from_mapping(row: dict[str, Any]) -> Fact:
    """A :class:`Fact` from a mapping with user-facing names (subject, property, target...)."""
    values: dict[str, Any] = {}
    for name, value in row.items():
        field = _FACT_FIELDS.get(name)
        if field is not None and value is not None:
            values[field] = value if field in {"value_num", "confidence", "observability"} \
                else str(value).lower() if isinstance(value, bool) else str(value)
    if "subject_id" not in values or "property" not in values:
        msg = f"fact {row!r} needs at least 'subject' and 'property'"
        raise InvalidInputError(msg)
    return Fact(**values)


def _agent(store: Store, row: dict[str, Any]) -> str:
    agent = row.get("agent")
    return str(agent) if agent else store.self_agent()


def _req(row: dict[str, Any], *names: str) -> str:
    for name in names:
        if row.get(name) not in (None, ""):
            return str(row[name])
    msg = f"row {row!r} lacks {names[0]!r}"
    raise InvalidInputError(msg)


def _opt(row: dict[str, Any], *names: str) -> str | None:
    for name in names:
        if row.get(name) is not None:
            return str(row[name])
    return None


def _time(value: Any, base: int, origin: str, what: str) -> int:
    try:
        return parse_time(value if isinstance(value, int) else str(value), base_ns=base)
    except InvalidInputError as exc:
        msg = f"{origin}: {what}: {exc}"
        raise FileFormatError(msg) from None


def _rows(data: dict[str, Any], section: str, origin: str) -> list[tuple[int, dict[str, Any]]]:
    rows = data.get(section) or []
    if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
        msg = f"{origin}: section {section!r} must be a list of mappings"
        raise FileFormatError(msg)
    return list(enumerate(rows))


def _wrap(origin: str, section: str, index: int, action: Callable[[], object]) -> None:
    try:
        action()
    except InvalidInputError as exc:
        msg = f"{origin}: {section}[{index}]: {exc}"
        raise type(exc)(msg) from None


# ---------------------------------------------------------------------------- original XML
def _read_xml(path: Path) -> list[dict[str, str]]:
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as exc:
        msg = f"cannot read {str(path)!r}: {exc} (expected one of the original's seed XML files)"
        raise FileFormatError(msg) from None
    return [{k: _unquote(v) for k, v in child.attrib.items()} for child in root]


def _unquote(value: str) -> str:
    value = value.strip()
    if len(value) >= 2 and value[0] == value[-1] == "'":
        value = value[1:-1]
    return value.strip()


def _apply_xml(store: Store, path: Path, rows: list[dict[str, str]]) -> BatchReport:
    report = BatchReport()
    origin = str(path)
    had_self = any(store.agents().values())
    for index, row in enumerate(rows):
        if "entityClass" in row:
            def edge(row: dict[str, str] = row) -> None:
                store.add_ontology(row["entityClass"], _req(row, "individual"),
                                   row.get("instantiated", "false"))
            _wrap(origin, "ontology", index, edge)
            report.add("ontology")
        elif "color" in row or "linkType" in row:
            entity_id = _req(row, "id")
            if not entities(store.db, entity_id):  # properties of undeclared entities
                store.add_entity(entity_id, "", entity_id)
            for key in ("color", "height", "linkedToId", "linkType"):
                if key in row:
                    _wrap(origin, "properties", index,
                          partial(store.set_property, entity_id, key, row[key]))
                    report.add("properties")
        elif "id" in row and "type" in row:
            kind = row["type"]
            make_self = not had_self and kind.lower() == "robot"
            _wrap(origin, "entities", index,
                  partial(store.add_entity, row["id"], kind, row.get("name", ""),
                          row.get("owner_id", ""), is_self=True if make_self else None))
            had_self = had_self or make_self
            report.add("entities")
        else:
            msg = (f"{origin}: element {index + 1} has attributes {sorted(row)}; expected an "
                   "id list (id, type), ontology (entityClass, individual) or static properties")
            raise FileFormatError(msg)
    return report

