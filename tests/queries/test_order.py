"""Listings spanning several agents come in one order, whatever the plan: a belief shared by
holders that perceive alike is one interval (one fact id) and one event (one event id) under
several agents, so time and id alone leave ties that a LIMIT would cut anywhere."""

from __future__ import annotations

from pathlib import Path

import toaster

SALLY_ANNE = Path(toaster.__file__).parent / "examples" / "beliefs_sally_anne.yaml"


def test_history_memory_and_events_break_ties_by_agent(db: toaster.Database) -> None:
    toaster.beliefs.replay(db, SALLY_ANNE)
    q = toaster.queries
    with db.transaction() as conn:
        ids = {
            tuple(row[:-1]): row[-1]
            for row in conn.exec_driver_sql(
                "SELECT agent_id, subject_id, property, target_id, valid_from_ns, fact_id "
                "FROM fact_history"
            )
        }
    assert len(set(ids.values())) < len(ids), "no interval under several agents: no tie to break"
    for listing in (q.history, q.memory):
        rows = listing(db)
        keys = [
            (r.valid_from_ns, ids[r.agent_id, r.subject_id, r.property, r.target_id, r.valid_from_ns],
             r.agent_id)
            for r in rows
        ]  # fmt: skip
        assert keys == sorted(keys), listing.__name__
        assert listing(db, limit=7) == rows[:7]
    events = q.events(db)
    keys = [(e.stamp_ns, e.id, e.agent_id) for e in events]
    assert keys == sorted(keys)
    newest = q.events(db, newest_first=True)
    assert newest == events[::-1]
    assert q.events(db, limit=5) == events[:5]
