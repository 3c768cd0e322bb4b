"""Debounce: IsMoving / IsFacing resist tracker noise at 30 Hz and stay exact at 2.5 Hz."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from tests.conftest import shared_data
from toaster.errors import InvalidInputError
from toaster.producers import AgentMonitor, AreaManager, make_config
from toaster.world import World, read_obsmat

S = 1_000_000_000
TICK_30HZ = S // 30
DEFAULT = make_config()["min_duration"]


def moving_series(
    positions: np.ndarray,
    dt_ns: int,
    min_duration: float | None,
    hand_noise: np.ndarray | None = None,
) -> list[dict[str, float]]:
    """Per tick, {subject: value_num} of the IsMoving facts for a person (and its hand)."""
    world = World()
    world.add_entity("bob", "human")
    world.add_entity("bob/hand", "joint", owner_id="bob", name="rightHand")
    world.set_joint_local("bob/hand", (0.3, -0.2, 1.0))
    config = None if min_duration is None else {"min_duration": {"IsMoving": min_duration}}
    monitor = AgentMonitor(config)
    out = []
    t = 10 * S
    for k, p in enumerate(positions):
        world.set_pose("bob", p, t)
        if hand_noise is not None:
            world.set_pose("bob/hand", p + (0.3, -0.2, 1.0) + hand_noise[k], t)
        world.commit()
        out.append(
            {
                f.subject_id: f.value_num
                for f in monitor.compute(world, t)
                if f.property == "IsMoving"
            }
        )
        t += dt_ns
    return out


def flips(series: list[dict[str, float]], subject: str = "bob") -> int:
    states = [subject in s for s in series]
    return sum(a != b for a, b in itertools.pairwise(states))


def standing(seconds: float, hz: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    n = int(seconds * hz)
    return np.column_stack([rng.normal(0, 0.02, (n, 2)), np.zeros(n)])


@pytest.mark.slow
def test_standing_person_with_tracker_noise_stops_flickering():
    pos = standing(60, 30)
    hand = np.column_stack(
        [np.random.default_rng(9).normal(0, 0.02, (len(pos), 2)), np.zeros(len(pos))]
    )
    raw = moving_series(pos, TICK_30HZ, 0.0, hand)
    debounced = moving_series(pos, TICK_30HZ, None, hand)
    raw_flips, flips_now = flips(raw), flips(debounced)
    hand_raw, hand_now = flips(raw, "bob/hand"), flips(debounced, "bob/hand")
    print(
        f"\nstanding 60 s, 2 cm noise, 30 Hz: IsMoving flips {raw_flips} with min_duration 0, "
        f"{flips_now} with {DEFAULT['IsMoving']} s; hand {hand_raw} → {hand_now}"
    )
    assert raw_flips > 300  # the problem: ~0.11 m/s of speed noise vs a 0.12 m/s threshold
    assert flips_now <= 10
    assert hand_now <= 10 < hand_raw
    # not asserted: which state is held. With a 0.25 s speed window the raw detector says
    # "moving" ~55 % of the time for this standing person; the debounce only stops the flicker


def test_walk_start_is_reported_within_min_duration_and_a_tick():
    md = DEFAULT["IsMoving"]
    still, walk = standing(5, 30, seed=1), standing(3, 30, seed=2)
    walk[:, 0] += np.arange(len(walk)) / 30 * 1.2  # 1.2 m/s from t = 5 s
    pos = np.vstack([still, walk])
    raw = [("bob" in s) for s in moving_series(pos, TICK_30HZ, 0.0)]
    debounced = moving_series(pos, TICK_30HZ, None)
    # the raw detector's final, lasting run of "moving" starts at this tick
    start = len(raw) - next(i for i, m in enumerate(reversed(raw)) if not m)
    assert start >= len(still)
    reported = next(i for i in range(start, len(pos)) if "bob" in debounced[i])
    assert (reported - start) * TICK_30HZ <= md * S + TICK_30HZ
    assert all("bob" in s for s in debounced[reported:])


def test_held_is_moving_keeps_the_measured_speed():
    walk = np.column_stack([np.arange(60) / 30 * 1.0, np.zeros(60), np.zeros(60)])
    stop = np.repeat(walk[-1:], 30, axis=0)
    series = moving_series(np.vstack([walk, stop]), TICK_30HZ, None)
    held = [s["bob"] for s in series[60:] if "bob" in s and s["bob"] <= 0.12]
    assert held  # still reported just after the stop, with the measured (low) speed
    assert series[-1] == {}  # and no longer once stopped for min_duration


def test_sparse_tracks_are_unchanged():
    rng = np.random.default_rng(4)
    hz = 2.5
    steps = np.r_[np.zeros(10), np.full(15, 1.0), np.zeros(10), np.full(10, 0.5), np.zeros(5)]
    x = np.cumsum(steps / hz)
    pos = np.column_stack([x, np.zeros(len(x)), np.zeros(len(x))])
    pos[:, :2] += rng.normal(0, 0.02, (len(x), 2))
    dt = round(S / hz)
    raw = moving_series(pos, dt, 0.0)
    assert moving_series(pos, dt, None) == raw
    assert flips(raw) >= 4


def facing_flips(min_duration: float | None, seconds: float = 30) -> int:
    """A person at the edge of facing the robot (yaw 0.5 rad off), 3° yaw noise, 30 Hz."""
    rng = np.random.default_rng(5)
    world = World()
    world.add_entity("robot", "robot")
    world.add_entity("bob", "human")
    area = {
        "near": {
            "shape": "circle",
            "center": [0, 0],
            "radius": 3.0,
            "owner": "robot",
            "facts": ["interaction"],
        }
    }
    config = None if min_duration is None else {"min_duration": {"IsFacing": min_duration}}
    manager = AreaManager(area, config)
    t, prev, count = 10 * S, False, 0
    for _ in range(int(seconds * 30)):
        world.set_pose("robot", (0, 0, 0), t)
        world.set_pose(
            "bob",
            (1.0, *rng.normal(0, 0.02, 1), 0),
            t,
            (0, 0, math.pi + 0.48 + rng.normal(0, 0.05)),
        )
        world.commit()
        now = any(f.property == "IsFacing" for f in manager.compute(world, t))
        count += now != prev
        prev = now
        t += TICK_30HZ
    return count


@pytest.mark.slow
def test_is_facing_resists_noise_at_its_threshold():
    raw, debounced = facing_flips(0.0), facing_flips(None)
    print(
        f"\nIsFacing at the edge of facing_angle, 3° yaw noise, 30 s at 30 Hz: {raw} flips with "
        f"min_duration 0, {debounced} with {DEFAULT['IsFacing']} s"
    )
    assert raw > 100
    assert debounced <= 5


def test_min_duration_is_validated_and_merged():
    cfg = make_config({"min_duration": {"IsMoving": "100ms"}})
    assert cfg["min_duration"] == {**DEFAULT, "IsMoving": 0.1}
    assert make_config()["min_duration"] == DEFAULT  # no shared dict was changed
    for bad, word in (
        ({"IsRunning": 1}, "IsRunning"),
        ({"IsMoving": -1}, "IsMoving"),
        ({"IsFacing": "soon"}, "IsFacing"),
        (0.3, "min_duration"),
    ):
        with pytest.raises(InvalidInputError, match=word) as err:
            make_config({"min_duration": bad})
        assert "\n" not in str(err.value)


@pytest.mark.slow
def test_eth_track_with_noise_at_30hz_flickers_less():
    """ETH hotel's first 60 s, interpolated from 2.5 Hz to 30 Hz, with 2 cm noise."""
    src = read_obsmat(shared_data("eth-ucy-opentraj", "ETH", "seq_hotel", "obsmat.txt"))
    ids = np.asarray(src.ids)
    end = src.t[0] + 60 * S
    rng = np.random.default_rng(6)
    grid, who, where = [], [], []
    for ped in dict.fromkeys(src.ids):
        mine = (ids == ped) & (src.t <= end)
        t = src.t[mine]
        if len(t) < 2:
            continue
        g = np.arange(t[0], t[-1] + 1, TICK_30HZ)
        grid.append(g)
        who += [ped] * len(g)
        xy = [np.interp(g, t, src.pos[mine, c]) for c in (0, 1)]
        where.append(np.column_stack([*xy, np.zeros(len(g))]))
    t_all = np.concatenate(grid)
    order = np.argsort(t_all, kind="stable")
    t_all, who = t_all[order], np.asarray(who)[order]
    pos = np.concatenate(where)[order]
    pos[:, :2] += rng.normal(0, 0.02, (len(pos), 2))
    ticks = np.unique(t_all)
    stops = np.searchsorted(t_all, ticks, side="right")

    def count(min_duration: float | None) -> int:
        world = World()
        for ped in set(who.tolist()):
            world.add_entity(ped, "human")
        cfg = None if min_duration is None else {"min_duration": {"IsMoving": min_duration}}
        monitor = AgentMonitor(cfg)
        state: dict[str, bool] = {}
        total, lo = 0, 0
        for t, hi in zip(ticks.tolist(), stops.tolist(), strict=True):
            world.observe("eth", who[lo:hi].tolist(), t_all[lo:hi], pos[lo:hi])
            world.commit()
            moving = {f.subject_id for f in monitor.compute(world, t) if f.property == "IsMoving"}
            for ped in who[lo:hi].tolist():
                now = ped in moving
                total += state.get(ped, now) != now
                state[ped] = now
            lo = hi
        return total

    raw, debounced = count(0.0), count(None)
    print(f"\nETH hotel 60 s at 30 Hz + 2 cm noise: IsMoving flips {raw} → {debounced}")
    assert debounced * 5 < raw


