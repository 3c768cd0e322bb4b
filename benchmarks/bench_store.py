"""Benchmark of the temporal fact store (issue 2), on a SQLite file (WAL) and on PostgreSQL.

For each backend, in one run:

* snapshot sync: 10,000-fact snapshots, 5 % of them changing per tick (a third symbolic value
  changes, a third ended, a third appearing): changed facts persisted per second with all their
  rows (interval closed and opened, event), and rows written per second as a fraction of the
  raw limit measured by the same script (plain batched inserts of as many rows with the bare
  driver, one transaction per tick);
* the naive baseline: one autocommitted statement at a time per change (the original's way);
* a tick with no change; the current value of one fact through the Python API;
* as-of: all beliefs of one agent at time t in a memory of 1M rows, against a plain b-tree
  scan on (agent, start) over the same rows: the median of 200 calls at random agents and
  times (PostgreSQL plans the statement for its first 5 calls on a connection, then keeps a
  generic plan).

The memory is written by the store itself (a change of every key every 1,000 ns), so filling
1M rows takes a minute or two per backend; then it is maintained as a running node maintains
it (``Database.maintain``: PostgreSQL vacuums the dead row versions of the closed
intervals). ``--quick``: 2,000-fact snapshots, 10,000 memory rows, a smoke run of seconds
(tests/test_benchmarks.py).

Usage: ``python benchmarks/bench_store.py [--quick] [--backend sqlite|postgresql] [--pg URL]
[--only sync|as-of]``.
Medians of repeated runs; compare ratios, not absolute times (these machines are noisy).
"""

from __future__ import annotations

import argparse
import random
import statistics
import sys
import tempfile
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import toaster
from toaster import Fact
from toaster import queries as q
from toaster.db.engine import make_engine

PG_URL = "postgresql+psycopg://postgres@127.0.0.1:5432/test"
AGENT = "R"


@contextmanager
def database(backend: str, pg_url: str = PG_URL) -> Iterator[toaster.Database]:
    """A fresh database at head: a SQLite file in a temp dir or a private PostgreSQL schema."""
    if backend == "sqlite":
        with tempfile.TemporaryDirectory() as folder:
            db = toaster.connect(f"sqlite:///{Path(folder) / 'bench.db'}")
            try:
                yield db
            finally:
                db.close()
        return
    schema = f"bench_{uuid.uuid4().hex[:10]}"
    admin = make_engine(pg_url)
    with admin.begin() as conn:
        conn.exec_driver_sql(f'CREATE SCHEMA "{schema}"')
    sep = "&" if "?" in pg_url else "?"
    db = toaster.connect(f"{pg_url}{sep}options=-csearch_path%3D{schema}")
    try:
        yield db
    finally:
        db.close()
        with admin.begin() as conn:
            conn.exec_driver_sql(f'DROP SCHEMA "{schema}" CASCADE')
        admin.dispose()


