"""The live node and its control plane, on both backends: what a user changes from another
connection is applied within a tick; a restart carries on; bad input keeps it running."""

from __future__ import annotations

import threading
import time

import pytest

import toaster
from tests.conftest import count
from toaster.errors import InvalidInputError
from toaster.node import LiveNode, control
from toaster.queries import current_facts

TICK = 33_333_333
ANSWER_TIMEOUT_S = 60.0  # a loaded machine may take seconds; a node that never answers fails
ROOM = {"shape": "polygon", "points": [[-1, -1], [6, -1], [6, 2], [-1, 2]], "area_type": "room"}


class Clock:
    """Tick times in the recent past, one tick apart (what a live node uses is the wall clock;
    tests give times so that they can also send poses at them)."""

    def __init__(self) -> None:
        self.t = time.time_ns() - 10**9 * 600

    def next(self) -> int:
        self.t += TICK
        return self.t


def walk(
    node: LiveNode,
    clock: Clock,
    ticks: int,
    *,
    who: str = "bob",
    speed: float = 1.0,
    x0: float = 0.0,
    stamp_shift: int = 0,
) -> dict:
    """``who`` walks along +x; a cup stands ahead; returns the last tick's facts. Poses are
    stamped ``stamp_shift`` ns away from the tick (another clock)."""
    facts: dict = {}
    for k in range(ticks):
        t = clock.next()
        node.api.push(who, (x0 + speed * k * TICK / 1e9, 0.0, 0.0), t_ns=t + stamp_shift)
        node.api.push("cup", (4.0, 0.0, 0.8), kind="object", t_ns=t + stamp_shift)
        facts = node.tick(t)
    return facts


def props(facts: dict, producer: str) -> set[tuple[str, str, str]]:
    return {(f.subject_id, f.property, f.target_id) for f in facts.get(producer, [])}


def stored(db: toaster.Database, prop: str) -> set[tuple[str, str]]:
    return {(r.subject_id, r.target_id) for r in current_facts(db, "toaster", property=prop)}


@pytest.fixture
def other(db_url: str):
    """A second connection to the same database (another shell, another process)."""
    database = toaster.connect(db_url)
    yield database
    database.close()


@pytest.mark.slow
def test_poses_become_stored_facts_and_a_second_connection_controls_the_node(db, other):
    node, clock = LiveNode(db), Clock()
    facts = walk(node, clock, 20)
    assert ("bob", "IsMoving", "") in props(facts, "agent_monitor")
    assert ("bob", "") in stored(db, "IsMoving")
    # areas, monitoring and streams changed from another connection: applied at the next tick
    other.store().put_area("kitchen", ROOM)
    control.monitor_clear(other)
    facts = walk(node, clock, 1, x0=0.7)
    assert {("bob", "IsInRoom", "kitchen"), ("cup", "IsInRoom", "kitchen")} <= props(
        facts, "area_manager"
    )
    assert props(facts, "agent_monitor") == set()
    assert stored(db, "IsMoving") == set()
    control.monitor_add(other, "bob")
    facts = walk(node, clock, 15, x0=0.8)
    assert ("bob", "IsMoving", "") in props(facts, "agent_monitor")
    other.store().remove_area("kitchen")
    facts = walk(node, clock, 1, x0=1.3)
    assert props(facts, "area_manager") == set()


@pytest.mark.slow
def test_monitor_all_humans_covers_humans_seen_later_and_remove_excludes_one(db, other):
    node, clock = LiveNode(db), Clock()
    control.monitor_clear(other)
    control.monitor_all(other, "humans")
    control.monitor_remove(other, "ann")
    for k in range(15):
        t = clock.next()
        for who, y in (("bob", 0.0), ("ann", 3.0)):
            node.api.push(who, (k * TICK / 1e9, y, 0.0), t_ns=t)
        facts = node.tick(t)
    moving = {s for s, p, _ in props(facts, "agent_monitor") if p == "IsMoving"}
    assert moving == {"bob"}
    with other.transaction() as conn:
        assert control.read_state(conn).excluded == ["ann"]


@pytest.mark.slow
def test_stream_off_drops_its_poses_and_on_takes_them_again(db, other):
    node, clock = LiveNode(db), Clock()
    walk(node, clock, 3)
    row = node.world.row("bob")
    control.set_stream(other, "api", False)
    walk(node, clock, 3, x0=2.0)
    assert node.world.pos[row, 0] < 1.0  # the x0=2 poses were dropped
    control.set_stream(other, "api", True)
    walk(node, clock, 1, x0=3.0)
    assert node.world.pos[row, 0] == pytest.approx(3.0)


