"""Sally-Anne from geometry alone: visibility facts feed the belief rules (SQLite file)."""

from __future__ import annotations

from pathlib import Path

import pytest

import toaster
from toaster.beliefs.api import belief_value
from toaster.producers import Runner, load_session

EXAMPLE = Path(toaster.__file__).parent / "examples" / "scenario_spatial_sally_anne.yaml"
S = 1_000_000_000


def run_into_store(path: Path, url: str) -> object:
    """Tick a scenario into a fresh store, registering entities as ``toaster run`` does."""
    db = toaster.connect(url)
    store = db.store()
    session = load_session(path)
    world = session.world
    runner = Runner(
        world, session.sources, session.producers, store=store, agent_id=session.self_id
    )
    session.register(store)
    runner.run(session.start_ns, session.end_ns, session.rate_hz)
    return db


@pytest.fixture(scope="module")
def sally_db(tmp_path_factory: pytest.TempPathFactory) -> object:
    path = tmp_path_factory.mktemp("sally") / "sally.db"
    db = run_into_store(EXAMPLE, f"sqlite:///{path}")
    yield db
    db.close()


def held(db: object, agent: str, target: str, at: int, about: str | None = None) -> bool:
    return belief_value(db, agent, "MARBLE", "IsIn", target, about=about, at=at) is not None


@pytest.mark.slow
def test_everyone_sees_the_marble_go_into_the_basket(sally_db: object) -> None:
    for agent in ("ROBOT", "SALLY", "ANNE"):
        assert held(sally_db, agent, "BASKET", 2 * S)
    assert held(sally_db, "ANNE", "BASKET", 2 * S, about="SALLY")


def test_false_belief_after_sally_comes_back(sally_db: object) -> None:
    at = 13 * S  # Sally is back, looking at the closed basket and box
    assert held(sally_db, "ROBOT", "BOX", at)
    assert not held(sally_db, "ROBOT", "BASKET", at)
    assert held(sally_db, "ANNE", "BOX", at)
    assert not held(sally_db, "ANNE", "BASKET", at)
    assert held(sally_db, "SALLY", "BASKET", at)
    assert not held(sally_db, "SALLY", "BOX", at)
    assert held(sally_db, "ANNE", "BASKET", at, about="SALLY")
    assert not held(sally_db, "ANNE", "BOX", at, about="SALLY")


def test_sally_sees_the_containers_closed(sally_db: object) -> None:
    at = 13 * S
    assert belief_value(sally_db, "SALLY", "BASKET", "IsClosed", at=at) is not None
    assert belief_value(sally_db, "SALLY", "BOX", "IsClosed", at=at) is not None


def test_sally_opens_the_basket(sally_db: object) -> None:
    at = 15 * S
    assert belief_value(sally_db, "SALLY", "BASKET", "IsClosed", at=at) is None
    assert belief_value(sally_db, "ROBOT", "BASKET", "IsClosed", at=at) is None


@pytest.mark.slow
def test_sally_anne_on_each_backend(db_url: str) -> None:
    """The same false beliefs on SQLite and PostgreSQL (skips when PostgreSQL is absent)."""
    db = run_into_store(EXAMPLE, db_url)
    try:
        at = 13 * S
        assert held(db, "ANNE", "BOX", at) and held(db, "ROBOT", "BOX", at)
        assert held(db, "SALLY", "BASKET", at) and not held(db, "SALLY", "BOX", at)
        assert held(db, "ANNE", "BASKET", at, about="SALLY")
        assert belief_value(db, "SALLY", "BASKET", "IsClosed", at=15 * S) is None
        assert not held(db, "SALLY", "BASKET", 15 * S)
    finally:
        db.close()


def test_opening_the_basket_ends_sallys_belief_in_it(sally_db: object) -> None:
    """Sally opens the lidded basket and sees it empty: her belief that the marble is in it
    ends (the issue's last step)."""
    assert held(sally_db, "SALLY", "BASKET", 13 * S)
    assert not held(sally_db, "SALLY", "BASKET", 15 * S)
