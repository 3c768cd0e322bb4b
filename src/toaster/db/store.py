"""The write path: snapshots from sources become validity intervals and events.

A *source* (a producer, a rule, a user) hands :meth:`Store.sync_snapshot` the complete set of
facts it holds true for one agent at time ``t``. The store compares it with what that source
wrote last (kept in memory, so unchanged facts cost nothing), then in one transaction:

* appeared facts open an interval and write an ``appeared`` event;
* a changed symbolic value (``value_text``) closes the interval at ``t``, opens the next one and
  writes a ``changed`` event (with the previous value);
* a changed numeric value, confidence or observability refreshes the open interval in place;
* facts missing from the snapshot close their interval at ``t`` and write an ``ended`` event.

Writes that bypass snapshots (user assertions, retractions, EMPTY) bump ``store_state``'s
``cache_epoch``; every store re-reads what its sources hold on its next transaction, so that the
world state re-asserts itself as in the original's EMPTY. Belief rules registered with
:meth:`Store.add_rule` run in the same transaction as the write that triggers them.
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, NamedTuple

from sqlalchemy import Connection, text
from sqlalchemy.exc import IntegrityError

from toaster.db import catalog
from toaster.db.dialects import Key
from toaster.errors import InvalidInputError, TimeOrderError, UnknownAgentError
from toaster.model import Fact, check_fact, check_id, fact_key
from toaster.timeutil import format_ns, now_ns

#: fact_key in C: (subject, subject owner, property, sub-property, target, target owner).
_KEY = operator.itemgetter(0, 9, 1, 8, 2, 10)


class ChangeSet(NamedTuple):
    """What one write changed for one agent, handed to belief rules (same transaction)."""

    agent_id: str
    source: str
    t_ns: int
    appeared: list[tuple[int, Fact]]
    changed: list[tuple[int, Fact, str]]
    refreshed: list[tuple[int, Fact, Fact]]  # (key, new fact, the fact it held before)
    ended: list[tuple[int, Fact]]

    @property
    def empty(self) -> bool:
        """True when nothing was written."""
        return not (self.appeared or self.changed or self.refreshed or self.ended)


#: A rule: called as ``rule(conn, changes)`` inside the transaction of the triggering write.
#: A rule that shares rows between agents may also have ``detach(conn, agent_id, keep=...)``,
#: called before writes that bypass it (see :meth:`Store._detach`).
Rule = Callable[[Connection, ChangeSet], None]


class SyncResult(NamedTuple):
    """Counts of what a snapshot changed."""

    appeared: int
    changed: int
    refreshed: int
    ended: int
    unchanged: int


@dataclass
class _SourceState:
    facts: dict[Key, Fact] = field(default_factory=dict)
    last_list: list[Fact] | None = None  # the last snapshot as given: equal lists skip the diff
    last_t: int = -(2**63)


class _StaleCache(Exception):
    """Another writer opened an interval concurrently: forget what is remembered and retry."""


class Store:
    """Writes facts, entities and everything else into a :class:`~toaster.db.Database`."""

    def __init__(self, db: Any) -> None:
        self.db = db
        self.backend = db.backend
        self._sources: dict[tuple[str, str], _SourceState] = {}
        self._key_ids: dict[tuple[str, Key], int] = {}
        self._agents: dict[str, bool] | None = None
        self._entities: set[str] = set()
        self._epoch: int | None = None
        self._rules: list[Rule] = []
        self._in_tx = False

    # ------------------------------------------------------------------ transactions, caches
    @contextmanager
    def transaction(self) -> Iterator[Connection]:
        """One write transaction; store calls made inside it join it (all or nothing)."""
        if self._in_tx:
            yield self.db.connection
            return
        self._in_tx = True
        try:
            with self.db.transaction(write=True) as conn:
                self._check_epoch(conn)
                yield conn
        except BaseException:
            self.forget()
            raise
        finally:
            self._in_tx = False

    def forget(self) -> None:
        """Drop everything remembered about the database (it is re-read on demand)."""
        self._sources.clear()
        self._key_ids.clear()
        self._agents = None
        self._entities.clear()
        self._epoch = None

    def _check_epoch(self, conn: Connection) -> None:
        epoch = conn.execute(text("SELECT cache_epoch FROM store_state WHERE id = 1")).scalar_one()
        if epoch != self._epoch:
            self.forget()
            self._epoch = epoch

    def bump_epoch(self, conn: Connection) -> None:
        """Tell every store (this one included) to re-read what its sources hold."""
        conn.execute(text("UPDATE store_state SET cache_epoch = cache_epoch + 1 WHERE id = 1"))
        self.forget()
        self._epoch = conn.execute(
            text("SELECT cache_epoch FROM store_state WHERE id = 1")).scalar_one()

    def add_rule(self, rule: Rule) -> None:
        """Run ``rule(conn, changes)`` after every fact write, in the same transaction."""
        self._rules.append(rule)

    def _detach(self, conn: Connection, agent_id: str | None, *, keep: bool) -> None:
        """Let rules turn rows they share with ``agent_id`` into its own rows (``keep``) or
        drop them (the agent's facts are being deleted) before a write that bypasses them."""
        for rule in self._rules:
            detach = getattr(rule, "detach", None)
            if detach is not None:
                detach(conn, agent_id, keep=keep)

    # ------------------------------------------------------------------ agents and entities
    def agents(self) -> dict[str, bool]:
        """Known agents: id -> is_self."""
        if self._agents is None:
            with self.db.transaction() as conn:
                rows = conn.execute(text("SELECT id, is_self FROM agents")).all()
            self._agents = {row[0]: bool(row[1]) for row in rows}
        return self._agents

    def check_agent(self, agent_id: str) -> str:
        """Return ``agent_id`` if registered, else raise :class:`UnknownAgentError`."""
        check_id(agent_id, "agent id")
        if agent_id not in self.agents():
            self._agents = None
            if agent_id not in self.agents():
                known = ", ".join(sorted(self.agents())) or "none yet"
                msg = (f"unknown agent {agent_id!r} (known: {known}): register it with "
                       f"`toaster set-info ENTITY --id {agent_id} --type human` (or robot)")
                raise UnknownAgentError(msg)
        return agent_id

    def self_agent(self, fix: str = "name the agent (--agent ID, or 'agent: ID' in a file)"
                   ) -> str:
        """The one self agent, which facts default to; an error says ``fix`` when there is
        none or several."""
        selves = [agent for agent, is_self in self.agents().items() if is_self]
        if len(selves) != 1:
            msg = (f"no agent given and there is not exactly one self agent "
                   f"({', '.join(sorted(selves)) or 'none'}): {fix}")
            raise InvalidInputError(msg)
        return selves[0]

    def add_entity(self, entity_id: str, kind: str = "object", name: str = "", owner_id: str = "",
                   *, is_self: bool | None = None, agent: bool | None = None,
                   t_ns: int | None = None) -> None:
        """Add or update an entity; humans and robots (or ``agent=True``) become agents.

        ``is_self=True`` marks a robot whose perception is the world state.
        """
        with self.transaction() as conn:
            catalog.upsert_entity(conn, entity_id, kind, name, owner_id,
                                  is_self=is_self, agent=agent, t_ns=t_ns)
            self._agents = None
            self._entities.add(entity_id)

    def remove_entity(self, entity_id: str) -> None:
        """Remove an entity (an agent loses its beliefs, views and events too)."""
        with self.transaction() as conn:
            if entity_id in self.agents():
                self._detach(conn, entity_id, keep=False)
            catalog.remove_entity(conn, entity_id)
            self.bump_epoch(conn)

    def set_self(self, agent_id: str, is_self: bool = True) -> None:
        """Mark (or unmark) an agent as a *self* agent whose perception is the world state."""
        with self.transaction() as conn:
            self.check_agent(agent_id)
            self._detach(conn, agent_id, keep=True)
            conn.execute(text("UPDATE agents SET is_self = :s WHERE id = :a"),
                         {"s": is_self, "a": agent_id})
            self._agents = None

    def _ensure_entities(self, facts: Iterable[Fact]) -> None:
        rows, stamp = [], now_ns()
        for fact in facts:
            for entity_id, owner in ((fact.subject_id, fact.subject_owner_id),
                                     (fact.target_id, fact.target_owner_id)):
                if entity_id and entity_id not in self._entities:
                    self._entities.add(entity_id)
                    rows.append((entity_id, owner, stamp))
        if rows:
            self.backend.insert_entities(self.db.cursor(), rows)

    # ------------------------------------------------------------------ snapshot sync
    def sync_snapshot(self, source: str, agent_id: str, t_ns: int,
                      facts: Iterable[Fact]) -> SyncResult:
        """Make ``source``'s facts for ``agent_id`` at ``t_ns`` exactly ``facts``.

        Only differences with what the source wrote last reach the database, in one
        transaction. Facts about entities nobody registered register them (kind '').
        """
        check_id(source, "source")
        if not isinstance(t_ns, int) or isinstance(t_ns, bool):
            msg = f"invalid time {t_ns!r}: times are integer nanoseconds"
            raise InvalidInputError(msg)
        given = facts if isinstance(facts, list) else list(facts)
        for attempt in range(2):
            try:
                with self.transaction() as conn:
                    return self._sync(conn, source, agent_id, t_ns, given)
            except _StaleCache:
                if attempt:
                    raise
        msg = "unreachable"
        raise AssertionError(msg)

    def _state(self, conn: Connection, source: str, agent_id: str) -> _SourceState:
        state = self._sources.get((source, agent_id))
        if state is None:
            state = _SourceState()
            rows = conn.execute(text(
                "SELECT k.id, k.subject_id, k.property, k.target_id, f.value_text, f.value_num, "
                "f.confidence, f.observability, k.property_type, k.sub_property, "
                "k.subject_owner_id, k.target_owner_id, f.valid_from_ns "
                "FROM fact_keys k JOIN facts f ON f.key_id = k.id "
                "WHERE k.agent_id = :a AND f.source = :s AND f.valid_to_ns IS NULL"),
                {"a": agent_id, "s": source}).all()
            for row in rows:
                fact = Fact(*row[1:12])
                key = fact_key(fact)
                state.facts[key] = fact
                self._key_ids[(agent_id, key)] = row[0]
                state.last_t = max(state.last_t, row[12])
            self._sources[(source, agent_id)] = state
        return state

    def _sync(self, conn: Connection, source: str, agent_id: str, t_ns: int,
              given: list[Fact]) -> SyncResult:
        self.check_agent(agent_id)
        state = self._state(conn, source, agent_id)
        if t_ns < state.last_t:
            msg = (f"snapshot of {source!r} for {agent_id!r} at {format_ns(t_ns)} is older than "
                   f"its previous one ({format_ns(state.last_t)}): send snapshots in time order")
            raise TimeOrderError(msg)
        old = state.facts
        if given == state.last_list:  # the same facts in the same order: nothing to do
            state.last_t = t_ns
            return SyncResult(0, 0, 0, 0, len(old))
        new = dict(zip(map(_KEY, given), given, strict=True))
        if new == old:
            state.last_list, state.last_t = given, t_ns
            return SyncResult(0, 0, 0, 0, len(new))
        held_get = old.get
        touched = [(key, check_fact(fact)) for key, fact in new.items() if held_get(key) != fact]
        gone = old.keys() - new.keys()
        key_ids = self._key_ids
        writes = _Writes(agent_id, source, t_ns)  # events in order: ended, changed, appeared
        for key in gone:
            writes.end(key_ids[(agent_id, key)], old[key])
        if touched:
            self._resolve(conn, agent_id, touched, writes)
        self._apply(conn, writes)
        for key, fact in touched:
            old[key] = fact
        for key in gone:
            del old[key]
        state.last_list, state.last_t = given, t_ns
        return SyncResult(len(writes.appeared), len(writes.changed), len(writes.refreshed),
                          len(writes.ended), len(new) - len(touched))

    def _key_id_map(self, conn: Connection, agent_id: str,
                    facts: list[tuple[Key, Fact]]) -> set[Key]:
        """Fill the key-id cache for ``facts``; return the keys that were just created."""
        missing = [(key, fact) for key, fact in facts if (agent_id, key) not in self._key_ids]
        if not missing:
            return set()
        # Keys this process never saw are usually new: insert first, look up the rest.
        cur = self.db.cursor()
        self._ensure_entities([fact for _, fact in missing])
        created = self.backend.insert_keys(
            cur, agent_id, [(key, fact.property_type) for key, fact in missing])
        found: dict[Key, int] = {}
        if len(created) != len(missing):
            found = self.backend.lookup_keys(
                cur, agent_id, [key for key, _ in missing if key not in created])
        for key, key_id in (*found.items(), *created.items()):
            self._key_ids[(agent_id, key)] = key_id
        return set(created)

    def _resolve(self, conn: Connection, agent_id: str, items: list[tuple[Key, Fact]],
                 writes: _Writes) -> None:
        """Compare stated facts with what is stored now (the open interval, whoever wrote it):
        a missing interval appears, another symbolic value changes, the rest refreshes."""
        if not self.agents().get(agent_id):
            self._detach(conn, agent_id, keep=True)
        created = self._key_id_map(conn, agent_id, items)
        known = [self._key_ids[(agent_id, key)] for key, _ in items if key not in created]
        open_rows = self.backend.open_rows(self.db.cursor(), known) if known else {}
        for key, fact in items:
            key_id = self._key_ids[(agent_id, key)]
            row = open_rows.get(key_id)
            if row is None:
                writes.appear(key_id, fact)
            else:
                held = Fact(fact.subject_id, fact.property, fact.target_id, row[0], row[1],
                            row[2], row[3], fact.property_type, fact.sub_property,
                            fact.subject_owner_id, fact.target_owner_id)
                writes.update(key_id, fact, held)

    def _apply(self, conn: Connection, writes: _Writes) -> None:
        cur = self.db.cursor()
        backend = self.backend
        if writes.closing:
            # A fact this source held may have been ended by another writer: no event then.
            closed = backend.close_intervals(cur, writes.t_ns, writes.closing)
            writes.ended = [(k, f) for k, f in writes.ended if k in closed]
        writes.events[:0] = [writes.event(k, f, "ended", None) for k, f in writes.ended]
        if writes.refreshed:
            backend.refresh_intervals(
                cur, [(f.value_num, f.confidence, f.observability, k)
                      for k, f, _ in writes.refreshed])
        try:
            if writes.opening:
                backend.insert_intervals(cur, writes.opening)
        except Exception as exc:
            if _is_integrity_error(exc):
                raise _StaleCache from exc
            raise
        if writes.events:
            backend.insert_events(cur, writes.events)
        if writes.retyped:
            conn.execute(text("UPDATE fact_keys SET property_type = :p WHERE id = :k"),
                         [{"p": p, "k": k} for k, p in writes.retyped])
        if self._rules:
            changes = writes.change_set()
            for rule in self._rules:
                rule(conn, changes)

    # ------------------------------------------------------------------ single writes
    def assert_fact(self, agent_id: str, fact: Fact, *, t_ns: int | None = None,
                    source: str = "user", strict: bool = True) -> str:
        """State one fact for an agent at ``t_ns`` (default now); return what happened
        (``appeared``, ``changed``, ``refreshed`` or ``unchanged``).

        With ``strict`` the subject and target must be registered entities.
        """
        fact = check_fact(fact)
        t_ns = now_ns() if t_ns is None else t_ns
        with self.transaction() as conn:
            self.check_agent(agent_id)
            if strict:
                catalog.check_entities(conn, [fact.subject_id, fact.target_id])
            key = fact_key(fact)
            writes = _Writes(agent_id, source, t_ns)
            self._resolve(conn, agent_id, [(key, fact)], writes)
            self._apply(conn, writes)
            self.bump_epoch(conn)
        return writes.outcome()

    def retract_facts(self, agent_id: str, property: str, subject_id: str | None = None,
                      target_id: str | None = None, *, sub_property: str | None = None,
                      subject_owner_id: str | None = None, target_owner_id: str | None = None,
                      t_ns: int | None = None, source: str = "user") -> int:
        """End the matching current facts of an agent at ``t_ns`` (default now).

        ``None`` or ``"NULL"`` for subject or target match any (the original's wildcard).
        Returns the number of facts ended.
        """
        check_id(property, "property")
        t_ns = now_ns() if t_ns is None else t_ns
        filters = {"subject_id": subject_id, "target_id": target_id,
                   "sub_property": sub_property, "subject_owner_id": subject_owner_id,
                   "target_owner_id": target_owner_id}
        with self.transaction() as conn:
            self.check_agent(agent_id)
            if not self.agents().get(agent_id):
                self._detach(conn, agent_id, keep=True)
            rows = catalog.open_facts_matching(conn, agent_id, property, filters)
            writes = _Writes(agent_id, source, t_ns)
            for key_id, fact, valid_from in rows:
                if valid_from > t_ns:
                    msg = (f"cannot end {fact.subject_id} {fact.property} {fact.target_id} at "
                           f"{format_ns(t_ns)}: it started later, at {format_ns(valid_from)}")
                    raise TimeOrderError(msg)
                writes.end(key_id, fact)
            self._apply(conn, writes)
            self.bump_epoch(conn)
        return len(rows)

    def record_event(self, agent_id: str, fact: Fact, *, t_ns: int | None = None,
                     source: str = "user") -> None:
        """Record a user event (the original's set_info EVENT) for an agent."""
        fact = check_fact(fact)
        t_ns = now_ns() if t_ns is None else t_ns
        with self.transaction() as conn:
            self.check_agent(agent_id)
            key = fact_key(fact)
            self._key_id_map(conn, agent_id, [(key, fact)])
            self.backend.insert_events(self.db.cursor(), [(
                self._key_ids[(agent_id, key)], agent_id, "event", t_ns, fact.value_text,
                fact.value_num, fact.confidence, fact.observability, None, source, now_ns())])

    def empty(self, agent_id: str | None = None) -> None:
        """Delete the facts, memory and events of one agent, or of every agent (EMPTY)."""
        with self.transaction() as conn:
            if agent_id is not None:
                self.check_agent(agent_id)
            self._detach(conn, agent_id, keep=False)
            catalog.empty_facts(conn, agent_id)
            self.bump_epoch(conn)

    def load_file(self, path: Any) -> dict[str, int]:
        """Import an XML seed, JSON or YAML batch file in one transaction (see
        :mod:`toaster.db.seed`); returns counts of rows written per kind."""
        from toaster.db.seed import load_file

        return load_file(self, path)

    # ------------------------------------------------------------------ catalog pass-throughs
    def add_ontology(self, entity_class: str, individual: str, instantiated: bool = False) -> None:
        """Add (or update) the class-tree edge ``entity_class`` -> ``individual``."""
        with self.transaction() as conn:
            catalog.upsert_ontology(conn, entity_class, individual, instantiated)

    def remove_ontology(self, entity_class: str, individual: str | None = None) -> int:
        """Remove one edge, or every edge below ``entity_class``; return the count."""
        with self.transaction() as conn:
            return catalog.delete_ontology(conn, entity_class, individual)

    def set_property(self, entity_id: str, key: str, value: object) -> None:
        """Set a static property of a registered entity (values are stored as text)."""
        with self.transaction() as conn:
            catalog.upsert_property(conn, entity_id, key, value)

    def remove_property(self, entity_id: str, key: str | None = None) -> int:
        """Remove one property of an entity, or all of them; return the count."""
        with self.transaction() as conn:
            return catalog.delete_property(conn, entity_id, key)

    def put_area(self, area_id: str, spec: dict[str, Any], owner_id: str = "") -> None:
        """Store an area definition (a JSON-able dict) so that it survives restarts."""
        with self.transaction() as conn:
            catalog.put_area(conn, area_id, spec, owner_id)

    def remove_area(self, area_id: str) -> bool:
        """Remove an area; False when there was none with that id."""
        with self.transaction() as conn:
            return catalog.remove_area(conn, area_id)

    def areas(self) -> dict[str, dict[str, Any]]:
        """Every stored area: id -> spec."""
        with self.db.transaction() as conn:
            return catalog.areas(conn)

    def put_setting(self, scope: str, key: str, value: object) -> None:
        """Store a JSON-able setting (thresholds, rule configuration)."""
        with self.transaction() as conn:
            catalog.put_setting(conn, scope, key, value)

    def get_setting(self, scope: str, key: str, default: object = None) -> Any:
        """A stored setting, or ``default``."""
        with self.db.transaction() as conn:
            return catalog.get_setting(conn, scope, key, default)


class _Writes:
    """The rows one write produces, collected before they go to the database in bulk."""

    def __init__(self, agent_id: str, source: str, t_ns: int) -> None:
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
        self.opening.append((key_id, fact.value_text, fact.value_num, fact.confidence,
                             fact.observability, self.t_ns, self.recorded_ns, self.source))
        self.events.append(self.event(key_id, fact, kind, previous))

    def event(self, key_id: int, fact: Fact, kind: str, previous: str | None) -> tuple[Any, ...]:
        """The events row for one change."""
        return (key_id, self.agent_id, kind, self.t_ns, fact.value_text, fact.value_num,
                fact.confidence, fact.observability, previous, self.source, self.recorded_ns)

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
                held.value_num, held.confidence, held.observability):
            self.refreshed.append((key_id, fact, held))

    def end(self, key_id: int, fact: Fact) -> None:
        """Close the key's open interval (its event is written once the close is known)."""
        self.closing.append(key_id)
        self.ended.append((key_id, fact))

    def change_set(self) -> ChangeSet:
        return ChangeSet(self.agent_id, self.source, self.t_ns, self.appeared, self.changed,
                         self.refreshed, self.ended)

    def outcome(self) -> str:
        for name in ("appeared", "changed", "refreshed"):
            if getattr(self, name):
                return name
        return "unchanged"


def _is_integrity_error(exc: Exception) -> bool:
    if isinstance(exc, IntegrityError):
        return True
    name = type(exc).__name__
    return name in {"IntegrityError", "UniqueViolation"}
