"""Opening databases: bad URLs, files that are no toaster database, unreachable servers and
held locks all give one line (a ToasterError; exit 1 from the CLI) and change nothing."""

from __future__ import annotations

import hashlib
import re
import sqlite3
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
import sqlalchemy as sa
from click.testing import CliRunner

import toaster
from tests.conftest import PG_URL
from toaster.cli import cli
from toaster.db import migrate, open_database
from toaster.db.engine import make_engine
from toaster.errors import (
    DatabaseLockedError,
    DatabaseOpenError,
    InvalidInputError,
)

ROOT = Path(__file__).resolve().parents[2]
PG_BASE = PG_URL.rsplit("/", 1)[0]  # postgresql+psycopg://user@host:port

BAD_URLS = {
    "sqlite://": "in-memory database, which keeps nothing",
    "sqlite:///:memory:": "in-memory database, which keeps nothing",
    ":memory:": "in-memory database, which keeps nothing",
    "sqlite:///": "in-memory database, which keeps nothing",
    "postgresql://": "names no database",
    "postgresql://127.0.0.1": "names no database",
    "postgresql://127.0.0.1:5432/": "names no database",
    "sqlite:///x.db?timeout=3": "takes no options",
    "postgresql://127.0.0.1/test?colour=blue": "unknown PostgreSQL URL option 'colour'",
    "postgresql+psycopg2://127.0.0.1/test": "unsupported driver 'psycopg2'",
    "mysql://127.0.0.1/test": "unsupported database 'mysql'",
    "sqlite:///file:x.db?mode=ro&uri=true": "takes no options",
    "no-scheme": "invalid database URL",
    "": "empty database URL ''",  # --db "" is not the default file
    " ": "empty database URL ' '",
    "sqlite:///a\x00b.db": "NUL character",
    "sqlite:///\udc80.db": "not valid UTF-8",
}


def one_line_error(args: list[str], env: dict[str, str] | None = None) -> str:
    """``toaster ARGS`` through click: exit 1 and one line ``Error: ...``; that line."""
    result = CliRunner().invoke(cli, args, env=env)
    assert result.exit_code == 1, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: "), result.output
    return lines[0]


def digest(folder: Path) -> dict[str, str]:
    """Every file of ``folder`` (hidden ones too) -> the SHA-1 of its bytes."""
    return {
        p.name: hashlib.sha1(p.read_bytes()).hexdigest()
        for p in sorted(folder.iterdir())
        if p.is_file()
    }


