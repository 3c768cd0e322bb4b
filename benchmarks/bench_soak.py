"""Soak of a live toaster: what an hour (or a day) of `toaster serve --ros1` costs in memory,
disk and tick time, per window of the run.

The path users run: a real roscore, `toaster serve --ros1 --tf-map FRAMES` with its defaults
(30 Hz) and a status line every window (`--status-every`), and a rospy client under Debian's
Python (`live_client.py`) publishing /tf for 20 humans (2 joints each) and 50 objects at 30 Hz,
each human stepping into and out of its zone once per `--cycle` seconds (10 by default: a
person at a counter; bench_live.py's 1 s cycle changes every distance twice a second). Each
window's row: the node's ticks, p50 / p99 / max tick time and overruns (from its status line),
its RSS and the database's size when the line came. The summary: RSS slope and database growth
(least squares over the run after its first sixth, 10 minutes of an hour), rows an hour, the
worst tick, against the targets (RSS < 5 MB/h, growth < 100 MB/h, no tick over 500 ms). The
baseline, measured in the same run: the RSS slope of the client process, which holds nothing
that grows (the noise floor of the method), and the node's RSS slope before that sixth.

Run: .venv/bin/python benchmarks/bench_soak.py [--minutes 60] [--no-pg | --only-pg] [--quick]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import toaster
from bench_live import frame_map, latencies, pct, put_zones
from bench_run import Database
from toaster.ros1.core import RosCore

HERE = Path(__file__).resolve().parent
PG_DEFAULT = "postgresql://postgres@127.0.0.1:5432/test"
SAMPLE_S = 5.0
WINDOW = re.compile(
    r"window ([\d.]+) s: (\d+) ticks, p50 ([\d.]+) ms, p99 ([\d.]+) ms, "
    r"max ([\d.]+) ms, (\d+) overruns"
)
TARGET_RSS_MB_H, TARGET_GROWTH_MB_H, TARGET_TICK_MS = 5.0, 100.0, 500.0
#: The tables an hour of input fills (the rows of the summary: the first three).
TABLES = ("facts", "fact_samples", "events", "fact_keys")


def rss_mb(pid: int) -> float:
    """Resident set size of process ``pid`` in MB (0 once it is gone)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return 0.0
    found = re.search(r"VmRSS:\s+(\d+) kB", status)
    return int(found.group(1)) / 1024 if found else 0.0


def slope_per_hour(samples: list[tuple[float, float]]) -> float:
    """Least-squares slope of (seconds, value) samples, per hour."""
    if len(samples) < 2:
        return float("nan")
    t, v = np.array(samples).T
    return float(np.polyfit(t, v, 1)[0] * 3600)


@dataclass
class Soak:
    """What one backend's run measured."""

    backend: str
    seconds: float
    windows: list[dict[str, float]] = field(default_factory=list)
    node_rss: list[tuple[float, float]] = field(default_factory=list)
    client_rss: list[tuple[float, float]] = field(default_factory=list)
    db_mb: list[tuple[float, float]] = field(default_factory=list)
    rows: dict[str, int] = field(default_factory=dict)
    table_bytes: dict[str, int] = field(default_factory=dict)
    summary: str = ""
    latency_ms: list[float] = field(default_factory=list)


def count_rows(url: str) -> dict[str, int]:
    with toaster.connect(url) as db, db.transaction() as conn:
        return {
            table: int(conn.exec_driver_sql(f"SELECT count(*) FROM {table}").scalar_one())
            for table in TABLES
        }


def soak(backend: str, pg: str, args: argparse.Namespace, tmp: str, report: Any) -> Soak:
    """One run: roscore, `toaster serve --ros1`, the client for ``args.minutes``."""
    seconds = args.minutes * 60
    database = Database(backend, pg, tmp)
    frames = Path(tmp) / f"frames-{backend}.json"
    frames.write_text(json.dumps(frame_map(args.humans, args.objects)))
    result = Soak(backend, seconds)
    try:
        put_zones(database.url, args.humans)
        with RosCore(Path(tmp) / f"ros-{uuid.uuid4().hex[:6]}") as env:
            log = Path(tmp) / f"serve-{backend}.log"
            with log.open("w") as err:
                node = subprocess.Popen(
                    [
                        sys.executable,
                        "-m",
                        "toaster",
                        "--db",
                        database.url,
                        "serve",
                        "--ros1",
                        "--tf-map",
                        str(frames),
                        "--status-every",
                        str(args.window),
                    ],
                    env=env,
                    stderr=err,
                    start_new_session=True,
                )
                try:
                    _drive(node, log, env, database, args, result, report)
                finally:
                    if node.poll() is None:
                        os.killpg(node.pid, signal.SIGTERM)
                        node.wait(60)
            result.summary = log.read_text()
        result.rows = count_rows(database.url)
        result.table_bytes = database.tables()
    finally:
        database.close()
    return result


