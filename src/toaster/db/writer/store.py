"""The write path: snapshots from sources become validity intervals and events.

A *source* (a producer, a rule, a user) hands :meth:`Store.sync_snapshot` the complete set of
facts it holds true for one agent at time ``t``. The store compares it with what that source
wrote last (kept in memory, so unchanged facts cost nothing), then in one transaction:

* appeared facts open an interval and write an ``appeared`` event;
* a changed symbolic value (``value_text``) closes the interval at ``t``, opens the next one and
  writes a ``changed`` event (with the previous value);
* a numeric value, confidence or observability that moved beyond the property's tolerance
  (:mod:`toaster.db.tolerance`) refreshes the open interval in place and keeps the numbers it
  held until then in ``fact_samples`` (as-of queries read them); a change within the
  tolerance is not written;
* facts missing from the snapshot close their interval at ``t`` and write an ``ended`` event.

Writes that bypass snapshots (user assertions, retractions, EMPTY) bump ``store_state``'s
``cache_epoch``; every store re-reads what its sources hold on its next transaction, so that the
world state re-asserts itself as in the original's EMPTY. Belief rules registered with
:meth:`Store.add_rule` run in the same transaction as the write that triggers them.
"""

from __future__ import annotations

import random
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol, TypeAlias, TypeVar

from sqlalchemy import Connection, text
from sqlalchemy.exc import IntegrityError

from toaster.db import catalog, tolerance
from toaster.db.dialects import Key
from toaster.db.tolerance import Tolerance
from toaster.db.writer.diff import BatchState, FactArrays, Snapshot, key_of
from toaster.errors import (
    ConcurrentWriteError,
    InvalidInputError,
    TimeOrderError,
    UnknownAgentError,
)
from toaster.model import Fact, check_fact, check_id, fact_key, listed
from toaster.timeutil import check_ns, format_ns, now_ns

if TYPE_CHECKING:
    from toaster.db.handle import Handle

_KEY = key_of
_T = TypeVar("_T")
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
        return {item[0] for part in (self.appeared, self.changed, self.refreshed, self.ended)
                for item in part}


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


#: Makes a rule for one store (a :class:`~toaster.db.Database` calls each of its factories
#: once, when it makes its store).
RuleFactory = Callable[["Store"], Rule]


class SyncResult(NamedTuple):
    """Counts of what a snapshot changed."""

    appeared: int
    changed: int
    refreshed: int
    ended: int
    unchanged: int


@dataclass
class _SourceState:
    facts: dict[Key, Fact] = field(default_factory=dict)  # as stored (within tolerance)
    last_list: list[Fact] | None = None  # the last snapshot as given: equal lists skip the diff
    last_t: int = -(2**63)
    arrays: BatchState | None = None  # the same facts as arrays, for fact-batch sources


class _StaleCache(Exception):
    """Another writer opened an interval concurrently: forget what is remembered and retry."""


