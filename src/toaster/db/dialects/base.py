"""What every backend shares: the fact key, the guarded tables, the ``Backend`` interface and
the ``Cursor`` it is handed.

The backend modules import this one, not the package (whose ``backend_for`` imports them).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from typing import TYPE_CHECKING, Any, Protocol, TypeAlias, TypeVar

if TYPE_CHECKING:
    from sqlalchemy import Connection
    from sqlalchemy.engine.interfaces import DBAPIConnection

#: Natural key of a fact without the agent: subject, subject owner, property, sub-property,
#: target, target owner.
Key = tuple[str, str, str, str, str, str]

_T = TypeVar("_T")
#: A statement's result, read when called: inside :meth:`Backend.batch` the statement is only
#: queued, so call it after the batch (PostgreSQL: calling it inside waits for the server).
Later: TypeAlias = Callable[[], _T]
#: The rules' clock as a write transaction found it: ``(clock_ns, clock_self)``.
Clock = tuple[int | None, str | None]
#: The latest clock of the self agent ``:agent`` and of the holders its facts name (revision
#: 0028: a clock per holder; the self's own since 0031), read without a lock: a snapshot
#: stamps its rows there when it is a little behind (Store._writes); its run takes its own
#: holders' clocks (toaster.rules.pipeline.CLOCK) and waits only for the runs that share one
#: of them. (A nested holder's clock is never ahead of all its agents': the runs that move it
#: move theirs.) None found (a robot's first snapshot: its keys name nobody yet): the store
#: reads the clocks of the holders the snapshot's facts name (Store._writes).
LATEST_CLOCK = (
    "SELECT h.clock_ns, h.clock_self FROM holders h WHERE h.depth = 1 "
    "AND h.clock_ns IS NOT NULL "
    "AND (h.id = :agent "
    "OR EXISTS (SELECT 1 FROM fact_keys k WHERE k.subject_id = h.id AND k.agent_id = :agent) "
    "OR EXISTS (SELECT 1 FROM fact_keys k WHERE k.target_id = h.id AND k.agent_id = :agent)) "
    "ORDER BY h.clock_ns DESC LIMIT 1"
)


#: Tables only toaster's store and rules write (the guard triggers of migration 0006 refuse
#: any other write), and the one-line error a direct write gets.
GUARDED_TABLES = (
    "fact_keys",
    "facts",
    "events",
    "fact_samples",
    "fact_sample_blocks",
    "belief_follow",
    "belief_chain",
    "belief_groups",
    "belief_perceived",
    "belief_settled",
)
GUARD_MESSAGE = (
    "{table} is kept by toaster's store and belief rules and cannot be written "
    "directly: write facts by inserting rows into fact_inbox (or with toaster "
    "set-info); see docs/beliefs.md, Writing facts from SQL"
)


class Cursor(Protocol):
    """The part of a raw PEP 249 cursor toaster calls (sqlite3 or psycopg 3): statements in
    the driver's own parameter style, rows as tuples; ``execute`` returns the cursor."""

    @property
    def description(self) -> Sequence[Sequence[Any]] | None:
        """One sequence per result column, its name first; None without a result."""

    @property
    def rowcount(self) -> int:
        """Rows the last statement changed (-1: not known)."""

    def execute(self, operation: str, parameters: Any = ..., /) -> Any:
        """Run one statement."""

    def executemany(self, operation: str, seq_of_parameters: Any, /) -> Any:
        """Run one statement once per parameter set."""

    def fetchone(self) -> Any:
        """The next row (a tuple), None after the last."""

    def fetchall(self) -> Sequence[Any]:
        """The remaining rows (tuples)."""

    def close(self) -> None:
        """Release the cursor."""


