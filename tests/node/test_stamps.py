"""A live tick is at the perception time (toaster.node.stamps, docs/time.md): the newest stamp
it applies, within max_stamp_lag of the wall clock; else the wall clock, with one warning.
The node's wall clock is a test's own (``node.clock.wall``), so nothing depends on timing."""

from __future__ import annotations

import logging
import subprocess
import sys
import time

import pytest

import toaster
from toaster.errors import InvalidInputError
from toaster.node import LiveNode
from toaster.node.live_node import MAX_STAMP_LAG_S
from toaster.queries import current_facts
from toaster.world.live import LiveSource

MS = 1_000_000
TICK = 33 * MS


class Wall:
    """A wall clock that moves one tick per call of :meth:`step`."""

    def __init__(self) -> None:
        self.t = time.time_ns() - 600 * 10**9

    def __call__(self) -> int:
        return self.t

    def step(self) -> int:
        self.t += TICK
        return self.t


class Times:
    """An output that keeps each tick's time."""

    def __init__(self) -> None:
        self.ticks: list[int] = []

    def publish(self, t_ns: int, facts: object, world: object) -> None:
        self.ticks.append(t_ns)


def live(db: toaster.Database, *, stamp: str = "perception", sources=None) -> tuple:
    times, wall = Times(), Wall()
    node = LiveNode(db, sources=sources, outputs=[times], stamp=stamp)
    node.clock.wall = wall
    return node, wall, times


def starts(db: toaster.Database, prop: str) -> dict[tuple[str, str], int]:
    rows = current_facts(db, "toaster", property=prop)
    return {(r.subject_id, r.target_id): r.valid_from_ns for r in rows}


@pytest.mark.slow
def test_a_pose_stamped_200_ms_ago_gives_facts_at_its_stamp(db):
    node, wall, times = live(db)
    stamp = wall.step() - 200 * MS
    node.api.push("bob", (0.0, 0.0, 0.0), t_ns=stamp)
    node.api.push("cup", (2.0, 0.0, 0.8), kind="object", t_ns=stamp)
    node.tick()
    assert times.ticks == [stamp]
    assert starts(db, "isPresent")[("bob", "")] == stamp
    assert node.stats.warnings == 0


@pytest.mark.slow
def test_two_sources_give_the_newest_stamp_and_both_are_applied(db):
    cam, lidar = LiveSource("cam"), LiveSource("lidar")
    node, wall, times = live(db, sources=[cam, lidar])
    now = wall.step()
    cam.push("bob", (0.0, 0.0, 0.0), t_ns=now - 300 * MS)
    lidar.push("cup", (2.0, 0.0, 0.8), kind="object", t_ns=now - 100 * MS)
    node.tick()
    assert times.ticks == [now - 100 * MS]
    assert starts(db, "isPresent")[("bob", "")] == now - 100 * MS


@pytest.mark.slow
@pytest.mark.parametrize("off_s", [-10.0, 10.0, -3.0])
def test_stamps_far_off_fall_back_to_the_wall_clock_with_one_warning(db, off_s, caplog):
    """10 s either side: the source shifts its stamps onto the tick's clock (its warning line),
    then they are the ticks' times again; 3 s behind (under that shift, over max_stamp_lag):
    every tick on the wall clock, one warning line (the tick's; nobody is present then: the
    poses are older than presence_timeout)."""
    node, wall, times = live(db)
    off = int(off_s * 1e9)
    walls = []
    with caplog.at_level(logging.WARNING, logger="toaster.node"):
        for k in range(3):
            walls.append(wall.step())
            stamp = wall.t + off - (20 * MS if k else 0)  # 20 ms old after the first
            node.api.push("bob", (0.1 * k, 0.0, 0.0), t_ns=stamp)
            node.api.push("cup", (2.0, 0.0, 0.8), kind="object", t_ns=stamp)
            node.tick()
    assert times.ticks[0] == walls[0]
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 1, lines
    assert f"{abs(off_s):.1f} s" in lines[0]
    assert "--clock and use_sim_time" in lines[0]
    assert node.stats.warnings == 1
    if off_s == -3.0:
        assert times.ticks == walls
        assert node.clock.wall_ticks == 3
    else:
        assert times.ticks == [walls[0], walls[1] - 20 * MS, walls[2] - 20 * MS]
        assert starts(db, "isPresent")[("bob", "")] == walls[0]
        assert node.clock.wall_ticks == 0


@pytest.mark.slow
def test_stamp_wall_keeps_the_wall_clock(db):
    node, wall, times = live(db, stamp="wall")
    now = wall.step()
    node.api.push("bob", (0.0, 0.0, 0.0), t_ns=now - 200 * MS)
    node.api.push("cup", (2.0, 0.0, 0.8), kind="object", t_ns=now - 200 * MS)
    node.tick()
    assert times.ticks == [now]
    assert starts(db, "isPresent")[("bob", "")] == now


def test_a_bad_stamp_mode_is_refused_with_the_choices():
    with pytest.raises(InvalidInputError, match="perception, wall"):
        LiveNode(None, stamp="sensor")


@pytest.mark.slow
def test_time_never_goes_backwards_and_idle_ticks_keep_the_perception_lag(db):
    node, wall, times = live(db)
    lag = 200 * MS
    now = wall.step()
    node.api.push("bob", (0.0, 0.0, 0.0), t_ns=now - lag)
    node.tick()  # perceived: at its stamp
    wall.step()
    node.tick()  # nothing new: the wall clock minus the last lag, not ahead of the next pose
    assert times.ticks == [now - lag, wall.t - lag]
    node.api.push("bob", (0.1, 0.0, 0.0), t_ns=wall.t - lag - 50 * MS)  # older than that tick
    node.tick()  # applied, but time moves on
    assert times.ticks[-1] == wall.t - lag + 1
    old = wall.step() - int(3 * MAX_STAMP_LAG_S * 1e9)  # too old: the wall clock
    node.api.push("bob", (0.2, 0.0, 0.0), t_ns=old)
    node.tick()
    assert times.ticks[-1] == wall.t
    node.api.push("bob", (0.3, 0.0, 0.0), t_ns=wall.t - lag)  # in the window, before that tick
    node.tick()
    assert times.ticks[-1] == wall.t + 1
    assert times.ticks == sorted(set(times.ticks))
    assert node.world.pos[node.world.row("bob"), 0] == pytest.approx(0.3)


@pytest.mark.slow
def test_serve_takes_stamp_wall_and_refuses_another_mode_in_one_line(db_url):
    def serve(*args: str) -> subprocess.CompletedProcess[str]:
        argv = [sys.executable, "-m", "toaster", "--db", db_url, "serve", "--seconds", "0.3"]
        return subprocess.run([*argv, *args], capture_output=True, text=True, timeout=60)

    assert serve("--stamp", "wall").returncode == 0
    bad = serve("--stamp", "sensor")
    assert bad.returncode != 0 and "Traceback" not in bad.stderr
    assert "'perception', 'wall'" in bad.stderr or "perception, wall" in bad.stderr, bad.stderr