class Store:
    """Writes facts, entities and everything else into a :class:`~toaster.db.Database`
    (typed as the :class:`~toaster.db.handle.Handle` it uses)."""

    def __init__(self, db: Handle) -> None:
        self.db = db
        self.backend = db.backend
        self._sources: dict[tuple[str, str], _SourceState] = {}
        self._key_ids: dict[tuple[str, Key], int] = {}
        self._agents: dict[str, bool] | None = None
        self._entities: set[str] = set()
        self._epoch: int | None = None
        self._agents_version: int | None = None
        self._rules: list[Rule] = []
        self._tolerances: dict[str, Tolerance] | None = None
        self._pending: list[ChangeSet] | None = None  # changes whose rules wait (sync_many)
        self._tick_ns: int | None = None  # sync_many: the stamp of its sources, once known
        self._tick_sources: tuple[str, ...] = ()  # sync_many: its sources
        self._actor: str | None = None  # who makes the changes being written (acting())
        self._actor_of: Callable[[Fact], str | None] | None = None  # per fact (acting())
        self._in_tx = False
        # (agent, source) -> where its last snapshot moved to the clock was written (_writes)
        self._moved_to: dict[tuple[str, str], int] = {}

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
                cur = self.db.cursor()
                self._check_epoch(self.backend.begin_writes(cur))
                yield conn
                self.backend.end_writes(cur)
        except BaseException:
            self.forget()
            raise
        finally:
            self._in_tx = False
        for rule in self._rules:
            committed = getattr(rule, "committed", None)
            if committed is not None:
                committed()

    def forget(self) -> None:
        """Drop everything remembered about the database (it is re-read on demand)."""
        self._sources.clear()
        self._key_ids.clear()
        self._agents = None
        self._entities.clear()
        self._epoch = None
        self._tolerances = None

    def _check_epoch(self, versions: tuple[int, int]) -> None:
        """Forget what another writer may have changed: everything when the cache epoch
        moved, the agents when ``agents`` was written (registrations, self marks)."""
        epoch, agents = versions
        if epoch != self._epoch:
            self.forget()
            self._epoch = epoch
        if agents != self._agents_version:
            self._agents = None
            self._agents_version = agents

    def bump_epoch(self, conn: Connection) -> None:
        """Tell every store (this one included) to re-read what its sources hold."""
        conn.execute(text("UPDATE store_state SET cache_epoch = cache_epoch + 1 WHERE id = 1"))
        self.forget()
        self._epoch = conn.execute(
            text("SELECT cache_epoch FROM store_state WHERE id = 1")).scalar_one()

    @contextmanager
    def acting(self, actor: str | None, actors: Actors | None = None) -> Iterator[None]:
        """Writes inside are changes made by ``actor`` (an agent): the belief rules let it
        perceive them wherever it is. None: unknown (perception alone decides).

        ``actors`` names who made each change, per fact (a function of the fact, or a mapping
        fact key -> agent id); a fact it gives no actor (None, or absent) has ``actor``. A
        producer tick knows, for instance, that the facts about where a held object is were
        made by the agent holding it.
        """
        if actor is None and actors is None:
            yield
            return
        if actor is not None:
            self._check_actor(actor)
        actor_of: Callable[[Fact], str | None] | None
        if actors is None or callable(actors):
            actor_of = actors
        else:
            for who in set(actors.values()):
                self._check_actor(who)
            actor_of = _by_key(actors)
        previous = self._actor, self._actor_of
        self._actor = actor if actor is not None else previous[0]
        self._actor_of = actor_of if actor_of is not None else previous[1]
        try:
            yield
        finally:
            self._actor, self._actor_of = previous

    def _check_actor(self, actor: str) -> None:
        """Raise :class:`UnknownAgentError` unless ``actor`` is a registered agent."""
        check_id(actor, "actor")
        try:
            known = ">" not in self.check_agent(actor)  # a nested holder acts on nothing
        except UnknownAgentError:
            known = False
        if not known:
            msg = (f"unknown actor {actor!r}: the actor is the agent who made the change; "
                   f"register it with `toaster set-info ENTITY --id {actor} --type human`")
            raise UnknownAgentError(msg)

    def add_rule(self, rule: Rule) -> None:
        """Run ``rule(conn, changes)`` after every fact write, in the same transaction."""
        self._rules.append(rule)

    def _detach(self, conn: Connection, agent_id: str | None, *, keep: bool) -> None:
        """Let rules turn rows they share with ``agent_id`` into its own rows (``keep``) or
        drop them (the agent's facts are being deleted) before a write that bypasses them."""
        for rule in self._rules:
            rule.detach(conn, agent_id, keep=keep)

    # ------------------------------------------------------------------ agents and entities
    def agents(self) -> dict[str, bool]:
        """Known agents and nested belief holders (``A>B``): id -> is_self."""
        if self._agents is None:
            with self.db.transaction() as conn:
                rows = conn.execute(text(
                    "SELECT h.id, COALESCE(a.is_self, false) FROM holders h "
                    "LEFT JOIN agents a ON a.id = h.agent_id")).all()
            self._agents = {row[0]: bool(row[1]) for row in rows}
        return self._agents

    def check_agent(self, agent_id: str) -> str:
        """Return ``agent_id`` if registered, else raise :class:`UnknownAgentError`."""
        check_id(agent_id, "agent id")
        if agent_id not in self.agents():
            self._agents = None
            if agent_id not in self.agents():
                known = listed(sorted(self.agents()), none="none yet")
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
                   f"({listed(sorted(selves))}): {fix}")
            raise InvalidInputError(msg)
        return selves[0]

    def add_entity(self, entity_id: str, kind: str = "object", name: str = "", owner_id: str = "",
                   *, is_self: bool | None = None, agent: bool | None = None,
                   t_ns: int | None = None, views: bool = True) -> None:
        """Add or update an entity; humans and robots (or ``agent=True``) become agents.

        ``is_self=True`` marks a robot whose perception is the world state. ``views=False``
        registers an agent without its per-agent views (``fact_table_ID``...), as recordings
        of crowds do (``toaster db views`` makes them later).
        """
        with self.transaction() as conn:
            catalog.upsert_entity(conn, entity_id, kind, name, owner_id,
                                  is_self=is_self, agent=agent, t_ns=t_ns, views=views)
            self._agents = None
            self._entities.add(entity_id)

    def add_entities(self, rows: Iterable[tuple[str, str, str, str, bool | None]], *,
                     t_ns: int | None = None, views: bool = True) -> None:
        """:meth:`add_entity` of many ``(id, kind, name, owner_id, agent)`` rows (none of them
        self) in a few statements (a recording's people)."""
        with self.transaction() as conn:
            catalog.upsert_entities(conn, list(rows), t_ns=now_ns() if t_ns is None else t_ns,
                                    views=views)
            self._agents = None

    def remove_entity(self, entity_id: str) -> None:
        """Remove an entity (an agent loses its beliefs, views and events too)."""
        check_id(entity_id, "entity id")
        with self.transaction() as conn:
            if entity_id in self.agents():
                for holder in (entity_id, *catalog.nested_holders_of(conn, entity_id)):
                    self._detach(conn, holder, keep=False)
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
                      facts: Iterable[Fact] | FactArrays, *,
                      actor: str | None = None, actors: Actors | None = None) -> SyncResult:
        """Make ``source``'s facts for ``agent_id`` at ``t_ns`` exactly ``facts`` (a list of
        facts, or a producer's :class:`~toaster.producers.batch.FactBatch`).

        Only differences with what the source wrote last reach the database, in one
        transaction; numbers that moved less than their tolerance are not differences.
        Facts about entities nobody registered register them (kind ''). A batch is diffed
        as arrays: only its changed facts become tuples. ``actor``: the agent who made the
        changes, if known; ``actors``: who made each change, per fact, over ``actor`` (a
        function of the fact, called for changed and ended facts only, or a mapping fact key
        -> agent id; see :meth:`acting`).
        """
        if actor is not None or actors is not None:
            with self.acting(actor, actors):
                return self.sync_snapshot(source, agent_id, t_ns, facts)
        check_id(source, "source")
        check_ns(t_ns)
        batch: FactArrays | None = None
        given: list[Fact] = []
        if isinstance(facts, list):  # the common case first: a protocol check costs ~10 µs
            given = facts
        elif isinstance(facts, FactArrays):
            batch = facts
        else:
            given = list(facts)
        def write(conn: Connection) -> SyncResult:
            if batch is not None:
                return self._sync_batch(conn, source, agent_id, t_ns, batch)
            return self._sync(conn, source, agent_id, t_ns, given)

        return self._retrying(write)

    def retried(self, write: Callable[[Connection], _T]) -> _T:
        """``write(conn)`` (store calls, for instance registrations) in one transaction,
        written again from the start when it conflicts with a concurrent writer."""
        return self._retrying(write)

    def _retrying(self, write: Callable[[Connection], _T]) -> _T:
        """``write(conn)`` in one transaction. Outermost, a conflict with a concurrent writer
        (a stale cache, a deadlock, a serialization failure, a unique key taken meanwhile)
        rolls it back and runs it again with fresh caches, a few times; inside a caller's
        transaction a stale cache is re-read once (the caller's retry covers the rest)."""
        if self._in_tx:
            try:
                return write(self.db.connection)
            except _StaleCache as exc:
                if exc.__cause__ is not None:  # a failed statement (PostgreSQL: the
                    raise  # transaction is aborted): the caller's retry starts it again
                self.forget()  # inside a caller's transaction nothing else forgets
                return write(self.db.connection)
        for attempt in range(1, _ATTEMPTS + 1):
            try:
                with self.transaction() as conn:
                    return write(conn)
            except Exception as exc:
                if not _is_conflict(exc):
                    raise
                if attempt == _ATTEMPTS:
                    msg = (f"write abandoned after {_ATTEMPTS} conflicts with concurrent "
                           f"writers ({_one_line(exc)}): retry it")
                    raise ConcurrentWriteError(msg) from exc
                time.sleep(random.uniform(0, min(0.2, 0.005 * 2 ** attempt)))
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
            if self._clocked(agent_id):  # stored times may be the clock's, ahead of the source's
                state.last_t = -(2**63)
            self._sources[(source, agent_id)] = state
        return state

    def _begin(self, conn: Connection, source: str, agent_id: str, t_ns: int) -> _SourceState:
        """The source's state, after checking the agent and the time order."""
        self.check_agent(agent_id)
        state = self._state(conn, source, agent_id)
        if t_ns < state.last_t:
            msg = (f"snapshot of {source!r} for {agent_id!r} at {format_ns(t_ns)} is older than "
                   f"its previous one ({format_ns(state.last_t)}): send snapshots in time order")
            raise TimeOrderError(msg)
        return state

    def tolerances(self, conn: Connection | None = None) -> dict[str, Tolerance]:
        """Tolerance per property (``*``: the rest), read once per cache epoch."""
        if self._tolerances is None:
            if conn is None:
                with self.db.transaction() as read_conn:
                    self._tolerances = tolerance.read(read_conn)
            else:
                self._tolerances = tolerance.read(conn)
        return self._tolerances

    def _sync(self, conn: Connection, source: str, agent_id: str, t_ns: int,
              given: list[Fact]) -> SyncResult:
        state = self._begin(conn, source, agent_id, t_ns)
        state.arrays = None
        old = state.facts
        if given == state.last_list:  # the same facts in the same order: nothing to do
            state.last_t = t_ns
            return SyncResult(0, 0, 0, 0, len(old))
        try:
            new = dict(zip(map(_KEY, given), given, strict=True))
        except (TypeError, IndexError):  # not facts, or a key field that is no text: say which
            for fact in given:
                check_fact(fact)
            raise
        if new == old:
            state.last_list, state.last_t = given, t_ns
            return SyncResult(0, 0, 0, 0, len(new))
        held_get = old.get
        table = self.tolerances(conn)
        touched = [(key, check_fact(fact)) for key, fact in new.items()
                   if (held := held_get(key)) != fact and not _within(table, fact, held)]
        gone = [key for key in old if key not in new]
        result = self._write_diff(conn, state, agent_id, source, t_ns, touched,
                                  [(key, old[key]) for key in gone], len(new))
        state.last_list = given
        return result

    def _write_diff(self, conn: Connection, state: _SourceState, agent_id: str, source: str,
                    t_ns: int, touched: list[tuple[Key, Fact]], gone: list[tuple[Key, Fact]],
                    size: int, *, trust_cache: bool = False) -> SyncResult:
        """Write a snapshot's differences (stated facts, ended facts); remember them.

        Stated facts are compared with the open interval, whoever wrote it; with
        ``trust_cache`` (producers' batches), a fact whose numbers alone moved refreshes what
        this source wrote without reading it back first."""
        if not touched and not gone:
            state.last_t = t_ns
            return SyncResult(0, 0, 0, 0, size)
        key_ids = self._key_ids
        old = state.facts
        # Events in order: ended, changed, appeared.
        writes = self._writes(conn, agent_id, source, t_ns, snapshot=True)
        for key, fact in gone:
            writes.end(key_ids[(agent_id, key)], fact)
        if touched and trust_cache and self.agents().get(agent_id):
            # Only numbers moved: refresh what this source wrote without reading it back (a
            # refresh that finds no open interval means another writer ended it: retry).
            resolve = []
            for key, fact in touched:
                held = old.get(key)
                if held is not None and held[3] == fact[3] and held[7] == fact[7]:
                    writes.refreshed.append((key_ids[(agent_id, key)], fact, held))
                else:
                    resolve.append((key, fact))
            touched_db = resolve
        else:
            touched_db = touched
        if touched_db:
            self._resolve(conn, agent_id, touched_db, writes)
        self._apply(conn, writes)
        for key, fact in touched:
            old[key] = fact
        for key, _ in gone:
            del old[key]
        state.last_t = t_ns
        return SyncResult(len(writes.appeared), len(writes.changed), len(writes.refreshed),
                          len(writes.ended), size - len(touched))

    def _sync_batch(self, conn: Connection, source: str, agent_id: str, t_ns: int,
                    batch: FactArrays) -> SyncResult:
        """:meth:`sync_snapshot` of a fact batch, diffed as arrays (:mod:`.diff`)."""
        state = self._begin(conn, source, agent_id, t_ns)
        arrays = state.arrays
        if arrays is None or arrays.world is not batch.world:
            result = self._sync(conn, source, agent_id, t_ns, batch.facts())
            state.last_list = None
            state.arrays = BatchState.of(batch, state.facts)
            return result
        new = Snapshot.of(batch, self.tolerances(conn))
        touched, keep, old_pos, gone = arrays.diff(new)
        facts = [check_fact(f) for f in batch.facts_at(new.order[touched])]
        keys = list(map(_KEY, facts))
        gone_items = list(zip(arrays.tkey[gone].tolist(), arrays.fact[gone].tolist(),
                              strict=True))
        result = self._write_diff(conn, state, agent_id, source, t_ns,
                                  list(zip(keys, facts, strict=True)), gone_items, len(new.keys),
                                  trust_cache=True)
        state.last_list = None
        state.arrays = arrays.updated(new, touched, keep, old_pos, keys, facts)
        return result

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
        cur = self.db.cursor()
        open_rows = self.backend.open_rows(cur, known) if known else {}
        reopened = [k for k in known if k not in open_rows]
        ends = self.backend.last_ends(cur, reopened) if reopened else {}
        t_ns = writes.t_ns
        for key, fact in items:
            key_id = self._key_ids[(agent_id, key)]
            row = open_rows.get(key_id)
            last = row[5] if row is not None else ends.get(key_id)
            if last is not None and last > t_ns:
                msg = (f"{fact.subject_id} {fact.property} {fact.target_id}".rstrip()
                       + f" for {agent_id!r} at {format_ns(t_ns)} is older than its last "
                       f"change ({format_ns(last)}): write each fact in time order")
                raise TimeOrderError(msg)
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
        if writes.refreshed:  # first: a stale cache is found before anything is written
            rows = [(f.value_num, f.confidence, f.observability, k)
                    for k, f, _ in writes.refreshed]
            if backend.refresh_intervals(cur, writes.t_ns, rows) != len(rows):
                raise _StaleCache
        if writes.closing:
            # A fact this source held may have been ended by another writer: no event then.
            closed = backend.close_intervals(cur, writes.t_ns, writes.closing)
            writes.ended = [(k, f) for k, f in writes.ended if k in closed]
        writes.events[:0] = [writes.event(k, f, "ended", None) for k, f in writes.ended]
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
        if self._rules and not writes.empty:
            changes = writes.change_set()
            for actor in set(changes.actors.values()):
                self._check_actor(actor)
            if self._pending is not None:  # sync_many: the rules run once, at its end
                self._pending.append(changes)
            else:
                self._run_rules(conn, changes)

    def _clocked(self, agent_id: str) -> bool:
        """Snapshots of ``agent_id`` follow the rules' clock (see :meth:`_writes`): rules run,
        ``agent_id`` is registered and somebody holds beliefs."""
        agents = self.agents()
        return bool(self._rules) and agent_id in agents and not all(agents.values())

    def _writes(self, conn: Connection, agent_id: str, source: str, t_ns: int, *,
                snapshot: bool = False) -> _Writes:
        """The rows of one write of ``agent_id`` at ``t_ns``.

        The belief runs follow the rules' clock (``store_state.beliefs_ns``, the last run's
        time, and ``beliefs_self``, its self agent): a write at the time of its own robot's
        last run shares that instant, any other run at or before the clock comes 1 ns after it
        (revision 0015: one robot's writes at one time reach the holders at that time, two
        robots' runs never share an instant). A ``snapshot`` behind the clock (before it, or
        at another robot's run) by at most :data:`LIVE_CLOCK_SKEW_NS` (a live robot or
        producer whose clock is a little behind another's, or ticks at the same instant) is
        written 1 ns after it, so that the self rows and the holders' rows that follow them
        share one timeline. A source's later
        snapshots are never written before one so moved: a live robot whose lag grows past
        the skew stays on the clock's timeline instead of failing with a time-order error.
        The sources of one :meth:`sync_many` (a tick) are written at one stamp, the latest any
        of them needs. Older snapshots (one source imported after another) and single writes
        (assert, retract, tell) keep their time: their runs happen at the clock's (or just
        after). On PostgreSQL reading the clock locks it: such writes run one at a time
        (their belief runs would anyway)."""
        given = t_ns
        if snapshot and self._pending is not None and self._tick_ns is not None:
            t_ns = self._tick_ns  # a later source of the tick: the first one's stamp
        elif snapshot and self._clocked(agent_id):
            last, last_self = conn.execute(text(
                "UPDATE store_state SET beliefs_ns = beliefs_ns WHERE id = 1 "
                "RETURNING beliefs_ns, beliefs_self")).one()
            moved = max(self._moved_to.get((agent_id, s), t_ns)
                        for s in (*self._tick_sources, source))
            behind = last is not None and (
                t_ns < last or (t_ns == last and last_self != agent_id))
            if behind and last <= t_ns + LIVE_CLOCK_SKEW_NS:
                t_ns = max(last + 1, moved)
            elif t_ns < moved:
                t_ns = moved if last is None else max(moved, last + 1)
        if snapshot and self._pending is not None:
            self._tick_ns = t_ns
        if snapshot and t_ns != given:
            self._moved_to[(agent_id, source)] = t_ns
        return _Writes(agent_id, source, t_ns, self._actor, self._actor_of)

    def _run_rules(self, conn: Connection, changes: ChangeSet) -> None:
        for rule in self._rules:
            rule(conn, changes)

    def sync_many(self, agent_id: str, t_ns: int,
                  snapshots: Iterable[tuple[str, Iterable[Fact] | FactArrays]], *,
                  actor: str | None = None, actors: Actors | None = None) -> list[SyncResult]:
        """:meth:`sync_snapshot` of several sources for one agent at one time, in one
        transaction, the rules running once over all their changes (a producer tick).
        ``actor`` and ``actors`` (per fact) name who made the changes, as for
        :meth:`sync_snapshot`."""
        given = list(snapshots)

        def write(conn: Connection) -> list[SyncResult]:
            self._pending, self._tick_ns = [], None
            self._tick_sources = tuple(source for source, _ in given)
            try:
                results = [self.sync_snapshot(source, agent_id, t_ns, facts)
                           for source, facts in given]
                for changes in _merged(self._pending):
                    self._run_rules(conn, changes)
            finally:
                self._pending, self._tick_ns, self._tick_sources = None, None, ()
            return results

        with self.acting(actor, actors):
            return self._retrying(write)

    # ------------------------------------------------------------------ single writes
    def assert_fact(self, agent_id: str, fact: Fact, *, t_ns: int | None = None,
                    source: str = "user", strict: bool = True,
                    actor: str | None = None) -> str:
        """State one fact for an agent at ``t_ns`` (default now); return what happened
        (``appeared``, ``changed``, ``refreshed`` or ``unchanged``).

        With ``strict`` the subject and target must be registered entities. ``actor``: the
        agent who made the change, if known.
        """
        fact = check_fact(fact)
        t_ns = now_ns() if t_ns is None else check_ns(t_ns)
        with self.acting(actor), self.transaction() as conn:
            self.check_agent(agent_id)
            if strict:
                catalog.check_entities(conn, [fact.subject_id, fact.target_id])
            key = fact_key(fact)
            writes = self._writes(conn, agent_id, source, t_ns)
            self._resolve(conn, agent_id, [(key, fact)], writes)
            self._apply(conn, writes)
            self.bump_epoch(conn)
        return writes.outcome()

    def retract_facts(self, agent_id: str, property: str, subject_id: str | None = None,
                      target_id: str | None = None, *, sub_property: str | None = None,
                      subject_owner_id: str | None = None, target_owner_id: str | None = None,
                      t_ns: int | None = None, source: str = "user",
                      actor: str | None = None) -> int:
        """End the matching current facts of an agent at ``t_ns`` (default now).

        ``None`` or ``"NULL"`` for subject or target match any (the original's wildcard).
        Returns the number of facts ended. ``actor``: the agent who ended them, if known.
        """
        check_id(property, "property")
        t_ns = now_ns() if t_ns is None else check_ns(t_ns)
        filters = {"subject_id": subject_id, "target_id": target_id,
                   "sub_property": sub_property, "subject_owner_id": subject_owner_id,
                   "target_owner_id": target_owner_id}
        with self.acting(actor), self.transaction() as conn:
            self.check_agent(agent_id)
            if not self.agents().get(agent_id):
                self._detach(conn, agent_id, keep=True)
            rows = catalog.open_facts_matching(conn, agent_id, property, filters)
            writes = self._writes(conn, agent_id, source, t_ns)
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
        t_ns = now_ns() if t_ns is None else check_ns(t_ns)
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

    # ------------------------------------------------------------------ catalog pass-throughs
    def add_ontology(self, entity_class: str, individual: str,
                     instantiated: bool | str = False) -> None:
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

    def remove_all_areas(self) -> int:
        """Remove every area; return how many there were."""
        with self.transaction() as conn:
            return catalog.remove_all_areas(conn)

    def areas(self) -> dict[str, dict[str, Any]]:
        """Every stored area: id -> spec."""
        with self.db.transaction() as conn:
            return catalog.areas(conn)

    def put_setting(self, scope: str, key: str, value: object) -> None:
        """Store a JSON-able setting (thresholds, rule configuration)."""
        if scope == tolerance.SCOPE:
            tolerance.validate(key, value)
        with self.transaction() as conn:
            catalog.put_setting(conn, scope, key, value)
            if scope == tolerance.SCOPE:  # every store re-reads its tolerances
                self.bump_epoch(conn)

    def get_setting(self, scope: str, key: str, default: object = None) -> Any:
        """A stored setting, or ``default``."""
        with self.db.transaction() as conn:
            return catalog.get_setting(conn, scope, key, default)


