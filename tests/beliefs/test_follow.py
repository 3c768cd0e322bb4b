"""Followed periods: holders share the robot's rows while they perceive every change.

Random stories (rooms, containers, visibility with two confidences, value and number changes)
are replayed on both backends; every holder's timeline must then read as if it had its own
rows: no overlap, no split of an unchanged belief, one event per interval start and end, and
the as-of query agreeing with the stored history at every tick.
"""

from __future__ import annotations

import random
from collections import defaultdict

import pytest
from sqlalchemy import text

import toaster
import toaster.queries as q
from toaster import Fact
from toaster.beliefs import api
from toaster.db import migrate
from toaster.db.engine import make_engine
from toaster.db.invariants import violations
from toaster.db.writer.store import LIVE_CLOCK_SKEW_NS

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

HUMANS = ("ANNE", "BOB", "CAROL")
OBJECTS = ("MUG", "KEYS", "BALL")
ROOMS = ("KITCHEN", "HALL")


def _key(row: object) -> tuple[str, ...]:
    return (
        row.subject_id,
        row.subject_owner_id,
        row.property,
        row.sub_property,
        row.target_id,
        row.target_owner_id,
    )


class Story:
    """A random world: humans and objects move between rooms and a box, values change."""

    def __init__(self, seed: int) -> None:
        self.rng = random.Random(seed)
        self.room = {h: self.rng.choice(ROOMS) for h in HUMANS}
        self.room.update({o: self.rng.choice(ROOMS) for o in (*OBJECTS, "BOX")})
        self.in_box = dict.fromkeys(OBJECTS, False)
        self.color = dict.fromkeys(OBJECTS, "red")
        self.temp = dict.fromkeys(OBJECTS, 20.0)
        self.seen: dict[tuple[str, str], float] = {}
        self.closed = True

    def step(self) -> None:
        for _ in range(self.rng.randint(1, 3)):
            what = self.rng.randrange(7)
            if what == 0:
                h = self.rng.choice(HUMANS)
                self.room[h] = self.rng.choice((*ROOMS, None))
            elif what == 1:
                self.room[self.rng.choice((*OBJECTS, "BOX"))] = self.rng.choice(ROOMS)
            elif what == 2:
                o = self.rng.choice(OBJECTS)
                self.in_box[o] = not self.in_box[o]
            elif what == 3:
                self.color[self.rng.choice(OBJECTS)] = self.rng.choice(("red", "blue", "green"))
            elif what == 4:
                self.temp[self.rng.choice(OBJECTS)] += self.rng.choice((-1.0, 1.0))
            elif what == 5:
                pair = (self.rng.choice(OBJECTS), self.rng.choice(HUMANS))
                if pair in self.seen:
                    del self.seen[pair]
                else:
                    self.seen[pair] = self.rng.choice((0.5, 1.0))
            else:
                self.closed = not self.closed

    def facts(self) -> list[Fact]:
        out = [Fact(e, "IsInRoom", r) for e, r in self.room.items() if r is not None]
        out += [Fact(o, "IsIn", "BOX") for o, inside in self.in_box.items() if inside]
        out += [Fact(o, "Color", value_text=c) for o, c in self.color.items()]
        out += [Fact(o, "Temperature", value_text="num", value_num=v) for o, v in self.temp.items()]
        out += [Fact(o, "IsVisibleBy", h, confidence=c) for (o, h), c in self.seen.items()]
        if self.closed:
            out.append(Fact("BOX", "IsClosed", value_text="true"))
        return out


def _replay(db: toaster.Database, seed: int, ticks: int) -> list[int]:
    st = db.store()
    st.add_entity("R", "robot", is_self=True, t_ns=0)
    for h in HUMANS:
        st.add_entity(h, "human", t_ns=0)
    for e in (*OBJECTS, "BOX", *ROOMS):
        st.add_entity(e, "object", t_ns=0)
    story, times = Story(seed), []
    for tick in range(1, ticks + 1):
        story.step()
        st.sync_snapshot("world", "R", tick * 10, story.facts())
        times.append(tick * 10)
    return times


