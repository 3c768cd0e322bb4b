"""PostgreSQL: statistics that say a session's scratch tables are empty are forgotten by the
next run (10_focus, revision 0019). An ANALYZE in the session between two runs records the
emptied tables as 0 rows on their pages, and the planner took every later run's rows for none
(docs/beliefs.md)."""

from __future__ import annotations

from typing import Any

import pytest
import sqlalchemy as sa

import toaster
from toaster.db.engine import make_engine
from toaster.model import Fact

pytestmark = pytest.mark.postgresql

#: The session's temporary tables whose statistics say 0 rows on some pages.
EMPTY_ON_PAGES = (
    "SELECT c.relname FROM pg_class c WHERE c.relnamespace = pg_my_temp_schema() "
    "AND c.relkind = 'r' AND c.reltuples = 0 AND c.relpages > 0 ORDER BY c.relname"
)


def _analyze_scratch(conn: Any) -> list[str]:
    """ANALYZE the session's temporary tables (as a bare ANALYZE in the session does); the
    ones then recorded as 0 rows on some pages."""
    names = conn.exec_driver_sql(
        "SELECT relname FROM pg_class WHERE relnamespace = pg_my_temp_schema() AND relkind = 'r'"
    )
    conn.exec_driver_sql("ANALYZE " + ", ".join(f"pg_temp.{name}" for (name,) in names))
    return list(conn.exec_driver_sql(EMPTY_ON_PAGES).scalars())


def _tick(store: Any, tick: int) -> None:
    store.sync_snapshot(
        "p",
        "ROBOT",
        (tick + 1) * 1_000_000,
        [
            Fact("MARBLE", "IsIn", ("BASKET", "BOX")[tick % 2]),
            Fact("SALLY", "IsInRoom", "ROOM"),
            Fact("BASKET", "IsInRoom", "ROOM"),
            Fact("BOX", "IsInRoom", "ROOM"),
        ],
    )


def _sally_believes(conn: Any) -> list[str]:
    return list(
        conn.execute(
            sa.text(
                "SELECT target_id FROM current_facts WHERE agent_id = 'SALLY' "
                "AND subject_id = 'MARBLE'"
            )
        ).scalars()
    )


def test_a_store_session_forgets_statistics_of_its_emptied_scratch_tables(
    pg_schema_url: str,
) -> None:
    with toaster.connect(pg_schema_url) as db:
        store = db.store()
        store.add_entity("ROBOT", "robot", is_self=True, t_ns=0)
        store.add_entity("SALLY", "human", t_ns=0)
        store.add_entity("MARBLE", "object", t_ns=0)
        for tick in range(2):
            _tick(store, tick)
        with db.transaction() as conn:
            assert {"belief_changed", "belief_in"} <= set(_analyze_scratch(conn))
        _tick(store, 2)
        with db.transaction() as conn:
            assert list(conn.exec_driver_sql(EMPTY_ON_PAGES)) == []
            assert _sally_believes(conn) == ["BASKET"]


def test_a_sql_client_forgets_them_within_its_transaction(pg_schema_url: str) -> None:
    """A plain SQL client's scratch tables are emptied at commit; an ANALYZE between two of
    its writes in one transaction is forgotten by the second write's run (a TRUNCATE inside
    the fact_inbox trigger's run)."""
    with toaster.connect(pg_schema_url) as db:
        store = db.store()
        store.add_entity("ROBOT", "robot", is_self=True, t_ns=0)
        store.add_entity("SALLY", "human", t_ns=0)
        store.add_entity("MARBLE", "object", t_ns=0)
        _tick(store, 0)
    engine = make_engine(pg_schema_url)
    write = sa.text(
        "INSERT INTO fact_inbox (agent_id, subject_id, property, target_id, value_text, t_ns) "
        "VALUES ('ROBOT', 'MARBLE', 'IsIn', 'BASKET', 'true', :t)"
    )
    retract = sa.text(
        "INSERT INTO fact_inbox (action, agent_id, subject_id, property, target_id, "
        "value_text, t_ns) VALUES ('retract', 'ROBOT', 'MARBLE', 'IsIn', 'BASKET', 'true', :t)"
    )
    try:
        with engine.begin() as conn:
            conn.execute(retract, {"t": 2_000_000})
            assert "belief_changed" in _analyze_scratch(conn)
            conn.execute(write, {"t": 3_000_000})
            assert list(conn.exec_driver_sql(EMPTY_ON_PAGES)) == []
        with engine.connect() as conn:
            assert _sally_believes(conn) == ["BASKET"]
    finally:
        engine.dispose()
