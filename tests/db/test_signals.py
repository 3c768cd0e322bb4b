"""Continuous values: tolerances, samples inside intervals, as-of numbers, batches vs lists."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import toaster
from tests.conftest import count
from toaster import Fact
from toaster import queries as q
from toaster.errors import InvalidInputError
from toaster.producers import AgentMonitor
from toaster.producers.batch import as_facts
from toaster.world import World

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

S = 1_000_000_000
TICK = S // 30


def _distance(value: float, text: str = "medium") -> Fact:
    return Fact("BOB", "Distance", "MUG", text, value, 0.9, sub_property="3D")


def test_as_of_number_is_within_tolerance_at_every_tick(store: toaster.Store) -> None:
    """A distance sampled at 30 Hz: fewer rows than ticks, and the value read as of any tick
    (or between ticks) is within the Distance tolerance of the true one."""
    db = store.db
    tol = store.tolerances()["Distance"].value
    truth = {i * TICK: 1.0 + 0.4 * math.sin(i / 20) + 0.002 * (i % 3) for i in range(300)}
    for t, value in truth.items():
        store.sync_snapshot("am", "PR2_ROBOT", t, [_distance(value)])
    samples = count(db, "SELECT COUNT(*) FROM fact_samples")
    assert 0 < samples < len(truth) / 3
    for t, value in list(truth.items())[::7]:
        for at in (t, t + TICK // 2):
            row = q.fact_value(db, "PR2_ROBOT", "BOB", "Distance", "MUG", at=at)
            assert row is not None and abs(row.value_num - value) <= tol + 1e-12, (at, row)
    # the current value too, and history keeps one interval (numbers do not split it)
    now = q.fact_value(db, "PR2_ROBOT", "BOB", "Distance", "MUG")
    assert abs(now.value_num - truth[299 * TICK]) <= tol
    assert len(q.history(db, "PR2_ROBOT", property="Distance")) == 1


def test_exact_without_tolerance_and_settings_change_it(store: toaster.Store) -> None:
    """Properties without a tolerance keep every number; a stored setting changes that, for
    every store of the database; bad settings are refused in one line."""
    db = store.db
    speeds = [0.5, 0.51, 0.515, 0.6]
    for i, v in enumerate(speeds):
        store.sync_snapshot("x", "PR2_ROBOT", i * S, [Fact("BOB", "Speed", "", "", v)])
    for i, v in enumerate(speeds):
        assert q.fact_value(db, "PR2_ROBOT", "BOB", "Speed", at=i * S).value_num == v
    other = db.store()
    other.put_setting("tolerance", "Speed", {"value": 0.2})
    assert store.tolerances()["Speed"].value == 0.2  # the epoch told this store too
    store.sync_snapshot("x", "PR2_ROBOT", 10 * S, [Fact("BOB", "Speed", "", "", 0.7)])
    assert q.fact_value(db, "PR2_ROBOT", "BOB", "Speed").value_num == 0.6
    for bad in (-1, "fast", {"value": math.nan}, {"speed": 1}):
        with pytest.raises(InvalidInputError, match="tolerance") as err:
            store.put_setting("tolerance", "Speed", bad)
        assert "\n" not in str(err.value)


def test_signal_points_give_the_number_over_time(store: toaster.Store) -> None:
    """signal(): interval start, each refresh beyond tolerance, the end (None)."""
    values = [2.0, 2.01, 2.3, 2.31, 1.0]
    for i, v in enumerate(values):
        store.sync_snapshot("am", "PR2_ROBOT", i * S, [_distance(v)])
    store.sync_snapshot("am", "PR2_ROBOT", 9 * S, [])
    points = q.signal(store.db, "PR2_ROBOT", property="Distance")
    assert [(p.t_ns // S, p.value_num) for p in points] == [(0, 2.0), (2, 2.3), (4, 1.0), (9, None)]


def _world(seed: int) -> tuple[World, np.ndarray, np.random.Generator]:
    rng = np.random.default_rng(seed)
    world = World()
    for i in range(12):
        world.add_entity(f"H{i}", "human" if i < 5 else "object")
    for i in range(5):
        world.add_entity(f"H{i}/head", "joint", owner_id=f"H{i}", name="head")
        world.set_joint_local(f"H{i}/head", (0.0, 0.0, 1.7))
    return world, rng.uniform(0, 6, (12, 3)) * (1, 1, 0), rng


@pytest.mark.parametrize("seed", [1, 2])
def test_batches_store_exactly_what_lists_store(db_url: str, tmp_path, seed: int) -> None:
    """The array path (batches) and the tuple path (lists) write the same intervals, numbers,
    samples and events for the same producer output."""
    other_url = f"sqlite:///{tmp_path / 'lists.db'}"
    results = []
    for url, as_batch in ((db_url, True), (other_url, False)):
        world, pos, rng = _world(seed)
        monitor = AgentMonitor()
        with toaster.connect(url) as db:
            store = db.store()
            store.add_entity("R", "robot", is_self=True, t_ns=0)
            for i in range(80):
                t = S + i * TICK
                pos[:5, :2] += rng.normal(0.03, 0.02, (5, 2))
                world.observe("sim", np.arange(12), np.full(12, t), pos)
                world.commit()
                batch = monitor.compute_batch(world, t)
                store.sync_snapshot("am", "R", t, batch if as_batch else as_facts(batch))
            hist = sorted(
                (
                    r.subject_id,
                    r.property,
                    r.sub_property,
                    r.target_id,
                    r.value_text,
                    r.value_num,
                    r.confidence,
                    r.valid_from_ns,
                    r.valid_to_ns,
                )
                for r in q.history(db, "R")
            )
            events = sorted(
                (e.kind, e.stamp_ns, e.subject_id, e.property, e.target_id, e.value_num)
                for e in q.events(db, "R")
            )
            points = q.signal(db, "R")
            samples = count(db, "SELECT COUNT(*) FROM fact_samples")
        results.append((hist, events, points, samples))
    assert results[0][0] and results[0][3] > 0
    assert results[0] == results[1]


def test_get_info_value_at_a_past_time_gives_the_number_then(db_url: str) -> None:
    """`toaster get-info FACT VALUE --at T` answers with the number held at T, not the last."""
    from click.testing import CliRunner

    from toaster.cli import cli
    from toaster.timeutil import parse_time

    t0 = parse_time("2026-11-22T12:00:00Z")
    with toaster.connect(db_url) as db:
        store = db.store()
        store.add_entity("PR2_ROBOT", "robot", is_self=True, t_ns=0)
        for i, value in enumerate((1.0, 1.3, 1.8)):
            store.sync_snapshot("agent_monitor", "PR2_ROBOT", t0 + i * S, [_distance(value)])
    runner = CliRunner()
    for at, want in (("12:00:00.5", 1.0), ("12:00:01.5", 1.3), ("12:00:02.5", 1.8)):
        result = runner.invoke(
            cli,
            [
                "--db",
                db_url,
                "get-info",
                "FACT",
                "VALUE",
                "--subject",
                "BOB",
                "--property",
                "Distance",
                "--target",
                "MUG",
                "--at",
                f"2026-11-22T{at}Z",
                "--json",
            ],
        )
        assert result.exit_code == 0, result.output
        assert json.loads(result.output.splitlines()[0])["value_num"] == want


def test_tolerance_command_shows_and_sets(db_url: str) -> None:
    """`toaster tolerance` lists the table, sets one property (kept by the database), and
    refuses a bad value in one line without changing it."""
    from click.testing import CliRunner

    from toaster.cli import cli

    runner = CliRunner()
    shown = runner.invoke(cli, ["--db", db_url, "tolerance", "--json"])  # a listing
    rows = {row["property"]: row for row in map(json.loads, shown.output.splitlines())}
    assert shown.exit_code == 0 and rows["Distance"]["value"] == 0.05
    done = runner.invoke(cli, ["--db", db_url, "tolerance", "Distance", '{"value": 0.02}'])
    assert done.exit_code == 0, done.output
    bad = runner.invoke(cli, ["--db", db_url, "tolerance", "Distance", '"far"'])
    assert bad.exit_code == 1 and len(bad.output.strip().splitlines()) == 1
    assert "tolerance" in bad.output
    with toaster.connect(db_url) as db:
        assert db.store().tolerances()["Distance"] == (0.02, 0.05, 0.0)


def test_batch_refresh_of_a_fact_another_writer_ended_reopens_it(db_url: str) -> None:
    """A producer's batch refreshes numbers without reading them back; when another process
    ended that interval meanwhile, the tick is redone from the database: the fact reopens."""
    from toaster.producers.batch import FactBatch

    world = World()
    for name in ("BOB", "MUG"):
        world.add_entity(name, "human" if name == "BOB" else "object")

    def batch(value: float) -> FactBatch:
        out = FactBatch(world)
        out.add(
            "Distance",
            np.array([0]),
            np.array([1]),
            value_text="medium",
            value_num=np.array([value]),
            conf=0.9,
            obs=0.0,
            sub_property="3D",
        )
        return out

    with toaster.connect(db_url) as db, toaster.connect(db_url) as other_db:
        store, other = db.store(), other_db.store()
        store.add_entity("R", "robot", is_self=True, t_ns=0)
        store.sync_snapshot("am", "R", 1 * S, batch(1.0))
        store.sync_snapshot("am", "R", 2 * S, batch(1.5))  # the array path from here on
        fact = q.current_facts(db, "R")[0].to_fact()
        other.sync_snapshot("x", "R", 3 * S, [fact])  # adopts the open interval...
        other.sync_snapshot("x", "R", 4 * S, [])  # ...and ends it (no cache epoch bump)
        assert q.current_facts(db, "R") == []
        store.sync_snapshot("am", "R", 5 * S, batch(2.0))
        (row,) = q.current_facts(db, "R")
        assert (row.value_num, row.valid_from_ns) == (2.0, 5 * S)
        assert [(r.valid_from_ns, r.valid_to_ns) for r in q.history(db, "R")] == [
            (1 * S, 4 * S),
            (5 * S, None),
        ]