def _check_timelines(db: toaster.Database, times: list[int]) -> int:
    """Assert the invariants of every holder's timeline; return the number of intervals."""
    checked = 0
    for holder in api.holders(db):
        rows = q.history(db, holder)
        events = defaultdict(list)
        for e in q.events(db, holder):
            events[_key(e)].append(e)
        by_key = defaultdict(list)
        for r in rows:
            by_key[_key(r)].append(r)
        for key, intervals in by_key.items():
            intervals.sort(key=lambda r: r.valid_from_ns)
            expected = []
            for i, r in enumerate(intervals):
                assert r.valid_to_ns is None or r.valid_to_ns > r.valid_from_ns, (holder, r)
                prev = intervals[i - 1] if i else None
                nxt = intervals[i + 1] if i + 1 < len(intervals) else None
                touching = prev is not None and prev.valid_to_ns == r.valid_from_ns
                if prev is not None:
                    assert prev.valid_to_ns is not None, (holder, key, "two open intervals")
                    assert prev.valid_to_ns <= r.valid_from_ns, (holder, key, "overlap")
                    assert not (touching and prev.value_text == r.value_text), (
                        holder,
                        key,
                        "an unchanged belief split in two intervals",
                    )
                expected.append(
                    (
                        "changed" if touching else "appeared",
                        r.valid_from_ns,
                        r.value_text,
                        prev.value_text if touching else None,
                    )
                )
                if r.valid_to_ns is not None and (
                    nxt is None or nxt.valid_from_ns != r.valid_to_ns
                ):
                    expected.append(("ended", r.valid_to_ns, r.value_text, None))
                checked += 1
            got = [
                (e.kind, e.stamp_ns, e.value_text, e.previous_text)
                for e in sorted(events.pop(key, []), key=lambda e: (e.stamp_ns, e.kind))
            ]
            assert got == sorted(expected, key=lambda x: (x[1], x[0])), (holder, key)
        assert not events, (holder, "events without intervals", list(events))
        for t in times:
            held = {
                (_key(r), r.value_text, round(r.confidence, 9))
                for r in rows
                if r.valid_from_ns <= t and (r.valid_to_ns is None or r.valid_to_ns > t)
            }
            as_of = {
                (_key(r), r.value_text, round(r.confidence, 9)) for r in q.beliefs_at(db, holder, t)
            }
            assert as_of == held, (holder, t)
        current = {(_key(r), r.value_text) for r in q.current_facts(db, holder)}
        assert current == {(_key(r), r.value_text) for r in rows if r.valid_to_ns is None}
    return checked


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_stories_keep_every_timeline_consistent(db: toaster.Database, seed: int) -> None:
    times = _replay(db, seed, 40)
    assert _check_timelines(db, times) > 50


def test_a_change_every_holder_perceives_writes_no_holder_row(db: toaster.Database) -> None:
    st = db.store()
    st.add_entity("R", "robot", is_self=True, t_ns=0)
    for h in HUMANS:
        st.add_entity(h, "human", t_ns=0)
    room = [Fact(h, "IsInRoom", "KITCHEN") for h in HUMANS] + [Fact("MUG", "IsInRoom", "KITCHEN")]

    def physical_rows() -> int:
        with db.transaction() as conn:
            return conn.execute(
                text(
                    "SELECT (SELECT count(*) FROM facts f JOIN fact_keys k ON k.id = f.key_id "
                    "WHERE k.agent_id <> 'R') + (SELECT count(*) FROM events WHERE agent_id <> 'R')"
                )
            ).scalar_one()

    st.sync_snapshot("w", "R", 1, [*room, Fact("MUG", "Color", value_text="red")])
    st.sync_snapshot("w", "R", 2, [*room, Fact("MUG", "Color", value_text="blue")])
    before = physical_rows()
    for t, color in ((3, "green"), (4, "red"), (5, "blue")):
        st.sync_snapshot("w", "R", t, [*room, Fact("MUG", "Color", value_text=color)])
    assert physical_rows() == before
    # ... and yet every holder, nested ones included, has the three changes as its own.
    for holder in (*HUMANS, "ANNE>BOB"):
        changes = q.events(db, holder, subject="MUG", property="Color", kind="changed")
        assert [(e.stamp_ns, e.previous_text, e.value_text) for e in changes][-3:] == [
            (3, "blue", "green"),
            (4, "green", "red"),
            (5, "red", "blue"),
        ]


