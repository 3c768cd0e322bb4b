"""Tick latency against the number of writers sharing one PostgreSQL database.

Each writer is one robot running ``toaster run`` on the spatial Sally-Anne scenario at 30 Hz
(the library path of the command, tests/db/writers.py ``run:`` role: load, register, tick)
for ``--ticks`` ticks, all started at once and ticking together once all are registered
(each waits for a go file): several robots in one world (each is the scene's
robot body under its own id), the same people and things registered by all of them, every
robot's ticks running the belief rules. "shared" puts
every writer on one database (one schema); "own" is the baseline measured in the same run:
the same number of processes, each on its own schema, so that what the machine's CPUs cost is
told apart from what sharing the database costs. The table gives, per case, the median over
``--repeats`` runs of the tick latency's p50 and p99 (all writers' ticks together, the first
tick of each left out), the wall time, the failed ticks (there must be none), and the belief
runs a second: every database's runs (its ``belief_runs`` id sequence, registrations'
runs left out) over the span of ticking, the first tick's start to the last tick's end.
``--people own``: each robot's people are its own (renamed per robot), so the robots'
belief holders are disjoint sets, as sites whose people never meet sharing one server.
``--holders none``: the scenario's people hold no beliefs, so the ticks measure the store
alone (no belief run to serialize). ``--pace live`` (default) paces each robot's ticks at
30 Hz of wall time, as live robots tick (``toaster serve``, ``run --realtime``); ``--pace
none`` ticks back to back, as an offline ``toaster run``: every writer then saturates the
machine and, shared, the one timeline of the holders' beliefs (one belief run at a time).
Usage: python benchmarks/bench_writers.py [--writers 1,2,4,8] [--ticks 150] [--repeats 3]
       [--holders humans|none] [--people shared|own] [--pace live|none] [--pg URL] [--quick]
(PostgreSQL only. ``--quick``: 2 writers, 10 ticks each, one run: a smoke run.)
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import uuid
from importlib import resources
from pathlib import Path

import sqlalchemy as sa

from toaster.db import migrate
from toaster.db.engine import make_engine

PG = "postgresql://postgres@127.0.0.1:5432/test"
ROOT = Path(__file__).resolve().parents[1]
SCENARIO = str(resources.files("toaster") / "examples" / "scenario_spatial_sally_anne.yaml")


def _schema(url: str) -> str:
    name = f"bw_{uuid.uuid4().hex[:10]}"
    engine = make_engine(url)
    with engine.begin() as conn:
        conn.exec_driver_sql(f'CREATE SCHEMA "{name}"')
    engine.dispose()
    sep = "&" if "?" in url else "?"
    schema_url = f"{url}{sep}options=-csearch_path%3D{name}"
    engine = make_engine(schema_url)
    migrate.upgrade(engine)
    engine.dispose()
    return schema_url


def _drop(url: str, urls: list[str]) -> None:
    engine = make_engine(url)
    with engine.begin() as conn:
        for schema_url in urls:
            name = schema_url.rsplit("%3D", 1)[1]
            conn.execute(sa.text(f'DROP SCHEMA IF EXISTS "{name}" CASCADE'))
    engine.dispose()


def _belief_runs(urls: list[str]) -> int:
    """How many belief runs the databases ran (each inserts one ``belief_runs`` row, which is
    not kept: its id sequence counts them)."""
    total = 0
    for schema_url in urls:
        engine = make_engine(schema_url)
        with engine.connect() as conn:
            total += conn.execute(
                sa.text(
                    "SELECT CASE WHEN is_called THEN last_value ELSE 0 END FROM belief_runs_id_seq"
                )
            ).scalar_one()
        engine.dispose()
    return total


def _start_together(outs: list[Path], procs: list[subprocess.Popen[bytes]]) -> None:
    """Wait until every writer is registered and waits for the go file (``OUT.ready``), so
    that their ticks overlap and the span of ticking is theirs, not their start-ups'."""
    waiting = list(zip(outs, procs, strict=True))
    while waiting:  # a writer that died is not waited for (its report says why)
        waiting = [
            (o, p) for o, p in waiting if not Path(f"{o}.ready").exists() and p.poll() is None
        ]
        time.sleep(0.01)


