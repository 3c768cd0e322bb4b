"""Fresh databases: ``toaster.connect()`` on a new database, and one ToM-bAbI story on one.

For each backend, in one run, medians of ``--repeats`` (cases interleaved, so that a busy
machine slows both sides alike):

* connect: ``toaster.connect(url)`` then ``close()`` on a new SQLite file (a copy of the
  migrated template, :mod:`toaster.db.template`) or a new PostgreSQL schema (the head's
  final-state script, :mod:`toaster.db.final_state`); the baseline is the migration path
  (SQLite: a new file migrated by every revision; PostgreSQL: ``migrate.upgrade(...,
  script=False)``), then the same ``connect``;
* story: the same fresh database, then one ToM-bAbI story replayed and its question answered
  by the ToM runner (``tools/tombabi.replay_story``: a second-order false-belief story of nine
  lines, written here in the data set's format), then ``close()``; the baseline makes the
  database by the migration path. "replay" is the story alone.

"cpu ms" is this process's CPU time of the fresh case (``time.process_time``): a busy machine
inflates it less than the wall time (PostgreSQL's server time is not in it).

A PostgreSQL schema is made empty beforehand (``CREATE SCHEMA``, not timed) and dropped after.
The first creation of a run leaves the script (and the SQLite template) in the cache
(``$XDG_CACHE_HOME/toaster/templates``); it is made before timing.

Usage: python benchmarks/bench_fresh.py [--no-pg | --only-pg] [--repeats 7] [--pg URL]
       [--quick]   (``--quick``: 1 repeat, a smoke run of seconds)
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
import uuid
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # tools/ (the ToM-bAbI runner) is beside src/

import toaster  # noqa: E402
from toaster.db import migrate  # noqa: E402
from toaster.db.engine import make_engine  # noqa: E402
from tools import tombabi  # noqa: E402

PG = "postgresql+psycopg://postgres@127.0.0.1:5432/test"
STORY = [
    "1 Sally entered the kitchen.\t1",
    "2 Anne entered the kitchen.\t1 2",
    "3 The marble is in the basket.\t1 2",
    "4 Anne exited the kitchen.\t1 2",
    "5 Sally moved the marble to the box.\t1",
    "6 Sally exited the kitchen.\t1",
    "7 Phone rang.\t",
    "8 Anne entered the kitchen.\t2",
    "9 Where does Sally think that Anne searches for the marble?\tbasket\t1",
]


class Fresh:
    """New empty databases of one backend: SQLite files in a temporary folder, or schemas of
    the PostgreSQL database ``pg`` (dropped by :meth:`close`)."""

    def __init__(self, backend: str, pg: str) -> None:
        self.backend, self.pg = backend, pg
        self.folder = tempfile.TemporaryDirectory()
        self.schemas: list[str] = []
        self.admin = make_engine(pg) if backend == "postgresql" else None

    def url(self) -> str:
        if self.admin is None:
            return f"sqlite:///{Path(self.folder.name) / uuid.uuid4().hex}.db"
        schema = f"bf_{uuid.uuid4().hex[:10]}"
        with self.admin.begin() as conn:
            conn.exec_driver_sql(f'CREATE SCHEMA "{schema}"')
        self.schemas.append(schema)
        sep = "&" if "?" in self.pg else "?"
        return f"{self.pg}{sep}options=-csearch_path%3D{schema}"

    def close(self) -> None:
        if self.admin is not None:
            for schema in self.schemas:  # one at a time: a schema takes ~150 locks to drop
                with self.admin.begin() as conn:
                    conn.exec_driver_sql(f'DROP SCHEMA IF EXISTS "{schema}" CASCADE')
            self.admin.dispose()
        self.folder.cleanup()


def migrated(url: str) -> None:
    """The baseline: the database made by the migrations (no template, no script)."""
    engine = make_engine(url)
    try:
        migrate.upgrade(engine, script=False)
    finally:
        engine.dispose()


def timed(fresh: Fresh, baseline: bool, story: bool) -> tuple[float, float, float]:
    """(seconds of the whole case, of the story's replay alone, of this process's CPU)."""
    url = fresh.url()
    start, cpu = time.perf_counter(), time.process_time()
    if baseline:
        migrated(url)
    db = toaster.connect(url)
    replay = 0.0
    try:
        if story:
            begin = time.perf_counter()
            result = tombabi.replay_story(db, STORY)
            replay = time.perf_counter() - begin
            if result.misses or result.correct != 1 or result.perceiver_mismatches:
                msg = f"the story went wrong: {result.misses} {result.perceiver_mismatches}"
                raise SystemExit(msg)
    finally:
        db.close()
    return time.perf_counter() - start, replay, time.process_time() - cpu


def _medians(
    cases: dict[bool, list[tuple[float, float, float]]],
) -> Callable[[bool, int], float]:
    """``med(baseline, i)``: the median in ms of the ``i``-th time of ``cases[baseline]``."""
    return lambda baseline, i: 1000 * statistics.median(r[i] for r in cases[baseline])


def run(backend: str, pg: str, repeats: int) -> list[tuple[str, ...]]:
    fresh = Fresh(backend, pg)
    rows = []
    try:
        timed(fresh, False, True)  # leaves the template / the script, warms the imports
        for story in (False, True):
            cases: dict[bool, list[tuple[float, float, float]]] = {False: [], True: []}
            for _ in range(repeats):
                for baseline in (True, False):
                    cases[baseline].append(timed(fresh, baseline, story))
            med = _medians(cases)
            fast, slow = med(False, 0), med(True, 0)
            replay = f"{med(False, 1):.0f}" if story else ""
            name = "story (fresh + replay)" if story else "connect (new database)"
            cpu = f"{med(False, 2):.0f}"
            rows.append(
                (name, backend, f"{fast:.0f}", f"{slow:.0f}", f"{slow / fast:.2f}x", replay, cpu)
            )
    finally:
        fresh.close()
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--pg", default=PG, help="PostgreSQL URL")
    parser.add_argument("--no-pg", action="store_true", help="SQLite only")
    parser.add_argument("--only-pg", action="store_true", help="PostgreSQL only")
    parser.add_argument("--quick", action="store_true", help="one repeat (a smoke run)")
    args = parser.parse_args()
    repeats = 1 if args.quick else args.repeats
    backends = [b for b in ("sqlite", "postgresql") if not (b == "sqlite" and args.only_pg)]
    backends = [b for b in backends if not (b == "postgresql" and args.no_pg)]
    rows = [row for backend in backends for row in run(backend, args.pg, repeats)]
    header = ("measure", "backend", "fresh ms", "migrations ms", "ratio", "replay ms", "cpu ms")
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    for row in [header, *rows]:
        print("  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)))
    print(f"medians of {repeats}; the baseline makes the database by the migrations")
    return 0


if __name__ == "__main__":
    sys.exit(main())