def test_a_missed_change_keeps_one_unsplit_interval(db: toaster.Database) -> None:
    st = db.store()
    st.add_entity("R", "robot", is_self=True, t_ns=0)
    st.add_entity("SALLY", "human", t_ns=0)
    here = [Fact("MARBLE", "IsInRoom", "LAB")]
    st.sync_snapshot(
        "w", "R", 1, [*here, Fact("SALLY", "IsInRoom", "LAB"), Fact("MARBLE", "IsIn", "BASKET")]
    )
    st.sync_snapshot("w", "R", 2, [*here, Fact("MARBLE", "IsIn", "BASKET")])  # Sally leaves
    st.sync_snapshot("w", "R", 3, [*here, Fact("MARBLE", "IsIn", "BOX")])  # unseen move
    basket = q.history(db, "SALLY", subject="MARBLE", property="IsIn")
    assert [(r.target_id, r.valid_from_ns, r.valid_to_ns) for r in basket] == [("BASKET", 1, None)]
    assert [
        (e.kind, e.stamp_ns) for e in q.events(db, "SALLY", subject="MARBLE", property="IsIn")
    ] == [("appeared", 1)]


def test_direct_writes_and_emptying_the_robot_keep_holder_beliefs(db: toaster.Database) -> None:
    times = _replay(db, 4, 15)
    before = {h: {(_key(r), r.value_text) for r in q.current_facts(db, h)} for h in api.holders(db)}
    st = db.store()
    # A user corrects Anne directly: the rest of what she follows stays as it was.
    st.assert_fact("ANNE", Fact("MUG", "Color", value_text="purple"), t_ns=times[-1] + 1)
    anne = {(_key(r), r.value_text) for r in q.current_facts(db, "ANNE")}
    assert anne == {x for x in before["ANNE"] if x[0][2] != "Color" or x[0][0] != "MUG"} | {
        (("MUG", "", "Color", "", "", ""), "purple")
    }
    assert _check_timelines(db, times) > 0
    # Emptying the robot's facts leaves every holder's beliefs (and history) in place.
    history = {h: q.history(db, h) for h in api.holders(db)}
    st.empty("R")
    assert q.current_facts(db, "R") == []
    for h in api.holders(db):
        assert sorted(q.history(db, h)) == sorted(history[h])
    with db.transaction() as conn:
        assert conn.execute(text("SELECT count(*) FROM belief_follow")).scalar_one() == 0


def test_downgrade_to_0001_keeps_holder_beliefs(empty_url: str) -> None:
    """The followed periods become own rows: first-order holders keep their timelines (the
    nested holders are removed with the beliefs revision)."""
    with toaster.connect(empty_url) as db:
        _replay(db, 5, 12)
        holders = [h for h in api.holders(db) if ">" not in h]
        history = {h: sorted(q.history(db, h)) for h in holders}
        events = {h: len(q.events(db, h)) for h in holders}
        with db.transaction() as conn:
            assert conn.execute(text("SELECT count(*) FROM belief_follow")).scalar_one() > 0
    engine = make_engine(empty_url)
    migrate.downgrade(engine, "0001")
    engine.dispose()
    with toaster.connect(empty_url, check=False) as db:
        for h in holders:
            assert sorted(q.history(db, h)) == history[h]
            assert len(q.events(db, h)) == events[h]


def test_two_robots_writing_the_same_fact(db: toaster.Database) -> None:
    """A holder follows whichever robot's change it perceived last, with no overlap."""
    st = db.store()
    for robot in ("R1", "R2"):
        st.add_entity(robot, "robot", is_self=True, t_ns=0)
    st.add_entity("ANNE", "human", t_ns=0)
    here = [Fact("ANNE", "IsInRoom", "LAB"), Fact("MUG", "IsInRoom", "LAB")]
    away = [Fact("ANNE", "IsInRoom", "HALL"), Fact("MUG", "IsInRoom", "LAB")]
    st.sync_snapshot("w", "R1", 1, [*here, Fact("MUG", "Color", value_text="red")])
    st.sync_snapshot("w", "R2", 2, [*here, Fact("MUG", "Color", value_text="blue")])
    st.sync_snapshot("w", "R1", 3, [*here, Fact("MUG", "Color", value_text="green")])
    st.sync_snapshot("w", "R1", 4, [*away, Fact("MUG", "Color", value_text="green")])
    st.sync_snapshot("w", "R1", 5, [*away, Fact("MUG", "Color", value_text="white")])
    st.sync_snapshot("w", "R2", 6, [*here, Fact("MUG", "Color", value_text="black")])
    colors = q.history(db, "ANNE", subject="MUG", property="Color")
    assert [(r.value_text, r.valid_from_ns, r.valid_to_ns) for r in colors] == [
        ("red", 1, 2),
        ("blue", 2, 3),
        ("green", 3, 6),
        ("black", 6, None),
    ]
    assert _check_timelines(db, [1, 2, 3, 4, 5, 6]) >= 4


