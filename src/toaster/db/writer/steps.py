"""The fact writes of a transaction as two batches of statements: the reads a diff needs (the
ids of new keys, the open intervals of the facts the store cannot tell from memory), then the
writes (refreshes, closes, new intervals, events, the rules' run). On PostgreSQL each batch is
one round trip (:meth:`toaster.db.dialects.Backend.batch`); SQLite runs them as they come.

What the writes find is checked once their batch is answered: a refresh that finds no open
interval, or an ended fact already closed by another writer, means the store's memory is stale
(:class:`StaleCache`: the write is rolled back and written again). Inside a transaction the
store does not own (it cannot roll it back) and on the attempt after such a close, the checks
come first, each in its own round trip, as before batching: a fact ended meanwhile then ends
without an event.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass, field
from typing import Any

from sqlalchemy import Connection

from toaster.db.dialects.base import Key, Later
from toaster.db.writer.base import WriterBase
from toaster.db.writer.changes import ChangeSet, Writes
from toaster.db.writer.retry import StaleCache, is_integrity_error, on_facts
from toaster.errors import TimeOrderError
from toaster.model import Fact
from toaster.timeutil import format_ns


@dataclass(eq=False)
class Reads:
    """The reads of one write's stated facts, sent in a batch (:meth:`FactSteps._send_reads`)."""

    items: list[tuple[Key, Fact]]
    missing: list[tuple[Key, Fact]]  # keys this process has no id for: inserted first
    created: Later[dict[Key, int]] | None = None
    open_rows: Later[dict[int, tuple[Any, ...]]] | None = None
    ends: Later[dict[int, int]] | None = None


@dataclass(eq=False)
class Sent:
    """One write's statements, sent; what their answers must say (:meth:`FactSteps._check`)."""

    writes: Writes
    refreshed: Later[int] | None = None  # None: checked already, or nothing refreshed
    closed: Later[set[int]] | None = None  # None: checked already (ended keys filtered)
    changes: list[ChangeSet] = field(default_factory=list)