def toward_series(min_duration: float, seed: int = 4) -> list[set[tuple[str, str]]]:
    """A walker at 1.2 m/s along x with 2 cm noise at 30 Hz, a door ahead at the edge of the
    direction cone (deviation ≈ body_toward_angle): per tick, its IsMovingToward pairs."""
    rng = np.random.default_rng(seed)
    world = World()
    world.add_entity("bob", "human")
    world.add_entity("door", "object")
    t = 10 * S
    world.set_pose("door", (3.0, 3.0 * math.tan(1.0), 0.0), t)  # 1 rad off the heading
    monitor = AgentMonitor({"min_duration": {"IsMovingToward": min_duration}})
    out = []
    for k in range(300):
        x = 1.2 * k / 30 - 6.0
        world.set_pose("bob", (x + rng.normal(0, 0.02), rng.normal(0, 0.02), 0.0), t)
        world.commit()
        out.append(
            {
                (f.target_id, f.sub_property)
                for f in monitor.compute(world, t)
                if f.property == "IsMovingToward"
            }
        )
        t += TICK_30HZ
    return out


@pytest.mark.slow
def test_moving_toward_pairs_resist_noise_at_the_cone_edge():
    """IsMovingToward is debounced per (mover, target) pair: at the edge of the direction cone
    noise no longer makes the pair flip every few ticks; 0 keeps the raw flicker."""

    def pair_flips(series: list[set[tuple[str, str]]]) -> int:
        states = [("door", "direction") in s for s in series]
        return sum(a != b for a, b in itertools.pairwise(states))

    raw, debounced = pair_flips(toward_series(0.0)), pair_flips(toward_series(0.3))
    print(f"\nIsMovingToward(direction) flips at the cone edge: {raw} raw, {debounced} debounced")
    # genuine: the pair appears once the walk is seen, and leaves the cone once
    assert debounced == 2
    assert raw >= debounced + 4