S = 1_000_000_000
ROBOT_ROOMS = {"ANNE": "OFFICE", "BOB": "OFFICE", "CARL": "KITCHEN"}


def _two_robots(db: toaster.Database) -> toaster.Store:
    st = db.store()
    with st.transaction():
        for robot in ("R1", "R2"):
            st.add_entity(robot, "robot", is_self=True, t_ns=0)
        for who in ROBOT_ROOMS:
            st.add_entity(who, "human", t_ns=0)
        for thing in ("PEN", "DRAWER", "OFFICE", "KITCHEN", "HALL"):
            st.add_entity(thing, "object", t_ns=0)
    return st


def _rooms(where: dict[str, str]) -> list[Fact]:
    return [Fact(who, "IsInRoom", room) for who, room in sorted(where.items())] + [
        Fact("DRAWER", "IsInRoom", "OFFICE")
    ]


def _late_story(db: toaster.Database) -> None:
    """R2 reports, 5 s late, a pen that was in the drawer for one second: R1's clock is ahead,
    so the holders take R2's changes just after R1's time. Bob leaves the office in between."""
    st = _two_robots(db)
    kitchen = {**ROBOT_ROOMS, "BOB": "KITCHEN"}
    st.sync_many("R1", 100 * S, [("rooms", _rooms(ROBOT_ROOMS))])
    st.sync_many("R2", 94 * S, [("rooms", _rooms(ROBOT_ROOMS))])
    st.sync_many("R2", 95 * S, [("things", [Fact("PEN", "IsIn", "DRAWER")])])
    st.sync_many("R1", 101 * S, [("rooms", _rooms(kitchen))])
    st.sync_many("R2", 95 * S + S // 2, [("rooms", _rooms(kitchen))])
    st.sync_many("R1", 102 * S, [("rooms", _rooms({**kitchen, "CARL": "HALL"}))])
    st.sync_many("R2", 96 * S, [("things", [])])


def test_a_late_robot_changes_beliefs_at_the_clock(db: toaster.Database, tmp_path: object) -> None:
    """A robot whose snapshots lag another's by more than LIVE_CLOCK_SKEW_NS keeps its own
    times; the holders take its changes when the rules run (1 ns after the clock's time: a
    run behind the clock takes the instant after it, revisions 0014 and 0015), even a fact
    that ended in the robot's past before they began to follow it: who sees the pen go ends
    the belief then, who left keeps it (a false belief), with one event per interval boundary
    and the same timelines as with copied rows."""
    _late_story(db)
    pen = [
        (r.valid_from_ns, r.valid_to_ns)
        for r in q.history(db, "R2", subject="PEN", property="IsIn")
    ]
    assert pen == [(95 * S, 96 * S)]
    assert [
        (r.valid_from_ns, r.valid_to_ns)
        for r in q.history(db, "ANNE", subject="PEN", property="IsIn")
    ] == [(100 * S + 2, 102 * S + 1)]  # R2's runs after R1's at 100 s (then 100 s + 1) and 102 s
    assert [(e.kind, e.stamp_ns) for e in q.events(db, "ANNE") if e.subject_id == "PEN"] == [
        ("appeared", 100 * S + 2),
        ("ended", 102 * S + 1),
    ]
    assert [r.target_id for r in q.current_facts(db, "BOB") if r.subject_id == "PEN"] == ["DRAWER"]
    with db.transaction() as conn:
        assert violations(conn) == []
    with toaster.connect(f"sqlite:///{tmp_path}/copied.db") as copied:
        api.configure(copied, share_rows=False)
        _late_story(copied)
        assert _timeline(db) == _timeline(copied)


def test_two_robots_changing_a_belief_at_one_instant_give_one_event(db: toaster.Database) -> None:
    """R1 moves Bob to the kitchen at the clock's time; R2's late snapshot says the same and
    runs at that instant too: Bob's belief starts once, with one event."""
    st = _two_robots(db)
    st.sync_many("R1", 100 * S, [("rooms", _rooms(ROBOT_ROOMS))])
    st.sync_many("R1", 101 * S, [("rooms", _rooms({**ROBOT_ROOMS, "BOB": "KITCHEN"}))])
    st.sync_many("R2", 99 * S, [("rooms", _rooms({**ROBOT_ROOMS, "BOB": "KITCHEN"}))])
    kitchen = [
        (e.kind, e.stamp_ns)
        for e in q.events(db, "BOB")
        if e.subject_id == "BOB" and e.target_id == "KITCHEN"
    ]
    assert kitchen == [("appeared", 101 * S)]
    assert [
        (r.valid_from_ns, r.valid_to_ns)
        for r in q.history(db, "BOB", subject="BOB", property="IsInRoom")
        if r.target_id == "KITCHEN"
    ] == [(101 * S, None)]
    with db.transaction() as conn:
        assert violations(conn) == []


def test_a_robot_whose_lag_grows_past_the_skew_stays_on_the_clock(db: toaster.Database) -> None:
    """A live robot 0.5 s behind another is written on the rules' clock; when its lag then
    grows past LIVE_CLOCK_SKEW_NS its snapshots stay on the clock (not before the one already
    moved there, which would be a time-order error)."""
    st = _two_robots(db)
    st.sync_many("R1", 100 * S, [("rooms", _rooms(ROBOT_ROOMS))])
    st.sync_many("R2", 100 * S - S // 2, [("rooms", _rooms(ROBOT_ROOMS))])
    st.sync_many("R1", 103 * S, [("rooms", _rooms({**ROBOT_ROOMS, "BOB": "KITCHEN"}))])
    st.sync_many("R2", 100 * S - S // 10, [("rooms", _rooms({**ROBOT_ROOMS, "CARL": "HALL"}))])
    carl = {
        r.target_id: (r.valid_from_ns, r.valid_to_ns)
        for r in q.history(db, "R2", subject="CARL", property="IsInRoom")
    }
    assert carl == {"KITCHEN": (100 * S + 1, 103 * S + 1), "HALL": (103 * S + 1, None)}
    with db.transaction() as conn:
        assert violations(conn) == []


def _timeline(db: toaster.Database) -> dict[str, tuple[list, list]]:
    """Every holder's intervals and events, without row ids and wall-clock stamps."""
    out = {}
    for holder in api.holders(db):
        rows = sorted(
            (
                _key(r),
                r.value_text,
                r.value_num,
                round(r.confidence, 9),
                r.observability,
                r.valid_from_ns,
                r.valid_to_ns,
            )
            for r in q.history(db, holder)
        )
        events = sorted(
            (
                _key(e),
                e.kind,
                e.stamp_ns,
                e.value_text,
                e.previous_text,
                None if e.confidence is None else round(e.confidence, 9),
            )
            for e in q.events(db, holder)
        )
        out[holder] = (rows, events)
    return out


@pytest.mark.parametrize("seed", [1, 2, 3, 6])
def test_shared_rows_read_exactly_like_copied_rows(
    db: toaster.Database, tmp_path: object, seed: int
) -> None:
    """The same story with share_rows off (every perceived change copied into the holder's
    own rows, on SQLite) gives every holder the same intervals and events."""
    times = _replay(db, seed, 40)
    with toaster.connect(f"sqlite:///{tmp_path}/copied.db") as copied:
        api.configure(copied, share_rows=False)
        _replay(copied, seed, 40)
        with copied.transaction() as conn:
            assert conn.execute(text("SELECT count(*) FROM belief_follow")).scalar_one() == 0
        reference = _timeline(copied)
    shared = _timeline(db)
    assert sorted(shared) == sorted(reference)
    for holder, (rows, events) in reference.items():
        assert shared[holder][0] == rows, holder
        assert shared[holder][1] == events, holder
    assert _check_timelines(db, times) > 50


def test_robots_writing_through_sql_at_one_instant_keep_every_invariant(
    db: toaster.Database,
) -> None:
    """Two robots' SQL clients (fact_inbox, no store) that disagree at one instant: R1 sees the
    pen in the drawer and then not, R2 the same, all at 5 s. A robot's write at the time of
    its own run shares that instant, any other run at or behind the clock comes 1 ns after it
    (revision 0015): R1's two runs happen at 5 s, as its own rows (the pen in the drawer for
    no time: Anne, in the office, believes that too, an empty interval with its appeared and
    ended events), R2's at 5 s + 1 ns (after R1's run) and 5 s + 2 ns (behind the clock).
    Before 0014, the four runs shared the instant and left her two empty intervals at 5 s
    whose events `toaster db check` could not match; 0014 gave every run its own nanosecond
    (5 s .. 5 s + 3 ns)."""
    store = _two_robots(db)
    for robot in ("R1", "R2"):
        store.sync_many(robot, 1 * S, [("rooms", _rooms(ROBOT_ROOMS))])
    engine = make_engine(db.url)
    try:
        for robot in ("R1", "R2"):
            for action in ("assert", "retract"):
                with engine.begin() as conn:
                    conn.execute(
                        text(
                            "INSERT INTO fact_inbox (action, agent_id, subject_id, property, "
                            "target_id, t_ns) VALUES (:a, :r, 'PEN', 'IsIn', 'DRAWER', :t)"
                        ),
                        {"a": action, "r": robot, "t": 5 * S},
                    )
    finally:
        engine.dispose()
    with db.transaction() as conn:
        assert violations(conn) == []
    assert [
        (r.valid_from_ns, r.valid_to_ns)
        for r in q.history(db, "ANNE", subject="PEN", property="IsIn")
    ] == [(5 * S, 5 * S), (5 * S + 1, 5 * S + 2)]
    assert [(e.kind, e.stamp_ns) for e in q.events(db, "ANNE") if e.subject_id == "PEN"] == [
        ("appeared", 5 * S),
        ("ended", 5 * S),
        ("appeared", 5 * S + 1),
        ("ended", 5 * S + 2),
    ]
    assert not [f for f in q.current_facts(db, "ANNE") if f.subject_id == "PEN"]


def test_the_sources_of_one_tick_are_written_at_one_stamp(db: toaster.Database) -> None:
    """R2's rooms were moved onto the rules' clock (its snapshot lagged R1's by 0.5 s); then R1
    runs 10 s ahead. R2's next tick (rooms and things) is written at one stamp, just after the
    clock, and its rules run there: before, its things (no earlier move, lagging past the
    skew) kept their own time, 10 s before its rooms of the same tick."""
    store = _two_robots(db)
    store.sync_many("R1", 20 * S, [("rooms", _rooms(ROBOT_ROOMS))])
    store.sync_many("R2", 19 * S + S // 2, [("rooms", _rooms(ROBOT_ROOMS))])
    store.sync_many("R1", 30 * S, [("rooms", _rooms({**ROBOT_ROOMS, "CARL": "HALL"}))])
    store.sync_many(
        "R2",
        19 * S + 6 * S // 10,
        [
            ("things", [Fact("PEN", "IsIn", "DRAWER")]),
            ("rooms", _rooms({**ROBOT_ROOMS, "BOB": "KITCHEN"})),
        ],
    )
    starts = {(r.subject_id, r.target_id): r.valid_from_ns for r in q.current_facts(db, "R2")}
    assert starts[("PEN", "DRAWER")] == starts[("BOB", "KITCHEN")] == 30 * S + 1
    with db.transaction() as conn:
        assert violations(conn) == []


def test_a_snapshot_at_its_own_robots_run_keeps_its_time(db: toaster.Database) -> None:
    """R1 writes its rooms, then its things, both at 10 s: its second snapshot is written at
    10 s, as its run was (one robot's runs at one time share the instant, revision 0015). R2's
    snapshot at 10 s comes after another robot's run: it is written 1 ns later. Before, R1's
    things went to 10 s + 1 ns as well."""
    st = _two_robots(db)
    st.sync_many("R1", 10 * S, [("rooms", _rooms(ROBOT_ROOMS))])
    st.sync_many("R1", 10 * S, [("things", [Fact("PEN", "IsIn", "DRAWER")])])
    st.sync_many("R2", 10 * S, [("rooms", _rooms({**ROBOT_ROOMS, "BOB": "KITCHEN"}))])
    assert [r.valid_from_ns for r in q.history(db, "R1", subject="PEN")] == [10 * S]
    assert [r.valid_from_ns for r in q.history(db, "ANNE", subject="PEN")] == [10 * S]
    assert [r.valid_from_ns for r in q.history(db, "R2", subject="BOB")] == [10 * S + 1]
    with db.transaction() as conn:
        assert violations(conn) == []


def test_a_late_robots_runs_never_share_an_instant(db: toaster.Database) -> None:
    """R2, 5 s behind R1 (past LIVE_CLOCK_SKEW_NS: its rows keep its times), sees the pen in
    the drawer at 5 s, not at 5.1 s, again at 5.2 s. Its runs are behind the clock (R1's at
    10 s, then its own): each comes 1 ns after the one before, so Anne takes the pen in, out
    and in at three instants. Sharing one instant because the clock was its own run, whatever
    the run's time (a rule tried for 0015), gave her an empty interval next to one of the same
    value, whose events `toaster db check` could not match (as a robot lagging 2 s did in
    benchmarks/soak_writers.py on SQLite)."""
    st = _two_robots(db)
    st.sync_many("R1", 10 * S, [("rooms", _rooms(ROBOT_ROOMS))])
    st.sync_many(
        "R2", 5 * S, [("rooms", _rooms(ROBOT_ROOMS)), ("things", [Fact("PEN", "IsIn", "DRAWER")])]
    )
    st.sync_many("R2", 5 * S + S // 10, [("rooms", _rooms(ROBOT_ROOMS)), ("things", [])])
    st.sync_many(
        "R2",
        5 * S + S // 5,
        [("rooms", _rooms(ROBOT_ROOMS)), ("things", [Fact("PEN", "IsIn", "DRAWER")])],
    )
    with db.transaction() as conn:
        assert violations(conn) == []
    assert [
        (r.valid_from_ns, r.valid_to_ns)
        for r in q.history(db, "ANNE", subject="PEN", property="IsIn")
    ] == [(10 * S + 1, 10 * S + 2), (10 * S + 3, None)]


@pytest.mark.parametrize("later_s", [3, 5])
def test_a_run_never_reads_a_self_fact_later_than_its_time(
    db: toaster.Database, later_s: int
) -> None:
    """R1's things put the pen in the box (1 s), then in the drawer (``later_s``), naming
    nobody; its rooms, written after, have Anne in the hall with the box from 2 s. Before
    revision 0031 the things' runs moved no clock, so the rooms' run happened at 2 s: Anne saw
    the pen (in the box then) and took where it is *now*, in the drawer, with an event of 2 s
    that no interval began at (two producers of one robot writing at once, in
    tests/db/test_many_writers.py). Now R1's runs take turns on its own clock: the rooms come
    just after it (within LIVE_CLOCK_SKEW_NS: the snapshot is moved there; beyond it: the
    snapshot keeps its time, its run comes after the clock), when the pen is in the drawer,
    out of Anne's sight."""
    st = _two_robots(db)
    with st.transaction():
        st.add_entity("BOX", "object", t_ns=0)
    st.sync_many("R1", 1 * S, [("things", [Fact("PEN", "IsIn", "BOX")])])
    st.sync_many("R1", later_s * S, [("things", [Fact("PEN", "IsIn", "DRAWER")])])
    rooms = [*_rooms({**ROBOT_ROOMS, "ANNE": "HALL"}), Fact("BOX", "IsInRoom", "HALL")]
    st.sync_many("R1", 2 * S, [("rooms", rooms)])
    with db.transaction() as conn:
        assert violations(conn) == []
    anne = [r.valid_from_ns for r in q.history(db, "R1", subject="ANNE")]
    assert anne == [later_s * S + 1 if later_s * S - 2 * S <= LIVE_CLOCK_SKEW_NS else 2 * S]
    assert [r for r in q.history(db, "ANNE") if r.subject_id == "PEN"] == []
    assert [e for e in q.events(db, "ANNE") if e.subject_id == "PEN"] == []