def _drive(
    node: subprocess.Popen[Any],
    log: Path,
    env: dict[str, str],
    database: Database,
    args: argparse.Namespace,
    result: Soak,
    report: Any,
) -> None:
    while "(Ctrl-C stops)" not in log.read_text():
        if node.poll() is not None:
            raise RuntimeError(log.read_text()[-2000:])
        time.sleep(0.05)
    # the client's output goes to files, not pipes: an hour of its JSON is ~1 MB, and a full
    # pipe blocks the client while nobody reads it
    out_path, err_path = log.with_suffix(".client.out"), log.with_suffix(".client.err")
    with out_path.open("w") as out_file, err_path.open("w") as err_file:
        client = _start_client(out_file, err_file, env, args, result)
        _watch(client, node, log, database, result, report)
    out, err = out_path.read_text(), err_path.read_text()
    if client.returncode != 0 or not out.strip():
        raise RuntimeError("live_client.py failed: " + err[-2000:])
    seen = json.loads(out.strip().splitlines()[-1])
    result.latency_ms = latencies(seen["toggles"], seen["seen"])


def _start_client(
    out_file: Any, err_file: Any, env: dict[str, str], args: argparse.Namespace, result: Soak
) -> subprocess.Popen[Any]:
    return subprocess.Popen(
        [
            "/usr/bin/python3",
            str(HERE / "live_client.py"),
            str(args.humans),
            str(args.objects),
            str(result.seconds),
            str(args.cycle),
        ],
        env=env,
        stdout=out_file,
        stderr=err_file,
    )


def _watch(
    client: subprocess.Popen[Any],
    node: subprocess.Popen[Any],
    log: Path,
    database: Database,
    result: Soak,
    report: Any,
) -> None:
    """Rows as the node's status lines come, samples every ``SAMPLE_S``, until the client
    ends."""
    start = time.monotonic()
    seen_windows = 0
    next_sample = 0.0
    while client.poll() is None:
        if node.poll() is not None:
            client.kill()
            raise RuntimeError("toaster serve stopped: " + log.read_text()[-2000:])
        now = time.monotonic() - start
        windows = WINDOW.findall(log.read_text())
        for found in windows[seen_windows:]:
            span, ticks, p50, p99, worst, overruns = (float(x) for x in found)
            row = {
                "end_min": now / 60,
                "span_s": span,
                "ticks": ticks,
                "p50": p50,
                "p99": p99,
                "max": worst,
                "overruns": overruns,
                "rss": rss_mb(node.pid),
                "db": database.size()[0] / 1e6,
            }
            result.windows.append(row)
            report(result.backend, row)
        seen_windows = len(windows)
        if now >= next_sample:
            result.node_rss.append((now, rss_mb(node.pid)))
            result.client_rss.append((now, rss_mb(client.pid)))
            result.db_mb.append((now, database.size()[0] / 1e6))
            next_sample = now + SAMPLE_S
        time.sleep(0.5)


def settled(samples: list[tuple[float, float]], seconds: float) -> list[tuple[float, float]]:
    """The samples after the run's first sixth (10 minutes of an hour)."""
    return [(t, v) for t, v in samples if t >= seconds / 6]


def print_tables(runs: list[Soak]) -> None:
    """Where the bytes go: each table with its indexes, per hour of input and per row."""
    print()
    print(f"  {'backend':<11} {'table':<13} {'rows/h':>9} {'MB/h':>7} {'bytes/row':>9}")
    for run in runs:
        rest = dict(run.table_bytes)
        for table in TABLES:
            size, count = rest.pop(table, 0), run.rows.get(table, 0)
            print(
                f"  {run.backend:<11} {table:<13} {count * 3600 / run.seconds:>9.0f} "
                f"{size * 3.6e-3 / run.seconds:>7.1f} {size / max(1, count):>9.0f}"
            )
        other = sum(rest.values())
        print(
            f"  {run.backend:<11} {'(the rest)':<13} {'':>9} {other * 3.6e-3 / run.seconds:>7.1f}"
        )
    print("  (MB/h: the table's bytes at the end, with its indexes, over the run's length)")


