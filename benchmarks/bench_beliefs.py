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
Usage: python benchmarks/bench_beliefs.py [--ticks 10] [--entities 1000] [--writes 300]
       [--pg URL]
"""

from __future__ import annotations

import argparse
import tempfile
import time

import sqlalchemy as sa

import toaster
from toaster.beliefs import api

PG = "postgresql://postgres@127.0.0.1:5432/test"


def _pg_schema(url: str, name: str) -> str:
    engine = sa.create_engine(url.replace("postgresql://", "postgresql+psycopg://"))
    with engine.begin() as conn:
        conn.exec_driver_sql(f'DROP SCHEMA IF EXISTS "{name}" CASCADE')
        conn.exec_driver_sql(f'CREATE SCHEMA "{name}"')
    engine.dispose()
    return f"{url}?options=-csearch_path%3D{name}"


def _holder_rows(db: toaster.Database) -> int:
    with db.transaction() as conn:
        return conn.exec_driver_sql(
            "SELECT (SELECT count(*) FROM facts f JOIN fact_keys k ON k.id = f.key_id "
            "WHERE k.agent_id <> 'R') + (SELECT count(*) FROM events WHERE agent_id <> 'R') "
            "+ (SELECT count(*) FROM belief_follow)"
        ).scalar_one()


def run(url: str, agents: int, depth: int, rules: bool, ticks: int, entities: int,
        churn: bool = False, share: bool = True) -> tuple[float, float]:
    """(changed self facts per second, holder rows written per changed self fact)."""
    with toaster.connect(url) as db:
        api.configure(db, enabled=rules, depth=depth, share_rows=share)
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
            return where + [toaster.Fact(f"O{i}", "Distance", "R", "near" if k % 2 else "far")
                            for i in range(entities)]

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
        st.sync_snapshot("room", "R", 1, [toaster.Fact(f"H{i}", "IsInRoom", "LAB")
                                          for i in range(agents)]
                         + [toaster.Fact(f"O{i}", "IsInRoom", "LAB") for i in range(50)])
        changes = [(f"O{k % 50}", "near" if (k // 50) % 2 else "far", k + 2)
                   for k in range(writes)]
        engine = sa.create_engine(db.url.replace("postgresql://", "postgresql+psycopg://"))
        start = time.perf_counter()
        if raw:
            for subject, value, t in changes:
                with engine.begin() as conn:
                    conn.execute(sa.text(
                        "INSERT INTO fact_inbox (agent_id, subject_id, property, target_id, "
                        "value_text, t_ns, source) VALUES ('R', :s, 'Distance', 'R', :v, :t, "
                        "'user')"), {"s": subject, "v": value, "t": t})
        else:
            for subject, value, t in changes:
                st.assert_fact("R", toaster.Fact(subject, "Distance", "R", value), t_ns=t,
                               strict=False)
        elapsed = time.perf_counter() - start
        engine.dispose()
        return writes / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--ticks", type=int, default=10)
    parser.add_argument("--entities", type=int, default=1000)
    parser.add_argument("--writes", type=int, default=300)
    parser.add_argument("--pg", default=PG, help="PostgreSQL URL ('' to skip)")
    args = parser.parse_args()
    # (agents, depth, rules, churn, share_rows); the last case is the straightforward design.
    cases = [(0, 1, False, False, True), (1, 1, True, False, True), (5, 1, True, False, True),
             (10, 1, True, False, True), (20, 1, True, False, True), (5, 2, True, False, True),
             (10, 2, True, False, True), (10, 1, True, True, True), (10, 1, True, False, False)]
    print(f"{'backend':10} {'agents':>6} {'depth':>5} {'rules':>7} {'churn':>5} "
          f"{'changed facts/s':>16} {'vs no rules':>11} {'holder rows/change':>18}")
    with tempfile.TemporaryDirectory() as tmp:
        for backend in ("sqlite", "postgresql"):
            if backend == "postgresql" and not args.pg:
                continue
            baseline = None
            for n, (agents, depth, rules, churn, share) in enumerate(cases):
                if backend == "sqlite":
                    url = f"sqlite:///{tmp}/bench{n}.db"
                else:
                    url = _pg_schema(args.pg, f"bench_beliefs_{n}")
                rate, rows = run(url, agents, depth, rules, args.ticks, args.entities, churn,
                                 share)
                baseline = baseline or rate
                kind = ("shared" if share else "copied") if rules else "no"
                print(f"{backend:10} {agents:6d} {depth:5d} {kind:>7} "
                      f"{'yes' if churn else 'no':>5} {rate:16,.0f} {rate / baseline:10.2f}x "
                      f"{rows:18.2f}", flush=True)
        print(f"\nsingle writes (one change per transaction, 10 agents in the room)\n"
              f"{'backend':10} {'library/s':>10} {'fact_inbox/s':>13} {'inbox vs library':>17}")
        for backend in ("sqlite", "postgresql"):
            if backend == "postgresql" and not args.pg:
                continue
            rates = []
            for n, raw in enumerate((False, True)):
                url = (f"sqlite:///{tmp}/single{n}.db" if backend == "sqlite"
                       else _pg_schema(args.pg, f"bench_single_{n}"))
                rates.append(single_writes(url, 10, args.writes, raw))
            print(f"{backend:10} {rates[0]:10,.0f} {rates[1]:13,.0f} {rates[1] / rates[0]:16.2f}x",
                  flush=True)


if __name__ == "__main__":
    main()
