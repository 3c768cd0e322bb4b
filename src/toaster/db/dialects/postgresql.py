"""PostgreSQL (psycopg 3): each bulk operation is one statement over ``unnest`` arrays.

Each round trip costs a fixed latency, so a tick issues a handful of statements whatever its
size, and sends them in batches (:meth:`PostgreSQLBackend.batch`: psycopg's pipeline mode),
each answered in one round trip. Arrays travel in binary (``%b``): psycopg's text-array quoting
costs time per element (figures: docs/store.md).
"""

from __future__ import annotations

import functools
import re
from collections.abc import Iterator
from contextlib import AbstractContextManager, closing, contextmanager, nullcontext
from typing import TYPE_CHECKING, Any

from toaster.db.dialects.base import LATEST_CLOCK, Clock, Cursor, Key, Later

if TYPE_CHECKING:
    from sqlalchemy import Connection
    from sqlalchemy.engine.interfaces import DBAPIConnection


@contextmanager
def _autocommit(raw: DBAPIConnection) -> Iterator[Cursor]:
    """A cursor of the idle DBAPI connection ``raw`` outside any transaction (VACUUM cannot
    run in a transaction block)."""
    raw.autocommit = True
    try:
        with closing(raw.cursor()) as cur:  # what psycopg's own __exit__ does
            yield cur
    finally:
        raw.autocommit = False


_NAMED = re.compile(r"(?<![:\w]):(\w+)")
_IDLE = 0  # psycopg.pq.TransactionStatus.IDLE: no transaction open


@functools.cache
def _pipelines() -> bool:
    """psycopg's pipeline mode works (its libpq is 14 or later)."""
    import psycopg

    return bool(psycopg.Pipeline.is_supported())


#: Samples a row of ``fact_sample_blocks`` holds: the most whose row (40 bytes and four arrays
#: of 24 + 8 × BLOCK) stays under PostgreSQL's 2,032-byte TOAST threshold, four to a page.
BLOCK = 59
#: An open interval's samples but its newest, oldest first, in whole blocks (the newest stays a
#: row: a second refresh at its instant meets ``ON CONFLICT``); ``fact_samples`` keeps under
#: BLOCK + 1 rows of an interval, and a closed one's last rows.
_PACK = f"""WITH open AS (SELECT f.id FROM facts f WHERE f.valid_to_ns IS NULL),
numbered AS (SELECT s.fact_id, s.until_ns, row_number() OVER (PARTITION BY s.fact_id
  ORDER BY s.until_ns) AS n, count(*) OVER (PARTITION BY s.fact_id) AS rows
  FROM fact_samples s WHERE s.fact_id IN (SELECT id FROM open)),
moved AS (DELETE FROM fact_samples s USING numbered x WHERE s.fact_id = x.fact_id
  AND s.until_ns = x.until_ns AND x.n <= (x.rows - 1) / {BLOCK} * {BLOCK}
  RETURNING s.*, (x.n - 1) / {BLOCK} AS block)
INSERT INTO fact_sample_blocks (fact_id, until_ns, untils_ns, value_nums, confidences,
  observabilities) SELECT fact_id, max(until_ns), array_agg(until_ns ORDER BY until_ns),
  array_agg(value_num ORDER BY until_ns), array_agg(confidence ORDER BY until_ns),
  array_agg(observability ORDER BY until_ns) FROM moved GROUP BY fact_id, block"""


def pack_samples(raw: DBAPIConnection) -> int:
    """Move open intervals' older samples into blocks (one transaction on the idle
    connection ``raw``, as the store's writer); the number of blocks written."""
    with closing(raw.cursor()) as cur:
        try:
            cur.execute("SELECT set_config('toaster.writer', 'rules', true)")
            cur.execute(_PACK)
            blocks = cur.rowcount
        except BaseException:
            raw.rollback()
            raise
        raw.commit()
    return int(blocks)


_KEY_COLS = "subject_id, subject_owner_id, property, sub_property, target_id, target_owner_id"
_KEY_ARRAYS = "%b::text[], %b::text[], %b::text[], %b::text[], %b::text[], %b::text[]"


