"""Perception kept between runs (revision 0023): the same beliefs as when it is computed anew.

A run whose changes hold no perception input reuses who perceives what from the last run that
computed it (``belief_perceived``), and the keys whose holders all follow them as they perceive
them leave its change set (``belief_settled``). Random stories of steady ticks (values and
numbers changing while nobody moves) broken by perception changes (people walking, things
carried with and without an actor, looking, boxes closing), late single writes from SQL
(``fact_inbox``) and tellings are written on three databases of one backend: at head with the
perception kept, at head with it forgotten before every write (computed by every run), and at
revision 0022 (the rule before 0023). Every holder's intervals and events must be identical,
and so must the as-of beliefs at head.
"""

from __future__ import annotations

import random
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa

import toaster
import toaster.queries as q
from tests.conftest import pg_schema
from toaster import Fact
from toaster.beliefs import api
from toaster.beliefs.tell import tell
from toaster.db import migrate
from toaster.db.engine import make_engine

S = 1_000_000_000
HUMANS = ("SALLY", "ANNE", "BOB")
ROOMS = ("KITCHEN", "HALL")
BOXES = ("BOX", "BASKET")
THINGS = ("MARBLE", "BALL", "CUP")
#: One write: ("tick", t, world, actor) | ("inbox", t, subject, property, target, value,
#: number, actor) | ("tell", t, speaker, listener, thing, box) | ("holder", t, listener,
#: thing, box): a direct write to a holder's beliefs from SQL.
Step = tuple[Any, ...]


