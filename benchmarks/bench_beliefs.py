"""Belief propagation cost: changed self facts per second with N other agents perceiving.

Each tick is one snapshot of the self robot in which every one of ``--entities`` objects in the
room changes its symbolic value: a close + open + event for the robot. "no" rules is the same
run with beliefs disabled (the baseline). With the rules ("shared", the default), a holder that
perceives every change follows the robot's rows and writes none; "copied" (the setting
share_rows = false) is the straightforward design, measured in the same run: every perceiving
holder gets a close + open + event per change. "holder rows/change" counts the facts, events and
belief_follow rows inserted for holders per changed self fact (the straightforward design
inserts 2 and updates 1 per perceiving holder). "churn" keeps one holder out of the room two
ticks in four: it misses every change of one tick (1,000 beliefs stop following) and catches
up on the next (1,000 start again), the expensive transitions.
"single writes" compares one change per transaction written by the library
(Store.assert_fact) with the same change written by a plain SQL client (INSERT INTO fact_inbox,
a separate connection): both run the database's rule; the inbox also applies the write itself
in SQL.
Depth 2 to 4 with 5 or 10 agents (25 to 780 holders, everyone in one room) measure groups of
holders that perceive alike (setting group_holders); "alone" is the same case with
group_holders = false, every holder computed by itself. Each case runs ``--repeats`` times
(fresh database each time); the table gives the median rate (and the range).
Usage: python benchmarks/bench_beliefs.py [--ticks 10] [--entities 1000] [--writes 300]
       [--repeats 3] [--pg URL] [--no-pg | --only-pg] [--only SUBSTRING] [--quick]
(``--quick``: 2 ticks of 50 entities, 10 single writes, one run of three of the cases: a smoke
run. PostgreSQL schemas are private to the run and dropped at its end.)
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time

import sqlalchemy as sa

import toaster
from toaster.beliefs import api

PG = "postgresql://postgres@127.0.0.1:5432/test"


_SCHEMAS: list[str] = []  # created by this run, dropped at its end


def _engine(url: str) -> sa.Engine:
    return sa.create_engine(url.replace("postgresql://", "postgresql+psycopg://"))


def _pg_schema(url: str, name: str) -> str:
    name = f"{name}_{os.getpid()}"
    engine = _engine(url)
    with engine.begin() as conn:
        conn.exec_driver_sql(f'DROP SCHEMA IF EXISTS "{name}" CASCADE')
        conn.exec_driver_sql(f'CREATE SCHEMA "{name}"')
    engine.dispose()
    if name not in _SCHEMAS:
        _SCHEMAS.append(name)
    sep = "&" if "?" in url else "?"
    return f"{url}{sep}options=-csearch_path%3D{name}"


def _drop_schemas(url: str) -> None:
    engine = _engine(url)
    with engine.begin() as conn:
        for name in _SCHEMAS:
            conn.exec_driver_sql(f'DROP SCHEMA IF EXISTS "{name}" CASCADE')
    engine.dispose()


def _holder_rows(db: toaster.Database) -> int:
    with db.transaction() as conn:
        return conn.exec_driver_sql(
            "SELECT (SELECT count(*) FROM facts f JOIN fact_keys k ON k.id = f.key_id "
            "WHERE k.agent_id <> 'R') + (SELECT count(*) FROM events WHERE agent_id <> 'R') "
            "+ (SELECT count(*) FROM belief_follow)"
        ).scalar_one()


def run(
    url: str,
    agents: int,
    depth: int,
    rules: bool,
    ticks: int,
    entities: int,
    churn: bool = False,
    share: bool = True,
    grouped: bool = True,
) -> tuple[float, float]:
    """(changed self facts per second, holder rows written per changed self fact)."""
    with toaster.connect(url) as db:
        api.configure(db, enabled=rules, depth=depth, share_rows=share, group_holders=grouped)
        st = db.store()
        st.add_entity("R", "robot", is_self=True, t_ns=0)
        for i in range(agents):
            st.add_entity(f"H{i}", "human", t_ns=0)
        room = [toaster.Fact(f"H{i}", "IsInRoom", "LAB") for i in range(agents)]
        room += [toaster.Fact(f"O{i}", "IsInRoom", "LAB") for i in range(entities)]

        def snapshot(k: int) -> list[toaster.Fact]:
            where = list(room)
            if churn and k % 4 >= 2:  # H0 spends two ticks in four in the hall: it misses
                where[0] = toaster.Fact("H0", "IsInRoom", "HALL")  # the 2nd, sees the 1st again
            return where + [
                toaster.Fact(f"O{i}", "Distance", "R", "near" if k % 2 else "far")
                for i in range(entities)
            ]

        st.sync_snapshot("bench", "R", 1, snapshot(0))  # warm-up: keys, holders
        st.sync_snapshot("bench", "R", 2, snapshot(1))
        if url.startswith("postgresql"):
            with db.transaction() as conn:
                conn.exec_driver_sql("ANALYZE")
        rows = _holder_rows(db)
        start = time.perf_counter()
        for k in range(2, ticks + 2):
            st.sync_snapshot("bench", "R", k + 1, snapshot(k))
        elapsed = time.perf_counter() - start
        return ticks * entities / elapsed, (_holder_rows(db) - rows) / (ticks * entities)


def single_writes(url: str, agents: int, writes: int, raw: bool) -> float:
    """Changes per second, one per transaction, by the library or through fact_inbox."""
    with toaster.connect(url) as db:
        st = db.store()
        st.add_entity("R", "robot", is_self=True, t_ns=0)
        for i in range(agents):
            st.add_entity(f"H{i}", "human", t_ns=0)
        st.sync_snapshot(
            "room",
            "R",
            1,
            [toaster.Fact(f"H{i}", "IsInRoom", "LAB") for i in range(agents)]
            + [toaster.Fact(f"O{i}", "IsInRoom", "LAB") for i in range(50)],
        )
        changes = [(f"O{k % 50}", "near" if (k // 50) % 2 else "far", k + 2) for k in range(writes)]
        engine = sa.create_engine(db.url.replace("postgresql://", "postgresql+psycopg://"))
        start = time.perf_counter()
        if raw:
            for subject, value, t in changes:
                with engine.begin() as conn:
                    conn.execute(
                        sa.text(
                            "INSERT INTO fact_inbox (agent_id, subject_id, property, target_id, "
                            "value_text, t_ns, source) VALUES ('R', :s, 'Distance', 'R', :v, :t, "
                            "'user')"
                        ),
                        {"s": subject, "v": value, "t": t},
                    )
        else:
            for subject, value, t in changes:
                st.assert_fact(
                    "R", toaster.Fact(subject, "Distance", "R", value), t_ns=t, strict=False
                )
        elapsed = time.perf_counter() - start
        engine.dispose()
        return writes / elapsed


#: (agents, depth, rules, churn, share_rows, group_holders); "copied" is the straightforward
#: design, "alone" every holder computed by itself.
CASES = [
    (0, 1, False, False, True, True),
    (1, 1, True, False, True, True),
    (5, 1, True, False, True, True),
    (10, 1, True, False, True, True),
    (20, 1, True, False, True, True),
    (5, 2, True, False, True, True),
    (10, 2, True, False, True, True),
    (10, 2, True, False, True, False),
    (5, 3, True, False, True, True),
    (5, 4, True, False, True, True),
    (10, 1, True, True, True, True),
    (10, 1, True, False, False, True),
]


def _label(rules: bool, share: bool, grouped: bool) -> str:
    if not rules:
        return "no"
    return ("shared" if share else "copied") if grouped else "alone"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--ticks", type=int, default=10)
    parser.add_argument("--entities", type=int, default=1000)
    parser.add_argument("--writes", type=int, default=300)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--pg", default=PG, help="PostgreSQL URL ('' to skip)")
    parser.add_argument("--no-pg", action="store_true", help="SQLite only")
    parser.add_argument("--only-pg", action="store_true", help="PostgreSQL only")
    parser.add_argument("--quick", action="store_true", help="small sizes (a smoke run)")
    parser.add_argument(
        "--only",
        default="",
        help="run the cases whose label contains this (e.g. 'depth 2', 'sqlite')",
    )
    args = parser.parse_args()
    if args.quick:
        args.ticks, args.entities, args.writes, args.repeats = 2, 50, 10, 1
    cases = [CASES[i] for i in (0, 6, 10)] if args.quick else CASES
    backends = [
        b
        for b in ("sqlite", "postgresql")
        if not (b == "postgresql" and (args.no_pg or not args.pg))
        and not (b == "sqlite" and args.only_pg)
    ]
    try:
        _run(args, cases, backends)
    finally:
        if _SCHEMAS:
            _drop_schemas(args.pg)


def _run(args: argparse.Namespace, cases: list[tuple], backends: list[str]) -> None:
    print(
        f"{'backend':10} {'agents':>6} {'depth':>5} {'rules':>7} {'churn':>5} "
        f"{'changed facts/s':>16} {'range':>15} {'vs no rules':>11} {'holder rows/change':>18}"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for backend in backends:
            baseline = None
            for n, (agents, depth, rules, churn, share, grouped) in enumerate(cases):
                label = (
                    f"{backend} {agents} agents depth {depth} {_label(rules, share, grouped)}"
                    f"{' churn' if churn else ''}"
                )
                if rules and args.only not in label:  # (the baseline always runs)
                    continue
                rates, rows = [], 0.0
                for r in range(args.repeats):
                    if backend == "sqlite":
                        url = f"sqlite:///{tmp}/bench{n}_{r}.db"
                    else:
                        url = _pg_schema(args.pg, f"bench_beliefs_{n}")
                    rate, rows = run(
                        url, agents, depth, rules, args.ticks, args.entities, churn, share, grouped
                    )
                    rates.append(rate)
                rate = statistics.median(rates)
                baseline = baseline or rate
                spread = f"{min(rates) / 1000:.1f}-{max(rates) / 1000:.1f}k"
                print(
                    f"{backend:10} {agents:6d} {depth:5d} {_label(rules, share, grouped):>7} "
                    f"{'yes' if churn else 'no':>5} {rate:16,.0f} {spread:>15} "
                    f"{rate / baseline:10.2f}x {rows:18.2f}",
                    flush=True,
                )
        print(
            f"\nsingle writes (one change per transaction, 10 agents in the room)\n"
            f"{'backend':10} {'library/s':>10} {'fact_inbox/s':>13} {'inbox vs library':>17}"
        )
        for backend in backends:
            if args.only and "single" not in args.only:
                continue
            rates = []
            for n, raw in enumerate((False, True)):
                url = (
                    f"sqlite:///{tmp}/single{n}.db"
                    if backend == "sqlite"
                    else _pg_schema(args.pg, f"bench_single_{n}")
                )
                rates.append(single_writes(url, 10, args.writes, raw))
            print(
                f"{backend:10} {rates[0]:10,.0f} {rates[1]:13,.0f} {rates[1] / rates[0]:16.2f}x",
                flush=True,
            )


if __name__ == "__main__":
    main()
