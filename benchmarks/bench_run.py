"""One full tick with the database, and ETH/UCY replay speed into the database.

Run: .venv/bin/python benchmarks/bench_run.py [--pg URL] [--no-pg] [--ticks N]

1. Tick with the store: the producer benchmark's scene (1,000 entities, 100 areas, 20 agents
   with 2 joints) through ``Runner``-equivalent steps plus ``store.sync_snapshot`` per producer,
   on a SQLite file and on PostgreSQL (a private schema, dropped afterwards). Two scenes: every
   entity moves (the producer benchmark: every Distance / IsMovingToward value_num changes, so
   every fact is refreshed every tick) and only the agents move (objects still). Baselines
   measured in the same run: the same tick without the database, and the bare driver's raw
   limit for as many rows (sqlite3 executemany, psycopg executemany into a temp table).
2. Replay of ETH hotel and UCY zara01 (``obsmat.txt``) with ``toaster run``'s session (pdg,
   area manager, agent monitor) into a fresh database: × real time (target ≥ 100×), against the
   same replay without a database.
"""

from __future__ import annotations

import argparse
import os
import sqlite3
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

import bench_producers as bp
import toaster
from toaster.producers import AgentMonitor, AreaManager, Runner, SnapshotDiff, load_session
from toaster.producers.batch import as_facts

S = 1_000_000_000
DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "eth-ucy-opentraj"
RECORDINGS = {"ETH hotel": DATA / "ETH" / "seq_hotel" / "obsmat.txt",
              "UCY zara01": DATA / "UCY" / "zara01" / "obsmat.txt"}
PG_DEFAULT = "postgresql://postgres@127.0.0.1:5432/test"


# -- databases -------------------------------------------------------------------------------
class PgSchema:
    """A private schema on a PostgreSQL server, dropped on exit."""

    def __init__(self, base: str) -> None:
        import psycopg

        self.base = base
        self.name = f"bench_run_{os.getpid()}_{int(time.time() * 1000) % 100000}"
        self.conn = psycopg.connect(base, autocommit=True)
        self.conn.execute(f"CREATE SCHEMA {self.name}")

    @property
    def url(self) -> str:
        sep = "&" if "?" in self.base else "?"
        return f"{self.base}{sep}options=-csearch_path%3D{self.name}"

    def analyze(self) -> None:
        """ANALYZE the schema's tables (the store's tables start empty: trap 2)."""
        tables = self.conn.execute("SELECT tablename FROM pg_tables WHERE schemaname = %s",
                                   (self.name,)).fetchall()
        for (table,) in tables:
            self.conn.execute(f'ANALYZE {self.name}."{table}"')

    def drop(self) -> None:
        self.conn.execute(f"DROP SCHEMA IF EXISTS {self.name} CASCADE")
        self.conn.close()


def open_store(url: str):
    db = toaster.connect(url)
    store = db.store()
    store.add_entity("toaster", "robot", is_self=True, t_ns=0)
    return db, store


# -- 1. tick with the database ------------------------------------------------------------------
def scene(n: int, objects_move: bool):
    world, areas, pos, rng = bp.build(n)
    managers = [AreaManager(areas), AgentMonitor()]
    moving = len(pos) if objects_move else 20

    def tick(t: int, diff: SnapshotDiff, store=None) -> int:
        pos[:moving, :2] += rng.normal(0, 0.02, (moving, 2))
        world.observe("bench", np.arange(len(pos)), np.full(len(pos), t), pos)
        world.commit()
        written = 0
        for m in managers:
            batch = m.compute_batch(world, t)
            diff.apply(m.name, batch)
            if store is not None:
                r = store.sync_snapshot(m.name, "toaster", t, as_facts(batch))
                written += r.appeared + r.changed + r.refreshed + r.ended
        return written

    return tick


def time_ticks(tick, store, ticks: int, warmup: int = 3,
               after_warmup=None) -> tuple[float, float, float]:
    """(median ms, median rows written per tick, median facts)."""
    diff = SnapshotDiff()
    t = 10 * S
    for _ in range(warmup):
        tick(t, diff, store)
        t += S // 30
    if after_warmup is not None:
        after_warmup()
    times, rows = [], []
    for _ in range(ticks):
        start = time.perf_counter()
        rows.append(tick(t, diff, store))
        times.append(time.perf_counter() - start)
        t += S // 30
    return statistics.median(times) * 1e3, statistics.median(rows), 0.0


def raw_sqlite(rows: int, path: str) -> float:
    """Bare sqlite3: one transaction upserting ``rows`` fact-like rows (ms)."""
    con = sqlite3.connect(path)
    con.execute("PRAGMA journal_mode=WAL")
    con.execute("PRAGMA synchronous=NORMAL")
    con.execute("CREATE TABLE IF NOT EXISTS f (k INTEGER PRIMARY KEY, v REAL, c REAL)")
    data = [(i, float(i), 0.5) for i in range(max(rows, 1))]
    con.executemany("INSERT OR REPLACE INTO f VALUES (?, ?, ?)", data)
    con.commit()
    times = []
    for rep in range(5):
        data = [(i, float(i + rep), 0.5) for i in range(max(rows, 1))]
        start = time.perf_counter()
        con.executemany("UPDATE f SET v = ?, c = ? WHERE k = ?", [(v, c, k) for k, v, c in data])
        con.commit()
        times.append(time.perf_counter() - start)
    con.close()
    return statistics.median(times) * 1e3