@pytest.mark.parametrize(("url", "expected"), BAD_URLS.items())
def test_bad_urls_are_refused_in_one_line(
    url: str, expected: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Nothing that keeps nothing or lets the server pick the database is accepted."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InvalidInputError, match=re.escape(expected)):
        toaster.connect(url)
    for command in (["db", "check"], ["db", "upgrade"], ["get-info", "AGENT"]):
        assert expected in one_line_error(["--db", url, *command])
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("url", [5, b"sqlite:///x.db", ["sqlite:///x.db"]])
def test_urls_that_are_not_text_are_refused(
    url: object, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InvalidInputError, match="invalid database URL"):
        toaster.connect(url)  # type: ignore[arg-type]
    assert list(tmp_path.iterdir()) == []


def test_folder_and_missing_folder(tmp_path: Path) -> None:
    """A folder is not a database file; a file in a missing folder cannot be created."""
    assert "is a folder: name a file in it" in one_line_error(
        ["--db", f"sqlite:///{tmp_path}", "db", "check"]
    )
    line = one_line_error(["--db", f"sqlite:///{tmp_path / 'no' / 'x.db'}", "get-info", "AGENT"])
    assert "does not exist" in line and str(tmp_path / "no") in line


def test_memory_is_for_library_users_who_ask() -> None:
    """open_database(allow_memory=True) gives a throw-away database; connect() refuses."""
    with open_database("sqlite://", allow_memory=True) as db:
        db.store().add_entity("BOB", "human", t_ns=0)
        with db.transaction() as conn:
            assert conn.execute(sa.text("SELECT COUNT(*) FROM entities")).scalar_one() == 1
    with pytest.raises(InvalidInputError, match="keeps nothing"):
        toaster.connect("sqlite:///:memory:")


def _garbage_head(path: Path, template: Path) -> None:
    data = bytearray(template.read_bytes())
    data[:4096] = bytes((i * 7919) % 251 for i in range(4096))
    path.write_bytes(bytes(data))


def _other_application(path: Path, _template: Path) -> None:
    conn = sqlite3.connect(path)
    conn.execute("CREATE TABLE invoices (id INTEGER PRIMARY KEY, total REAL)")
    conn.execute("INSERT INTO invoices VALUES (1, 9.5)")
    conn.commit()
    conn.close()


BAD_FILES = {
    "text": (lambda p, t: p.write_text("hello, not a database\n"), "not a SQLite database"),
    "garbage_head": (_garbage_head, "not a SQLite database or is corrupted"),
    "truncated": (lambda p, t: p.write_bytes(t.read_bytes()[:20000]), "is corrupted"),
    "other_application": (_other_application, "is not a toaster database (it holds invoices"),
}


@pytest.mark.parametrize("kind", BAD_FILES)
def test_bad_files_are_refused_and_left_unchanged(
    kind: str, tmp_path: Path, sqlite_template: Path
) -> None:
    """Not a database, corrupted, truncated, another application's: one line naming the
    file, from the library and every command; the folder's bytes do not change."""
    make, expected = BAD_FILES[kind]
    path = tmp_path / "bad.db"
    make(path, sqlite_template)
    before = digest(tmp_path)
    url = f"sqlite:///{path}"
    with pytest.raises(DatabaseOpenError, match=re.escape(expected)):
        toaster.connect(url)
    for command in (
        ["db", "check"],
        ["db", "current"],
        ["db", "upgrade"],
        ["get-info", "AGENT"],
        ["execute", "SQL", "SELECT 1"],
    ):
        line = one_line_error(["--db", url, *command])
        assert expected in line and str(path) in line, line
    assert digest(tmp_path) == before


@pytest.mark.slow
def test_no_traceback_from_the_real_command(tmp_path: Path, sqlite_template: Path) -> None:
    """``python -m toaster``: a corrupted file and an unreachable server, one stderr line."""
    bad = tmp_path / "bad.db"
    _garbage_head(bad, sqlite_template)
    for url in (f"sqlite:///{bad}", "postgresql://127.0.0.1:1/test"):
        for command in (["db", "check"], ["get-info", "AGENT"]):
            proc = subprocess.run(
                [sys.executable, "-m", "toaster", "--db", url, *command],
                capture_output=True,
                text=True,
                timeout=60,
                cwd=ROOT,
            )
            assert proc.returncode == 1, proc.stderr
            assert "Traceback" not in proc.stderr
            assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
            assert proc.stderr.startswith("Error: ")


@pytest.mark.slow
def test_empty_file_is_repaired(tmp_path: Path) -> None:
    """A 0-byte file and a SQLite file without any table (a crash of an older toaster) are
    taken as new databases and migrated to head."""
    zero = tmp_path / "zero.db"
    zero.touch()
    tableless = tmp_path / "tableless.db"
    conn = sqlite3.connect(tableless)
    conn.execute("PRAGMA journal_mode=WAL")
    conn.close()
    for path in (zero, tableless):
        with toaster.connect(f"sqlite:///{path}") as db:
            assert migrate.current_revision(db.engine) == migrate.head_revision()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tableless.db", "zero.db"]


def test_missing_file_is_not_created_by_check(tmp_path: Path) -> None:
    """db check / current on a missing file say so and create nothing; db upgrade creates."""
    url = f"sqlite:///{tmp_path / 'new.db'}"
    for command in (["db", "check"], ["db", "current"]):
        assert "no SQLite database at" in one_line_error(["--db", url, *command])
    assert list(tmp_path.iterdir()) == []
    result = CliRunner().invoke(cli, ["--db", url, "db", "upgrade"])
    assert result.exit_code == 0, result.output
    assert "(was none)" in result.output
    assert [p.name for p in tmp_path.iterdir()] == ["new.db"]


@pytest.mark.parametrize(
    "url", ["postgresql://127.0.0.1:1/test", "postgresql://postgres@no-such-host.invalid/test"]
)
def test_unreachable_server(url: str) -> None:
    """Refused connection, unknown host: one line naming the URL, for every db command."""
    with pytest.raises(DatabaseOpenError, match="cannot connect to PostgreSQL"):
        toaster.connect(url)
    for command in (
        ["db", "check"],
        ["db", "current"],
        ["db", "upgrade"],
        ["execute", "SQL", "SELECT 1"],
    ):
        line = one_line_error(["--db", url, *command])
        assert "cannot connect to PostgreSQL" in line and url.split("//")[1] in line


@pytest.mark.postgresql
def test_missing_database_schema_and_other_application_on_postgresql(pg_schema_url: str) -> None:
    """A database that does not exist, a search_path naming no schema, a schema holding
    another application's tables: one line each; the other tables stay as they were."""
    line = one_line_error(["--db", f"{PG_BASE}/no_such_db_x", "db", "current"])
    assert 'database "no_such_db_x" does not exist' in line
    nowhere = re.sub(r"search_path%3D\w+", "search_path%3Dno_such_schema_x", pg_schema_url)
    with pytest.raises(DatabaseOpenError, match="selects no existing schema"):
        toaster.connect(nowhere)
    engine = make_engine(pg_schema_url)
    with engine.begin() as conn:
        conn.exec_driver_sql("CREATE TABLE invoices (id int PRIMARY KEY)")
    try:
        line = one_line_error(["--db", pg_schema_url, "db", "upgrade"])
        assert "is not a toaster database (it holds invoices" in line
        with engine.connect() as conn:
            assert conn.dialect.get_table_names(conn) == ["invoices"]
    finally:
        engine.dispose()


def test_bad_lock_timeout_setting(tmp_path: Path) -> None:
    """TOASTER_LOCK_TIMEOUT must be a number of seconds."""
    line = one_line_error(
        ["--db", str(tmp_path / "x.db"), "get-info", "AGENT"], env={"TOASTER_LOCK_TIMEOUT": "soon"}
    )
    assert "TOASTER_LOCK_TIMEOUT='soon' is not a number of seconds" in line


@contextmanager
def _sqlite_lock_held(path: Path) -> Iterator[None]:
    """Another connection holds the write lock of ``path`` until the block ends (released and
    closed then): a writer inside the block meets it however slow the machine is."""
    held, release = threading.Event(), threading.Event()

    def hold() -> None:
        conn = sqlite3.connect(path, isolation_level=None)
        conn.execute("BEGIN IMMEDIATE")
        held.set()
        release.wait(120)
        conn.execute("ROLLBACK")
        conn.close()

    thread = threading.Thread(target=hold, daemon=True)
    thread.start()
    assert held.wait(60), "the lock holder did not take the lock in 60 s"
    try:
        yield
    finally:
        release.set()
        thread.join(60)


@pytest.mark.slow
def test_locked_sqlite_fails_in_one_line_and_writes_nothing(
    tmp_path: Path, sqlite_template: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A write transaction held elsewhere: after TOASTER_LOCK_TIMEOUT (0.5 s) the writer
    gets the one-line error, nothing is written, and it writes once the lock is gone."""
    path = tmp_path / "locked.db"
    path.write_bytes(sqlite_template.read_bytes())
    url = f"sqlite:///{path}"
    monkeypatch.setenv("TOASTER_LOCK_TIMEOUT", "0.5")
    with toaster.connect(url) as db:
        with _sqlite_lock_held(path):
            with pytest.raises(DatabaseLockedError) as caught:
                db.store().add_entity("BOB", "human", t_ns=0)
            message = str(caught.value)
            assert "\n" not in message
            assert message.startswith(
                f"database '{path}' is locked by another process (waited 0.5 s)"
            )
            assert "TOASTER_LOCK_TIMEOUT=" in message
            with db.transaction() as conn:
                assert conn.execute(sa.text("SELECT COUNT(*) FROM entities")).scalar_one() == 0
        db.store().add_entity("BOB", "human", t_ns=0)  # the handle still works
    with _sqlite_lock_held(path):
        line = one_line_error(
            ["--db", url, "set-info", "ENTITY", "--id", "ANNE", "--type", "human"],
            env={"TOASTER_LOCK_TIMEOUT": "0.5"},
        )
    assert "is locked by another process (waited 0.5 s)" in line
    conn = sqlite3.connect(path)
    assert conn.execute("SELECT id FROM entities").fetchall() == [("BOB",)]
    assert conn.execute("PRAGMA quick_check").fetchone() == ("ok",)
    conn.close()


@pytest.mark.slow
@pytest.mark.postgresql
def test_locked_postgresql_fails_in_one_line(
    pg_schema_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """PostgreSQL: a table lock held by another session ends the wait after the lock
    timeout (lock_timeout), in one line, rolled back."""
    db_url = pg_schema_url
    toaster.connect(db_url).close()
    monkeypatch.setenv("TOASTER_LOCK_TIMEOUT", "0.5")
    holder = make_engine(db_url)
    with toaster.connect(db_url) as db, holder.connect() as other:
        other.begin()
        other.exec_driver_sql("LOCK TABLE entities IN ACCESS EXCLUSIVE MODE")
        started = time.monotonic()
        with pytest.raises(
            DatabaseLockedError,
            match=r"locked by another session \(waited "
            r"0.5 s\)",
        ):
            db.store().add_entity("BOB", "human", t_ns=0)
        assert time.monotonic() - started < 60  # ended by lock_timeout, not by the holder
        other.rollback()
        with db.transaction() as conn:
            assert conn.execute(sa.text("SELECT COUNT(*) FROM entities")).scalar_one() == 0
    holder.dispose()


def test_an_unknown_revision_is_one_line_and_changes_nothing(tmp_path: Path) -> None:
    from click.testing import CliRunner

    from toaster.cli import cli

    url = f"sqlite:///{tmp_path / 'r.db'}"
    assert CliRunner().invoke(cli, ["--db", url, "db", "upgrade"]).exit_code == 0
    before = (tmp_path / "r.db").read_bytes()
    for command in ("downgrade", "upgrade"):
        result = CliRunner().invoke(cli, ["--db", url, "db", command, "zzzz"])
        assert result.exit_code == 1
        assert result.exception is None or isinstance(result.exception, SystemExit)
        assert "unknown revision 'zzzz'" in result.output
    assert (tmp_path / "r.db").read_bytes() == before


@pytest.mark.postgresql
def test_postgresql_connections_notice_a_lost_peer_and_urls_set_their_own(
    pg_schema_url: str,
) -> None:
    """A server host that vanishes without a word (cable, power, Wi-Fi) is noticed in seconds
    (TCP keepalives, a time-out for unacknowledged data) instead of the kernel's hours; a
    URL's own libpq settings win."""
    from tests.conftest import require_postgres

    require_postgres()
    for url, idle in ((pg_schema_url, "10"), (pg_schema_url + "&keepalives_idle=60", "60")):
        engine = make_engine(url)
        try:
            with engine.connect() as conn:
                params = conn.connection.dbapi_connection.info.get_parameters()
        finally:
            engine.dispose()
        assert params["keepalives"] == "1"
        assert params["keepalives_idle"] == idle
        assert (params["keepalives_interval"], params["keepalives_count"]) == ("5", "3")
        assert params["tcp_user_timeout"] == "30000"
