"""Belief propagation cost: changed self facts per second with N other agents perceiving.

Each tick is one snapshot of the self robot in which every one of ``--entities`` objects in the
room changes its symbolic value (so each change is a close + open + event for the robot and, with
the rules, for every perceiving holder). "no rules" is the same run with beliefs disabled.
Usage: python benchmarks/bench_beliefs.py [--ticks 10] [--entities 1000] [--pg URL]
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


def run(url: str, agents: int, depth: int, rules: bool, ticks: int, entities: int) -> float:
    """Changed self facts per second for one configuration."""
    with toaster.connect(url) as db:
        api.configure(db, enabled=rules, depth=depth)
        st = db.store()
        st.add_entity("R", "robot", is_self=True, t_ns=0)
        for i in range(agents):
            st.add_entity(f"H{i}", "human", t_ns=0)
        room = [toaster.Fact(f"H{i}", "IsInRoom", "LAB") for i in range(agents)]
        room += [toaster.Fact(f"O{i}", "IsInRoom", "LAB") for i in range(entities)]

        def snapshot(k: int) -> list[toaster.Fact]:
            return room + [toaster.Fact(f"O{i}", "Distance", "R", "near" if k % 2 else "far")
                           for i in range(entities)]

        st.sync_snapshot("bench", "R", 1, snapshot(0))  # warm-up: keys, holders
        st.sync_snapshot("bench", "R", 2, snapshot(1))
        if url.startswith("postgresql"):
            with db.transaction() as conn:
                conn.exec_driver_sql("ANALYZE")
        start = time.perf_counter()
        for k in range(2, ticks + 2):
            st.sync_snapshot("bench", "R", k + 1, snapshot(k))
        return ticks * entities / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--ticks", type=int, default=10)
    parser.add_argument("--entities", type=int, default=1000)
    parser.add_argument("--pg", default=PG, help="PostgreSQL URL ('' to skip)")
    args = parser.parse_args()
    cases = [(0, 1, False), (1, 1, True), (5, 1, True), (10, 1, True), (20, 1, True),
             (5, 2, True)]
    print(f"{'backend':10} {'agents':>6} {'depth':>5} {'rules':>5} {'changed facts/s':>16}")
    with tempfile.TemporaryDirectory() as tmp:
        for backend in ("sqlite", "postgresql"):
            if backend == "postgresql" and not args.pg:
                continue
            for n, (agents, depth, rules) in enumerate(cases):
                if backend == "sqlite":
                    url = f"sqlite:///{tmp}/bench{n}.db"
                else:
                    url = _pg_schema(args.pg, f"bench_beliefs_{n}")
                rate = run(url, agents, depth, rules, args.ticks, args.entities)
                print(f"{backend:10} {agents:6d} {depth:5d} {'yes' if rules else 'no':>5} "
                      f"{rate:16,.0f}", flush=True)


if __name__ == "__main__":
    main()