class Backend(Protocol):
    """What the store needs from a backend; ``cur`` is a raw DBAPI cursor in a transaction."""

    name: str
    #: FROM-clause fragment joining the key ``{key}`` (a format field: ``k.id``,
    #: ``w.self_key``) to its interval ``f`` starting last at or before ``:t`` (the per-key
    #: seek behind every as-of query).
    as_of_join: str
    #: FROM-clause fragment joining ``s``, the first sample of the interval ``{fact}`` after
    #: ``:t`` (its numbers then), or NULLs when there is none (the interval's own hold).
    sample_join: str
    #: FROM-able relation of every sample ``(fact_id, until_ns, value_num, confidence,
    #: observability)``, rows and PostgreSQL's packed blocks alike.
    samples: str
    #: The two-argument scalar minimum and maximum (``MIN``/``MAX`` or ``LEAST``/``GREATEST``).
    least: str
    greatest: str

    def named(self, sql: str) -> str:
        """``sql`` with ``:name`` placeholders rewritten to the driver's named style."""

    def batch(self, cur: Cursor) -> AbstractContextManager[None]:
        """Statements run inside are sent together and answered at the end (PostgreSQL's
        pipeline mode: one round trip; SQLite runs them as they come); a batch inside another
        is answered at its own end. Only raw cursor statements, whose results are read after
        the batch (:data:`Later`); an error of any of them is raised when the batch ends."""

    def lookup_keys(self, cur: Cursor, agent_id: str, keys: list[Key]) -> Later[dict[Key, int]]:
        """Ids of the given keys of ``agent_id`` that exist."""

    def insert_keys(
        self, cur: Cursor, agent_id: str, rows: list[tuple[Key, str]]
    ) -> Later[dict[Key, int]]:
        """Insert ``(key, property_type)`` rows (skipping existing ones); their ids."""

    def open_rows(self, cur: Cursor, key_ids: list[int]) -> Later[dict[int, tuple[Any, ...]]]:
        """Open intervals of these keys: key_id -> (value_text, value_num, confidence,
        observability, source, valid_from_ns)."""

    def last_ends(self, cur: Cursor, key_ids: list[int]) -> Later[dict[int, int]]:
        """key_id -> the end of its last interval, for the keys whose last one is closed."""

    def close_intervals(self, cur: Cursor, t_ns: int, key_ids: list[int]) -> Later[set[int]]:
        """Close the open interval of each key at ``t_ns`` (one that started after ``t_ns``
        stays open: a later write opened it); the keys closed."""

    def refresh_intervals(self, cur: Cursor, t_ns: int, rows: list[tuple[Any, ...]]) -> Later[int]:
        """``(value_num, confidence, observability, key_id)``: refresh open intervals in
        place, keeping the numbers they held as a ``fact_samples`` row until ``t_ns`` (a second
        refresh at the same time keeps the first sample); how many were refreshed."""

    def insert_intervals(self, cur: Cursor, rows: list[tuple[Any, ...]]) -> None:
        """``(key_id, value_text, value_num, confidence, observability, valid_from_ns,
        recorded_ns, source)``: open new intervals."""

    def insert_events(self, cur: Cursor, rows: list[tuple[Any, ...]]) -> None:
        """``(key_id, agent_id, kind, stamp_ns, value_text, value_num, confidence,
        observability, previous_text, source, recorded_ns)``: append events."""

    def retype_keys(self, cur: Cursor, rows: list[tuple[int, str]]) -> None:
        """``(key_id, property_type)``: a key's facts changed their type."""

    def insert_entities(self, cur: Cursor, rows: list[tuple[str, str, int]]) -> None:
        """``(id, owner_id, created_ns)``: register entities (kind '') unless they exist."""

    def maintain(self, raw: DBAPIConnection, *, beside_writer: bool = False) -> None:
        """Housekeeping of long runs on an idle DBAPI connection ``raw`` (no transaction);
        ``beside_writer``: on a connection of its own while a writer goes on, so nothing
        that would make the writer wait (:mod:`toaster.db.maintenance`)."""

    def set_page_cache(self, raw: DBAPIConnection, kib: int) -> None:
        """Bound the page cache of the DBAPI connection ``raw`` to ``kib`` KiB (a no-op
        where the server holds the cache)."""

    def vacuum_scratch(self, raw: DBAPIConnection) -> None:
        """Reclaim the dead rows of the session's scratch tables of the belief rule on an idle
        DBAPI connection ``raw`` (a no-op where they are emptied otherwise)."""

    def set_read_only(self, cur: Cursor) -> None:
        """Make the current transaction read-only, enforced by the database."""

    def begin_writes(
        self, cur: Cursor, *, clock: str | None = None, begin: bool = False
    ) -> tuple[int, int, Clock | None]:
        """Open a store write: take the rules' writer role (the guard triggers of the
        internal tables let this transaction through) and return ``store_state``'s
        ``(cache_epoch, agents_version, clock)``; with ``clock`` (a self agent), the latest
        clock of its holders too (:data:`LATEST_CLOCK`, not locked; else None).
        ``begin``: nothing was sent in the transaction yet, it may begin with this statement
        (call :meth:`after_writes` once it ended)."""

    def end_writes(self, cur: Cursor) -> None:
        """Give the writer role back before the commit (see :data:`GUARD_MESSAGE`)."""

    def after_writes(self, cur: Cursor) -> None:
        """Once a transaction begun by ``begin_writes(begin=True)`` ended (committed or
        rolled back): the connection as it was before."""

    def clear_read_only(self, cur: Cursor) -> None:
        """Undo :meth:`set_read_only` for a pooled connection."""

    def lock_registrations(self, conn: Connection) -> None:
        """Hold, until the transaction ends, the lock under which agents are numbered (a
        no-op where writers already take turns)."""


def insert_with_conflicts(dialect_name: str) -> Any:
    """SQLAlchemy's ``insert`` of the dialect, with ``on_conflict_do_update`` /
    ``on_conflict_do_nothing`` (both backends spell the clause alike)."""
    if dialect_name == "postgresql":
        from sqlalchemy.dialects.postgresql import insert as postgresql_insert

        return postgresql_insert
    from sqlalchemy.dialects.sqlite import insert as sqlite_insert

    return sqlite_insert
