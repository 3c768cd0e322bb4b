"""Creating a database is atomic: concurrent first openings migrate once, and a process
killed (SIGKILL) at any moment of the first migration leaves no database or one at head,
which the next :func:`toaster.connect` uses without repair."""

from __future__ import annotations

import os
import random
import re
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest
import sqlalchemy as sa

import toaster
from toaster.db import migrate
from toaster.db.engine import make_engine

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

ROOT = Path(__file__).resolve().parents[2]
KILLS = 10

#: A child that imports everything, says "ready", waits for a line, then opens the database
#: (creating and migrating it) and says "done".
CHILD = """
import sys
import toaster
from toaster.db import migrate
from toaster.db.schema import metadata
print("ready", flush=True)
sys.stdin.readline()
toaster.connect(sys.argv[1]).close()
print("done", flush=True)
"""


def spawn(url: str) -> subprocess.Popen[str]:
    """A child that will open ``url`` (see :data:`CHILD`)."""
    return subprocess.Popen(
        [sys.executable, "-c", CHILD, url],
        cwd=ROOT,
        text=True,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )


def start(url: str) -> subprocess.Popen[str]:
    """A child ready to open ``url`` (imports done)."""
    return ready(spawn(url))


def ready(child: subprocess.Popen[str]) -> subprocess.Popen[str]:
    """``child`` once its imports are done."""
    assert child.stdout is not None and child.stdout.readline().strip() == "ready"
    return child


def go(child: subprocess.Popen[str]) -> None:
    """Let a ready child open its database."""
    assert child.stdin is not None
    child.stdin.write("go\n")
    child.stdin.flush()


def finish(child: subprocess.Popen[str]) -> None:
    """Wait for a child that was not killed; it must have opened the database."""
    out, err = child.communicate(timeout=60)
    assert child.returncode == 0 and out.strip() == "done", err


def schema_state(url: str) -> str | None:
    """None for an empty database (schema), else its revision; asserts it is not half-made."""
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            tables = set(conn.dialect.get_table_names(conn))
            revision = migrate.toaster_revision(conn, url)
            if revision is None:
                assert tables <= {"alembic_version"}, tables
            else:
                assert revision == migrate.head_revision()
                assert (
                    conn.execute(sa.text("SELECT COUNT(*) FROM alembic_version")).scalar_one() == 1
                )
                assert conn.execute(sa.text("SELECT COUNT(*) FROM store_state")).scalar_one() == 1
        return revision
    finally:
        engine.dispose()


def sqlite_state(path: Path) -> str | None:
    """None when no database file is there, else its revision (quick_check must pass)."""
    if not path.exists():
        assert not Path(f"{path}-wal").exists()
        return None
    conn = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    try:
        assert conn.execute("PRAGMA quick_check").fetchone() == ("ok",)
    finally:
        conn.close()
    revision = schema_state(f"sqlite:///{path}")
    assert revision is not None, "a database file without schema"
    return revision


def state(url: str) -> str | None:
    if url.startswith("sqlite:///"):
        return sqlite_state(Path(url.removeprefix("sqlite:///")))
    return schema_state(url)


def reset(url: str) -> None:
    """Make the database new again: remove the file, or empty the PostgreSQL schema."""
    if url.startswith("sqlite:///"):
        path = Path(url.removeprefix("sqlite:///"))
        for leftover in path.parent.iterdir():
            leftover.unlink()
        return
    match = re.search(r"search_path%3D(\w+)", url)
    assert match is not None
    engine = make_engine(url)
    with engine.begin() as conn:
        conn.exec_driver_sql(f'DROP SCHEMA "{match[1]}" CASCADE')
        conn.exec_driver_sql(f'CREATE SCHEMA "{match[1]}"')
    engine.dispose()


def test_concurrent_first_opening(empty_url: str) -> None:
    """Four processes open a new database at once: all succeed, the schema is made once."""
    children = [start(empty_url) for _ in range(4)]
    for child in children:
        go(child)
    for child in children:
        finish(child)
    assert state(empty_url) == migrate.head_revision()
    if empty_url.startswith("sqlite:///"):
        folder = Path(empty_url.removeprefix("sqlite:///")).parent
        assert [p.name for p in folder.iterdir()] == ["empty.db"]


def test_kill_during_first_migration(empty_url: str) -> None:
    """SIGKILL at 10 seeded moments of the first opening: the database is absent (empty)
    or at head, never half-made, and connect() then works without repair."""
    child = start(empty_url)
    began = time.perf_counter()
    go(child)
    finish(child)
    migration_s = time.perf_counter() - began
    outcomes: list[str | None] = []
    pending = spawn(empty_url)
    for seed in range(KILLS):
        reset(empty_url)
        delay = random.Random(seed).uniform(0, migration_s)
        child = ready(pending)
        go(child)
        time.sleep(delay)
        os.kill(child.pid, signal.SIGKILL)
        child.communicate(timeout=30)
        if seed + 1 < KILLS:
            pending = spawn(empty_url)  # imports while this round is checked
        outcomes.append(state(empty_url))
        with toaster.connect(empty_url) as db:
            assert migrate.current_revision(db.engine) == migrate.head_revision()
        assert state(empty_url) == migrate.head_revision()
        if empty_url.startswith("sqlite:///"):  # the killed builder's leftovers are gone
            folder = Path(empty_url.removeprefix("sqlite:///")).parent
            assert [p.name for p in folder.iterdir() if ".tmp-" in p.name] == []
    print(f"migration {migration_s:.3f} s; after each kill: {outcomes}")