def _columns(rows: list[tuple[Any, ...]], width: int) -> list[list[Any]]:
    if not rows:
        return [[] for _ in range(width)]
    return [list(column) for column in zip(*rows, strict=True)]


class PostgreSQLBackend:
    """The PostgreSQL implementation of :class:`toaster.db.dialects.Backend`."""

    name = "postgresql"
    as_of_join = (  # LATERAL fetches the row in the seek itself (no second look-up by id)
        "CROSS JOIN LATERAL (SELECT * FROM facts f2 WHERE f2.key_id = {key} "
        "AND f2.valid_from_ns <= :t ORDER BY f2.valid_from_ns DESC, f2.id DESC LIMIT 1) f"
    )
    # the first sample after :t among the rows and in the first block ending after it (its
    # element after :t: width_bucket counts the block's times at or before :t)
    sample_join = (
        "LEFT JOIN LATERAL (SELECT s3.value_num, s3.confidence, s3.observability FROM ("
        "(SELECT s2.until_ns, s2.value_num, s2.confidence, s2.observability "
        "FROM fact_samples s2 WHERE s2.fact_id = {fact} AND s2.until_ns > :t "
        "ORDER BY s2.until_ns LIMIT 1) UNION ALL (SELECT b.untils_ns[b.i], b.value_nums[b.i], "
        "b.confidences[b.i], b.observabilities[b.i] FROM (SELECT b2.*, "
        "width_bucket(:t, b2.untils_ns) + 1 AS i FROM fact_sample_blocks b2 "
        "WHERE b2.fact_id = {fact} AND b2.until_ns > :t ORDER BY b2.until_ns LIMIT 1) b)"
        ") s3 ORDER BY s3.until_ns LIMIT 1) s ON true"
    )
    samples = (
        "(SELECT fact_id, until_ns, value_num, confidence, observability FROM fact_samples "
        "UNION ALL SELECT b.fact_id, u.* FROM fact_sample_blocks b CROSS JOIN LATERAL unnest("
        "b.untils_ns, b.value_nums, b.confidences, b.observabilities) AS u(until_ns, "
        "value_num, confidence, observability))"
    )
    least, greatest = "LEAST", "GREATEST"
    _begun: Any = None  # the connection begin_writes put in autocommit mode (after_writes)

    def named(self, sql: str) -> str:
        return _NAMED.sub(r"%(\1)s", sql)

    def batch(self, cur: Cursor) -> AbstractContextManager[None]:
        if not _pipelines():  # a libpq older than 14: one round trip per statement
            return nullcontext()
        pipeline: AbstractContextManager[None] = cur.connection.pipeline()  # type: ignore[attr-defined]
        return pipeline

    def lookup_keys(self, cur: Cursor, agent_id: str, keys: list[Key]) -> Later[dict[Key, int]]:
        cur.execute(
            f"SELECT k.id, k.subject_id, k.subject_owner_id, k.property, k.sub_property, "
            f"k.target_id, k.target_owner_id FROM unnest({_KEY_ARRAYS}) "
            "AS u(s, so, p, sp, t, tow) JOIN fact_keys k ON k.agent_id = %s "
            "AND k.subject_id = u.s AND k.subject_owner_id = u.so AND k.property = u.p "
            "AND k.sub_property = u.sp AND k.target_id = u.t AND k.target_owner_id = u.tow",
            [*_columns(keys, 6), agent_id],
        )
        return lambda: {tuple(row[1:]): row[0] for row in cur.fetchall()}

    def insert_keys(
        self, cur: Cursor, agent_id: str, rows: list[tuple[Key, str]]
    ) -> Later[dict[Key, int]]:
        keys = [key for key, _ in rows]
        cur.execute(
            f"INSERT INTO fact_keys (agent_id, {_KEY_COLS}, property_type) "
            f"SELECT %s, u.* FROM unnest({_KEY_ARRAYS}, %b::text[]) AS u "
            f"ON CONFLICT DO NOTHING RETURNING id, {_KEY_COLS}",
            [agent_id, *_columns(keys, 6), [ptype for _, ptype in rows]],
        )
        return lambda: {tuple(row[1:]): row[0] for row in cur.fetchall()}

    def open_rows(self, cur: Cursor, key_ids: list[int]) -> Later[dict[int, tuple[Any, ...]]]:
        cur.execute(
            "SELECT key_id, value_text, value_num, confidence, observability, source, "
            "valid_from_ns FROM facts WHERE key_id = ANY(%b::bigint[]) AND valid_to_ns IS NULL",
            [key_ids],
        )
        return lambda: {row[0]: tuple(row[1:]) for row in cur.fetchall()}

    def last_ends(self, cur: Cursor, key_ids: list[int]) -> Later[dict[int, int]]:
        cur.execute(
            "SELECT k, (SELECT f.valid_to_ns FROM facts f WHERE f.key_id = k "
            "ORDER BY f.valid_from_ns DESC LIMIT 1) FROM unnest(%b::bigint[]) AS k",
            [key_ids],
        )
        return lambda: {row[0]: row[1] for row in cur.fetchall() if row[1] is not None}

    def close_intervals(self, cur: Cursor, t_ns: int, key_ids: list[int]) -> Later[set[int]]:
        cur.execute(
            "UPDATE facts SET valid_to_ns = %s WHERE key_id = ANY(%b::bigint[]) "
            "AND valid_to_ns IS NULL AND valid_from_ns <= %s RETURNING key_id",
            [t_ns, key_ids, t_ns],
        )
        return lambda: {row[0] for row in cur.fetchall()}

    def refresh_intervals(self, cur: Cursor, t_ns: int, rows: list[tuple[Any, ...]]) -> Later[int]:
        # The CTEs and the UPDATE see the same snapshot: the samples get the values before.
        cur.execute(
            "WITH u AS (SELECT * FROM unnest(%b::float8[], %b::float8[], %b::float8[], "
            "%b::bigint[]) AS u(n, c, o, k)), "
            "kept AS (INSERT INTO fact_samples (fact_id, until_ns, value_num, confidence, "
            "observability) SELECT f.id, %b, f.value_num, f.confidence, f.observability "
            "FROM facts f JOIN u ON f.key_id = u.k AND f.valid_to_ns IS NULL "
            "ON CONFLICT DO NOTHING) "
            "UPDATE facts f SET value_num = u.n, confidence = u.c, observability = u.o "
            "FROM u WHERE f.key_id = u.k AND f.valid_to_ns IS NULL",
            [*_columns(rows, 4), t_ns],
        )
        return lambda: cur.rowcount

    def insert_intervals(self, cur: Cursor, rows: list[tuple[Any, ...]]) -> None:
        cur.execute(
            "INSERT INTO facts (key_id, value_text, value_num, confidence, observability, "
            "valid_from_ns, recorded_ns, source) SELECT * FROM unnest(%b::bigint[], %b::text[], "
            "%b::float8[], %b::float8[], %b::float8[], %b::bigint[], %b::bigint[], %b::text[])",
            _columns(rows, 8),
        )

    def insert_events(self, cur: Cursor, rows: list[tuple[Any, ...]]) -> None:
        cur.execute(
            "INSERT INTO events (key_id, agent_id, kind, stamp_ns, value_text, value_num, "
            "confidence, observability, previous_text, source, recorded_ns) SELECT * FROM "
            "unnest(%b::bigint[], %b::text[], %b::text[], %b::bigint[], %b::text[], %b::float8[], "
            "%b::float8[], %b::float8[], %b::text[], %b::text[], %b::bigint[])",
            _columns(rows, 11),
        )

    def retype_keys(self, cur: Cursor, rows: list[tuple[int, str]]) -> None:
        cur.execute(
            "UPDATE fact_keys k SET property_type = u.p FROM unnest(%b::bigint[], %b::text[]) "
            "AS u(k, p) WHERE k.id = u.k",
            _columns(rows, 2),
        )

    def insert_entities(self, cur: Cursor, rows: list[tuple[str, str, int]]) -> None:
        cur.execute(
            "INSERT INTO entities (id, name, kind, owner_id, created_ns) SELECT u.i, u.i, '', "
            "u.o, u.t FROM unnest(%b::text[], %b::text[], %b::bigint[]) AS u(i, o, t) "
            "ON CONFLICT DO NOTHING",
            _columns(rows, 3),
        )

    def maintain(self, raw: DBAPIConnection, *, beside_writer: bool = False) -> None:
        # Packing deletes only rows that no refresh writes again, and VACUUM takes a lock that
        # only schema changes and other vacuums wait for: the same statements serve beside a
        # writer
        pack_samples(raw)
        with _autocommit(raw) as cur:
            cur.execute(
                "VACUUM (ANALYZE) facts, fact_samples, fact_sample_blocks, events, fact_keys, "
                "belief_follow"
            )

    def set_page_cache(self, raw: DBAPIConnection, kib: int) -> None:
        """Nothing to bound: the server holds the page cache (shared_buffers)."""

    def vacuum_scratch(self, raw: DBAPIConnection) -> None:
        with _autocommit(raw) as cur:
            cur.execute(
                "SELECT c.relname FROM pg_class c WHERE c.relnamespace = "
                "pg_my_temp_schema() AND c.relkind = 'r' ORDER BY c.relname"
            )
            names = [row[0] for row in cur.fetchall()]
            if names:  # the session's temporary tables: the scratch tables (00_temp)
                cur.execute("VACUUM " + ", ".join(f'pg_temp."{name}"' for name in names))

    def begin_writes(
        self, cur: Cursor, *, clock: str | None = None, begin: bool = False
    ) -> tuple[int, int, Clock | None]:
        # A transaction-local setting: other sessions never see it; one round trip in all.
        # The clocks are not locked here: the run locks its own holders' (pipeline.CLOCK).
        header = (
            "SELECT s.cache_epoch, s.agents_version, "
            "set_config('toaster.writer', 'rules', true), "
            + (
                f"c.clock_ns, c.clock_self FROM store_state s LEFT JOIN "
                f"({self.named(LATEST_CLOCK)}) c ON true WHERE s.id = 1"
                if clock
                else "NULL, NULL FROM store_state s WHERE s.id = 1"
            )
        )
        params = {"agent": clock} if clock else None
        raw: Any = cur.connection  # type: ignore[attr-defined]
        if begin and _pipelines() and not raw.autocommit and raw.info.transaction_status == _IDLE:
            # psycopg would send its own BEGIN and wait for it: sent with the header instead,
            # the connection in autocommit mode (no BEGIN of psycopg's) until after_writes
            raw.autocommit = True
            self._begun = raw
            with raw.pipeline():
                raw.execute("BEGIN")
                cur.execute(header, params)
        else:
            cur.execute(header, params)
        epoch, agents, _, beliefs_ns, beliefs_self = cur.fetchone()
        return int(epoch), int(agents), (beliefs_ns, beliefs_self) if clock else None

    def end_writes(self, cur: Cursor) -> None:
        """Nothing to do: the setting ends with the transaction."""

    def after_writes(self, cur: Cursor) -> None:
        raw: Any = cur.connection  # type: ignore[attr-defined]
        if self._begun is raw and raw.info.transaction_status == _IDLE:
            raw.autocommit = False  # (a broken connection is left to be replaced)
        self._begun = None

    def set_read_only(self, cur: Cursor) -> None:
        cur.execute("SET TRANSACTION READ ONLY")

    def clear_read_only(self, cur: Cursor) -> None:
        """Nothing to undo: the setting ends with the transaction."""

    def lock_registrations(self, conn: Connection) -> None:
        conn.exec_driver_sql(
            "SELECT pg_advisory_xact_lock(hashtext('toaster agents ' || current_schema()))"
        )