def snapshots(n_facts: int, ticks: int, rate: float, seed: int = 1) -> list[list[Fact]]:
    """Snapshots of ``n_facts`` facts where ``rate`` of them change each tick."""
    rng = random.Random(seed)
    values = ("far", "medium", "close")
    live = {
        i: Fact(f"E{i % 500}", "Distance", f"T{i}", values[0], 1.0, 0.9, sub_property="3D")
        for i in range(n_facts)
    }
    next_id = n_facts
    out = [list(live.values())]
    per_kind = max(1, int(n_facts * rate) // 3)
    for _ in range(ticks):
        ids = rng.sample(sorted(live), 2 * per_kind)
        for i in ids[:per_kind]:  # symbolic value changes
            fact = live[i]
            live[i] = fact._replace(value_text=values[(values.index(fact.value_text) + 1) % 3])
        for i in ids[per_kind:]:  # ended
            del live[i]
        for _ in range(per_kind):  # appeared
            live[next_id] = Fact(
                f"E{next_id % 500}", "Distance", f"T{next_id}", "far", 2.0, 0.9, sub_property="3D"
            )
            next_id += 1
        out.append(list(live.values()))
    return out


def median_ms(samples: list[float]) -> float:
    return statistics.median(samples) * 1000


def bench_sync(db: toaster.Database, snaps: list[list[Fact]]) -> dict[str, float]:
    """Snapshot sync: changed facts/s, rows/s, no-change tick."""
    store = db.store()
    store.add_entity(AGENT, "robot", is_self=True)
    store.sync_snapshot("bench", AGENT, 0, snaps[0])
    times, changed, rows = [], 0, 0
    for tick, snap in enumerate(snaps[1:], start=1):
        start = time.perf_counter()
        result = store.sync_snapshot("bench", AGENT, tick * 1000, snap)
        times.append(time.perf_counter() - start)
        changed += result.appeared + result.changed + result.ended
        # rows: appeared = interval + event; changed = close + interval + event;
        # ended = close + event
        rows += 2 * result.appeared + 3 * result.changed + 2 * result.ended
    quiet = []
    for tick in range(30):
        start = time.perf_counter()
        store.sync_snapshot("bench", AGENT, (len(snaps) + tick) * 1000, snaps[-1])
        quiet.append(time.perf_counter() - start)
    per_tick = statistics.median(times)
    return {
        "changed_per_s": changed / len(times) / per_tick,
        "rows_per_s": rows / len(times) / per_tick,
        "rows_per_tick": rows / len(times),
        "tick_ms": per_tick * 1000,
        "quiet_ms": median_ms(quiet),
    }


def raw_limit(db: toaster.Database, rows_per_tick: int, ticks: int = 15) -> float:
    """Plain batched inserts of fact-shaped rows with the bare driver, one commit per tick."""
    raw = db.engine.raw_connection()
    cur = raw.cursor()
    sqlite = db.dialect_name == "sqlite"
    cur.execute(
        "CREATE TABLE raw_rows (id INTEGER PRIMARY KEY, key_id BIGINT NOT NULL, "
        "value_text TEXT, value_num DOUBLE PRECISION, confidence DOUBLE PRECISION, "
        "valid_from_ns BIGINT, source TEXT)"
        if not sqlite
        else "CREATE TABLE raw_rows (id INTEGER PRIMARY KEY, key_id INTEGER NOT NULL, "
        "value_text TEXT, value_num REAL, confidence REAL, valid_from_ns INTEGER, "
        "source TEXT)"
    )
    cur.execute("CREATE UNIQUE INDEX raw_rows_key ON raw_rows (key_id, valid_from_ns)")
    raw.commit()
    times, key = [], 0
    for tick in range(ticks):
        batch = [(key + i, "far", 1.0, 0.9, tick, "bench") for i in range(rows_per_tick)]
        key += rows_per_tick
        start = time.perf_counter()
        if sqlite:
            cur.execute("BEGIN")
            cur.executemany(
                "INSERT INTO raw_rows (key_id, value_text, value_num, confidence, "
                "valid_from_ns, source) VALUES (?,?,?,?,?,?)",
                batch,
            )
        else:
            cols = [list(c) for c in zip(*batch, strict=True)]
            cur.execute(
                "INSERT INTO raw_rows (id, key_id, value_text, value_num, confidence, "
                "valid_from_ns, source) SELECT k, k, v, n, c, f, s FROM "
                "unnest(%s::bigint[], %s::text[], %s::float8[], %s::float8[], "
                "%s::bigint[], %s::text[]) AS u(k, v, n, c, f, s)",
                cols,
            )
        raw.commit()
        times.append(time.perf_counter() - start)
    cur.execute("DROP TABLE raw_rows")
    raw.commit()
    raw.close()
    return rows_per_tick / statistics.median(times)


def raw_same_tables(db: toaster.Database, rows_per_tick: int, ticks: int = 15) -> float:
    """Bare-driver batched inserts into toaster's own ``facts`` and ``events`` tables (same
    indexes, same guard), half each, one commit per tick: the ceiling for rows written by the
    store. Each tick takes the store's writer role and uses the store's own insert statements
    (``Backend.begin_writes``, ``insert_intervals``, ``insert_events``), without its diff."""
    raw = db.engine.raw_connection()
    cur = raw.cursor()
    backend = db.backend
    half = max(1, rows_per_tick // 2)
    times, key = [], 50_000_000
    for tick in range(ticks):
        facts = [(key + i, "far", 1.0, 0.9, 1.0, tick, 0, "raw") for i in range(half)]
        events = [
            (key + i, AGENT, "appeared", tick, "far", 1.0, 0.9, 1.0, None, "raw", 0)
            for i in range(half)
        ]
        key += half
        start = time.perf_counter()
        if db.dialect_name == "sqlite":
            cur.execute("BEGIN")
        backend.begin_writes(cur)
        backend.insert_intervals(cur, facts)
        backend.insert_events(cur, events)
        backend.end_writes(cur)
        raw.commit()
        times.append(time.perf_counter() - start)
    raw.close()
    return 2 * half / statistics.median(times)


def naive_baseline(db: toaster.Database, n_changes: int = 300) -> float:
    """The original's way: per change, autocommitted SELECT, UPDATE, INSERT, event INSERT.

    On SQLite it runs on a file of its own with the original's settings (SQLite's defaults:
    rollback journal, synchronous FULL), since that is what the original ran."""
    sqlite = db.dialect_name == "sqlite"
    if sqlite:
        import sqlite3

        folder = tempfile.mkdtemp()
        driver = sqlite3.connect(str(Path(folder) / "naive.db"), isolation_level=None)
        raw = driver
    else:
        raw = db.engine.raw_connection()
        driver = raw.driver_connection
        driver.autocommit = True
    cur = driver.cursor()
    mark = "?" if sqlite else "%s"
    cur.execute(
        "CREATE TABLE naive_facts (subject TEXT, predicate TEXT, target TEXT, "
        "value TEXT, start BIGINT, stop BIGINT)"
    )
    cur.execute("CREATE UNIQUE INDEX naive_key ON naive_facts (subject, predicate, target, stop)")
    cur.execute(
        "CREATE TABLE naive_events (subject TEXT, predicate TEXT, target TEXT, "
        "value TEXT, stamp BIGINT)"
    )
    start = time.perf_counter()
    for i in range(n_changes):
        key = (f"E{i % 50}", "Distance", f"T{i}")
        cur.execute(
            f"SELECT value FROM naive_facts WHERE subject = {mark} AND predicate = {mark} "
            f"AND target = {mark} AND stop = 0",
            key,
        )
        cur.fetchall()
        cur.execute(
            f"UPDATE naive_facts SET stop = {mark} WHERE subject = {mark} AND "
            f"predicate = {mark} AND target = {mark} AND stop = 0",
            (i, *key),
        )
        cur.execute(
            f"INSERT INTO naive_facts VALUES ({mark}, {mark}, {mark}, {mark}, {mark}, 0)",
            (*key, "far", i),
        )
        cur.execute(
            f"INSERT INTO naive_events VALUES ({mark}, {mark}, {mark}, {mark}, {mark})",
            (*key, "far", i),
        )
    elapsed = time.perf_counter() - start
    cur.execute("DROP TABLE naive_facts")
    cur.execute("DROP TABLE naive_events")
    raw.close()
    return n_changes / elapsed


def bench_point(db: toaster.Database, snaps: list[list[Fact]], n: int = 500) -> float:
    """Median ms of q.fact_value for the current value of one fact."""
    facts = snaps[-1]
    rng = random.Random(2)
    times = []
    for _ in range(n):
        fact = facts[rng.randrange(len(facts))]
        start = time.perf_counter()
        row = q.fact_value(db, AGENT, fact.subject_id, fact.property, fact.target_id)
        times.append(time.perf_counter() - start)
        assert row is not None
    return median_ms(times)


def fill_memory(db: toaster.Database, agents: int, keys: int, intervals: int) -> int:
    """agents × keys × intervals intervals written by the store (``sync_snapshot``: every key
    of an agent changes value every 1,000 ns; the last interval stays open), plus a flat copy
    of the same intervals for the baseline."""
    store = db.store()
    flat = []
    for a in range(agents):
        agent = f"H{a}"
        store.add_entity(agent, "human", t_ns=0)
        for i in range(intervals):
            value = f"v{i % 2}"
            store.sync_snapshot(
                "bench", agent, i * 1000, [Fact(f"S{k}", "P", f"T{k}", value) for k in range(keys)]
            )
            end = (i + 1) * 1000 if i < intervals - 1 else None
            flat += [(agent, a * keys + k, value, i * 1000, end) for k in range(keys)]
    # As a running node keeps it (Runner's maintenance, or autovacuum, which these servers
    # run without): PostgreSQL's closed intervals otherwise leave a dead row version each,
    # which every as-of seek reads past.
    db.maintain()
    raw = db.engine.raw_connection()
    cur = raw.cursor()
    cur.execute(
        "CREATE TABLE flat_memory (agent_id TEXT, key_id BIGINT, value_text TEXT, "
        "valid_from_ns BIGINT, valid_to_ns BIGINT)"
    )
    if db.dialect_name == "sqlite":
        cur.executemany("INSERT INTO flat_memory VALUES (?,?,?,?,?)", flat)
    else:
        with cur.copy("COPY flat_memory FROM STDIN") as copy:
            for row in flat:
                copy.write_row(row)
    cur.execute("CREATE INDEX flat_memory_agent_from ON flat_memory (agent_id, valid_from_ns)")
    for table in ("fact_keys", "facts", "fact_samples", "belief_follow", "flat_memory"):
        # its own tables: a bare ANALYZE on PostgreSQL visits every schema of the database,
        # and waited for other sessions' locks there until the lock timeout
        cur.execute(f"ANALYZE {table}")
    raw.commit()
    raw.close()
    return agents * keys * intervals


def bench_as_of(
    db: toaster.Database, agents: int, intervals: int, n: int = 200
) -> tuple[float, float]:
    """Median ms of beliefs_at for one agent at random t, and of the plain b-tree scan."""
    rng = random.Random(3)
    ours: list[float] = []
    scan: list[float] = []
    raw = db.engine.raw_connection()
    cur = raw.cursor()
    mark = "?" if db.dialect_name == "sqlite" else "%s"
    for _ in range(n):
        agent, t = f"H{rng.randrange(agents)}", rng.randrange(intervals * 1000)
        start = time.perf_counter()
        rows = q.beliefs_at(db, agent, t)
        ours.append(time.perf_counter() - start)
        start = time.perf_counter()
        cur.execute(
            f"SELECT key_id, value_text, valid_from_ns, valid_to_ns FROM flat_memory "
            f"WHERE agent_id = {mark} AND valid_from_ns <= {mark} AND "
            f"(valid_to_ns IS NULL OR valid_to_ns > {mark})",
            (agent, t, t),
        )
        baseline = cur.fetchall()
        scan.append(time.perf_counter() - start)
        raw.rollback()
        assert len(rows) == len(baseline), (len(rows), len(baseline))
    raw.close()
    return median_ms(ours), median_ms(scan)


def run_backend(
    backend: str, quick: bool, pg_url: str = PG_URL, only: str | None = None
) -> list[tuple[str, str, str, str]]:
    """All measurements for one backend (``only``: sync or as-of), as table rows (measure,
    value, baseline, ratio)."""
    out: list[tuple[str, str, str, str]] = []
    if only != "as-of":
        out += _run_sync(backend, quick, pg_url)
    if only != "sync":
        out += _run_as_of(backend, quick, pg_url)
    return out


def _run_sync(backend: str, quick: bool, pg_url: str) -> list[tuple[str, str, str, str]]:
    n_facts, ticks = (2_000, 6) if quick else (10_000, 40)
    snaps = snapshots(n_facts, ticks, 0.05)
    out: list[tuple[str, str, str, str]] = []
    with database(backend, pg_url) as db:
        sync = bench_sync(db, snaps)
        raw = raw_limit(db, int(sync["rows_per_tick"]))
        same = raw_same_tables(db, int(sync["rows_per_tick"]))
        naive = naive_baseline(db, 50 if quick else 300)
        point = bench_point(db, snaps, 100 if quick else 500)
    out.append(
        (
            f"sync: changed facts/s (5% of {n_facts // 1000}k per tick)",
            f"{sync['changed_per_s']:,.0f}",
            f"naive {naive:,.0f}/s",
            f"{sync['changed_per_s'] / naive:.0f}×",
        )
    )
    out.append(
        (
            "sync: rows written/s",
            f"{sync['rows_per_s']:,.0f}",
            f"raw {raw:,.0f}/s",
            f"{sync['rows_per_s'] / raw:.0%} of raw",
        )
    )
    out.append(
        (
            "  raw inserts into toaster's own tables",
            "",
            f"{same:,.0f}/s",
            f"{sync['rows_per_s'] / same:.0%} of it",
        )
    )
    changes = int(n_facts * 0.05)
    out.append((f"sync: tick with {changes} changes", f"{sync['tick_ms']:.2f} ms", "", ""))
    out.append(("sync: tick with no change", f"{sync['quiet_ms']:.3f} ms", "target < 2 ms", ""))
    out.append(("fact_value (current, Python API)", f"{point:.3f} ms", "", ""))
    return out


def _run_as_of(backend: str, quick: bool, pg_url: str) -> list[tuple[str, str, str, str]]:
    out: list[tuple[str, str, str, str]] = []
    shapes = [(10, 100, 1000), (10, 1000, 100)] if not quick else [(2, 50, 100)]
    for agents, keys, intervals in shapes:  # agents × keys per agent × intervals per key
        with database(backend, pg_url) as db:
            rows = fill_memory(db, agents, keys, intervals)
            ours, scan = bench_as_of(db, agents, intervals, 20 if quick else 200)
        out.append(
            (
                f"as-of: {keys} beliefs of 1 agent, {rows:,} rows",
                f"{ours:.2f} ms",
                f"b-tree scan {scan:.2f} ms",
                f"{scan / ours:.1f}×",
            )
        )
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes (a smoke run)")
    parser.add_argument("--backend", choices=["sqlite", "postgresql"], action="append")
    parser.add_argument("--pg", default=PG_URL, help="PostgreSQL URL")
    parser.add_argument("--only", choices=["sync", "as-of"], help="one part of the benchmark")
    args = parser.parse_args(argv)
    backends = args.backend or ["sqlite", "postgresql"]
    for backend in backends:
        rows = run_backend(backend, args.quick, args.pg, args.only)
        print(f"\n{backend}")
        print(f"{'measure':46} {'toaster':>14} {'baseline':>22} {'ratio':>12}")
        for measure, value, baseline, ratio in rows:
            print(f"{measure:46} {value:>14} {baseline:>22} {ratio:>12}")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
