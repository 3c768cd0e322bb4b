"""Input checked at the edge of a live node (issue 25): what the store would refuse is refused
by ``LiveSource.push`` and by the node's commands, counted per topic and field, and never
reaches the tick; queries and commands about unknown or removed entities fail with a reason;
the status window's line."""

from __future__ import annotations

import json
from collections.abc import Iterator

import pytest

import toaster
from tests.node.test_node import Clock, walk
from toaster import queries as q
from toaster.errors import UnknownEntityError
from toaster.node import LiveNode, control
from toaster.node.stats import LiveStats
from toaster.world.drops import MAX_KEYS, Drops


@pytest.fixture
def other(db_url: str) -> Iterator[toaster.Database]:
    """A second connection to the same database (another process's)."""
    database = toaster.connect(db_url)
    yield database
    database.close()


HOSTILE_IDS = ["x" * 300, "cup\x00", "h" * 1_000_000, " ", "\ud800"]


@pytest.mark.slow
def test_ids_the_store_refuses_never_reach_the_tick(db):
    """A 300-character or NUL id was queued, then failed registration inside the tick."""
    node, clock = LiveNode(db), Clock()
    for entity_id in HOSTILE_IDS:
        assert not node.api.push(entity_id, (1.0, 0.0), kind="object", t_ns=clock.t)
    assert not node.api.push("BOB>ANNE", (1.0, 0.0), kind="human", t_ns=clock.t)
    assert node.api.push("BOB>ANNE", (1.0, 0.0), kind="object", t_ns=clock.t)  # objects may
    assert not node.api.push("bob/hand", (0, 0), kind="joint", owner_id="A>B", t_ns=clock.t)
    for bad in (
        {"t_ns": -1},
        {"t_ns": 2**64},
        {"t_ns": 1.5},
        {"confidence": 2.0},
        {"quat": (float("nan"), 0, 0, 1)},
        {"rpy": (0, 0)},
        {"yaw": float("inf")},
    ):
        assert not node.api.push("cup", (1.0, 0.0), kind="object", **{"t_ns": clock.t, **bad})
    assert not node.api.push("cup", (1e12, 0.0), kind="object", t_ns=clock.t)
    assert not node.api.push("cup", (1.0,), kind="object", t_ns=clock.t)
    walk(node, clock, 3)
    assert node.stats.ticks == 3 and "bob" in node.world.index
    assert not set(HOSTILE_IDS) & set(node.world.ids)
    counts = node.drops.counts()
    assert counts["api id"] == len(HOSTILE_IDS) + 1
    assert counts["api owner"] == 1 and counts["api stamp"] == 3
    assert counts["api position"] == 2 and counts["api orientation"] == 3
    assert counts["api confidence"] == 1


@pytest.mark.slow
def test_a_publisher_inventing_ids_cannot_grow_the_world_without_end(db):
    """Every new id became an entity, in the world and the database, for as long as the node
    ran: past ``max_entities`` the poses of new ids are refused and counted; known ids move."""
    node, clock = LiveNode(db), Clock()
    walk(node, clock, 1)
    known = len(node.world.ids)
    node.api.max_entities = known + 2
    for i in range(5):
        assert node.api.push(f"invented{i}", (1.0, float(i)), kind="object", t_ns=clock.t)
    walk(node, clock, 2)
    assert len(node.world.ids) == known + 2
    assert {"invented0", "invented1"} <= set(node.world.ids)
    assert node.drops.counts()["api id"] == 3
    assert node.api.push("invented0", (2.0, 0.0), kind="object", t_ns=clock.t)
    walk(node, clock, 1)
    assert node.world.pos[node.world.index["invented0"]][0] == 2.0
    assert {e.id for e in q.entities(db)} >= {"invented0", "invented1"}
    assert "invented4" not in {e.id for e in q.entities(db)}


