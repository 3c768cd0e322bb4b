"""A small belief story for the migration tests: followed periods, a missed change (a frozen
period), nested holders, a closed box, seeing again and a number refresh.

``data/beliefs_0005.sql`` is a SQLite dump of :func:`first_half` written by toaster at
revision 0005 as 0.1.0's development left it (commit 510c628, before the belief revisions were
squashed), made with::

    git archive 510c628 | tar -x -C /tmp/old
    PYTHONPATH=/tmp/old/src:. python -m tests.migrations.beliefs_story /tmp/old.db tests/migrations/data/beliefs_0005.sql

(the rows of its ``belief_rules`` table, the rule text of that time, are left out).
"""

from __future__ import annotations

import sqlite3
import sys
from typing import Any

from toaster import Fact

HUMANS = ("ANNE", "BOB")


def _world(t: int) -> list[Fact]:
    bob_room = "HALL" if t in (3, 4) else "LAB"
    facts = [
        Fact(
            "ANNE", "IsInRoom", "HALL" if t >= 8 else "LAB", confidence=0.9 if t in (2, 3) else 1.0
        ),
        Fact("BOB", "IsInRoom", bob_room),
        Fact("BOX", "IsInRoom", "LAB"),
        Fact("MUG", "IsInRoom", "LAB"),
    ]
    if t >= 2:
        facts.append(Fact("MUG", "IsIn", "BOX"))
    if t in (4, 5):
        facts.append(Fact("BOX", "IsClosed"))
    color = {1: "red", 2: "red", 3: "blue", 4: "green", 8: "yellow"}.get(t, "green")
    facts.append(Fact("MUG", "Color", value_text=color))
    facts.append(
        Fact(
            "MUG",
            "Temperature",
            value_text="warm",
            value_num=20.0 if t < 7 else 25.0,
            confidence=0.9 if t < 6 else 0.8,
        )
    )
    if t >= 6:
        facts.append(Fact("MUG", "IsVisibleBy", "ANNE", confidence=0.7))
    return facts


def first_half(db: Any) -> None:
    """Entities and ticks 1-4 (what the old database holds)."""
    st = db.store()
    st.add_entity("R", "robot", is_self=True, t_ns=0)
    for human in HUMANS:
        st.add_entity(human, "human", t_ns=0)
    for thing in ("MUG", "BOX", "LAB", "HALL"):
        st.add_entity(thing, "object", t_ns=0)
    for t in range(1, 5):
        st.sync_snapshot("world", "R", t * 10, _world(t))


def second_half(db: Any) -> None:
    """Ticks 5-8."""
    st = db.store()
    for t in range(5, 9):
        st.sync_snapshot("world", "R", t * 10, _world(t))


def _dump(path: str, out: str) -> None:
    import toaster

    with toaster.connect(f"sqlite:///{path}") as db:
        first_half(db)
    conn = sqlite3.connect(path)
    lines = [line for line in conn.iterdump() if not line.startswith('INSERT INTO "belief_rules"')]
    conn.close()
    with open(out, "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    _dump(sys.argv[1], sys.argv[2])
