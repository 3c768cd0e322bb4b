"""Ticks and replays with the database, the way users run them (``Runner`` / ``toaster run``).

Run: .venv/bin/python benchmarks/bench_run.py [--pg URL] [--no-pg | --only-pg]
     [--only tick|crowd|size|pg-long] [--repeats N] [--long SECONDS] [--humans 100,500]
     [--growth-rows N] [--quick]

``--quick`` (a smoke run of every section, figures meaningless): a 200-entity scene with 5
humans holding beliefs, 3 ticks, one run; one 40-person crowd for 10 s; growth from 2 s and 4 s
replays of 20 people; 4 s of PostgreSQL long run reported every 2 s.

1. **One full tick**: the producer benchmark's scene (1,000 entities, 100 areas, 20 humans with
   a head and a hand; every entity jitters 2 cm a tick at 30 Hz) and a 10,000-entity scene with
   30 humans, as a :class:`~toaster.producers.Session` (registered in the store as
   ``toaster run`` registers a file's entities; the store with its belief rule, defaults) ticked
   by :class:`~toaster.producers.Runner`. Same-run baselines: the tick without a database
   (the geometry alone) and *before*: the settings of the previous release (no range for
   IsMovingToward, no debounce, every number written exactly).
   Then **the live node's tick on crowds** (``--humans``, default 100 and 500): bench_live's
   scene (each human with a head and a right hand and its own zone, stepping in and out of it
   once a second; 50 objects) pushed into a :class:`~toaster.node.LiveNode` as one /tf
   message a tick (``LiveSource.push_many`` where the code has it, else a push per pose) and
   ticked at 30 Hz of input time: median ms to buffer a message and of a tick, without
   database and with each backend (target: the tick without database well under 33 ms).
2. **Crowd replay**: ``toaster run`` (a subprocess, its own figures) on synthetic crowds of
   :mod:`crowd`: 400 people crossing the scene over 200 s like the ETH/UCY recordings (about
   27 in it at once), at 2.5 Hz and at 30 Hz, and 400 people all present at once (stress, no
   target); SQLite and PostgreSQL; the × real time it prints, against ``--no-db``.
3. **Size**: 100 people all present at once, at 30 Hz with 2 cm of tracker noise, and the
   recordings-like crowd with the same noise, replayed by ``toaster run`` for 40 s and 120 s
   with its defaults, each then maintained (``toaster db maintain``; ``--growth-rows N``: the
   first N crowds only) (ticks on the samples; ``--rate 30``, used before 2026-11-28, ticked just
   before a third of them, whose times the CSV rounds to 0.1 ms, and wrote half the samples);
   growth per hour from the difference (bytes, rows; PostgreSQL: dead tuples at the end); then
   where the first crowd's bytes go: each table and index apart, bytes per row, and on
   PostgreSQL the share of ``facts`` updates that were HOT. ("before" baselines: ``before``
   column of section 1.)
4. **PostgreSQL over a long run** (``--long`` input seconds, default 600): the ``facts`` table's
   size, dead rows, share of HOT updates and vacuum runs every minute of input, ticked as
   ``toaster run`` ticks a recording (on its sample times), with maintenance (a VACUUM of the
   hot tables every minute of input, as a node running at real time does) and, same run,
   without it; then the growth per hour between the first and the last line.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

import bench_producers as bp
import crowd
import toaster
from toaster.db import tolerance
from toaster.producers import AgentMonitor, AreaManager, Runner, Session
from toaster.producers.perception import PerceptionFacts
from toaster.world import World

S = 1_000_000_000
PG_DEFAULT = "postgresql://postgres@127.0.0.1:5432/test"
TOASTER = str(Path(sys.executable).parent / "toaster")
#: sizes of each section; ``--quick`` replaces them with :data:`QUICK`
SIZES: dict[str, Any] = {
    "scenes": [
        (1_000, 20, "1,000 ent / 100 areas / 20 humans", {"sqlite": 20, "postgresql": 33}),
        (10_000, 30, "10,000 ent / 100 areas / 30 humans", {"sqlite": 100}),
    ],
    "crowds": [  # label, people, Hz, input seconds, arrivals, targets
        ("400 crossing, 2.5 Hz", 400, 2.5, 200.0, 2.0, {"sqlite": 30, "postgresql": 10}),
        ("400 crossing, 30 Hz", 400, 30.0, 100.0, 2.0, {"sqlite": 1, "postgresql": 1}),
        ("400 at once, 2.5 Hz", 400, 2.5, 60.0, 0.0, {"sqlite": 0, "postgresql": 0}),
    ],
    "growth": [  # label, people, arrivals, extra arguments of toaster run
        ("100 at once", 100, 0.0, ()),
        ("400 crossing", 400, 2.0, ()),
        ("100, toward people 3.6m", 100, 0.0, ("--config", "social.yaml")),
    ],
    "growth_s": (40, 120),  # the two replays' input seconds
    "long_people": 100,
    "long_report_s": 60,
    "holders": ("none", "humans"),  # who holds beliefs in section 1's scenes
    "live_humans": (100, 500),  # section 1b's crowds (--humans)
}
QUICK: dict[str, Any] = {
    "scenes": [(200, 5, "200 ent / 100 areas / 5 humans", {"sqlite": 20, "postgresql": 33})],
    "crowds": [("40 crossing, 2.5 Hz", 40, 2.5, 10.0, 2.0, {"sqlite": 30, "postgresql": 10})],
    "growth": [("20 at once", 20, 0.0, ())],
    "growth_s": (2, 4),
    "long_people": 20,
    "long_report_s": 2,
    "holders": ("humans",),
    "live_humans": (10,),
}
#: the previous release's behaviour, for the same-run "before" column
BEFORE = {"toward_range": 1e9, "min_duration": {"IsMoving": 0.0, "IsFacing": 0.0}}


class PgSchema:
    """A private schema on a PostgreSQL server, dropped on exit."""

    def __init__(self, base: str) -> None:
        import psycopg

        self.base = base
        self.name = f"bench_run_{os.getpid()}_{int(time.time() * 1000) % 100000}"
        plain = base.replace("postgresql+psycopg://", "postgresql://", 1)  # psycopg's form
        self.conn = psycopg.connect(plain, autocommit=True)
        self.conn.execute(f"CREATE SCHEMA {self.name}")

    @property
    def url(self) -> str:
        sep = "&" if "?" in self.base else "?"
        return f"{self.base}{sep}options=-csearch_path%3D{self.name}"

    def size(self) -> tuple[int, int, int]:
        """(bytes of every table and index, live rows, dead rows) of the schema."""
        self.conn.execute("SELECT pg_stat_clear_snapshot()")
        row = self.conn.execute(
            "SELECT COALESCE(SUM(pg_total_relation_size(relid)), 0), COALESCE(SUM(n_live_tup), "
            "0), COALESCE(SUM(n_dead_tup), 0) FROM pg_stat_user_tables WHERE schemaname = %s",
            (self.name,),
        ).fetchone()
        return int(row[0]), int(row[1]), int(row[2])

    def relations(self) -> dict[str, tuple[str, int]]:
        """Each table's heap and each index apart: name -> (its table, bytes)."""
        rows = self.conn.execute(
            "SELECT relname, relname, pg_table_size(relid) FROM pg_stat_user_tables "
            "WHERE schemaname = %s UNION ALL SELECT indexrelname, relname, "
            "pg_relation_size(indexrelid) FROM pg_stat_user_indexes WHERE schemaname = %s",
            (self.name, self.name),
        ).fetchall()
        return {str(name): (str(table), int(size)) for name, table, size in rows}

    def counters(self, table: str, inserted: int) -> tuple[int, int, int]:
        """(updates, HOT updates, dead rows) of ``table``, once the writers' statistics
        arrived (a backend sends them when it ends: wait until ``fact_samples``, which is only
        inserted into, counts its ``inserted`` rows, for at most 10 s)."""
        deadline = time.monotonic() + 10
        while True:
            self.conn.execute("SELECT pg_stat_clear_snapshot()")
            row = self.conn.execute(
                "SELECT (SELECT n_tup_ins FROM pg_stat_user_tables WHERE schemaname = %s AND "
                "relname = 'fact_samples'), n_tup_upd, n_tup_hot_upd, n_dead_tup FROM "
                "pg_stat_user_tables WHERE schemaname = %s AND relname = %s",
                (self.name, self.name, table),
            ).fetchone()
            if row[0] >= inserted or time.monotonic() > deadline:
                return int(row[1]), int(row[2]), int(row[3])
            time.sleep(0.1)

    def drop(self) -> None:
        self.conn.execute(f"DROP SCHEMA IF EXISTS {self.name} CASCADE")
        self.conn.close()