def raw_pg(rows: int, url: str) -> float:
    """Bare psycopg: COPY ``rows`` rows into a temp table + one UPDATE … FROM (ms)."""
    import psycopg

    with psycopg.connect(url) as con:
        con.execute("CREATE TABLE f (k bigint PRIMARY KEY, v float8, c float8)")
        with con.cursor().copy("COPY f FROM STDIN") as cp:
            for i in range(max(rows, 1)):
                cp.write_row((i, float(i), 0.5))
        con.commit()
        times = []
        for rep in range(5):
            start = time.perf_counter()
            con.execute("CREATE TEMP TABLE u (k bigint, v float8, c float8) ON COMMIT DROP")
            with con.cursor().copy("COPY u FROM STDIN") as cp:
                for i in range(max(rows, 1)):
                    cp.write_row((i, float(i + rep), 0.5))
            con.execute("UPDATE f SET v = u.v, c = u.c FROM u WHERE f.k = u.k")
            con.commit()
            times.append(time.perf_counter() - start)
        con.execute("DROP TABLE f")
    return statistics.median(times) * 1e3


def bench_ticks(pg_url: str | None, ticks: int) -> None:
    print("\n1. One full tick with the database (1,000 entities, 100 areas, 20 agents × 2 joints)")
    print(f"{'scene':<16} {'backend':<10} {'tick ms':>9} {'no-db ms':>9} {'ratio':>7}"
          f" {'rows/tick':>10} {'raw ms':>8} {'vs raw':>7}")
    for label, objects_move in (("all move", True), ("agents move", False)):
        base, _, _ = time_ticks(scene(1000, objects_move), None, ticks)
        backends = [("sqlite", None, False)]
        if pg_url:
            backends += [("postgresql", pg_url, False), ("pg+analyze", pg_url, True)]
        for backend, url, analyze in backends:
            with tempfile.TemporaryDirectory() as tmp:
                schema = None
                if backend == "sqlite":
                    db_url = f"sqlite:///{tmp}/bench.db"
                else:
                    schema = PgSchema(url)
                    db_url = schema.url
                try:
                    db, store = open_store(db_url)
                    ms, rows, _ = time_ticks(scene(1000, objects_move), store, ticks,
                                             after_warmup=schema.analyze if analyze else None)
                    db.close()
                    raw = (raw_sqlite(int(rows), f"{tmp}/raw.db") if backend == "sqlite"
                           else raw_pg(int(rows), schema.url))
                finally:
                    if schema is not None:
                        schema.drop()
            print(f"{label:<16} {backend:<10} {ms:>9.1f} {base:>9.2f} {ms / base:>6.0f}×"
                  f" {rows:>10.0f} {raw:>8.1f} {ms / raw:>6.1f}×")


# -- 2. replay -----------------------------------------------------------------------------------
def replay(path: Path, url: str | None, schema: PgSchema | None = None) -> tuple[float, float, int]:
    """(input seconds, wall seconds, ticks) of one replay, into ``url`` or without database."""
    store = db = None
    if url is not None:
        db, store = open_store(url)
    session = load_session(path, None)
    runner = Runner(session.world, session.sources, session.producers, store=store,
                    agent_id="toaster")
    start = time.perf_counter()
    stats = runner.run(session.start_ns, session.end_ns, session.rate_hz)
    wall = time.perf_counter() - start
    if db is not None:
        db.close()
    return (session.end_ns - session.start_ns) / S, wall, stats.ticks


def bench_replay(pg_url: str | None) -> None:
    print("\n2. Replay of ETH / UCY tracks into the database (target ≥ 100× real time)")
    print(f"{'recording':<12} {'backend':<10} {'input s':>8} {'ticks':>6} {'wall s':>8}"
          f" {'× real':>8} {'no-db ×':>8} {'ratio':>6}")
    for name, path in RECORDINGS.items():
        if not path.is_file():
            print(f"{name:<12} (missing: {path})")
            continue
        span, wall0, _ = replay(path, None)
        base_speed = span / wall0
        backends = [("sqlite", None)] + ([("postgresql", pg_url)] if pg_url else [])
        for backend, url in backends:
            with tempfile.TemporaryDirectory() as tmp:
                schema = None
                try:
                    if backend == "sqlite":
                        db_url = f"sqlite:///{tmp}/replay.db"
                    else:
                        schema = PgSchema(url)
                        db_url = schema.url
                    span, wall, ticks = replay(path, db_url)
                finally:
                    if schema is not None:
                        schema.drop()
            speed = span / wall
            print(f"{name:<12} {backend:<10} {span:>8.0f} {ticks:>6} {wall:>8.2f} {speed:>7.0f}×"
                  f" {base_speed:>7.0f}× {base_speed / speed:>5.1f}×")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pg", default=os.environ.get("TOASTER_BENCH_PG", PG_DEFAULT))
    parser.add_argument("--no-pg", action="store_true")
    parser.add_argument("--ticks", type=int, default=10)
    parser.add_argument("--only", choices=("tick", "replay"))
    args = parser.parse_args()
    pg = None if args.no_pg else args.pg
    if pg:
        try:
            PgSchema(pg).drop()
        except Exception as exc:
            print(f"PostgreSQL not reachable at {pg} ({exc.__class__.__name__}); skipping it")
            pg = None
    if args.only != "replay":
        bench_ticks(pg, args.ticks)
    if args.only != "tick":
        bench_replay(pg)


if __name__ == "__main__":
    main()
