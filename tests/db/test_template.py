"""New SQLite databases are copies of a migrated template (:mod:`toaster.db.template`): the
same schema, rows and settings as a migrated file, never a template of other revisions, and
safe when several processes create databases at once."""

from __future__ import annotations

import os
import sqlite3
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext

import toaster
from toaster.db import migrate, template
from toaster.db.engine import make_engine
from toaster.db.schema import metadata

ROOT = Path(__file__).resolve().parents[2]
_PRAGMAS = (
    "journal_mode",
    "page_size",
    "auto_vacuum",
    "encoding",
    "user_version",
    "application_id",
)


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty template cache of this test's own."""
    monkeypatch.setenv(template.CACHE_VAR, str(tmp_path / "cache"))
    return tmp_path / "cache" / "toaster" / "templates"


def snapshot(path: Path) -> dict[str, Any]:
    """Everything a database is made of: its schema objects (tables, columns, indexes, views,
    triggers: their SQL), every table's rows (the alembic version, seed rows) and the
    file-level settings."""
    conn = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    try:
        objects = sorted(
            conn.execute("SELECT type, name, tbl_name, sql FROM sqlite_master").fetchall(),
            key=repr,
        )
        tables = [name for kind, name, _, _ in objects if kind == "table"]
        rows = {
            t: sorted(conn.execute(f'SELECT * FROM "{t}"').fetchall(), key=repr) for t in tables
        }
        pragmas = {p: conn.execute(f"PRAGMA {p}").fetchone()[0] for p in _PRAGMAS}
    finally:
        conn.close()
    return {"objects": objects, "rows": rows, "pragmas": pragmas}


def migrated(path: Path) -> Path:
    """A database made by the migrations alone (no template)."""
    engine = make_engine(f"sqlite:///{path}")
    migrate.upgrade(engine)
    engine.dispose()
    return path


def test_a_copy_equals_a_migrated_database(cache: Path, tmp_path: Path) -> None:
    """toaster.connect on a new file copies the template; the result is the database the
    migrations make (schema, rows, WAL mode), at head, and later migrations work on it."""
    copied = tmp_path / "copied.db"
    toaster.connect(f"sqlite:///{copied}").close()
    assert [p.name for p in cache.iterdir()] == [template.template_name(migrate.head_revision())]
    assert snapshot(copied) == snapshot(migrated(tmp_path / "migrated.db"))
    assert snapshot(copied)["pragmas"]["journal_mode"] == "wal"
    engine = make_engine(f"sqlite:///{copied}")
    try:
        assert migrate.current_revision(engine) == migrate.head_revision()
        with engine.connect() as conn:
            assert compare_metadata(MigrationContext.configure(conn), metadata) == []
        migrate.downgrade(engine, "-1")
        migrate.upgrade(engine)
        assert migrate.current_revision(engine) == migrate.head_revision()
    finally:
        engine.dispose()
    with toaster.connect(f"sqlite:///{copied}") as db:  # and it takes writes
        db.store().add_entity("SALLY", "human", t_ns=0)