def story(seed: int, length: int, tells: bool = True) -> list[Step]:
    """Mostly steady ticks (values and numbers move), now and then a perception change
    (``tells``: tellings through the library, else direct writes to a holder from SQL)."""
    rng = random.Random(seed)
    world: dict[str, Any] = {
        "room": {x: rng.choice(ROOMS) for x in (*HUMANS, *BOXES)},
        "in": {x: rng.choice(BOXES) for x in THINGS},
        "looks": set(),
        "closed": dict.fromkeys(BOXES, "false"),
        "temp": {x: rng.choice(("hot", "cold")) for x in THINGS},
        "dist": dict.fromkeys(HUMANS, 1.0),
    }
    t = S
    steps: list[Step] = [("tick", t, _copy(world), None)]
    for _ in range(length):
        t += rng.choice((S, S, S // 2))
        roll = rng.random()
        actor = None
        if roll < 0.45:  # steady: values and numbers only
            for x in rng.sample(THINGS, rng.randint(0, len(THINGS))):
                world["temp"][x] = "hot" if world["temp"][x] == "cold" else "cold"
            for h in rng.sample(HUMANS, rng.randint(0, len(HUMANS))):
                world["dist"][h] = round(rng.uniform(0, 9), 1)
        elif roll < 0.55:
            world["room"][rng.choice(HUMANS)] = rng.choice(ROOMS)
        elif roll < 0.63:
            world["in"][rng.choice(THINGS)] = rng.choice(BOXES)
            actor = rng.choice((None, *HUMANS))
        elif roll < 0.68:
            world["looks"] ^= {(rng.choice(HUMANS), rng.choice(BOXES))}
        elif roll < 0.72:
            box = rng.choice(BOXES)
            world["closed"][box] = "true" if world["closed"][box] == "false" else "false"
        elif roll < 0.88:  # a single write from SQL, now or a little before the last tick
            when = t - rng.choice((0, 0, S // 2, S))
            subject = rng.choice(THINGS)
            if rng.random() < 0.5:
                value = rng.choice(("red", "blue"))
                steps.append(("inbox", when, subject, "Color", "", value, None, None))
            else:
                number = round(rng.uniform(0, 9), 1)
                steps.append(("inbox", when, subject, "Weight", "", "true", number, None))
            continue
        elif roll < 0.93:
            speaker, listener = rng.sample(HUMANS, 2)
            what = (rng.choice(THINGS), rng.choice(BOXES))
            if tells:
                steps.append(("tell", t, speaker, listener, *what))
            else:
                steps.append(("holder", t, listener, *what))
            continue
        steps.append(("tick", t, _copy(world), actor))
    return steps


def _copy(world: dict[str, Any]) -> dict[str, Any]:
    return {k: (set(v) if isinstance(v, set) else dict(v)) for k, v in world.items()}


def _facts(world: dict[str, Any]) -> list[Fact]:
    return (
        [Fact(x, "IsInRoom", r) for x, r in world["room"].items()]
        + [Fact(x, "IsIn", b) for x, b in world["in"].items()]
        + [Fact(h, "IsLookingToward", b) for h, b in sorted(world["looks"])]
        + [Fact(b, "IsClosed", "", v) for b, v in world["closed"].items()]
        + [Fact(x, "Temperature", "", v) for x, v in world["temp"].items()]
        + [Fact(h, "Distance", "BOX", value_num=d) for h, d in world["dist"].items()]
    )


_INBOX = sa.text(
    "INSERT INTO fact_inbox (agent_id, subject_id, property, value_text, value_num, t_ns, "
    "actor_id) VALUES ('ROBOT', :s, :p, :v, :n, :t, :a)"
)

_HOLDER = sa.text(
    "INSERT INTO fact_inbox (agent_id, subject_id, property, target_id, t_ns) "
    "VALUES (:h, :s, 'IsIn', :tg, :t)"
)


def write(db: toaster.Database, steps: list[Step], forget: bool) -> list[int]:
    """Write the story (``forget``: the kept perception forgotten before every write); the
    times of its writes."""
    api.configure(db, depth=2)
    store = db.store()
    store.add_entity("ROBOT", "robot", is_self=True, t_ns=0)
    for h in HUMANS:
        store.add_entity(h, "human", t_ns=0)
    for x in (*BOXES, *THINGS, *ROOMS):
        store.add_entity(x, "object", t_ns=0)
    times = []
    for step in steps:
        if forget:
            with db.transaction() as conn:
                conn.execute(sa.text("UPDATE store_state SET perceived_for = NULL"))
        kind, t = step[0], step[1]
        times.append(t)
        if kind == "tick":
            store.sync_snapshot("eyes", "ROBOT", t, _facts(step[2]), actor=step[3])
        elif kind == "inbox":
            _, _, subject, prop, _, value, number, actor = step
            with db.transaction() as conn:
                later = conn.execute(
                    sa.text(
                        "SELECT count(*) FROM facts f JOIN fact_keys k ON k.id = f.key_id "
                        "WHERE k.agent_id = 'ROBOT' AND k.subject_id = :s AND k.property = :p "
                        "AND COALESCE(f.valid_to_ns, f.valid_from_ns) > :t"
                    ),
                    {"s": subject, "p": prop, "t": t},
                ).scalar_one()
                if not later:  # (a write before the key's last change is refused)
                    conn.execute(
                        _INBOX,
                        {"s": subject, "p": prop, "v": value, "n": number, "t": t, "a": actor},
                    )
        elif kind == "holder":
            _, _, listener, thing, box = step
            with db.transaction() as conn:
                conn.execute(_HOLDER, {"h": listener, "s": thing, "tg": box, "t": t})
        else:
            _, _, speaker, listener, thing, box = step
            tell(db, speaker, Fact(thing, "IsIn", box), listeners=[listener], t_ns=t)
    return times


def views(db: toaster.Database) -> tuple[list[Any], list[Any]]:
    """Every holder's intervals and events as the views show them (ids and write times left
    out)."""
    with db.transaction() as conn:
        facts = conn.execute(
            sa.text(
                "SELECT agent_id, subject_id, property, target_id, value_text, value_num, "
                "valid_from_ns, valid_to_ns, ROUND(CAST(confidence AS NUMERIC), 9), source "
                "FROM fact_history WHERE agent_id <> 'ROBOT'"
            )
        ).all()
        events = conn.execute(
            sa.text(
                "SELECT agent_id, kind, stamp_ns, subject_id, property, target_id, value_text, "
                "value_num, previous_text, source FROM event_log WHERE agent_id <> 'ROBOT'"
            )
        ).all()
    return sorted(map(tuple, facts)), sorted(map(tuple, events))


def as_of(db: toaster.Database, times: list[int]) -> dict[str, list[Any]]:
    """Every holder's beliefs at each write's time (and just before it)."""
    return {
        holder: [
            sorted(row._replace(recorded_ns=0) for row in q.beliefs_at(db, holder, t))
            for when in sorted(set(times))
            for t in (when - 1, when)
        ]
        for holder in api.holders(db)
    }


@contextmanager
def _databases(backend_url: str, tmp_path: Path, n: int) -> Iterator[list[str]]:
    """``n`` empty databases of the backend of ``backend_url``."""
    if backend_url.startswith("sqlite"):
        yield [f"sqlite:///{tmp_path / f'db{i}.db'}" for i in range(n)]
        return
    with ExitStack() as stack:
        yield [stack.enter_context(pg_schema()) for _ in range(n)]


def _at(url: str, revision: str) -> toaster.Database:
    """A database at ``revision`` that this package's store can write: the holders' clocks it
    reads (revision 0028) are added, and stay empty (the old rule keeps its clock in
    ``store_state``; the stories' ticks only move forward, so no snapshot is stamped later)."""
    engine = make_engine(url)
    migrate.upgrade(engine, revision)
    with engine.begin() as conn:
        conn.execute(sa.text("ALTER TABLE holders ADD COLUMN clock_ns BIGINT"))
        conn.execute(sa.text("ALTER TABLE holders ADD COLUMN clock_self TEXT"))
    engine.dispose()
    return toaster.connect(url, check=False)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 5, 7, 11, 23, 42])
def test_kept_perception_believes_as_computed_perception(
    empty_url: str, tmp_path: Path, seed: int
) -> None:
    """Kept (and settled keys) against perception computed by every run, tellings included:
    the same intervals, events and as-of beliefs."""
    steps = story(seed, 40)
    with (
        _databases(empty_url, tmp_path, 2) as (kept_url, forgot_url),
        toaster.connect(kept_url) as kept,
        toaster.connect(forgot_url) as forgot,
    ):
        times = write(kept, steps, forget=False)
        write(forgot, steps, forget=True)
        expected = views(forgot)
        assert views(kept) == expected
        assert as_of(kept, times) == as_of(forgot, times)
    assert len(expected[0]) > 50 and len({row[0] for row in expected[0]}) >= 6


@pytest.mark.slow
@pytest.mark.parametrize("seed", [2, 5, 13, 31])
def test_kept_perception_believes_as_revision_0022(
    empty_url: str, tmp_path: Path, seed: int
) -> None:
    """The same story written with the rule of revision 0022 (perception computed by every
    run; its direct writes to holders from SQL, as the Python of a telling renders the
    current revision's SQL) gives the same intervals and events."""
    steps = story(seed, 40, tells=False)
    with _databases(empty_url, tmp_path, 2) as (kept_url, old_url):
        with toaster.connect(kept_url) as kept:
            write(kept, steps, forget=False)
            expected = views(kept)
        with _at(old_url, "0022") as old:
            write(old, steps, forget=False)
            assert views(old) == expected
    assert len(expected[0]) > 50 and len({row[0] for row in expected[0]}) >= 6


def _kept(db: toaster.Database) -> tuple[Any, ...]:
    """(perceived_for, perceived_ns, rows kept, {settled key's subject: since_ns})."""
    with db.transaction() as conn:
        state = conn.execute(
            sa.text(
                "SELECT perceived_for, perceived_ns, (SELECT count(*) FROM belief_perceived) "
                "FROM store_state"
            )
        ).one()
        settled = conn.execute(
            sa.text(
                "SELECT k.subject_id || ' ' || k.property, s.since_ns FROM belief_settled s "
                "JOIN fact_keys k ON k.id = s.key_id"
            )
        ).all()
    return (*state, dict(map(tuple, settled)))


def _temperature(db: toaster.Database, holder: str, t: int) -> set[str]:
    return {r.value_text for r in api.beliefs(db, holder, property="Temperature", at=t)}


def test_a_run_without_perception_input_reuses_the_kept_perception(
    db: toaster.Database,
) -> None:
    """Who perceives what is computed when a room changes and kept; runs that change values
    only reuse it (its time stays the room change's), and their settled keys take no step
    (the time they were settled at stays); forgetting it (a telling ends it) makes the next
    run compute it again."""
    api.configure(db, depth=1)
    store = db.store()
    store.add_entity("ROBOT", "robot", is_self=True, t_ns=0)
    for who in ("ANNE", "BOB"):
        store.add_entity(who, "human", t_ns=0)

    def tick(t: int, bob: str, temp: str) -> None:
        rooms = {"ANNE": "LAB", "BOB": bob, "CUP": "LAB"}
        store.sync_snapshot(
            "eyes",
            "ROBOT",
            t * S,
            [Fact(x, "IsInRoom", r) for x, r in rooms.items()]
            + [Fact("CUP", "Temperature", "", temp)],
        )

    tick(1, "LAB", "hot")  # rooms appear: computed, kept from after the tick
    for_, ns, rows, settled = _kept(db)
    assert (for_, ns, rows) == ("ROBOT", S + 1, 6)  # ANNE, BOB: themselves, each other, CUP
    assert settled["CUP Temperature"] == S
    tick(2, "LAB", "cold")  # values only: reused, and the settled key takes no step
    assert _kept(db)[:2] == ("ROBOT", S + 1)
    assert _kept(db)[3]["CUP Temperature"] == S
    assert _temperature(db, "ANNE", 2 * S) == _temperature(db, "BOB", 2 * S) == {"cold"}
    tick(3, "HALL", "cold")  # Bob leaves: computed again
    assert _kept(db)[:3] == ("ROBOT", 3 * S + 1, 3)
    assert "CUP Temperature" not in _kept(db)[3]
    tick(4, "HALL", "hot")  # reused: Bob (in the hall) misses it; the key is settled again
    assert _kept(db)[:2] == ("ROBOT", 3 * S + 1)
    assert _kept(db)[3]["CUP Temperature"] == 4 * S
    assert _temperature(db, "ANNE", 4 * S) == {"hot"}
    assert _temperature(db, "BOB", 4 * S) == {"cold"}
    tell(db, "ANNE", Fact("CUP", "IsIn", "SINK"), listeners=["BOB"], t_ns=5 * S)
    assert _kept(db)[0] is None  # a direct write to a holder ends the kept perception
    tick(6, "HALL", "cold")  # the groups of holders ended too: computed as a change of them
    assert _kept(db)[0] is None
    tick(7, "HALL", "hot")  # values only, the groups formed again: computed and kept
    assert _kept(db)[:2] == ("ROBOT", 7 * S)
    tick(8, "HALL", "cold")
    assert _kept(db)[:2] == ("ROBOT", 7 * S)
    assert _temperature(db, "ANNE", 8 * S) == {"cold"}
    assert _temperature(db, "BOB", 8 * S) == {"cold"}  # what he last saw (at 2 s)
    assert _temperature(db, "BOB", 7 * S) == {"cold"}


def test_a_holders_number_refreshed_in_place_keeps_its_past(db: toaster.Database) -> None:
    """Sally, back in the kitchen, sees the mug's temperature moved while she was out: her
    own interval (same value) is refreshed in place, and as of before she came back she
    still believes the number she last saw (it was lost before revision 0023)."""
    store = db.store()
    store.add_entity("ROBOT", "robot", is_self=True, t_ns=0)
    store.add_entity("SALLY", "human", t_ns=0)

    def tick(t: int, sally: str, degrees: float) -> None:
        store.sync_snapshot(
            "eyes",
            "ROBOT",
            t * S,
            [
                Fact("SALLY", "IsInRoom", sally),
                Fact("MUG", "IsInRoom", "KITCHEN"),
                Fact("MUG", "Temperature", "", value_num=degrees),
            ],
        )

    tick(1, "KITCHEN", 20.0)
    tick(2, "HALL", 20.0)
    tick(3, "HALL", 60.0)  # she misses it
    tick(4, "KITCHEN", 60.0)  # she sees it again

    def degrees(t: int) -> list[float | None]:
        return [
            r.value_num
            for r in q.beliefs_at(db, "SALLY", t * S)
            if r.subject_id == "MUG" and r.property == "Temperature"
        ]

    assert degrees(2) == degrees(3) == [20.0]
    assert degrees(4) == [60.0]
