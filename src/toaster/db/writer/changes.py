"""What a write changed: the change records the store hands its rules, and the rows it collects.

:class:`ChangeSet` is what a rule sees of one write; :class:`Writes` gathers the interval and
event rows of one write before they go to the database in bulk.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import Any, NamedTuple, Protocol, TypeAlias

from sqlalchemy import Connection

from toaster.db.dialects import Key
from toaster.model import Fact
from toaster.timeutil import now_ns

_NO_ACTORS: Mapping[int, str] = MappingProxyType({})

#: Who made each change of a write, per fact: a function of the fact (None: the write's
#: ``actor``), or a mapping fact key (:func:`toaster.model.fact_key`) -> agent id.
Actors: TypeAlias = Callable[[Fact], str | None] | Mapping[Key, str]


class ChangeSet(NamedTuple):
    """What one write changed for one agent, handed to belief rules (same transaction)."""

    agent_id: str
    source: str
    t_ns: int
    appeared: list[tuple[int, Fact]]
    changed: list[tuple[int, Fact, str]]
    refreshed: list[tuple[int, Fact, Fact]]  # (key, new fact, the fact it held before)
    ended: list[tuple[int, Fact]]
    actor: str | None = None  # the agent who made the changes, when the writer knows it
    actors: Mapping[int, str] = _NO_ACTORS  # key id -> who made that change (over ``actor``)

    @property
    def empty(self) -> bool:
        """True when nothing was written."""
        return not (self.appeared or self.changed or self.refreshed or self.ended)

    def actor_of(self, key_id: int) -> str | None:
        """The agent who made the change of ``key_id`` (None: unknown)."""
        return self.actors.get(key_id, self.actor)

    def key_ids(self) -> set[int]:
        """The keys this write changed."""
        return {
            item[0]
            for part in (self.appeared, self.changed, self.refreshed, self.ended)
            for item in part
        }


class Rule(Protocol):
    """A rule run in the transaction of every fact write (the belief rule is one).

    A rule may also have a ``committed()`` method: the store calls it after each of its write
    transactions committed (outside it), for housekeeping that must not lengthen the
    transaction, which may hold the rules' clock."""

    def __call__(self, conn: Connection, changes: ChangeSet) -> None:
        """Apply the rule to what one write changed."""

    def detach(self, conn: Connection, agent_id: str | None, *, keep: bool) -> None:
        """Before a write that bypasses the rule (a direct write to a holder, emptying an
        agent, changing who is self): turn rows shared with ``agent_id`` into its own rows
        (``keep``), or drop them (its rows are about to be deleted; None: every agent)."""


class SyncResult(NamedTuple):
    """Counts of what a snapshot changed."""

    appeared: int
    changed: int
    refreshed: int
    ended: int
    unchanged: int


class Writes:
    """The rows one write produces, collected before they go to the database in bulk."""

    def __init__(
        self,
        agent_id: str,
        source: str,
        t_ns: int,
        actor: str | None = None,
        actor_of: Callable[[Fact], str | None] | None = None,
    ) -> None:
        self.actor, self.actor_of = actor, actor_of
        self.agent_id, self.source, self.t_ns = agent_id, source, t_ns
        self.recorded_ns = now_ns()
        self.closing: list[int] = []
        self.opening: list[tuple[Any, ...]] = []
        self.events: list[tuple[Any, ...]] = []
        self.appeared: list[tuple[int, Fact]] = []
        self.changed: list[tuple[int, Fact, str]] = []
        self.refreshed: list[tuple[int, Fact, Fact]] = []
        self.ended: list[tuple[int, Fact]] = []
        self.retyped: list[tuple[int, str]] = []

    def _open(self, key_id: int, fact: Fact, kind: str, previous: str | None) -> None:
        self.opening.append(
            (
                key_id,
                fact.value_text,
                fact.value_num,
                fact.confidence,
                fact.observability,
                self.t_ns,
                self.recorded_ns,
                self.source,
            )
        )
        self.events.append(self.event(key_id, fact, kind, previous))

    def event(self, key_id: int, fact: Fact, kind: str, previous: str | None) -> tuple[Any, ...]:
        """The events row for one change."""
        return (
            key_id,
            self.agent_id,
            kind,
            self.t_ns,
            fact.value_text,
            fact.value_num,
            fact.confidence,
            fact.observability,
            previous,
            self.source,
            self.recorded_ns,
        )

    def appear(self, key_id: int, fact: Fact) -> None:
        self._open(key_id, fact, "appeared", None)
        self.appeared.append((key_id, fact))

    def update(self, key_id: int, fact: Fact, held: Fact) -> None:
        """``fact`` replaces ``held`` (the open interval's content) for the same key."""
        if fact.property_type != held.property_type:
            self.retyped.append((key_id, fact.property_type))
        if fact.value_text != held.value_text:
            self.closing.append(key_id)
            self._open(key_id, fact, "changed", held.value_text)
            self.changed.append((key_id, fact, held.value_text))
        elif (fact.value_num, fact.confidence, fact.observability) != (
            held.value_num,
            held.confidence,
            held.observability,
        ):
            self.refreshed.append((key_id, fact, held))

    def end(self, key_id: int, fact: Fact) -> None:
        """Close the key's open interval (its event is written once the close is known)."""
        self.closing.append(key_id)
        self.ended.append((key_id, fact))

    def change_set(self) -> ChangeSet:
        actors: Mapping[int, str] = _NO_ACTORS
        if self.actor_of is not None:  # asked of the changed facts only
            actor_of = self.actor_of
            actors = {
                item[0]: who
                for part in (self.appeared, self.changed, self.refreshed, self.ended)
                for item in part
                if (who := actor_of(item[1])) is not None
            }
        return ChangeSet(
            self.agent_id,
            self.source,
            self.t_ns,
            self.appeared,
            self.changed,
            self.refreshed,
            self.ended,
            self.actor,
            actors,
        )

    @property
    def empty(self) -> bool:
        """True when the write changes no fact."""
        return not (self.appeared or self.changed or self.refreshed or self.ended)

    def outcome(self) -> str:
        """What the write did to its (single) fact."""
        if self.appeared:
            return "appeared"
        if self.changed:
            return "changed"
        return "refreshed" if self.refreshed else "unchanged"


def merged(pending: list[ChangeSet]) -> list[ChangeSet]:
    """Change sets of several sources as one per agent (the same time), unless two of them
    touch the same key (then each stays alone, in order)."""
    if len(pending) < 2:
        return pending
    seen: set[int] = set()
    first = pending[0]
    for changes in pending:
        keys = changes.key_ids()
        if keys & seen or changes.agent_id != first.agent_id or changes.actor != first.actor:
            return pending
        seen |= keys
    return [
        ChangeSet(
            first.agent_id,
            "+".join(c.source for c in pending),
            first.t_ns,
            [item for c in pending for item in c.appeared],
            [item for c in pending for item in c.changed],
            [item for c in pending for item in c.refreshed],
            [item for c in pending for item in c.ended],
            first.actor,
            {k: v for c in pending for k, v in c.actors.items()},
        )
    ]