def test_a_template_of_another_head_or_hash_is_not_used(
    cache: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A template is only taken under its own key: one made for an older head, or for
    migrations whose files differ (an edited source checkout), is never copied."""
    cache.mkdir(parents=True)
    head = migrate.head_revision()
    old = migrate.create_sqlite_file(tmp_path / "old.db", "0018")
    assert old
    os.replace(tmp_path / "old.db", cache / template.template_name("0018"))
    (tmp_path / "old.db-wal").unlink(missing_ok=True)
    monkeypatch.setattr(template, "migrations_hash", lambda: "0" * 16)
    planted = cache / template.template_name(head)  # right head, other migration files
    sqlite3.connect(planted).execute("CREATE TABLE marker (x)").connection.close()
    monkeypatch.undo()
    monkeypatch.setenv(template.CACHE_VAR, str(cache.parents[1]))

    toaster.connect(f"sqlite:///{tmp_path / 'new.db'}").close()
    made = snapshot(tmp_path / "new.db")
    assert "marker" not in made["rows"] and made["rows"]["alembic_version"] == [(head,)]
    assert (cache / template.template_name(head)).exists()
    assert len(list(cache.iterdir())) == 3


def test_a_damaged_template_is_rebuilt(cache: Path, tmp_path: Path) -> None:
    """A template cut short (a disk that filled up, a hand edit) is built again, never copied."""
    toaster.connect(f"sqlite:///{tmp_path / 'first.db'}").close()
    path = cache / template.template_name(migrate.head_revision())
    whole = path.read_bytes()
    path.write_bytes(whole[: len(whole) // 2])
    toaster.connect(f"sqlite:///{tmp_path / 'second.db'}").close()
    assert template.is_whole(path) and path.stat().st_size == len(whole)
    assert snapshot(tmp_path / "second.db") == snapshot(tmp_path / "first.db")


def test_without_a_writable_cache_the_migrations_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A cache root that cannot hold the folder (here a file): the database is migrated in
    place, as before templates."""
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("")
    monkeypatch.setenv(template.CACHE_VAR, str(blocker))
    toaster.connect(f"sqlite:///{tmp_path / 'new.db'}").close()
    assert snapshot(tmp_path / "new.db") == snapshot(migrated(tmp_path / "migrated.db"))


def test_an_older_revision_is_migrated_not_copied(cache: Path, tmp_path: Path) -> None:
    """Creating at a revision below head runs the migrations (templates hold the head only)."""
    assert migrate.create_sqlite_file(tmp_path / "old.db", "0018")
    engine = make_engine(f"sqlite:///{tmp_path / 'old.db'}")
    assert migrate.current_revision(engine) == "0018"
    engine.dispose()
    assert not cache.exists()


#: A child that imports everything, says "ready", waits for a line, then creates databases.
CHILD = """
import sys
from pathlib import Path
import toaster
print("ready", flush=True)
sys.stdin.readline()
for name in sys.argv[1:]:
    toaster.connect(f"sqlite:///{name}").close()
print("done", flush=True)
"""


@pytest.mark.slow
def test_processes_creating_databases_at_once(cache: Path, tmp_path: Path) -> None:
    """Two processes that start on an empty cache at the same instant both build or take the
    template (each first creates databases in a folder of its own, so neither waits for the
    other's folder lock) and create their databases, then one file both name; every
    database is whole and at head, and the cache holds one template and no temporary file."""
    shared = tmp_path / "shared.db"
    children = []
    for n in range(2):
        (tmp_path / f"own{n}").mkdir()
        names = [*(str(tmp_path / f"own{n}" / f"{i}.db") for i in range(3)), str(shared)]
        children.append(
            subprocess.Popen(
                [sys.executable, "-c", CHILD, *names],
                cwd=ROOT,
                env={**os.environ, template.CACHE_VAR: str(cache.parents[1])},
                text=True,
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
            )
        )
    for child in children:
        assert child.stdout is not None and child.stdout.readline().strip() == "ready"
    for child in children:
        assert child.stdin is not None
        child.stdin.write("go\n")
        child.stdin.flush()
    deadline = time.monotonic() + 120
    for child in children:
        out, err = child.communicate(timeout=max(1.0, deadline - time.monotonic()))
        assert child.returncode == 0 and out.strip() == "done", err
    expected = snapshot(migrated(tmp_path / "migrated.db"))
    for path in [shared, *tmp_path.glob("own*/*.db")]:
        conn = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
        assert conn.execute("PRAGMA quick_check").fetchone() == ("ok",)
        conn.close()
        assert snapshot(path)["objects"] == expected["objects"]
    assert [p.name for p in cache.iterdir()] == [template.template_name(migrate.head_revision())]