@pytest.mark.slow
def test_put_in_hand_and_set_entity_pose_from_another_connection(db, other):
    node, clock = LiveNode(db), Clock()
    t = clock.next()
    node.world.add_entity("bob", "human")
    node.world.add_entity("bob/rightHand", "joint", owner_id="bob", name="rightHand")
    node.api.push("bob", (1.0, 1.0, 0.0), t_ns=t)
    node.api.push(
        "bob/rightHand", (1.3, 1.0, 1.0), kind="joint", owner_id="bob", joint="rightHand", t_ns=t
    )
    node.tick(t)
    control.submit(
        other, "set_entity_pose", {"id": "mug", "position": [5, 5, 0.8], "kind": "object"}
    )
    node.tick(clock.next())
    assert node.world.pos[node.world.row("mug")].tolist() == pytest.approx([5, 5, 0.8])
    control.put_in_hand(other, "mug", "bob", "rightHand")
    facts = node.tick(clock.next())
    assert ("mug", "IsInHand", "bob") in props(facts, "pdg")
    assert node.world.pos[node.world.row("mug")].tolist() == pytest.approx([1.3, 1.0, 1.0])
    assert control.remove_from_hand(other, "mug")
    facts = node.tick(clock.next())
    assert ("mug", "IsInHand", "bob") not in props(facts, "pdg")
    with other.transaction() as conn:
        assert control.pending(conn) == []


@pytest.mark.slow
def test_queries_are_answered_by_the_running_node_between_its_ticks(db, other):
    """A query is answered while the node runs, not when it stops (time-outs sized for a loaded
    machine: the answer, not its speed, is what this checks)."""
    node, clock = LiveNode(db), Clock()
    walk(node, clock, 2)
    stop = threading.Event()
    thread = threading.Thread(target=node.run, kwargs={"stop": stop})
    thread.start()
    try:
        answer = control.ask(
            other,
            "get_relative_position",
            {"subject": "bob", "target": "cup"},
            timeout_s=ANSWER_TIMEOUT_S,
        )
        assert answer["angle"] == pytest.approx(0.0, abs=1e-6)
        assert thread.is_alive() and not stop.is_set()
        with pytest.raises(InvalidInputError, match="nobody"):
            control.ask(
                other,
                "get_relative_position",
                {"subject": "bob", "target": "nobody"},
                timeout_s=ANSWER_TIMEOUT_S,
            )
    finally:
        stop.set()
        thread.join()
    assert node.stats.ticks > 0
    assert count(db, "SELECT COUNT(*) FROM control_commands") == 0  # askers delete answers


@pytest.mark.slow
def test_a_query_with_no_node_fails_with_a_hint_and_leaves_nothing_behind(db):
    with pytest.raises(control.NoNodeError, match="toaster serve"):
        control.ask(db, "pointing", {"agent": "bob"}, timeout_s=0.1)
    assert count(db, "SELECT COUNT(*) FROM control_commands") == 0


@pytest.mark.slow
def test_commands_given_with_no_node_running_apply_at_the_next_start(db, other):
    control.submit(other, "set_entity_pose", {"id": "box", "position": [2, 1], "kind": "object"})
    other.store().put_area("kitchen", ROOM)
    node = LiveNode(db)
    node.tick(Clock().next())
    assert node.world.pos[node.world.row("box"), :2].tolist() == [2.0, 1.0]
    assert ("box", "kitchen") in stored(db, "IsInRoom")


@pytest.mark.slow
def test_a_restart_carries_on_the_open_intervals(db_url):
    clock = Clock()
    with toaster.connect(db_url) as db:
        db.store().put_area("kitchen", ROOM)
        walk(LiveNode(db), clock, 20)
        appeared = count(db, "SELECT COUNT(*) FROM events WHERE kind = 'appeared'")
    with toaster.connect(db_url) as db:
        node = LiveNode(db)
        assert {"bob", "cup"} <= set(node.world.ids)  # read back from the database
        walk(node, clock, 20, x0=0.68)
        # still present, still in the kitchen: those intervals go on (motion needs a speed
        # window again after a restart, so IsMoving may pause)
        for prop in ("isPresent", "IsInRoom"):
            assert (
                count(
                    db,
                    "SELECT COUNT(*) FROM events e JOIN fact_keys k ON k.id = e.key_id "
                    "WHERE k.property = :p AND e.kind = 'ended'",
                    p=prop,
                )
                == 0
            )
            assert count(
                db,
                "SELECT COUNT(*) FROM facts f JOIN fact_keys k ON k.id = f.key_id "
                "WHERE k.property = :p AND k.agent_id = 'toaster'",
                p=prop,
            ) == (1 if prop == "isPresent" else 2)
        assert count(db, "SELECT COUNT(*) FROM events WHERE kind = 'appeared'") >= appeared


