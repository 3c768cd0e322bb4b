"""Fixtures: every database test runs on a fresh SQLite file and on the real PostgreSQL.

PostgreSQL: ``$TOASTER_TEST_POSTGRES_URL`` (default the local server of these machines). Each
test gets its own schema (``search_path``), dropped afterwards. When the server is unreachable
the PostgreSQL half skips with the reason, unless ``TOASTER_REQUIRE_POSTGRES=1`` (set by
``.ci/run``), where it fails. Tests that read ``../shared/data`` skip when it is absent, unless
``CI`` is set.
"""

from __future__ import annotations

import os
import shutil
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
import sqlalchemy as sa

import toaster
from toaster.db import migrate
from toaster.db.engine import make_engine

PG_URL = os.environ.get(
    "TOASTER_TEST_POSTGRES_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/test"
)
REQUIRE_PG = os.environ.get("TOASTER_REQUIRE_POSTGRES") == "1"
SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
BACKENDS = ["sqlite", pytest.param("postgresql", marks=pytest.mark.postgresql)]
BACKEND_NAMES = ("sqlite", "postgresql")

_pg_error: str | None = None
_pg_checked = False


def postgres_unavailable() -> str | None:
    """None when the PostgreSQL server answers, else why it does not (checked once)."""
    global _pg_checked, _pg_error
    if not _pg_checked:
        _pg_checked = True
        try:
            engine = make_engine(PG_URL)
            with engine.connect() as conn:
                conn.exec_driver_sql("SELECT 1")
            engine.dispose()
        except Exception as exc:  # any failure to reach the server
            _pg_error = str(exc).strip().splitlines()[0]
    return _pg_error


def require_postgres() -> None:
    """Skip (or fail under CI) when PostgreSQL is unreachable."""
    reason = postgres_unavailable()
    if reason is None:
        return
    message = f"PostgreSQL at {PG_URL} is unreachable ({reason})"
    if REQUIRE_PG:
        pytest.fail(message + " and TOASTER_REQUIRE_POSTGRES=1")
    pytest.skip(message + "; set TOASTER_TEST_POSTGRES_URL or start the server")


def shared_data(*parts: str) -> Path:
    """A path under ../shared/data; skips the test when it is absent (fails under CI)."""
    path = SHARED_DATA.joinpath(*parts)
    if not path.exists():
        if os.environ.get("CI"):
            pytest.fail(f"{path} is missing: CI must run with ../shared beside the project")
        pytest.skip(f"{path} is absent (the shared data folder is not beside the project)")
    return path


@pytest.fixture(scope="session")
def sqlite_template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A SQLite file migrated to head once; tests copy it."""
    path = tmp_path_factory.mktemp("template") / "template.db"
    engine = make_engine(f"sqlite:///{path}")
    migrate.upgrade(engine)
    engine.dispose()
    return path


@contextmanager
def pg_schema(*, migrated: bool = False) -> Iterator[str]:
    """A URL whose search_path is a fresh PostgreSQL schema (``migrated``: at head), dropped
    afterwards."""
    require_postgres()
    schema = f"t_{uuid.uuid4().hex[:12]}"
    admin = make_engine(PG_URL)
    with admin.begin() as conn:
        conn.exec_driver_sql(f'CREATE SCHEMA "{schema}"')
    sep = "&" if "?" in PG_URL else "?"
    url = f"{PG_URL}{sep}options=-csearch_path%3D{schema}"
    try:
        if migrated:
            engine = make_engine(url)
            migrate.upgrade(engine)
            engine.dispose()
        yield url
    finally:
        with admin.begin() as conn:
            conn.exec_driver_sql(f'DROP SCHEMA "{schema}" CASCADE')
        admin.dispose()


@pytest.fixture
def pg_schema_url() -> Iterator[str]:
    """A URL whose search_path is a fresh, empty PostgreSQL schema (dropped afterwards)."""
    with pg_schema() as url:
        yield url


@pytest.fixture(params=BACKENDS)
def db_url(request: pytest.FixtureRequest, tmp_path: Path, sqlite_template: Path) -> str:
    """A URL of a database at head: a fresh SQLite file or a fresh PostgreSQL schema."""
    if request.param == "sqlite":
        path = tmp_path / "toaster.db"
        shutil.copy(sqlite_template, path)
        return f"sqlite:///{path}"
    url = request.getfixturevalue("pg_schema_url")
    engine = make_engine(url)
    migrate.upgrade(engine)
    engine.dispose()
    return url


@pytest.fixture(params=BACKENDS)
def empty_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """A URL of an empty database (no schema yet) on each backend."""
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'empty.db'}"
    return request.getfixturevalue("pg_schema_url")


@pytest.fixture
def db(db_url: str) -> Iterator[toaster.Database]:
    """An open database at head on each backend."""
    database = toaster.connect(db_url)
    try:
        yield database
    finally:
        database.close()


@pytest.fixture
def store(db: toaster.Database) -> toaster.Store:
    """The store of :func:`db` with a self robot PR2_ROBOT, humans BOB and ANNE, objects."""
    st = db.store()
    st.add_entity("PR2_ROBOT", "robot", is_self=True, t_ns=0)
    st.add_entity("BOB", "human", t_ns=0)
    st.add_entity("ANNE", "human", t_ns=0)
    for name in ("MUG", "TABLE", "SHELF", "BOX"):
        st.add_entity(name, "object", t_ns=0)
    return st


def count(db: toaster.Database, sql: str, **params: object) -> int:
    """A scalar from SQL (helper for assertions)."""
    with db.transaction() as conn:
        return conn.execute(sa.text(sql), params).scalar_one()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """``@pytest.mark.backend("postgresql")`` (or ``"sqlite"``): a test of one backend's
    feature runs on that backend's parameter only; the others are deselected, not skipped, so
    a skip always means something is missing."""
    keep: list[pytest.Item] = []
    drop: list[pytest.Item] = []
    for item in items:
        marker = item.get_closest_marker("backend")
        callspec = getattr(item, "callspec", None)
        params = callspec.params.values() if callspec is not None else ()
        names = {v for v in params if isinstance(v, str) and v in BACKEND_NAMES}
        (drop if marker and names and marker.args[0] not in names else keep).append(item)
    if drop:
        config.hook.pytest_deselected(items=drop)
        items[:] = keep
