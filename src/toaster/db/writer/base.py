"""The store's foundation: its handle and caches, transactions, agents, entities and the
catalogue writes; :class:`~toaster.db.writer.store.Store` adds the fact writes.
"""

from __future__ import annotations

import random
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, TypeVar

from sqlalchemy import Connection, text

from toaster.db import catalog, tolerance
from toaster.db.dialects import Key
from toaster.db.dialects.base import Clock
from toaster.db.tolerance import Tolerance
from toaster.db.writer.changes import Actors, Rule
from toaster.db.writer.diff import SourceState, key_of
from toaster.db.writer.retry import ATTEMPTS, StaleCache, is_conflict, one_line
from toaster.errors import (
    ConcurrentWriteError,
    InvalidInputError,
    ToasterError,
    UnknownAgentError,
)
from toaster.model import Fact, check_id, listed
from toaster.timeutil import now_ns

if TYPE_CHECKING:
    from toaster.db.handle import Handle

_KEY = key_of
_T = TypeVar("_T")


class WriterBase:
    """What every write shares (:class:`~toaster.db.writer.store.Store` is the writer)."""

    def __init__(self, db: Handle) -> None:
        self.db = db
        self.backend = db.backend
        self._sources: dict[tuple[str, str], SourceState] = {}
        self._key_ids: dict[tuple[str, Key], int] = {}
        self._agents: dict[str, bool] | None = None
        self._entities: set[str] = set()
        self._epoch: int | None = None
        self._agents_version: int | None = None
        self._rules: list[Rule] = []
        self._tolerances: dict[str, Tolerance] | None = None
        self._in_tick = False  # sync_many: several sources written at one stamp
        self._tick_ns: int | None = None  # sync_many: the stamp of its sources, once known
        self._tick_sources: tuple[str, ...] = ()  # sync_many: its sources
        self._actor: str | None = None  # who makes the changes being written (acting())
        self._actor_of: Callable[[Fact], str | None] | None = None  # per fact (acting())
        self._in_tx = False
        #: Write transactions begun (a rule's ``committed()`` tells which one committed).
        self.transactions = 0
        self._clock: Clock | None = None  # the rules' clock as this transaction began
        # (agent, source) -> where its last snapshot moved to the clock was written (_writes)
        self._moved_to: dict[tuple[str, str], int] = {}

    # ------------------------------------------------------------------ transactions, caches
    @contextmanager
    def transaction(self, *, clock: str | None = None) -> Iterator[Connection]:
        """One write transaction; store calls made inside it join it (all or nothing).
        ``clock`` (a self agent): read the latest clock of its holders with the cache epoch,
        for a snapshot."""
        if self._in_tx:
            yield self.db.connection
            return
        # Before the flag: reaching the connection reconnects, which fails while the server
        # is down, and a flag left set would make every later call join a dead transaction.
        begin = not self.db.connection.in_transaction()  # else inside a db.transaction()
        self._in_tx = True
        self.transactions += 1
        cur = None
        try:
            with self.db.transaction(write=True) as conn:
                cur = self.db.cursor()
                epoch, agents, self._clock = self.backend.begin_writes(
                    cur, clock=clock, begin=begin
                )
                self._check_epoch((epoch, agents))
                yield conn
                self.backend.end_writes(cur)
        except Exception as exc:
            self.forget()
            locked = _lock_timed_out(self.db, exc)
            if locked is not None:
                raise locked from exc
            raise
        except BaseException:
            self.forget()
            raise
        finally:
            self._in_tx, self._clock = False, None
            if cur is not None:
                self.backend.after_writes(cur)
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
            text("SELECT cache_epoch FROM store_state WHERE id = 1")
        ).scalar_one()

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
            msg = (
                f"unknown actor {actor!r}: the actor is the agent who made the change; "
                f"register it with `toaster set-info ENTITY --id {actor} --type human`"
            )
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
            with self.db.transaction():  # a raw cursor: it may be asked inside a batch
                cur = self.db.cursor()
                cur.execute(
                    "SELECT h.id, COALESCE(a.is_self, false) FROM holders h "
                    "LEFT JOIN agents a ON a.id = h.agent_id"
                )
                rows = cur.fetchall()
            self._agents = {row[0]: bool(row[1]) for row in rows}
        return self._agents

    def check_agent(self, agent_id: str) -> str:
        """Return ``agent_id`` if registered, else raise :class:`UnknownAgentError`."""
        check_id(agent_id, "agent id")
        if agent_id not in self.agents():
            self._agents = None
            if agent_id not in self.agents():
                known = listed(sorted(self.agents()), none="none yet")
                msg = (
                    f"unknown agent {agent_id!r} (known: {known}): register it with "
                    f"`toaster set-info ENTITY --id {agent_id} --type human` (or robot)"
                )
                raise UnknownAgentError(msg)
        return agent_id

    def self_agent(self, fix: str = "name the agent (--agent ID, or 'agent: ID' in a file)") -> str:
        """The one self agent, which facts default to; an error says ``fix`` when there is
        none or several."""
        selves = [agent for agent, is_self in self.agents().items() if is_self]
        if len(selves) != 1:
            msg = (
                f"no agent given and there is not exactly one self agent "
                f"({listed(sorted(selves))}): {fix}"
            )
            raise InvalidInputError(msg)
        return selves[0]

    def add_entity(
        self,
        entity_id: str,
        kind: str = "object",
        name: str = "",
        owner_id: str = "",
        *,
        is_self: bool | None = None,
        agent: bool | None = None,
        t_ns: int | None = None,
        views: bool = True,
    ) -> None:
        """Add or update an entity; humans and robots (or ``agent=True``) become agents.

        ``is_self=True`` marks a robot whose perception is the world state. ``views=False``
        registers an agent without its per-agent views (``fact_table_ID``...), as recordings
        of crowds do (``toaster db views`` makes them later).
        """
        with self.transaction() as conn:
            catalog.upsert_entity(
                conn,
                entity_id,
                kind,
                name,
                owner_id,
                is_self=is_self,
                agent=agent,
                t_ns=t_ns,
                views=views,
            )
            self._agents = None
            self._entities.add(entity_id)

    def add_entities(
        self,
        rows: Iterable[tuple[str, str, str, str, bool | None]],
        *,
        t_ns: int | None = None,
        views: bool = True,
    ) -> None:
        """:meth:`add_entity` of many ``(id, kind, name, owner_id, agent)`` rows (none of them
        self) in a few statements (a recording's people)."""
        with self.transaction() as conn:
            catalog.upsert_entities(
                conn, list(rows), t_ns=now_ns() if t_ns is None else t_ns, views=views
            )
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
            conn.execute(
                text("UPDATE agents SET is_self = :s WHERE id = :a"), {"s": is_self, "a": agent_id}
            )
            self._agents = None

    def _ensure_entities(self, facts: Iterable[Fact]) -> None:
        rows, stamp = [], now_ns()
        for fact in facts:
            for entity_id, owner in (
                (fact.subject_id, fact.subject_owner_id),
                (fact.target_id, fact.target_owner_id),
            ):
                if entity_id and entity_id not in self._entities:
                    self._entities.add(entity_id)
                    rows.append((entity_id, owner, stamp))
        if rows:
            self.backend.insert_entities(self.db.cursor(), rows)

    def register_start(self, t_ns: int) -> None:
        """Begin a registration of an input starting at ``t_ns``: take the lock under which
        agents are numbered (first, before the writes whose triggers lock ``store_state``) and
        record ``t_ns`` as when the data starts (the earliest is kept). Call it first in the
        :meth:`retried` write that registers the input's areas and entities."""
        with self.transaction() as conn:
            catalog.lock_registrations(conn)
            catalog.note_data_start(conn, t_ns)

    def retried(self, write: Callable[[Connection], _T]) -> _T:
        """``write(conn)`` (store calls, for instance registrations) in one transaction,
        written again from the start when it conflicts with a concurrent writer."""
        return self._retrying(write)

    def _retrying(self, write: Callable[[Connection], _T], *, clock: str | None = None) -> _T:
        """``write(conn)`` in one transaction. Outermost, a conflict with a concurrent writer
        (a stale cache, a deadlock, a serialization failure, a unique key taken meanwhile)
        rolls it back and runs it again with fresh caches, a few times; inside a caller's
        transaction a stale cache is re-read once (the caller's retry covers the rest)."""
        if self._in_tx:
            try:
                return write(self.db.connection)
            except StaleCache as exc:
                if exc.__cause__ is not None:  # a failed statement (PostgreSQL: the
                    raise  # transaction is aborted): the caller's retry starts it again
                self.forget()  # inside a caller's transaction nothing else forgets
                return write(self.db.connection)
        for attempt in range(1, ATTEMPTS + 1):
            try:
                with self.transaction(clock=clock) as conn:
                    return write(conn)
            except Exception as exc:
                if not is_conflict(exc):
                    raise
                if attempt == ATTEMPTS:
                    msg = (
                        f"write abandoned after {ATTEMPTS} conflicts with concurrent "
                        f"writers ({one_line(exc)}): retry it"
                    )
                    raise ConcurrentWriteError(msg) from exc
                time.sleep(random.uniform(0, min(0.2, 0.005 * 2**attempt)))
        msg = "unreachable"
        raise AssertionError(msg)

    # ------------------------------------------------------------------ catalog pass-throughs
    def add_ontology(
        self, entity_class: str, individual: str, instantiated: bool | str = False
    ) -> None:
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


def _lock_timed_out(db: Handle, exc: Exception) -> ToasterError | None:
    """The one-line error of a lock wait a raw cursor's statement gave up (PostgreSQL's
    lock_timeout: the clock of a holder another robot's run holds, or another row);
    SQLAlchemy's statements get it from the engine's error handler."""
    if getattr(exc, "sqlstate", None) != "55P03":
        return None
    from toaster.db.engine import database_error, describe, lock_timeout

    return database_error(exc, describe(db.connection.engine.url), lock_timeout())


def _by_key(actors: Mapping[Key, str]) -> Callable[[Fact], str | None]:
    """The per-fact actor function of a mapping fact key -> actor."""
    get = actors.get
    return lambda fact: get(_KEY(fact))