def toward_births(hz: float, seconds: float = 4.0) -> list[tuple[int, float]]:
    """A walker at 1.2 m/s along x reaching toward_range (8 m) of a door straight ahead with
    2 cm noise: the (tick, time since the door was first within range) of every tick whose
    IsMovingToward(direction) set changed."""
    rng = np.random.default_rng(7)
    world = World()
    world.add_entity("bob", "human")
    world.add_entity("door", "object")
    t = 10 * S
    world.set_pose("door", (10.0, 0.0, 0.0), t)
    monitor = AgentMonitor()
    step = round(S / hz)
    entered, reported, changes = None, False, []
    for k in range(int(seconds * hz)):
        x = 1.2 * k / hz
        world.set_pose("bob", (x + rng.normal(0, 0.02), rng.normal(0, 0.02), 0.0), t)
        world.commit()
        now = ("door", "direction") in {
            (f.target_id, f.sub_property)
            for f in monitor.compute(world, t)
            if f.property == "IsMovingToward"
        }
        if entered is None and 10.0 - world.pos[world.row("bob"), 0] < 8.0:
            entered = t
        if now != reported:
            changes.append((k, (t - entered) / S if entered is not None else float("nan")))
            reported = now
        t += step
    return changes


def test_a_pair_entering_range_is_reported_after_min_duration_not_at_once():
    """A continuing walker's new pair (a target coming within range) needs min_duration of
    evidence at 30 Hz, so noise at the range edge cannot make it flicker; at 2.5 Hz the
    previous sample 0.4 s earlier is that evidence and it is reported at once."""
    fast = toward_births(30.0)
    assert len(fast) == 1  # reported once, never dropped again
    # min_duration counts from the last contrary evidence: the sample before the entry
    assert 0.3 - 1 / 30 - 1e-6 <= fast[0][1] <= 0.3 + 1 / 30
    slow = toward_births(2.5)
    assert len(slow) == 1
    assert slow[0][1] <= 0.4 + 1e-9