@pytest.mark.slow
def test_commands_are_checked_and_removal_is_complete(db, other):
    node, clock = LiveNode(db), Clock()
    walk(node, clock, 2)
    control.submit(other, "add_entity", {"id": "x" * 300})
    control.submit(other, "add_entity", {"id": "EVE>BOB", "kind": "human"})
    control.submit(other, "set_entity_pose", {"id": "cup\x00", "position": [1, 1]})
    control.submit(
        other, "set_entity_pose", {"id": "ghost", "position": [1, 1], "known_only": True}
    )
    control.submit(other, "set_entity_pose", {"id": "cup", "position": [1e300, 1]})
    with other.transaction(write=True) as conn:  # a row written by hand with SQL
        conn.exec_driver_sql(
            "INSERT INTO control_commands (kind, args_json, created_ns, "
            "state) VALUES ('add_entity', 'not json', 0, 'pending')"
        )
    control.submit(other, "add_entity", {"id": "stool", "kind": "object"})
    control.submit(
        other, "set_entity_pose", {"id": "stool", "position": [0.5, 0.0], "known_only": True}
    )
    walk(node, clock, 2)
    with other.transaction() as conn:
        rows = conn.exec_driver_sql(
            "SELECT kind, state, answer_json FROM control_commands ORDER BY id"
        ).all()
    states = [r.state for r in rows]
    assert states == ["failed"] * 6 + ["done", "done"], rows
    assert "unknown entity 'ghost'" in json.loads(rows[3].answer_json)
    assert "ghost" not in node.world.index and "stool" in node.world.index
    assert node.query("get_relative_position", {"subject": "bob", "target": "stool"})
    control.submit(other, "remove_entity", {"id": "stool"})
    walk(node, clock, 2)
    with pytest.raises(UnknownEntityError, match="stool"):
        node.query("get_relative_position", {"subject": "bob", "target": "stool"})
    with pytest.raises(UnknownEntityError, match="stool"):
        node.query("pointing", {"agent": "stool"})
    assert "stool" not in {e.id for e in q.entities(other)}


def test_drops_count_per_key_with_one_line_per_key_and_a_bounded_table():
    drops = Drops(every_s=3600)
    for k in range(5):
        drops.drop("/t", "id", f"invalid id {k}")
    drops.drop("/t", "pose", "nan")
    lines = drops.take_lines()
    assert lines == [
        "/t: invalid id 0 (dropped: id, 1 so far)",
        "/t: nan (dropped: pose, 1 so far)",
    ]
    assert drops.counts() == {"/t id": 5, "/t pose": 1}
    for k in range(MAX_KEYS + 50):
        drops.drop(f"/topic{k}", "id", "x")
    assert len(drops.counts()) <= MAX_KEYS + 1 and drops.total == 6 + MAX_KEYS + 50
    drops.drop("/t", "id", "line\nbreak\x1b")
    assert all("\n" not in line and "\x1b" not in line for line in drops.take_lines())


def test_the_window_line_has_the_format_benchmarks_parse():
    stats = LiveStats()
    stats.window_start = 100.0
    for ms in [1.0] * 98 + [5.0, 40.0]:
        stats.record(ms, overran=ms > 33.3)
    assert stats.take_window(now=110.0) == (
        "window 10 s: 100 ticks, p50 1.0 ms, p99 40.0 ms, max 40.0 ms, 1 overruns"
    )
    assert stats.take_window(now=111.0) == (
        "window 1 s: 0 ticks, p50 0.0 ms, p99 0.0 ms, max 0.0 ms, 0 overruns"
    )
    assert stats.overruns == 1 and stats.ticks == 0


def test_a_window_longer_than_it_keeps_counts_every_tick(monkeypatch):
    """A status window keeps only the newest durations (memory stays bounded with the status
    line off), but counts every tick and keeps the longest, however long ago it came."""
    monkeypatch.setattr("toaster.node.stats.WINDOW_TICKS", 10)
    stats = LiveStats()
    stats.window_start = 0.0
    for ms in [900.0] + [2.0] * 99:
        stats.record(ms, overran=ms > 33.3)
    assert len(stats.window_ms) <= 20
    assert stats.take_window(now=10.0) == (
        "window 10 s: 100 ticks, p50 2.0 ms, p99 2.0 ms, max 900.0 ms, 1 overruns"
    )