class FactSteps(WriterBase):
    """The batched steps of fact writes (:class:`~toaster.db.writer.store.Store` uses them)."""

    _exact = False  # the next write checks its closes first (after a close found nothing)

    @contextmanager
    def _batch(self) -> Iterator[None]:
        """Statements sent together; an open interval another writer made meanwhile (a
        unique or foreign key of ``facts`` refused) is a stale cache."""
        try:
            with self.backend.batch(self.db.cursor()):
                yield
        except Exception as exc:
            if on_facts(exc):
                raise StaleCache from exc
            raise

    def _send_reads(
        self, agent_id: str, items: list[tuple[Key, Fact]], *, rows: bool = True
    ) -> Reads:
        """Queue what ``items`` need read: new keys inserted (their ids back), the open
        interval and last end of the known ones (``rows``). Inside :meth:`_batch`."""
        key_ids, cursor, backend = self._key_ids, self.db.cursor, self.backend
        missing = [(key, fact) for key, fact in items if (agent_id, key) not in key_ids]
        reads = Reads(items, missing)
        if missing:
            # Keys this process never saw are usually new: insert first, look up the rest.
            self._ensure_entities([fact for _, fact in missing])
            reads.created = backend.insert_keys(
                cursor(), agent_id, [(key, fact.property_type) for key, fact in missing]
            )
        if rows:
            known = [key_ids[(agent_id, key)] for key, _ in items if (agent_id, key) in key_ids]
            if known:  # the ends of keys with an open interval are not read
                reads.open_rows = backend.open_rows(cursor(), known)
                reads.ends = backend.last_ends(cursor(), known)
        return reads

    def _take_reads(self, agent_id: str, reads: Reads, writes: Writes | None) -> None:
        """Remember the ids ``reads`` found; sort its facts into ``writes``: a missing interval
        appears, another symbolic value changes, the rest refreshes. After the batch."""
        created = reads.created() if reads.created is not None else {}
        open_rows = reads.open_rows() if reads.open_rows is not None else {}
        ends = reads.ends() if reads.ends is not None else {}
        if len(created) != len(reads.missing):  # keys another writer (or run) made
            rest = [key for key, _ in reads.missing if key not in created]
            with self._batch():
                later = self.backend.lookup_keys(self.db.cursor(), agent_id, rest)
            found = later()
            if writes is not None and found:
                with self._batch():
                    more_rows = self.backend.open_rows(self.db.cursor(), list(found.values()))
                    more_ends = self.backend.last_ends(self.db.cursor(), list(found.values()))
                open_rows, ends = {**open_rows, **more_rows()}, {**ends, **more_ends()}
            created = {**found, **created}
        for key, key_id in created.items():
            self._key_ids[(agent_id, key)] = key_id
        if writes is not None:
            self._sort(agent_id, reads.items, open_rows, ends, writes)

    def _sort(
        self,
        agent_id: str,
        items: list[tuple[Key, Fact]],
        open_rows: dict[int, tuple[Any, ...]],
        ends: dict[int, int],
        writes: Writes,
    ) -> None:
        t_ns = writes.t_ns
        for key, fact in items:
            key_id = self._key_ids[(agent_id, key)]
            row = open_rows.get(key_id)
            last = row[5] if row is not None else ends.get(key_id)
            if last is not None and last > t_ns:
                msg = (
                    f"{fact.subject_id} {fact.property} {fact.target_id}".rstrip()
                    + f" for {agent_id!r} at {format_ns(t_ns)} is older than its last "
                    f"change ({format_ns(last)}): write each fact in time order"
                )
                raise TimeOrderError(msg)
            if row is None:
                writes.appear(key_id, fact)
            else:
                held = Fact(
                    fact.subject_id,
                    fact.property,
                    fact.target_id,
                    row[0],
                    row[1],
                    row[2],
                    row[3],
                    fact.property_type,
                    fact.sub_property,
                    fact.subject_owner_id,
                    fact.target_owner_id,
                )
                writes.update(key_id, fact, held)

    def _resolve(
        self, conn: Connection, agent_id: str, items: list[tuple[Key, Fact]], writes: Writes
    ) -> None:
        """Compare stated facts with what is stored now (the open interval, whoever wrote it)
        and sort them into ``writes`` (one batch of reads)."""
        if not self.agents().get(agent_id):
            self._detach(conn, agent_id, keep=True)
        with self._batch():
            reads = self._send_reads(agent_id, items)
        self._take_reads(agent_id, reads, writes)

    def _key_id_map(self, agent_id: str, items: list[tuple[Key, Fact]]) -> None:
        """Fill the key-id cache for ``items``."""
        with self._batch():
            reads = self._send_reads(agent_id, items, rows=False)
        self._take_reads(agent_id, reads, None)

    def _send_writes(self, writes: Writes, *, exact: bool) -> Sent:
        """Queue one write's rows. ``exact``: read the refresh's and the closes' answers first
        (a stale cache is found before anything else is written; ended facts another writer
        closed write no event), else assume them (:meth:`_check` after the batch)."""
        cursor, backend, t_ns = self.db.cursor, self.backend, writes.t_ns
        sent = Sent(writes)
        if writes.refreshed:  # first: the refreshed intervals are this source's
            rows = [(f.value_num, f.confidence, f.observability, k) for k, f, _ in writes.refreshed]
            with self._batch() if exact else nullcontext():  # exact: answered here
                sent.refreshed = backend.refresh_intervals(cursor(), t_ns, rows)
            if exact:
                self._check(sent)
        if writes.closing:
            with self._batch() if exact else nullcontext():
                sent.closed = backend.close_intervals(cursor(), t_ns, writes.closing)
            if exact:
                closed = sent.closed()
                sent.closed = None
                # A fact this source held may have been ended by another writer: no event then.
                writes.ended = [(k, f) for k, f in writes.ended if k in closed]
        writes.events[:0] = [writes.event(k, f, "ended", None) for k, f in writes.ended]
        if writes.opening:
            try:
                backend.insert_intervals(cursor(), writes.opening)
            except Exception as exc:  # SQLite: here; PostgreSQL: at the batch's end
                if is_integrity_error(exc):
                    raise StaleCache from exc
                raise
        if writes.events:
            backend.insert_events(cursor(), writes.events)
        if writes.retyped:
            backend.retype_keys(cursor(), writes.retyped)
        if self._rules and not writes.empty:
            changes = writes.change_set()
            for actor in set(changes.actors.values()):
                self._check_actor(actor)
            sent.changes.append(changes)
        return sent

    def _check(self, sent: Sent) -> None:
        """Raise :class:`StaleCache` unless the answers of ``sent`` are what it assumed."""
        writes = sent.writes
        if sent.refreshed is not None:
            if sent.refreshed() != len(writes.refreshed):
                raise StaleCache
            sent.refreshed = None
        if sent.closed is not None:
            closed = sent.closed()
            if any(k not in closed for k, _ in writes.ended):
                self._exact = True  # the next attempt reads its closes first
                raise StaleCache

    def _rules_pipelined(self) -> bool:
        """True when every rule only sends statements (``pipelined``): they may join the
        writes' batch, before their answers are checked."""
        return all(getattr(rule, "pipelined", False) for rule in self._rules)

    def _apply(self, conn: Connection, writes: Writes) -> None:
        """One single write's rows (exact: checks first), then the rules."""
        self.agents()  # read before the batch (the rules ask)
        with self._batch():
            sent = self._send_writes(writes, exact=True)
            if self._rules_pipelined():
                for changes in sent.changes:
                    self._run_rules(conn, changes)
        if not self._rules_pipelined():
            for changes in sent.changes:
                self._run_rules(conn, changes)

    def _run_rules(self, conn: Connection, changes: ChangeSet) -> None:
        for rule in self._rules:
            rule(conn, changes)
