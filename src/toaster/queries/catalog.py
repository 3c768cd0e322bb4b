"""Reading entities, agents, the ontology and static properties.

The catalogue's writes (and the reads the store itself needs) take a connection in
:mod:`toaster.db.catalog`; these public reads take a :class:`~toaster.db.Database` and join its
open transaction or open a read one.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from sqlalchemy import select, text

from toaster.db import schema as s
from toaster.db.views import agent_view_names
from toaster.model import Agent, Entity, OntologyRow, PropertyRow, check_text

if TYPE_CHECKING:
    from toaster.db.database import Database

__all__ = ["agents", "descendants", "entities", "ontology", "properties"]

_MAX_DEPTH = 64


def entities(
    db: Database, entity_id: str | None = None, *, kind: str | None = None, name: str | None = None
) -> list[Entity]:
    """Registered entities, optionally one id, one kind or one name."""
    table = s.entities
    query = select(table.c.id, table.c.name, table.c.kind, table.c.owner_id).order_by(table.c.id)
    for column, value in ((table.c.id, entity_id), (table.c.kind, kind), (table.c.name, name)):
        if value is not None:
            query = query.where(column == check_text(value, f"entity {column.name} filter"))
    with db.transaction() as conn:
        return [Entity(*row) for row in conn.execute(query)]


def agents(db: Database, *, only_self: bool = False) -> list[Agent]:
    """Belief-holding agents with the names of their per-agent views."""
    query = select(s.agents.c.id, s.agents.c.is_self).order_by(s.agents.c.num)
    if only_self:
        query = query.where(s.agents.c.is_self.is_(True))
    with db.transaction() as conn:
        rows = conn.execute(query).all()
    return [Agent(row[0], bool(row[1]), *agent_view_names(row[0])) for row in rows]


def ontology(db: Database, entity_class: str | None = None) -> list[OntologyRow]:
    """Class-tree edges, all or those directly below ``entity_class``."""
    table = s.ontology
    query = select(table.c.entity_class, table.c.individual, table.c.instantiated)
    if entity_class is not None:
        query = query.where(table.c.entity_class == check_text(entity_class, "ontology class"))
    query = query.order_by(table.c.entity_class, table.c.individual)
    with db.transaction() as conn:
        return [OntologyRow(row[0], row[1], bool(row[2])) for row in conn.execute(query)]


def descendants(
    db: Database, entity_class: str, *, instantiated_only: bool = True
) -> list[OntologyRow]:
    """Every edge below ``entity_class``, recursively (the original's LEAVE). With
    ``instantiated_only`` (the original's behaviour) only instantiated individuals are kept;
    their ``instantiated`` flag is the stored one (the original always answered true)."""
    sql = (
        "WITH RECURSIVE tree(entity_class, individual, instantiated, depth) AS ("
        "SELECT entity_class, individual, instantiated, 1 FROM ontology WHERE entity_class = :c "
        "UNION ALL SELECT o.entity_class, o.individual, o.instantiated, t.depth + 1 "
        "FROM ontology o JOIN tree t ON o.entity_class = t.individual WHERE t.depth < :depth) "
        "SELECT DISTINCT entity_class, individual, instantiated FROM tree"
    )
    check_text(entity_class, "ontology class")
    with db.transaction() as conn:
        rows = conn.execute(text(sql), {"c": entity_class, "depth": _MAX_DEPTH}).all()
    found = sorted(OntologyRow(r[0], r[1], bool(r[2])) for r in rows)
    return [row for row in found if row.instantiated or not instantiated_only]


def properties(
    db: Database, entity_id: str | None = None, key: str | None = None
) -> list[PropertyRow]:
    """Static properties, all or of one entity, optionally one key."""
    table = s.properties
    query = select(table.c.entity_id, table.c.key, table.c.value).order_by(
        table.c.entity_id, table.c.key
    )
    if entity_id is not None:
        query = query.where(table.c.entity_id == check_text(entity_id, "entity id"))
    if key is not None:
        query = query.where(table.c.key == check_text(key, "property key"))
    with db.transaction() as conn:
        return [PropertyRow(*row) for row in conn.execute(query)]