class _Writes:
    """The rows one write produces, collected before they go to the database in bulk."""

    def __init__(self, agent_id: str, source: str, t_ns: int, actor: str | None = None,
                 actor_of: Callable[[Fact], str | None] | None = None) -> None:
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
        actors: Mapping[int, str] = _NO_ACTORS
        if self.actor_of is not None:  # asked of the changed facts only
            actor_of = self.actor_of
            actors = {item[0]: who for part in (self.appeared, self.changed, self.refreshed,
                                                self.ended)
                      for item in part if (who := actor_of(item[1])) is not None}
        return ChangeSet(self.agent_id, self.source, self.t_ns, self.appeared, self.changed,
                         self.refreshed, self.ended, self.actor, actors)

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


def _within(table: dict[str, Tolerance], new: Fact, held: Fact | None) -> bool:
    """``new`` only moved ``held``'s numbers within their tolerance (nothing to write)."""
    if held is None or new[:4] != held[:4] or new[7:] != held[7:]:
        return False
    return not tolerance.beyond(table.get(new[1]) or table["*"], new[4:7], held[4:7])


def _merged(pending: list[ChangeSet]) -> list[ChangeSet]:
    """Change sets of several sources as one per agent (the same time), unless two of them
    touch the same key (then each stays alone, in order)."""
    if len(pending) < 2:
        return pending
    seen: set[int] = set()
    first = pending[0]
    for changes in pending:
        keys = changes.key_ids()
        if (keys & seen or changes.agent_id != first.agent_id
                or changes.actor != first.actor):
            return pending
        seen |= keys
    return [ChangeSet(first.agent_id, "+".join(c.source for c in pending), first.t_ns,
                      [item for c in pending for item in c.appeared],
                      [item for c in pending for item in c.changed],
                      [item for c in pending for item in c.refreshed],
                      [item for c in pending for item in c.ended], first.actor,
                      {k: v for c in pending for k, v in c.actors.items()})]


