"""SQLite: ``executemany`` for bulk writes, multi-row VALUES for look-ups.

``INDEXED BY uq_facts_open_key`` pins the partial "open interval" index when closing and
refreshing intervals: left alone, SQLite prefers the (key, start) index and runs several times
slower (docs/store.md).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import AbstractContextManager, nullcontext
from typing import TYPE_CHECKING, Any

from toaster.db.dialects.base import LATEST_CLOCK, Clock, Cursor, Key, Later

if TYPE_CHECKING:
    from sqlalchemy import Connection
    from sqlalchemy.engine.interfaces import DBAPIConnection

# SQLite >= 3.32 accepts 32766 bound variables per statement; stay well below.
_MAX_VARS = 30000
_KEY_COLS = "subject_id, subject_owner_id, property, sub_property, target_id, target_owner_id"


def _chunks(items: list[Any], size: int) -> Iterator[list[Any]]:
    for start in range(0, len(items), size):
        yield items[start : start + size]


def _insert_rows(cur: Cursor, head: str, rows: list[tuple[Any, ...]]) -> None:
    """``head VALUES (…), (…)``: one statement per chunk, not one per row.

    The guard triggers give every INSERT into a guarded table a statement journal (a trigger
    may abort the statement), so one statement per row cost about twice the rows' own work.
    """
    if not rows:
        return
    width = len(rows[0])
    marks = "(" + ",".join("?" * width) + ")"
    for chunk in _chunks(rows, _MAX_VARS // width):
        cur.execute(
            f"{head} VALUES {','.join([marks] * len(chunk))}",
            [value for row in chunk for value in row],
        )


class SQLiteBackend:
    """The SQLite implementation of :class:`toaster.db.dialects.Backend`."""

    name = "sqlite"
    as_of_join = (
        "JOIN facts f ON f.id = (SELECT f2.id FROM facts f2 WHERE f2.key_id = {key} "
        "AND f2.valid_from_ns <= :t ORDER BY f2.valid_from_ns DESC, f2.id DESC LIMIT 1)"
    )
    sample_join = (
        "LEFT JOIN fact_samples s ON s.fact_id = {fact} AND s.until_ns = (SELECT "
        "MIN(s2.until_ns) FROM fact_samples s2 WHERE s2.fact_id = {fact} AND s2.until_ns > :t)"
    )
    samples = "fact_samples"  # never packed: a row is one 34-byte b-tree entry here
    least, greatest = "MIN", "MAX"  # two-argument scalar forms

    def named(self, sql: str) -> str:
        return sql  # sqlite3 takes :name as it is

    def batch(self, cur: Cursor) -> AbstractContextManager[None]:
        return nullcontext()  # in-process: no round trip to save

    def lookup_keys(self, cur: Cursor, agent_id: str, keys: list[Key]) -> Later[dict[Key, int]]:
        found: dict[Key, int] = {}
        for chunk in _chunks(keys, _MAX_VARS // 6):
            values = ",".join(["(?,?,?,?,?,?)"] * len(chunk))
            params = [agent_id]
            for key in chunk:
                params.extend(key)
            cur.execute(  # a join on the VALUES list seeks the identity index per key
                f"WITH v(s, so, p, sp, t, tw) AS (VALUES {values[0:]}) "
                f"SELECT k.id, k.subject_id, k.subject_owner_id, k.property, k.sub_property, "
                f"k.target_id, k.target_owner_id FROM v CROSS JOIN fact_keys k "
                f"ON k.agent_id = ? AND k.subject_id = v.s AND k.subject_owner_id = v.so "
                f"AND k.property = v.p AND k.sub_property = v.sp AND k.target_id = v.t "
                f"AND k.target_owner_id = v.tw",
                [*params[1:], params[0]],
            )
            for row in cur.fetchall():
                found[tuple(row[1:])] = row[0]
        return lambda: found

    def insert_keys(
        self, cur: Cursor, agent_id: str, rows: list[tuple[Key, str]]
    ) -> Later[dict[Key, int]]:
        created: dict[Key, int] = {}
        for chunk in _chunks(rows, _MAX_VARS // 8):
            values = ",".join(["(?,?,?,?,?,?,?,?)"] * len(chunk))
            params: list[Any] = []
            for key, property_type in chunk:
                params.append(agent_id)
                params.extend(key)
                params.append(property_type)
            cur.execute(
                f"INSERT INTO fact_keys (agent_id, {_KEY_COLS}, property_type) VALUES {values} "
                f"ON CONFLICT DO NOTHING RETURNING id, {_KEY_COLS}",
                params,
            )
            for row in cur.fetchall():
                created[tuple(row[1:])] = row[0]
        return lambda: created

    def open_rows(self, cur: Cursor, key_ids: list[int]) -> Later[dict[int, tuple[Any, ...]]]:
        found: dict[int, tuple[Any, ...]] = {}
        for chunk in _chunks(key_ids, _MAX_VARS):
            marks = ",".join("?" * len(chunk))
            cur.execute(
                "SELECT key_id, value_text, value_num, confidence, observability, source, "
                f"valid_from_ns FROM facts INDEXED BY uq_facts_open_key WHERE key_id IN ({marks}) "
                "AND valid_to_ns IS NULL",
                chunk,
            )
            for row in cur.fetchall():
                found[row[0]] = tuple(row[1:])
        return lambda: found

    def last_ends(self, cur: Cursor, key_ids: list[int]) -> Later[dict[int, int]]:
        found: dict[int, int] = {}
        for chunk in _chunks(key_ids, _MAX_VARS):
            values = ",".join(["(?)"] * len(chunk))
            cur.execute(
                f"WITH k(id) AS (VALUES {values}) SELECT k.id, (SELECT f.valid_to_ns FROM facts "
                "f WHERE f.key_id = k.id ORDER BY f.valid_from_ns DESC LIMIT 1) FROM k",
                chunk,
            )
            found.update((row[0], row[1]) for row in cur.fetchall() if row[1] is not None)
        return lambda: found

    def close_intervals(self, cur: Cursor, t_ns: int, key_ids: list[int]) -> Later[set[int]]:
        closed: set[int] = set()
        for chunk in _chunks(key_ids, _MAX_VARS):
            marks = ",".join("?" * len(chunk))
            cur.execute(
                "UPDATE facts INDEXED BY uq_facts_open_key SET valid_to_ns = ? "
                f"WHERE key_id IN ({marks}) AND valid_to_ns IS NULL AND valid_from_ns <= ? "
                "RETURNING key_id",
                [t_ns, *chunk, t_ns],
            )
            closed.update(row[0] for row in cur.fetchall())
        return lambda: closed

    def refresh_intervals(self, cur: Cursor, t_ns: int, rows: list[tuple[Any, ...]]) -> Later[int]:
        for chunk in _chunks([row[3] for row in rows], _MAX_VARS):
            marks = ",".join("?" * len(chunk))
            cur.execute(
                "INSERT INTO fact_samples (fact_id, until_ns, value_num, confidence, "
                "observability) SELECT id, ?, value_num, confidence, observability "
                f"FROM facts INDEXED BY uq_facts_open_key WHERE key_id IN ({marks}) "
                "AND valid_to_ns IS NULL ON CONFLICT DO NOTHING",
                [t_ns, *chunk],
            )
        updated = 0
        for chunk in _chunks(rows, _MAX_VARS // 4):
            values = ",".join(["(?,?,?,?)"] * len(chunk))
            cur.execute(
                "UPDATE facts INDEXED BY uq_facts_open_key SET value_num = v.column1, "
                f"confidence = v.column2, observability = v.column3 FROM (VALUES {values}) v "
                "WHERE facts.key_id = v.column4 AND facts.valid_to_ns IS NULL",
                [value for row in chunk for value in row],
            )
            updated += cur.rowcount
        return lambda: updated

    def insert_intervals(self, cur: Cursor, rows: list[tuple[Any, ...]]) -> None:
        _insert_rows(
            cur,
            "INSERT INTO facts (key_id, value_text, value_num, confidence, "
            "observability, valid_from_ns, recorded_ns, source)",
            rows,
        )

    def insert_events(self, cur: Cursor, rows: list[tuple[Any, ...]]) -> None:
        _insert_rows(
            cur,
            "INSERT INTO events (key_id, agent_id, kind, stamp_ns, value_text, "
            "value_num, confidence, observability, previous_text, source, "
            "recorded_ns)",
            rows,
        )

    def retype_keys(self, cur: Cursor, rows: list[tuple[int, str]]) -> None:
        cur.executemany(
            "UPDATE fact_keys SET property_type = ? WHERE id = ?", [(p, k) for k, p in rows]
        )

    def insert_entities(self, cur: Cursor, rows: list[tuple[str, str, int]]) -> None:
        cur.executemany(
            "INSERT INTO entities (id, name, kind, owner_id, created_ns) "
            "VALUES (?, ?, '', ?, ?) ON CONFLICT DO NOTHING",
            [(entity_id, entity_id, owner, t) for entity_id, owner, t in rows],
        )

    def vacuum_scratch(self, raw: DBAPIConnection) -> None:
        """Nothing to do: SQLite's scratch tables are the schema's, emptied by each run."""

    def maintain(self, raw: DBAPIConnection, *, beside_writer: bool = False) -> None:
        cur = raw.cursor()
        if beside_writer:
            # optimize writes statistics under the write lock: a bounded sample keeps that
            # short; a passive checkpoint copies what no reader needs and waits for nobody
            # (a truncating one waits for the writer and then holds it off)
            cur.execute("PRAGMA analysis_limit=400")
            cur.execute("PRAGMA optimize")
            cur.execute("PRAGMA wal_checkpoint(PASSIVE)")
        else:
            cur.execute("PRAGMA optimize")  # may write statistics: before the checkpoint
            cur.execute("PRAGMA wal_checkpoint(TRUNCATE)")  # the WAL back to zero bytes
        cur.close()

    def set_page_cache(self, raw: DBAPIConnection, kib: int) -> None:
        cur = raw.cursor()
        cur.execute(f"PRAGMA cache_size=-{int(kib)}")
        cur.close()

    def begin_writes(
        self, cur: Cursor, *, clock: str | None = None, begin: bool = False
    ) -> tuple[int, int, Clock | None]:
        # One writer at a time in SQLite: a row in rule_writer, deleted before the commit,
        # is seen only by this transaction (whose write lock also holds the clock).
        cur.execute("INSERT OR IGNORE INTO rule_writer (id, holder) VALUES (1, 'store')")
        epoch, agents, clock_ns, clock_self = cur.execute(
            "SELECT s.cache_epoch, s.agents_version, c.clock_ns, c.clock_self FROM store_state s "
            f"LEFT JOIN ({LATEST_CLOCK}) c ON 1 = 1 WHERE s.id = 1",
            {"agent": clock or ""},
        ).fetchone()
        return int(epoch), int(agents), (clock_ns, clock_self) if clock else None

    def end_writes(self, cur: Cursor) -> None:
        cur.execute("DELETE FROM rule_writer")

    def after_writes(self, cur: Cursor) -> None:
        """Nothing to undo: SQLAlchemy began the transaction (BEGIN IMMEDIATE)."""

    def set_read_only(self, cur: Cursor) -> None:
        cur.execute("PRAGMA query_only = ON")

    def clear_read_only(self, cur: Cursor) -> None:
        cur.execute("PRAGMA query_only = OFF")

    def lock_registrations(self, conn: Connection) -> None:
        """Nothing to take: a SQLite writer holds the database's one write lock."""
