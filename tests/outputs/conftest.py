"""Fixtures for the output tests: a real database (SQLite file and PostgreSQL) holding a small
run with three agents, facts changing over time and a false belief."""

from __future__ import annotations

import os
import shutil
import subprocess
import uuid
from collections.abc import Callable, Iterator
from typing import Any

import pytest

import toaster
from toaster import Fact

SYSTEM_PYTHON = "/usr/bin/python3"
PG_URL = os.environ.get("TOASTER_TEST_POSTGRES_URL", "postgresql://postgres@127.0.0.1:5432/test")
S = 1_000_000_000
T0 = 1_700_000_000 * S  # the run starts here


def _pg_admin() -> Any:
    import psycopg

    try:
        return psycopg.connect(
            PG_URL.replace("postgresql+psycopg://", "postgresql://"),
            autocommit=True,
            connect_timeout=3,
        )
    except psycopg.OperationalError as exc:
        reason = f"PostgreSQL at {PG_URL} unreachable: {str(exc).strip().splitlines()[0]}"
        if os.environ.get("TOASTER_REQUIRE_POSTGRES") == "1":
            pytest.fail(reason)
        pytest.skip(reason)


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.postgresql)])
def db_url(request: pytest.FixtureRequest, tmp_path: Any) -> Iterator[str]:
    """A URL to a fresh, empty database on each backend."""
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'run.db'}"
        return
    admin = _pg_admin()
    name = f"toaster_output_{uuid.uuid4().hex[:12]}"
    admin.execute(f'CREATE DATABASE "{name}"')
    try:
        yield PG_URL.rsplit("/", 1)[0] + "/" + name
    finally:
        admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.close()


def build_run(db: toaster.Database) -> None:
    """A 20 s run: the robot sees the mug move from the table to the shelf at 10 s; alice
    saw it on the table and left (false belief); bob never saw it (unaware); alice's distance
    to the mug changes value and confidence."""
    store = db.store()
    store.add_entity("pr2", "robot", is_self=True, t_ns=T0)
    store.add_entity("alice", "human", t_ns=T0)
    store.add_entity("bob", "human", t_ns=T0)
    for thing in ("mug", "table", "shelf"):
        store.add_entity(thing, "object", t_ns=T0)
    on_table = Fact("mug", "IsOn", "table", property_type="position")
    on_shelf = Fact("mug", "IsOn", "shelf", property_type="position")
    store.assert_fact("pr2", on_table, t_ns=T0)
    store.assert_fact("alice", on_table._replace(confidence=0.8), t_ns=T0 + 2 * S)
    store.retract_facts("pr2", "IsOn", "mug", "table", t_ns=T0 + 10 * S)
    store.assert_fact("pr2", on_shelf, t_ns=T0 + 10 * S)
    store.assert_fact("bob", on_shelf._replace(confidence=0.6), t_ns=T0 + 16 * S)
    far = Fact("alice", "Distance", "mug", "far", 3.0, 0.9, property_type="position")
    store.sync_snapshot("monitor", "pr2", T0 + 1 * S, [far])
    store.sync_snapshot(
        "monitor", "pr2", T0 + 5 * S, [far._replace(value_text="close", value_num=1.0)]
    )
    store.sync_snapshot(
        "monitor", "pr2", T0 + 8 * S, [far._replace(value_text="reach", value_num=0.4)]
    )
    store.sync_snapshot("monitor", "pr2", T0 + 14 * S, [])
    store.sync_snapshot("monitor", "pr2", T0 + 20 * S, [])


def open_built(
    db_url: str, build: Callable[[toaster.Database], None]
) -> Iterator[toaster.Database]:
    """Open ``db_url``, fill it with ``build``, yield it, close it (fixture body)."""
    db = toaster.connect(db_url)
    try:
        build(db)
        yield db
    finally:
        db.close()


@pytest.fixture
def run_db(db_url: str) -> Iterator[toaster.Database]:
    """An open database holding :func:`build_run`."""
    yield from open_built(db_url, build_run)


def run_scenario(db: toaster.Database, name: str, seconds: float) -> list[tuple[Any, ...]]:
    """Run a shipped scenario for ``seconds`` into ``db`` (as ``toaster run`` does) and return
    recorder frames ``(t_ns, entities, areas)`` taken from the world at every tick."""
    from importlib.resources import files

    from toaster.producers import Runner, load_session

    session = load_session(str(files("toaster") / "examples" / name))
    store, world = db.store(), session.world
    runner = Runner(
        world, session.sources, session.producers, store=store, agent_id=session.self_id
    )
    session.register(store)
    frames: list[tuple[Any, ...]] = []

    def grab(t_ns: int) -> None:
        frames.append(session.frame(t_ns, with_areas=not frames))

    end = session.start_ns + int(seconds * S)
    runner.run(session.start_ns, end, session.rate_hz, on_tick=grab)
    return frames


def require_tool(found: bool, reason: str) -> None:
    """Skip the test when a consumer it runs is missing (``reason`` says how to install it);
    under CI (``CI`` set) fail instead: CI must have it (.ci/run)."""
    if found:
        return
    if os.environ.get("CI"):
        pytest.fail(f"{reason}; CI must install it (.ci/run)")
    pytest.skip(reason)


def require_gnuplot() -> str:
    """The gnuplot program (skips without it, fails under CI)."""
    found = shutil.which("gnuplot")
    require_tool(found is not None, "gnuplot is not installed (apt-get install gnuplot-nox)")
    return str(found)


def require_system_rosbag() -> None:
    """Debian's python3-rosbag under /usr/bin/python3 (skips without it, fails under CI)."""
    probe = subprocess.run(
        [
            SYSTEM_PYTHON,
            "-c",
            "import sys; sys.path.append("
            "'/usr/lib/python3/dist-packages'); import rosbag, genpy, "
            "tf2_msgs.msg, visualization_msgs.msg, rosgraph_msgs.msg",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    require_tool(
        probe.returncode == 0,
        "Debian's python3-rosbag is not importable under "
        "/usr/bin/python3 (apt-get install python3-rosbag python3-tf2-msgs "
        "python3-visualization-msgs)",
    )