def once(
    url: str,
    writers: int,
    shared: bool,
    ticks: int,
    holders: str = "humans",
    pace: str = "",
    people: str = "shared",
) -> tuple[float, float, float, int, float]:
    """(p50 ms, p99 ms, wall s, failed ticks, belief runs/s) of one run (runs/s: every
    database's runs over the span of the writers' ticks, first start to last end)."""
    urls = [_schema(url)] if shared else [_schema(url) for _ in range(writers)]
    with tempfile.TemporaryDirectory() as tmp:
        procs = []
        start = time.perf_counter()
        for i in range(writers):
            out = Path(tmp) / f"w{i}.json"
            role = f"run:R{i}:{SCENARIO}:30:{ticks}:{holders}:{pace}:{people}"
            procs.append(
                (
                    out,
                    subprocess.Popen(
                        env={**os.environ, "TOASTER_WRITERS_GO": str(Path(tmp) / "go")},
                        args=[
                            sys.executable,
                            "-m",
                            "tests.db.writers",
                            urls[0 if shared else i],
                            role,
                            "0",
                            str(i),
                            str(out),
                        ],
                        cwd=ROOT,
                    ),
                )
            )
        _start_together([out for out, _ in procs], [proc for _, proc in procs])
        runs_before = _belief_runs(urls)  # the registrations' runs are not the ticks'
        (Path(tmp) / "go").touch()
        for _, proc in procs:
            proc.wait()
        wall = time.perf_counter() - start
        latencies: list[float] = []
        failed = 0
        spans: list[list[float]] = []
        for out, _ in procs:
            report = json.loads(out.read_text())
            latencies += report["latencies"][1:]
            spans.append(report["span"])
            failed += len(report["failures"])
            for failure in report["failures"][:1]:
                print(f"a writer's failed tick: {str(failure)[:300]}", file=sys.stderr)
    span = max(end for _, end in spans) - min(start for start, _ in spans)
    runs = _belief_runs(urls) - runs_before
    _drop(url, urls)
    latencies.sort()
    return (
        latencies[len(latencies) // 2] * 1e3,
        latencies[min(len(latencies) - 1, int(len(latencies) * 0.99))] * 1e3,
        wall,
        failed,
        runs / span,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--writers", default="1,2,4,8")
    parser.add_argument("--ticks", type=int, default=150)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--pg", default=PG)
    parser.add_argument(
        "--pace",
        choices=("live", "none"),
        default="live",
        help="live (default): each robot ticks at 30 Hz of wall time, as "
        "`toaster serve` and `run --realtime` do; none: ticks back to "
        "back, as an offline `toaster run` (every writer saturates)",
    )
    parser.add_argument(
        "--holders",
        default="humans",
        help="humans (the scenario's people hold beliefs) or none (no belief "
        "rule work: the store alone)",
    )
    parser.add_argument(
        "--people",
        choices=("shared", "own"),
        default="shared",
        help="shared (default): every robot sees the same people (the holders are one set); "
        "own: each robot's people are its own (disjoint holder sets, as sites whose people "
        "never meet)",
    )
    parser.add_argument("--quick", action="store_true", help="small sizes (a smoke run)")
    args = parser.parse_args()
    if args.quick:
        args.writers, args.ticks, args.repeats = "2", 10, 1
    counts = [int(n) for n in args.writers.split(",")]
    failures = 0
    print(
        f"{'writers':>7} {'database':>8} {'p50 ms':>8} {'p99 ms':>8} {'wall s':>7} "
        f"{'failed':>6} {'runs/s':>7}   (medians of {args.repeats}; {args.ticks} ticks per "
        f"writer; holders: {args.holders}; people: {args.people}; pace: {args.pace}; "
        "runs/s: belief runs of all the run's databases a second of ticking)"
    )
    for n in counts:
        results = {}
        for shared in (False, True):  # the baseline first
            runs = [
                once(
                    args.pg,
                    n,
                    shared,
                    args.ticks,
                    args.holders,
                    "" if args.pace == "none" else args.pace,
                    args.people,
                )
                for _ in range(args.repeats)
            ]
            p50, p99, wall = (statistics.median(r[k] for r in runs) for k in range(3))
            rate = statistics.median(r[4] for r in runs)
            failed = sum(r[3] for r in runs)
            failures += failed
            results[shared] = p50, p99
            print(
                f"{n:7d} {'shared' if shared else 'own':>8} {p50:8.1f} {p99:8.1f} "
                f"{wall:7.1f} {failed:6d} {rate:7.1f}",
                flush=True,
            )
        ratio50 = results[True][0] / results[False][0]
        ratio99 = results[True][1] / results[False][1]
        print(f"{'':7} {'ratio':>8} {ratio50:7.2f}x {ratio99:7.2f}x   (shared / own)")
    if failures:  # a figure over failed ticks measures something else: say so in the exit code
        sys.exit(f"{failures} ticks failed: the first of each writer's is printed above")


if __name__ == "__main__":
    main()
