"""The internal tables refuse direct writes, whatever the client: keys, intervals, samples,
events, followed periods and nested holders are written by toaster's store and rules only.

Each write comes from a separate connection (a plain SQL client: psql, sqlite3, a script)."""

from __future__ import annotations

from importlib import resources

import pytest
import sqlalchemy as sa

import toaster
from toaster.beliefs import api, scenario
from toaster.db.dialects import GUARD_MESSAGE, GUARDED_TABLES
from toaster.db.dialects.postgresql import BLOCK
from toaster.db.engine import make_engine

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

SALLY_ANNE = resources.files("toaster") / "examples" / "beliefs_sally_anne.yaml"
FIRST_COLUMN = {
    "fact_keys": "agent_id",
    "facts": "key_id",
    "events": "key_id",
    "fact_samples": "fact_id",
    "fact_sample_blocks": "fact_id",
    "belief_follow": "hkey",
    "belief_chain": "holder_id",
    "belief_groups": "holder_id",
    "belief_perceived": "holder_id",
    "belief_settled": "key_id",
}


@pytest.fixture
def story(db: toaster.Database) -> toaster.Database:
    """Sally-Anne (holders, followed periods, nested holders) plus a refreshed number
    (sample rows, on PostgreSQL a block of them once maintained) and two people in a lab, who
    perceive alike (a group of holders; the kept perception and settled keys of the lab's
    ticks): every guarded table has rows (on SQLite, which never packs, a block written in a
    store transaction)."""
    scenario.replay(db, SALLY_ANNE)
    st = db.store()
    for person in ("XAVI", "YUKI"):
        st.add_entity(person, "human", t_ns=0)
    lab = [toaster.Fact(x, "IsInRoom", "LAB") for x in ("XAVI", "YUKI", "CUP")]
    for t, metres in enumerate([1.0, 2.0] * (BLOCK // 2 + 2), start=10):
        st.sync_snapshot(
            "ranger",
            "ROBOT",
            t * 1_000_000_000,
            [toaster.Fact("SALLY", "Distance", "BOX", value_num=metres), *lab],
        )
    db.maintain()
    if db.backend.name == "sqlite":  # never packed there: a block as the store would write it
        with st.transaction():
            db.cursor().execute(
                "INSERT INTO fact_sample_blocks SELECT fact_id, MAX(until_ns), '[]', '[]', "
                "'[]', '[]' FROM fact_samples GROUP BY fact_id LIMIT 1"
            )
    return db


def counts(url: str) -> dict[str, int]:
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            return {
                t: conn.execute(sa.text(f"SELECT count(*) FROM {t}")).scalar_one()
                for t in GUARDED_TABLES
            }
    finally:
        engine.dispose()


def raw_write(url: str, sql: str) -> str:
    """Run ``sql`` on a new connection; return the database's error (fails if it worked)."""
    engine = make_engine(url)
    try:
        with engine.begin() as conn:
            conn.execute(sa.text(sql))
    except sa.exc.DBAPIError as exc:
        return str(exc.orig).strip()
    finally:
        engine.dispose()
    pytest.fail(f"the database accepted {sql!r}")


def test_guarded_tables_have_rows(story: toaster.Database) -> None:
    found = counts(story.url)
    assert all(found.values()), found


@pytest.mark.parametrize("table", GUARDED_TABLES)
@pytest.mark.parametrize("action", ["insert", "update", "delete"])
def test_direct_write_is_refused_in_one_line(
    story: toaster.Database, table: str, action: str
) -> None:
    before = counts(story.url)
    column = FIRST_COLUMN[table]
    sql = {
        "insert": f"INSERT INTO {table} SELECT * FROM {table}",
        "update": f"UPDATE {table} SET {column} = {column}",
        "delete": f"DELETE FROM {table}",
    }[action]
    error = raw_write(story.url, sql)
    assert error.splitlines()[0] == GUARD_MESSAGE.format(table=table)
    assert counts(story.url) == before


def test_ending_a_robot_interval_by_hand_cannot_rewrite_sallys_belief(
    story: toaster.Database,
) -> None:
    """The reported corruption: a raw UPDATE that ends the robot's interval used to end the
    intervals of every holder following it, Sally's false belief included."""

    def sallys_marble() -> set[tuple[str, int, int | None]]:
        return {
            (r.target_id, r.valid_from_ns, r.valid_to_ns)
            for r in api.belief_history(story, "MARBLE", "IsIn")
            if r.agent_id == "SALLY"
        }

    held = sallys_marble()
    raw_write(story.url, "UPDATE facts SET valid_to_ns = 5000000000 WHERE valid_to_ns IS NULL")
    assert sallys_marble() == held


def test_the_store_still_writes_and_other_tables_stay_open(story: toaster.Database) -> None:
    """Library writes pass the guard (one transaction each), and plain tables such as
    settings and entities stay writable by any client."""
    story.store().assert_fact("ROBOT", toaster.Fact("BOX", "IsOn", "TABLE"), t_ns=12, strict=False)
    assert api.belief_value(story, "ROBOT", "BOX", "IsOn", "TABLE") is not None
    engine = make_engine(story.url)
    try:
        with engine.begin() as conn:
            conn.execute(
                sa.text("INSERT INTO settings (scope, key, value_json) VALUES ('mine', 'k', '1')")
            )
    finally:
        engine.dispose()