def print_summary(runs: list[Soak], args: argparse.Namespace) -> None:
    print_tables(runs)
    print()
    print(
        f"{'backend':<11} {'RSS MB/h':>9} {'(first 1/6)':>11} {'client MB/h':>11} "
        f"{'db MB/h':>8} {'rows/h':>9} {'bytes/row':>9} {'worst ms':>9} {'overruns':>9} "
        f"{'fact p50':>9} {'fact p99':>9}  targets"
    )
    for run in runs:
        node_slope = slope_per_hour(settled(run.node_rss, run.seconds))
        early = slope_per_hour([s for s in run.node_rss if s[0] < run.seconds / 6])
        client = slope_per_hour(settled(run.client_rss, run.seconds))
        growth = slope_per_hour(settled(run.db_mb, run.seconds))
        counted = sum(run.rows[table] for table in TABLES[:3])
        rows = counted * 3600 / run.seconds
        size = run.db_mb[-1][1] * 1e6 if run.db_mb else float("nan")
        per_row = size / max(1, counted)
        worst = max((w["max"] for w in run.windows), default=float("nan"))
        overruns = sum(w["overruns"] for w in run.windows)
        met = [
            f"RSS {'met' if node_slope < TARGET_RSS_MB_H else 'MISSED'}",
            f"growth {'met' if growth < TARGET_GROWTH_MB_H else 'MISSED'}",
            f"stalls {'met' if worst < TARGET_TICK_MS else 'MISSED'}",
        ]
        print(
            f"{run.backend:<11} {node_slope:>9.2f} {early:>11.1f} {client:>11.2f} "
            f"{growth:>8.1f} {rows:>9.0f} {per_row:>9.0f} {worst:>9.1f} {overruns:>9.0f} "
            f"{pct(run.latency_ms, 50):>9.1f} {pct(run.latency_ms, 99):>9.1f}  "
            f"{', '.join(met)}"
        )
    print(
        f"(RSS and growth: least squares after the first {args.minutes / 6:.0f} min; "
        f"rows: facts + fact_samples + events at the end; fact p50/p99: pose published -> "
        "FactList received, ms; targets: RSS < 5 MB/h, growth < 100 MB/h, ticks < 500 ms)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pg", default=os.environ.get("TOASTER_BENCH_PG", PG_DEFAULT))
    parser.add_argument("--no-pg", action="store_true", help="SQLite only")
    parser.add_argument("--only-pg", action="store_true", help="PostgreSQL only")
    parser.add_argument("--minutes", type=float, default=60.0)
    parser.add_argument("--window", type=float, default=300.0, help="seconds per row")
    parser.add_argument("--humans", type=int, default=20)
    parser.add_argument("--objects", type=int, default=50)
    parser.add_argument(
        "--cycle", type=float, default=10.0, help="seconds of each human's in-and-out cycle"
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help="1 minute, 10 s windows, 4 humans and 10 objects (tests)",
    )
    args = parser.parse_args()
    args.pg = args.pg.replace("postgresql+psycopg://", "postgresql://", 1)  # psycopg's own
    if args.quick:
        args.minutes, args.window, args.humans, args.objects, args.cycle = 1.0, 10.0, 4, 10, 2.0
    backends = (
        ["postgresql"] if args.only_pg else ["sqlite"] + ([] if args.no_pg else ["postgresql"])
    )
    print(
        f"Soak of toaster serve --ros1: {args.humans} humans (2 joints) + {args.objects} "
        f"objects on /tf at 30 Hz, in and out of a zone every {args.cycle:g} s, "
        f"{args.minutes:g} min per backend, a row every {args.window:g} s"
    )
    print(
        f"{'backend':<11} {'end min':>7} {'ticks':>6} {'p50 ms':>7} {'p99 ms':>7} "
        f"{'max ms':>7} {'overruns':>8} {'RSS MB':>7} {'db MB':>7}",
        flush=True,
    )

    def report(backend: str, row: dict[str, float]) -> None:
        print(
            f"{backend:<11} {row['end_min']:>7.1f} {row['ticks']:>6.0f} {row['p50']:>7.1f} "
            f"{row['p99']:>7.1f} {row['max']:>7.1f} {row['overruns']:>8.0f} "
            f"{row['rss']:>7.1f} {row['db']:>7.1f}",
            flush=True,
        )

    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for backend in backends:
            runs.append(soak(backend, args.pg, args, tmp, report))
    print_summary(runs, args)


if __name__ == "__main__":
    main()