class Database:
    """A fresh SQLite file or PostgreSQL schema for one measurement."""

    def __init__(self, backend: str, pg_url: str | None, tmp: str) -> None:
        self.schema = PgSchema(pg_url) if backend == "postgresql" else None
        self.path = Path(tmp) / f"bench_{time.monotonic_ns()}.db"
        self.url = self.schema.url if self.schema else f"sqlite:///{self.path}"

    def size(self) -> tuple[int, int, int]:
        if self.schema:
            return self.schema.size()
        return sum(p.stat().st_size for p in self.path.parent.glob(self.path.name + "*")), 0, 0

    def tables(self) -> dict[str, int]:
        """Bytes of each table with its indexes (and TOAST): :meth:`relations` summed."""
        sizes: dict[str, int] = {}
        for table, size in self.relations().values():
            sizes[table] = sizes.get(table, 0) + size
        return sizes

    def relations(self) -> dict[str, tuple[str, int]]:
        """Each table and index apart: name -> (its table, bytes); SQLite from ``dbstat``."""
        if self.schema:
            return self.schema.relations()
        import sqlite3

        with sqlite3.connect(f"file:{self.path}?mode=ro", uri=True) as conn:
            rows = conn.execute(
                "SELECT d.name, COALESCE(m.tbl_name, d.name), SUM(d.pgsize) FROM dbstat d "
                "LEFT JOIN sqlite_master m ON m.name = d.name GROUP BY 1"
            ).fetchall()
        return {str(name): (str(table), int(size)) for name, table, size in rows}

    def close(self) -> None:
        if self.schema:
            self.schema.drop()