def _by_key(actors: Mapping[Key, str]) -> Callable[[Fact], str | None]:
    """The per-fact actor function of a mapping fact key -> actor."""
    get = actors.get
    return lambda fact: get(_KEY(fact))


#: How far behind the rules' clock a snapshot may be and still be taken for a live writer's
#: lag (written just after the clock, see Store._writes): beyond, it keeps its own time.
LIVE_CLOCK_SKEW_NS = 1_000_000_000
#: Attempts of a write that conflicts with concurrent writers (see Store._retrying).
_ATTEMPTS = 8
#: SQLSTATEs of conflicts that a new attempt resolves: serialization failure, deadlock,
#: unique violation (a key another writer inserted meanwhile).
_CONFLICTS = {"40001", "40P01", "23505"}


def _is_conflict(exc: BaseException) -> bool:
    if isinstance(exc, _StaleCache):
        return True
    orig = getattr(exc, "orig", exc)
    return getattr(orig, "sqlstate", None) in _CONFLICTS


def _one_line(exc: BaseException) -> str:
    inner = getattr(exc, "orig", None) or exc
    lines = str(inner).strip().splitlines()
    return lines[0] if lines else type(inner).__name__


def _is_integrity_error(exc: Exception) -> bool:
    if isinstance(exc, IntegrityError):
        return True
    name = type(exc).__name__
    return name in {"IntegrityError", "UniqueViolation"}