@pytest.mark.slow
def test_bad_poses_are_refused_with_a_reason_and_the_node_keeps_ticking(db):
    node, clock = LiveNode(db), Clock()
    assert not node.api.push("bob", (float("nan"), 0.0), t_ns=clock.t)
    assert "finite" in node.api.last_error
    assert not node.api.push("", (0, 0))
    assert not node.api.push("bob", (0, 0), kind="dragon")
    assert not node.api.push("bob", (0, 0), quat=(0, 0, 0, 0))
    assert node.api.rejected == 4
    walk(node, clock, 3)
    # stamps jumping 60 s back (a looping bag, simulated time) are shifted onto the node's
    # clock instead of being ignored as old: the entity keeps moving and stays present
    facts = walk(node, clock, 20, x0=5.0, stamp_shift=-60 * 10**9)
    assert node.world.pos[node.world.row("bob"), 0] == pytest.approx(5.0 + 19 * TICK / 1e9)
    assert {("bob", "isPresent", ""), ("bob", "IsMoving", "")} <= (
        props(facts, "pdg") | props(facts, "agent_monitor")
    )
    assert node.stats.warnings >= 1


@pytest.mark.slow
def test_the_newest_pose_per_entity_wins_and_the_buffer_stays_bounded(db):
    node, clock = LiveNode(db), Clock()
    t = clock.next()
    for k in range(1000):
        node.api.push("bob", (k / 1000, 0, 0), t_ns=t - 1000 + k)
    assert node.api.pending() <= node.api.max_pending
    node.tick(t)
    assert node.world.pos[node.world.row("bob"), 0] == pytest.approx(0.999)


def test_quaternions_give_the_heading():
    from toaster.world.live import quaternion_to_rpy

    roll, pitch, yaw = quaternion_to_rpy(0.0, 0.0, 0.7071068, 0.7071068)
    assert (roll, pitch) == pytest.approx((0.0, 0.0), abs=1e-6)
    assert yaw == pytest.approx(1.5707963, abs=1e-6)


@pytest.mark.slow
def test_monitor_commands_start_from_the_default_and_respect_a_clear(db):
    """add/remove start from what a node monitors by default (every human); after a clear,
    removing one agent does not bring the others back."""
    state = control.monitor_add(db, "robby")
    assert state.agents == ["humans", "robby"]
    control.monitor_clear(db)
    state = control.monitor_remove(db, "bob")
    assert state.agents == []
    assert state.excluded == []


@pytest.mark.slow
def test_fact_lists_go_out_before_the_write_and_the_rest_after(db):
    """An output's publish_facts sees the tick's facts before they are stored (the ROS fact
    lists do not wait for the database); publish sees them stored, in the same mapping."""
    seen: list[tuple[str, set, set]] = []

    class Probe:
        def publish_facts(self, t_ns, facts, world):
            seen.append(("facts", props(facts, "pdg"), stored(db, "isPresent")))

        def publish(self, t_ns, facts, world):
            seen.append(("stored", props(facts, "pdg"), stored(db, "isPresent")))

    node, clock = LiveNode(db, outputs=[Probe()]), Clock()
    walk(node, clock, 1)
    bob = ("bob", "isPresent", "")
    assert seen == [("facts", {bob}, set()), ("stored", {bob}, {("bob", "")})]


@pytest.mark.slow
@pytest.mark.backend("postgresql")
def test_a_running_node_reads_its_control_plane_when_notified(db, other, monkeypatch):
    """On PostgreSQL the control version is read after a NOTIFY (and at least every second),
    not every tick: a change from another connection is applied all the same."""
    from toaster.node import control_watch

    monkeypatch.setattr(control_watch, "MAX_AGE_S", 3600.0)
    node = LiveNode(db)
    seen: list = []
    stop = threading.Event()

    class Probe:
        def publish(self, t_ns, facts, world):
            seen.append(props(facts, "area_manager"))
            if node._watch is not None:
                watches.append(node._watch)

    watches: list = []
    node.outputs.append(Probe())
    node.api.push("bob", (1.0, 0.0, 0.0))
    thread = threading.Thread(target=node.run, kwargs={"stop": stop})
    thread.start()
    try:
        deadline = time.monotonic() + ANSWER_TIMEOUT_S
        while len(seen) < 20 and time.monotonic() < deadline:
            node.api.push("bob", (1.0, 0.0, 0.0))
            time.sleep(0.02)
        other.store().put_area("kitchen", ROOM)
        while ("bob", "IsInRoom", "kitchen") not in seen[-1] and time.monotonic() < deadline:
            node.api.push("bob", (1.0, 0.0, 0.0))
            time.sleep(0.02)
    finally:
        stop.set()
        thread.join()
    assert ("bob", "IsInRoom", "kitchen") in seen[-1]
    assert watches and watches[-1].reads < len(seen) / 2