def set_before(store: Any) -> None:
    """The previous release: every number written exactly."""
    for prop in tolerance.DEFAULTS:
        store.put_setting("tolerance", prop, {"value": 0, "confidence": 0, "observability": 0})


# -- 1. one full tick ---------------------------------------------------------------------------
class Jitter:
    """A source moving every entity by 2 cm (Gaussian) a tick, the producer benchmark's."""

    name = "bench"

    def __init__(self, pos: np.ndarray, rng: np.random.Generator) -> None:
        self.pos, self.rng = pos, rng

    def setup(self, world: World) -> None:
        """Entities are in the world already."""

    def advance(self, world: World, t_ns: int) -> None:
        pos = self.pos
        pos[:, :2] += self.rng.normal(0, 0.02, (len(pos), 2))
        world.observe("bench", np.arange(len(pos)), np.full(len(pos), t_ns), pos)


def scene_session(n: int, agents: int, config: dict[str, Any], holders: str) -> Session:
    world, areas, pos, rng = bp.build(n, agents=agents)
    producers = [PerceptionFacts(config), AreaManager(areas, config), AgentMonitor(config)]
    return Session(
        world,
        [Jitter(pos, rng)],
        producers,
        areas,
        "toaster",
        0,
        0,
        30.0,
        config,
        belief_holders=holders,
    )


def time_ticks(session: Session, store: Any, ticks: int) -> tuple[float, float]:
    """(median ms per tick, median rows written per tick) after 5 warm-up ticks."""
    if store is not None:
        session.register(store)
    runner = Runner(
        session.world, session.sources, session.producers, store=store, agent_id=session.self_id
    )
    t = 10 * S
    times, rows = [], []
    for i in range(ticks + 5):
        before = _written(store)
        start = time.perf_counter()
        runner.tick(t)
        if i >= 5:
            times.append(time.perf_counter() - start)
            rows.append(_written(store) - before)
        t += S // 30
    return statistics.median(times) * 1e3, statistics.median(rows)


