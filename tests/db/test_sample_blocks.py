"""PostgreSQL packs older samples into blocks (``fact_sample_blocks``, revision 0025) at each
maintenance; every reader answers as if they were rows.

The same writes go into two databases of one backend: one maintained every few ticks (on
PostgreSQL: packed), one never. As-of answers at every boundary (each sample's time, each
interval's ends, one either side), point reads, signals and the plot's data must be equal;
SQLite never packs, and gives the same answers too."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest

import toaster
import toaster.queries as q
from tests.conftest import count, pg_schema
from toaster import Fact
from toaster.db import migrate
from toaster.db.dialects.postgresql import BLOCK
from toaster.db.engine import make_engine
from toaster.model import FactRow

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

TICK = 1_000_000_000 // 30
TICKS = 3 * BLOCK + 20
AGENTS = ("R", "BOB")


@pytest.fixture
def twin_url(db_url: str, tmp_path: Path, sqlite_template: Path) -> Iterator[str]:
    """A second database at head on the backend of ``db_url``."""
    if db_url.startswith("sqlite"):
        path = tmp_path / "twin.db"
        shutil.copy(sqlite_template, path)
        yield f"sqlite:///{path}"
        return
    with pg_schema(migrated=True) as url:
        yield url


def _facts(tick: int) -> list[Fact]:
    """A distance refreshed every tick (value and confidence beyond tolerance), one that
    ends and comes back (its samples stay rows once it ended), one refreshed every 7th tick."""
    swing = 0.5 * (tick % 2) + tick * 1e-4
    facts = [
        Fact("BOB", "Distance", "MUG", "near", 1.0 + swing, 0.2 + 0.3 * (tick % 3), 0.5),
        Fact("MUG", "Distance", "TABLE", "far", 3.0 + (tick // 7) % 2, 0.9),
    ]
    if tick < BLOCK + 30 or tick > 2 * BLOCK:
        facts.append(Fact("ANNE", "Distance", "BOX", "near", 2.0 - swing, 0.8))
    return facts


def _write(db: toaster.Database, maintain_every: int | None, ticks: range) -> None:
    st = db.store()
    for tick in ticks:
        st.sync_snapshot("ranger", "R", tick * TICK, _facts(tick))
        if tick % 3 == 0:  # BOB's own belief, refreshed
            st.sync_snapshot("own", "BOB", tick * TICK, [Fact("BOB", "Distance", "BOX", "x", tick)])
        if maintain_every and tick % maintain_every == 0:
            db.maintain()


def _setup(db: toaster.Database) -> None:
    st = db.store()
    st.add_entity("R", "robot", is_self=True, t_ns=0)
    st.add_entity("BOB", "human", t_ns=0)
    st.add_entity("ANNE", "human", t_ns=0)
    for name in ("MUG", "TABLE", "BOX"):
        st.add_entity(name, "object", t_ns=0)


def _rows(rows: list[FactRow | None]) -> list[FactRow | None]:
    """Without the wall clock of the writes (``recorded_ns``)."""
    return [r if r is None else r._replace(recorded_ns=0) for r in rows]


def _answers(db: toaster.Database) -> dict[str, object]:
    """Everything a user reads of the numbers: as-of at every boundary ± 1, point reads,
    signals (what plots and their .dat draw), history."""
    times = {
        t + d
        for (t,) in q.execute(
            db,
            f"SELECT until_ns FROM {db.backend.samples} s UNION SELECT valid_from_ns FROM facts "
            "UNION SELECT valid_to_ns FROM facts WHERE valid_to_ns IS NOT NULL",
            max_rows=10**6,
        ).rows
        for d in (-1, 0, 1)
    }
    answers: dict[str, object] = {}
    for agent in AGENTS:
        answers[f"{agent} as-of"] = [_rows(q.beliefs_at(db, agent, t)) for t in sorted(times)]
        answers[f"{agent} signal"] = q.signal(db, agent)
    answers["point"] = _rows(
        [q.fact_value(db, "R", "BOB", "Distance", "MUG", at=t) for t in sorted(times)[::5]]
    )
    answers["history"] = _rows(q.history(db, None))
    return answers


def test_packed_samples_answer_as_rows(db: toaster.Database, twin_url: str) -> None:
    """Maintained every 50 ticks or never: the same answers; on PostgreSQL the refreshed
    interval's samples but its last under BLOCK + 1 are blocks, and writes go on after a
    packing (later samples, a closed and reopened interval)."""
    _setup(db)
    with toaster.connect(twin_url) as twin:
        _setup(twin)
        _write(twin, None, range(1, TICKS + 1))
        expected = _answers(twin)
    _write(db, 50, range(1, TICKS + 1))
    samples = count(db, f"SELECT COUNT(*) FROM {db.backend.samples} s")
    assert samples >= 2 * TICKS
    blocks = count(db, "SELECT COUNT(*) FROM fact_sample_blocks")
    if db.backend.name == "postgresql":
        # the every-tick interval: TICKS - 1 samples, packed in whole blocks at tick 150
        # (149 → 2 blocks), and the rest at each maintenance after
        assert blocks >= 2
        assert count(db, "SELECT COUNT(*) FROM fact_samples") == samples - blocks * BLOCK
    else:
        assert blocks == 0  # SQLite's rows are one narrow b-tree entry: never packed
    assert _answers(db) == expected


@pytest.mark.backend("postgresql")
def test_a_block_holds_whole_blocks_and_empty_deletes_them(db: toaster.Database) -> None:
    """A packing moves BLOCK samples a row, oldest first, keeping the newest as a row; EMPTY
    of an agent and of all removes blocks with the rows."""
    _setup(db)
    _write(db, None, range(1, 2 * BLOCK + 5))
    db.maintain()
    rows = q.execute(
        db,
        "SELECT cardinality(untils_ns), until_ns = untils_ns[cardinality(untils_ns)], "
        "(SELECT MIN(s.until_ns) FROM fact_samples s WHERE s.fact_id = b.fact_id) > until_ns "
        "FROM fact_sample_blocks b",
    ).rows
    assert rows and all(r == (BLOCK, True, True) for r in rows), rows
    db.store().empty("R")
    assert count(db, "SELECT COUNT(*) FROM fact_sample_blocks") == 0
    _write(db, None, range(3 * BLOCK, 5 * BLOCK))
    db.maintain()
    assert count(db, "SELECT COUNT(*) FROM fact_sample_blocks") > 0
    db.store().empty()
    assert count(db, "SELECT COUNT(*) FROM fact_sample_blocks") == 0


@pytest.mark.backend("postgresql")
def test_downgrade_moves_blocks_back_to_rows_and_upgrade_keeps_them(
    db: toaster.Database,
) -> None:
    """Revision 0025 down and up: no sample lost, the same answers."""
    _setup(db)
    _write(db, 40, range(1, TICKS + 1))
    expected = _answers(db)
    samples = count(db, f"SELECT COUNT(*) FROM {db.backend.samples} s")
    assert count(db, "SELECT COUNT(*) FROM fact_sample_blocks") > 0
    url = db.url
    db.close()
    engine = make_engine(url)
    migrate.downgrade(engine, "0023")
    with engine.connect() as conn:
        assert conn.exec_driver_sql("SELECT COUNT(*) FROM fact_samples").scalar() == samples
    migrate.upgrade(engine)
    engine.dispose()
    with toaster.connect(url) as again:
        assert count(again, "SELECT COUNT(*) FROM fact_sample_blocks") == 0
        assert _answers(again) == expected
        again.maintain()
        assert count(again, "SELECT COUNT(*) FROM fact_sample_blocks") > 0
        assert _answers(again) == expected