def time_run(session: Session, store: Any, ticks: int) -> float:
    """ms per tick of ``Runner.run_at`` as ``toaster run`` ticks (tick k+1 computed while tick
    k is written), after 5 warm-up ticks."""
    session.register(store)
    runner = Runner(
        session.world, session.sources, session.producers, store=store, agent_id=session.self_id
    )
    times = [10 * S + k * S // 30 for k in range(ticks + 5)]
    runner.run_at(times[:5])
    start = time.perf_counter()
    runner.run_at(times[5:])
    return (time.perf_counter() - start) / ticks * 1e3


def _written(store: Any) -> int:
    if store is None:
        return 0
    with store.db.transaction() as conn:
        return sum(
            conn.exec_driver_sql(f"SELECT COUNT(*) FROM {table}").scalar_one()
            for table in ("facts", "events", "fact_samples")
        )


def bench_ticks(backends: list[str], pg: str | None, ticks: int, repeats: int) -> None:
    print(
        "\n1. One full tick with the database (median ms of "
        f"{ticks} ticks, median of {repeats} runs; rows = new facts + events + samples)"
    )
    print(
        f"{'scene':<34} {'backend':<11} {'holders':<8} {'no-db ms':>9} {'before ms':>10}"
        f" {'rows':>7} {'tick ms':>8} {'rows':>6} {'db/geom':>8} {'run ms':>7} {'target':>7}"
    )
    print("  (run ms: a tick of `toaster run`, tick k+1 computed while tick k is written)")
    for n, agents, label, targets in SIZES["scenes"]:
        geom = statistics.median(
            time_ticks(scene_session(n, agents, {}, "none"), None, ticks)[0] for _ in range(repeats)
        )
        for backend in backends:
            if backend not in targets:
                continue
            for holders in SIZES["holders"]:
                figures: dict[str, list[tuple[float, float]]] = {"before": [], "now": []}
                run_ms: list[float] = []
                for run in range(repeats):  # the heavy baseline last: it leaves the server busy
                    for case in ("now", "before") if run == repeats - 1 else ("now",):
                        with tempfile.TemporaryDirectory() as tmp:
                            database = Database(backend, pg, tmp)
                            try:
                                db = toaster.connect(database.url)
                                store = db.store()
                                config = BEFORE if case == "before" else {}
                                if case == "before":
                                    set_before(store)
                                session = scene_session(n, agents, config, holders)
                                figures[case].append(time_ticks(session, store, ticks))
                                db.close()
                            finally:
                                database.close()
                        if case == "now":  # the same scene into a fresh database, as run
                            with tempfile.TemporaryDirectory() as tmp:
                                database = Database(backend, pg, tmp)
                                try:
                                    db = toaster.connect(database.url)
                                    session = scene_session(n, agents, {}, holders)
                                    run_ms.append(time_run(session, db.store(), ticks))
                                    db.close()
                                finally:
                                    database.close()
                before_ms = statistics.median(f[0] for f in figures["before"])
                before_rows = statistics.median(f[1] for f in figures["before"])
                ms = statistics.median(f[0] for f in figures["now"])
                rows = statistics.median(f[1] for f in figures["now"])
                print(
                    f"{label:<34} {backend:<11} {holders:<8} {geom:>9.2f} {before_ms:>10.1f}"
                    f" {before_rows:>7.0f} {ms:>8.1f} {rows:>6.0f} {(ms - geom) / geom:>7.1f}×"
                    f" {statistics.median(run_ms):>7.1f} {'≤' + str(targets[backend]):>7}",
                    flush=True,
                )


def live_crowd(
    humans: int, url: str | None, ticks: int, *, writer: bool = False
) -> tuple[float, float]:
    """(median ms to buffer one message's poses, median ms of a tick) of a live node on
    bench_live's scene, after 15 warm-up ticks. ``writer``: ticks at 30 Hz with the writer
    thread, as ``toaster serve`` runs (the tick's time is then its computation and hand-over on
    the node's thread, the write runs beside it; ``nan`` for code without one)."""
    from live_scene import joint_offsets, zone
    from toaster.node import LiveNode

    db = toaster.connect(url) if url else None
    if db is not None:
        store = db.store()
        for i in range(humans):
            store.put_area(f"zone_h{i}", zone(i))
    node = LiveNode(db)
    if db is None:
        for i in range(humans):
            node.areas.set_area(f"zone_h{i}", zone(i))
    targets = []
    for i in range(humans):
        targets.append((f"h{i}", "human", "", ""))
        targets += [(f"h{i}/{j}", "joint", f"h{i}", j) for j in joint_offsets()]
    targets += [(f"o{j}", "object", "", "") for j in range(50)]
    quats = np.tile([0.0, 0.0, 0.0, 1.0], (len(targets), 1))
    source, base = node.api, time.time_ns() - 600 * S
    push_ms: list[float] = []
    tick_ms: list[float] = []
    if writer and not hasattr(node, "writing"):
        return math.nan, math.nan
    with node.writing() if writer else contextlib.nullcontext():
        paced = time.perf_counter()
        for k in range(ticks + 15):
            if writer:  # at 30 Hz, as served
                paced += 1 / 30
                time.sleep(max(0.0, paced - time.perf_counter()))
            push_ms_k, tick_ms_k = _live_tick(node, source, humans, targets, quats, base, k)
            if k >= 15:
                push_ms.append(push_ms_k)
                tick_ms.append(tick_ms_k)
    if db is not None:
        db.close()
    return statistics.median(push_ms), statistics.median(tick_ms)


def _live_tick(
    node: Any, source: Any, humans: int, targets: list, quats: np.ndarray, base: int, k: int
) -> tuple[float, float]:
    """One message's poses buffered and one tick: (ms to buffer, ms of the tick)."""
    from live_scene import human_pose, joint_offsets, object_pose

    elapsed, t = k / 30, base + k * S // 30
    pos = []
    for i in range(humans):
        _, x, y = human_pose(i, humans, elapsed)
        pos.append((x, y, 0.0))
        pos += [(x + dx, y + dy, dz) for dx, dy, dz in joint_offsets().values()]
    pos += [object_pose(j) for j in range(50)]
    xyz = np.asarray(pos, float)
    start = time.perf_counter()
    if hasattr(source, "push_many"):
        source.push_many(targets, xyz, quats, [t] * len(targets))
    else:  # the code before push_many: a pose at a time
        for (eid, kind, owner, joint), p in zip(targets, pos, strict=True):
            source.push(
                eid,
                p,
                quat=(0.0, 0.0, 0.0, 1.0),
                t_ns=t,
                kind=kind,
                owner_id=owner,
                joint=joint,
            )
    pushed = time.perf_counter()
    node.tick(t)
    done = time.perf_counter()
    return (pushed - start) * 1e3, (done - pushed) * 1e3


def bench_live_crowds(backends: list[str], pg: str | None, ticks: int, repeats: int) -> None:
    print(
        f"\n1b. The live node's tick on crowds (bench_live's scene; median ms of {ticks} ticks,"
        f" median of {repeats} runs; target: the tick without database well under 33 ms)"
    )
    print(
        f"{'humans':>6} {'entities':>9} {'backend':<11} {'push ms':>8} {'tick ms':>8} {'writer':>8}"
    )
    print("  (writer: the tick on the node's thread at 30 Hz, its write on the writer thread)")
    for humans in SIZES["live_humans"]:
        for backend in ["none", *backends]:
            runs, written = [], []
            for _ in range(repeats):
                for out, writer in ((runs, False), (written, True)):
                    if writer and backend == "none":
                        continue
                    with tempfile.TemporaryDirectory() as tmp:
                        database = Database(backend, pg, tmp) if backend != "none" else None
                        url = database.url if database else None
                        try:
                            out.append(live_crowd(humans, url, ticks, writer=writer))
                        finally:
                            if database is not None:
                                database.close()
            beside = statistics.median(r[1] for r in written) if written else math.nan
            print(
                f"{humans:>6} {3 * humans + 50:>9} {backend:<11}"
                f" {statistics.median(r[0] for r in runs):>8.2f}"
                f" {statistics.median(r[1] for r in runs):>8.2f} {beside:>8.2f}",
                flush=True,
            )


# -- 2. crowd replay ------------------------------------------------------------------------------
_SPEED = re.compile(r"in ([\d.]+) s \(([\d.]+)× real time\)")


def toaster_run(
    csv: Path, url: str | None, rate: float | None, extra: tuple[str, ...] = ()
) -> tuple[float, str]:
    """``toaster run`` as a user types it: (wall seconds of the run loop, its output); no
    ``rate``: on the recording's own sample times, as without ``--rate``."""
    cmd = [
        TOASTER,
        *(["--db", url] if url else []),
        "run",
        str(csv),
        *(["--rate", str(rate)] if rate is not None else []),
        *(["--no-db"] if url is None else []),
        *extra,
    ]
    out = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if out.returncode:
        msg = f"{' '.join(cmd)} failed: {out.stderr.strip() or out.stdout}"
        raise RuntimeError(msg)
    match = _SPEED.search(out.stdout)
    if match is None:
        msg = f"unexpected output of toaster run: {out.stdout}"
        raise RuntimeError(msg)
    return float(match.group(1)), out.stdout


def bench_crowd(backends: list[str], pg: str | None, repeats: int) -> None:
    print(
        "\n2. Crowd replay with `toaster run` (× real time = input seconds / run seconds; "
        f"median of {repeats})"
    )
    print(
        f"{'crowd':<26} {'backend':<11} {'input s':>8} {'no-db ×':>8} {'×':>7} {'target':>7}"
        f" {'store ms/tick':>14}"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for label, people, hz, seconds, arrivals, targets in SIZES["crowds"]:
            csv = Path(tmp) / f"crowd_{hz}_{arrivals}.csv"
            crowd.write_crowd(csv, people, hz, seconds, arrivals=arrivals)
            base = statistics.median(
                seconds / toaster_run(csv, None, hz)[0] for _ in range(repeats)
            )
            for backend in backends:
                if backend not in targets:
                    continue
                speeds, store_ms = [], []
                for _ in range(repeats):
                    database = Database(backend, pg, tmp)
                    try:
                        wall, out = toaster_run(csv, database.url, hz)
                    finally:
                        database.close()
                    speeds.append(seconds / wall)
                    found = re.search(r"store\s+[\d.]+ ms\s+\(([\d.]+) ms/tick\)", out)
                    store_ms.append(float(found.group(1)) if found else float("nan"))
                print(
                    f"{label:<26} {backend:<11} {seconds:>8.0f} {base:>7.0f}×"
                    f" {statistics.median(speeds):>6.1f}× {'≥' + str(targets[backend]):>7}"
                    f" {statistics.median(store_ms):>14.2f}",
                    flush=True,
                )


# -- 3. size per hour -----------------------------------------------------------------------------
#: the tables whose rows section 3 counts (samples, intervals, events, keys)
COUNTED = ("fact_samples", "facts", "events", "fact_keys")


#: PostgreSQL's older samples, packed by maintenance (revision 0025): counted in samples
BLOCKS = "fact_sample_blocks"


def _counts(url: str) -> dict[str, int]:
    """Rows of each :data:`COUNTED` table; the samples packed in :data:`BLOCKS` apart."""
    with toaster.connect(url) as db, db.transaction() as conn:
        counts = {
            t: conn.exec_driver_sql(f"SELECT COUNT(*) FROM {t}").scalar_one() for t in COUNTED
        }
        if (
            conn.dialect.name == "postgresql"
            and conn.exec_driver_sql(f"SELECT to_regclass('{BLOCKS}')").scalar_one()
        ):
            counts[BLOCKS] = conn.exec_driver_sql(
                f"SELECT COALESCE(SUM(cardinality(untils_ns)), 0) FROM {BLOCKS}"
            ).scalar_one()
    return counts


def bench_size(backends: list[str], pg: str | None, rows: int | None = None) -> None:
    print(
        "\n3. Growth per hour: crowds at 30 Hz with 2 cm tracker noise (`toaster run`, defaults:"
        " ticks on the samples;"
        f" slope between a {SIZES['growth_s'][0]} s and a {SIZES['growth_s'][1]} s replay;"
        " target ≤ 100 MB/h for 100 people);\n"
        "   last rows: the same with IsMovingToward toward people asked for (opt-in)"
    )
    print(
        f"{'crowd':<22} {'backend':<11} {'MB/h':>8} {'rows/h':>12} {'dead rows at end':>17}"
        f" {'samples/h':>10} {'intervals/h':>12} {'events/h':>10}"
    )
    details: list[tuple[str, str, Growth]] = []
    with tempfile.TemporaryDirectory() as tmp:
        social = Path(tmp) / "social.yaml"
        social.write_text("toward_range_humans: 3.6\n")
        for label, people, arrivals, extra in SIZES["growth"][:rows]:
            extra = tuple(str(social) if e == "social.yaml" else e for e in extra)
            csv = Path(tmp) / f"crowd{people}.csv"
            if not csv.exists():
                longest = float(SIZES["growth_s"][1])
                crowd.write_crowd(csv, people, 30.0, longest, noise=0.02, seed=1, arrivals=arrivals)
            for backend in backends:
                growth = _size_row(label, csv, backend, pg, tmp, extra)
                if not details or details[0][0] == label:
                    details.append((label, backend, growth))
    _print_details(details)


class Growth:
    """What grew between the short and the long replay of one row of section 3."""

    def __init__(self, per_hour: float) -> None:
        self.per_hour = per_hour
        self.relations: list[dict[str, tuple[str, int]]] = []
        self.rows: list[dict[str, int]] = []
        self.facts_updates = (0, 0, 0)  # PostgreSQL: updates, HOT updates, dead rows at end

    def bytes_of(self, name: str) -> float:
        before = self.relations[0].get(name, ("", 0))[1]
        return (self.relations[1][name][1] - before) * self.per_hour

    def rows_of(self, table: str) -> float:
        return (self.rows[1].get(table, 0) - self.rows[0].get(table, 0)) * self.per_hour


def _size_row(
    label: str, csv: Path, backend: str, pg: str | None, tmp: str, extra: tuple[str, ...]
) -> Growth:
    """One row of section 3: a short and a long replay (40 s, 120 s), growth per hour from
    the difference."""
    sizes = []
    short, long = SIZES["growth_s"]
    growth = Growth(3600 / (long - short))
    for seconds in (short, long):
        database = Database(backend, pg, tmp)
        try:
            toaster_run(csv, database.url, None, ("--until", f"{seconds}s", *extra))
            # as a node maintains every minute: both replays end maintained, whatever their
            # wall time (toaster run maintains every 60 s of it, so a short replay never did)
            maintain = [TOASTER, "--db", database.url, "db", "maintain"]
            subprocess.run(maintain, capture_output=True, check=True)
            counts = _counts(database.url)
            if database.schema and seconds == long:
                growth.facts_updates = database.schema.counters("facts", counts["fact_samples"])
            sizes.append((database.size(), counts))
            growth.relations.append(database.relations())
            growth.rows.append(counts)
        finally:
            database.close()
    (b0, _, _), _ = sizes[0]
    (b1, _, dead), _ = sizes[1]
    deltas = [growth.rows_of(t) for t in COUNTED[:3]]
    deltas[0] += growth.rows_of(BLOCKS)
    print(
        f"{label:<22} {backend:<11} {(b1 - b0) * growth.per_hour / 1e6:>8.1f} {sum(deltas):>12,.0f}"
        f" {dead:>17,} {deltas[0]:>10,.0f} {deltas[1]:>12,.0f} {deltas[2]:>10,.0f}",
        flush=True,
    )
    return growth


def _print_details(details: list[tuple[str, str, Growth]]) -> None:
    """Where the bytes of section 3's first crowd go: each table (heap) and index apart."""
    if not details:
        return
    print(
        f"\n   where the bytes of {details[0][0]!r} go, per hour (bytes/row: per row of its"
        " table; PostgreSQL: heap = the table without its indexes)"
    )
    print(f"{'relation':<30} {'backend':<11} {'MB/h':>8} {'rows/h':>12} {'bytes/row':>10}")
    for _, backend, growth in details:
        names = sorted(growth.relations[1], key=lambda n: -growth.bytes_of(n))
        for name in names:
            table = growth.relations[1][name][0]
            grew = growth.bytes_of(name)
            if abs(grew) < 50_000:  # under 0.05 MB/h: the catalogue, settings
                continue
            rows = growth.rows_of(table)
            kind = "" if name == table else "  "
            per_row = f"{grew / rows:.0f}" if rows > 0 else "-"  # no rows added: dead versions
            print(
                f"{kind + name:<30} {backend:<11} {grew / 1e6:>8.1f} {rows:>12,.0f} {per_row:>10}",
                flush=True,
            )
        if backend == "postgresql":
            upd, hot, dead = growth.facts_updates
            print(
                f"   facts: {upd:,} updates (refreshes, closes) in the long replay, "
                f"{hot / upd if upd else 0:.0%} HOT (in place, no index entry), {dead:,} dead "
                "rows at its end",
                flush=True,
            )


# -- 4. PostgreSQL over a long run ----------------------------------------------------------------
def bench_pg_long(pg: str, seconds: float) -> None:
    print(
        f"\n4. PostgreSQL over {seconds:.0f} s of a {SIZES['long_people']}-person crowd at 30 Hz "
        "with 2 cm noise "
        "(Runner as `toaster run`): facts table and dead rows as the run goes (each line before"
        " that minute's maintenance);\n   baseline in the same run: no maintenance between ticks"
        " (these servers run without autovacuum)"
    )
    print(
        f"{'maintenance':<14} {'input s':>8} {'wall s':>7} {'facts MB':>9} {'all MB':>8}"
        f" {'facts dead':>11} {'HOT share of updates':>21} {'vacuums':>8}"
    )

    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "crowd100.csv"
        crowd.write_crowd(
            csv, SIZES["long_people"], 30.0, seconds, noise=0.02, seed=2, arrivals=0.0
        )
        for label in (f"every {SIZES['long_report_s']} s", "none"):
            _pg_long_run(pg, csv, label)


def _pg_long_run(pg: str, csv: Path, label: str) -> None:
    """One replay of section 4, a report line every minute of input, then the growth per
    hour between the first and the last line.

    Ticks and registers as ``toaster run`` does (on the recording's own sample times, the
    entities registered once the source has set the world up). Maintenance comes every minute
    of *input*, right after the line (which shows the dead rows a minute leaves): what a node
    running at real time does (``toaster serve``, ``toaster run --realtime``); a replay faster
    than real time maintains less often by wall time."""
    from toaster.app.runs import tick_times
    from toaster.producers import load_session

    schema = PgSchema(pg)
    try:
        db = toaster.connect(schema.url)
        store = db.store()
        session = load_session(csv)
        runner = Runner(
            session.world, session.sources, session.producers, store=store, agent_id=session.self_id
        )
        session.register(store)
        wall = time.perf_counter()
        every = SIZES["long_report_s"] * S
        next_report = session.start_ns + every
        lines: list[tuple[int, int, int, int]] = []  # (t, all bytes, facts bytes, samples)

        def report(t_ns: int) -> None:
            nonlocal next_report
            if t_ns < next_report:
                return
            next_report += every
            schema.conn.execute("SELECT pg_stat_clear_snapshot()")
            row = schema.conn.execute(
                "SELECT pg_total_relation_size(relid), n_dead_tup, n_tup_hot_upd, n_tup_upd, "
                "vacuum_count + autovacuum_count, (SELECT COUNT(*) FROM "
                f"{schema.name}.fact_samples) FROM pg_stat_user_tables WHERE schemaname = %s "
                "AND relname = 'facts'",
                (schema.name,),
            ).fetchone()
            total = schema.size()[0]
            hot = row[2] / row[3] if row[3] else 0.0
            lines.append((t_ns, total, row[0], row[5]))
            print(
                f"{label:<14} {(t_ns - session.start_ns) / S:>8.0f}"
                f" {time.perf_counter() - wall:>7.1f} {row[0] / 1e6:>9.1f}"
                f" {total / 1e6:>8.1f} {row[1]:>11,} {hot:>20.0%} {row[4]:>8}",
                flush=True,
            )
            if label != "none":
                db.maintain()

        times = tick_times(session, session.end_ns)
        runner.run_at(times.tolist(), on_tick=report, maintain_every_s=None)
        db.close()
        if len(lines) > 1:
            (t0, all0, facts0, n0), (t1, all1, facts1, n1) = lines[0], lines[-1]
            hour = 3600 * S / (t1 - t0)
            print(
                f"{label:<14} growth from {(t0 - session.start_ns) / S:.0f} s to "
                f"{(t1 - session.start_ns) / S:.0f} s of input: {(all1 - all0) * hour / 1e6:.1f}"
                f" MB/h in all, facts {(facts1 - facts0) * hour / 1e6:.1f} MB/h, "
                f"{(n1 - n0) * hour:,.0f} samples/h",
                flush=True,
            )
    finally:
        schema.drop()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pg", default=os.environ.get("TOASTER_BENCH_PG", PG_DEFAULT))
    parser.add_argument("--no-pg", action="store_true", help="SQLite only")
    parser.add_argument("--only-pg", action="store_true", help="PostgreSQL only (must answer)")
    parser.add_argument("--ticks", type=int, default=15)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--only", choices=("tick", "crowd", "size", "pg-long"))
    parser.add_argument(
        "--long",
        type=float,
        default=600.0,
        help="input seconds of the PostgreSQL long run (section 4)",
    )
    parser.add_argument("--humans", help="crowds of section 1b, comma-separated (default 100,500)")
    parser.add_argument(
        "--growth-rows", type=int, help="section 3: only its first N crowds (1: 100 at once)"
    )
    parser.add_argument("--quick", action="store_true", help="small sizes (a smoke run)")
    args = parser.parse_args()
    if args.quick:
        SIZES.update(QUICK)
        args.ticks, args.repeats, args.long = 3, 1, 4.0
    if args.humans:
        SIZES["live_humans"] = tuple(int(h) for h in args.humans.split(","))
    pg = None if args.no_pg else args.pg
    if pg:
        try:
            PgSchema(pg).drop()
        except Exception as exc:
            if args.only_pg:
                sys.exit(f"PostgreSQL not reachable at {pg} ({exc}); start it or pass --pg URL")
            print(f"PostgreSQL not reachable at {pg} ({exc.__class__.__name__}); skipping it")
            pg = None
    backends = [*([] if args.only_pg else ["sqlite"]), *(["postgresql"] if pg else [])]
    if args.only in (None, "tick"):
        if not args.humans:  # --humans asks for the live crowds only
            bench_ticks(backends, pg, args.ticks, args.repeats)
        bench_live_crowds(backends, pg, max(args.ticks, 30) if not args.quick else 3, args.repeats)
    if args.only in (None, "crowd"):
        bench_crowd(backends, pg, args.repeats)
    if args.only in (None, "size"):
        bench_size(backends, pg, args.growth_rows)
    if args.only in (None, "pg-long") and pg:
        bench_pg_long(pg, args.long)


if __name__ == "__main__":
    main()
