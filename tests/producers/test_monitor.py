import math

import pytest

from toaster.errors import InvalidInputError
from toaster.producers import AgentMonitor, PerceptionFacts, make_config, pointing

S = 1_000_000_000


def props(facts, prop, sub=None):
    return {
        (f.subject_id, f.target_id): f
        for f in facts
        if f.property == prop and (sub is None or f.sub_property == sub)
    }


def test_looking_toward_and_at_from_head_joint(scene):
    scene.add("bob", pos=(0, 0, 0), head=(0, 0, 1.7))
    scene.add("cup", "object", pos=(0.9, 0.05, 1.7))
    scene.add("tv", "object", pos=(1.6, 0.8, 1.7))  # 26.6° off, within 2 m
    scene.add("far", "object", pos=(5, 0, 1.7))
    scene.step()
    facts = AgentMonitor().compute(scene.world, scene.t)
    toward, at = props(facts, "IsLookingToward"), props(facts, "IsLookingAt")
    assert set(toward) == {("bob", "cup"), ("bob", "tv")}
    assert set(at) == {("bob", "cup")}
    f = toward[("bob", "tv")]
    assert f.value_num == pytest.approx(math.atan2(0.8, 1.6))
    assert f.confidence == pytest.approx((2.0944 - f.value_num) / 2.0944)
    assert (f.property_type, f.sub_property) == ("attention", "agent")


def test_looking_at_another_agents_head_not_hard_coded(scene):
    scene.add("bob", pos=(0, 0, 0), head=(0, 0, 1.7))
    scene.add("ann", pos=(1.5, 0, 0), head=(0, 0, 1.7))  # body at floor, head at eye level
    scene.step()
    facts = AgentMonitor().compute(scene.world, scene.t)
    assert ("bob", "ann") in props(facts, "IsLookingToward")
    assert props(facts, "IsLookingToward")[("bob", "ann")].value_num == pytest.approx(0.0)


def test_head_pitch_and_yaw_near_pi(scene):
    scene.add("bob", pos=(0, 0, 0), yaw=math.pi, head=(0, 0, 1.7))
    scene.add("cup", "object", pos=(-0.9, -0.02, 1.7))
    scene.step()
    assert ("bob", "cup") in props(AgentMonitor().compute(scene.world, scene.t), "IsLookingAt")


def walk(scene, eid, start, velocity, ticks, dt=S // 10):
    x, y = start
    for _ in range(ticks):
        scene.put(eid, (x, y, 0), math.atan2(velocity[1], velocity[0]))
        scene.step(dt)
        x += velocity[0] * dt / S
        y += velocity[1] * dt / S
    scene.t -= dt


def test_is_moving_body_with_speed_and_confidence(scene):
    scene.add("bob", pos=(0, 0, 0))
    scene.add("door", "object", pos=(5, 0.5, 0))  # within toward_range (8 m)
    scene.add("back", "object", pos=(-5, 0, 0))
    walk(scene, "bob", (0, 0), (1.0, 0), 10)
    facts = AgentMonitor().compute(scene.world, scene.t)
    (moving,) = [f for f in facts if f.property == "IsMoving"]
    assert moving.value_num == pytest.approx(1.0)
    assert moving.confidence == pytest.approx(3.6 / 5)
    direction = props(facts, "IsMovingToward", "direction")
    assert set(direction) == {("bob", "door")}
    assert direction[("bob", "door")].confidence == pytest.approx(
        1 - abs(math.atan2(0.5, 5 - 0.9)), abs=1e-6
    )
    dist = props(facts, "IsMovingToward", "distance")
    assert set(dist) == {("bob", "door")}
    assert 0.9 < dist[("bob", "door")].confidence <= 1.0
    assert dist[("bob", "door")].value_num == pytest.approx(0.3, abs=0.01)


def test_direction_wraps_around_pi(scene):
    # Walking along −x (heading ≈ π) toward a target at bearing ≈ −π: the original lost it.
    scene.add("bob", pos=(0, 0, 0))
    scene.add("goal", "object", pos=(-6, -0.01, 0))
    walk(scene, "bob", (0, 0.01), (-1.0, 0.0), 10)
    facts = AgentMonitor().compute(scene.world, scene.t)
    assert ("bob", "goal") in props(facts, "IsMovingToward", "direction")


def test_slow_body_not_moving_and_sparse_tracks(scene):
    scene.add("bob", pos=(0, 0, 0))
    walk(scene, "bob", (0, 0), (0.1, 0), 10)
    assert not props(AgentMonitor().compute(scene.world, scene.t), "IsMoving")
    scene.add("ann", pos=(5, 5, 0))
    walk(scene, "ann", (5, 5), (0.5, 0), 4, dt=4 * S // 10)  # 2.5 Hz, like ETH/UCY
    assert ("ann", "") in props(AgentMonitor().compute(scene.world, scene.t), "IsMoving")


def test_joints_distance_labels_and_joint_motion(scene):
    scene.add("bob", pos=(0, 0, 0), rightHand=(0.3, -0.2, 1.0))
    scene.add("cup", "object", pos=(0.75, -0.2, 1.0))
    scene.add("table", "object", pos=(1.0, -0.2, 1.0))
    scene.add("wall", "object", pos=(20, 0, 1.0))
    for k in range(8):  # the hand reaches toward the table while the body stays still
        scene.world.set_joint_local("bob/rightHand", (0.3 + 0.05 * k, -0.2, 1.0))
        scene.put("bob", (0, 0, 0))
        scene.step()
    scene.t -= S // 10
    facts = AgentMonitor().compute(scene.world, scene.t)
    dist = props(facts, "Distance")
    assert dist[("bob/rightHand", "table")].value_text == "medium"
    assert dist[("bob/rightHand", "cup")].value_text == "close"
    assert dist[("bob/rightHand", "bob")].value_text == "medium"
    assert ("bob/rightHand", "wall") not in dist  # "out" is not emitted by default
    d = dist[("bob/rightHand", "table")]
    assert (d.subject_owner_id, d.property_type, d.sub_property, d.confidence) == (
        "bob",
        "position",
        "3D",
        0.9,
    )
    moving = props(facts, "IsMoving", "joint")
    assert moving[("bob/rightHand", "")].confidence == pytest.approx(0.5 * 3.6 / 20)
    toward = props(facts, "IsMovingToward", "distance")
    assert ("bob/rightHand", "table") in toward  # approaching: sign fixed
    assert ("bob/rightHand", "bob") not in toward


def test_distance_out_can_be_enabled(scene):
    scene.add("bob", pos=(0, 0, 0), head=(0, 0, 1.7))
    scene.add("wall", "object", pos=(20, 0, 1.0))
    scene.step()
    facts = AgentMonitor({"distance_emit_out": True}).compute(scene.world, scene.t)
    assert props(facts, "Distance")[("bob/head", "wall")].value_text == "out"


def test_joints_follow_agent_rigidly(scene):
    scene.add("bob", pos=(0, 0, 0), yaw=0.0, head=(0.1, 0, 1.7), rightHand=(0.3, -0.2, 1.0))
    scene.step()
    scene.put("bob", (5, 5, 0), yaw=math.pi / 2)
    scene.step()
    w = scene.world
    hand = w.pos[w.row("bob/rightHand")]
    assert hand == pytest.approx([5.2, 5.3, 1.0])
    assert w.rpy[w.row("bob/head"), 2] == pytest.approx(math.pi / 2)


def test_monitored_agents_configurable(scene):
    scene.add("bob", pos=(0, 0, 0))
    scene.add("r2", "robot", pos=(3, 0, 0))
    walk(scene, "bob", (0, 0), (1, 0), 5)
    assert (
        props(AgentMonitor({"monitored_agents": ["r2"]}).compute(scene.world, scene.t), "IsMoving")
        == {}
    )
    with pytest.raises(InvalidInputError, match="monitored_agents"):
        AgentMonitor({"monitored_agents": "cats"}).compute(scene.world, scene.t)
    with pytest.raises(InvalidInputError, match="unknown threshold"):
        make_config({"dist_nearby": 1.0})


def test_pointing_now_and_in_the_past(scene):
    scene.add("bob", pos=(0, 0, 0), rightHand=(0.1, -0.2, 1.0))
    scene.add("cup", "object", pos=(3, 0, 0.8))
    scene.add("book", "object", pos=(0, 3, 0.8))
    scene.step()
    assert pointing(scene.world, "bob", "rightHand") == []  # hand close to the body
    scene.world.set_joint_local("bob/rightHand", (0.6, 0.0, 1.3))  # arm toward the cup
    scene.put("bob", (0, 0, 0))
    scene.step()
    said_at = scene.t - S // 10
    now = pointing(scene.world, "bob", "rightHand")
    assert [p[0] for p in now] == ["cup"]
    assert now[0][1] == pytest.approx(1.0)
    for _ in range(5):  # then the arm turns toward the book
        scene.world.set_joint_local("bob/rightHand", (0.0, 0.6, 1.3))
        scene.put("bob", (0, 0, 0))
        scene.step()
    assert [p[0] for p in pointing(scene.world, "bob", "rightHand")] == ["book"]
    assert [p[0] for p in pointing(scene.world, "bob", "rightHand", t_ns=said_at)] == ["cup"]
    with pytest.raises(InvalidInputError, match="no joint 'leftHand'"):
        pointing(scene.world, "bob", "leftHand")


def test_pointing_behind_uses_quadrant(scene):
    scene.add("bob", pos=(0, 0, 0), rightHand=(-0.6, -0.6, 1.2))
    scene.add("bin", "object", pos=(-3, -3, 0))
    scene.add("cup", "object", pos=(3, 3, 0))
    scene.step()
    assert [p[0] for p in pointing(scene.world, "bob", "rightHand")] == ["bin"]


def test_presence_and_in_hand(scene):
    scene.add("bob", pos=(0, 0, 0), rightHand=(0.3, -0.2, 1.0))
    scene.add("ann", pos=(1, 0, 0))
    scene.add("cup", "object", pos=(2, 0, 0))
    scene.world.put_in_hand("cup", "bob", "rightHand")
    scene.step()
    facts = PerceptionFacts().compute(scene.world, scene.t)
    assert set(props(facts, "isPresent")) == {("bob", ""), ("ann", "")}
    (held,) = props(facts, "IsInHand").values()
    assert (held.subject_id, held.target_id, held.target_owner_id) == ("cup", "bob", "bob")
    assert scene.world.pos[scene.world.row("cup")] == pytest.approx([0.3, -0.2, 1.0])
    assert scene.world.busy_hands("bob") == ["bob/rightHand"]
    for _ in range(15):  # ann is no longer perceived: after 1 s she is not present
        scene.put("bob", (0, 0, 0))
        scene.step()
    facts = PerceptionFacts().compute(scene.world, scene.t)
    assert set(props(facts, "isPresent")) == {("bob", "")}


def test_a_held_object_is_no_target_of_its_holders_motion(scene):
    """Issue 27 item 4: after put_in_hand the hand (and the body carrying it) "moved toward"
    the object it holds, at confidence 1; the original does not. Another agent moving toward
    the held object still does."""
    scene.add("bob", pos=(0, 0, 0), rightHand=(0.3, -0.2, 1.0))
    scene.add("ann", pos=(-3, -0.2, 0))
    scene.add("cube", "object", pos=(0.6, -0.2, 1.0))
    scene.world.put_in_hand("cube", "bob", "rightHand")
    monitor = AgentMonitor({"min_duration": {"IsMoving": 0, "IsMovingToward": 0}})
    for k in range(8):  # the hand reaches forward while the body stays still
        scene.world.set_joint_local("bob/rightHand", (0.3 + 0.05 * k, -0.2, 1.0))
        scene.put("bob", (0, 0, 0))
        scene.put("ann", (-3, -0.2, 0))
        scene.step()
        facts = monitor.compute(scene.world, scene.t - S // 10)
    assert ("bob/rightHand", "") in props(facts, "IsMoving")
    assert not [f for f in facts if f.property == "IsMovingToward" and f.target_id == "cube"]
    for k in range(10):  # bob walks on carrying it; ann walks toward him and the cube
        scene.put("bob", (0.1 * k, 0, 0))
        scene.put("ann", (-3 + 0.12 * k, -0.2, 0))
        scene.step()
        facts = monitor.compute(scene.world, scene.t - S // 10)
    toward = {(f.subject_id, f.target_id) for f in facts if f.property == "IsMovingToward"}
    assert ("bob", "") in props(facts, "IsMoving") and ("ann", "cube") in toward
    assert not {pair for pair in toward if pair[0].startswith("bob") and pair[1] == "cube"}


def test_toward_people_for_agents_monitored_by_id(scene):
    """The original computes IsMovingToward toward everyone for the agents it monitors
    (add_agent): an agent named by its id gets it toward people too; the default class
    ("humans", a crowd) keeps toward_range_humans (0: not toward people)."""
    scene.add("bob", pos=(0, 0, 0))
    scene.add("ann", pos=(5, 0.2, 0))
    scene.add("cup", "object", pos=(5, -0.2, 0))
    walk(scene, "bob", (0, 0), (1.0, 0), 10)
    crowd = AgentMonitor().compute(scene.world, scene.t)
    assert set(props(crowd, "IsMovingToward", "direction")) == {("bob", "cup")}
    for which in (["humans", "bob"], ["bob"]):
        named = AgentMonitor({"monitored_agents": which}).compute(scene.world, scene.t)
        assert set(props(named, "IsMovingToward", "direction")) == {("bob", "cup"), ("bob", "ann")}
        assert ("bob", "ann") in props(named, "IsMovingToward", "distance")


def test_body_approach_needs_more_than_the_threshold(scene):
    """The original's body Δdistance threshold is about 3.6e-12 m (a conversion bug): any
    approach counts. toaster's is 0.12 m/s over the window (0.03 m in 0.25 s): passing 5 m
    beside a post (0.016 m nearer in the window) is no approach; threshold 0 gives the original's."""
    scene.add("bob", pos=(0, 0, 0))
    scene.add("post", "object", pos=(1.0, 5.0, 0))
    walk(scene, "bob", (0.0, 0.0), (1.0, 0.0), 9)  # at x = 0.8 now, 0.55 one window ago
    keys = {"min_duration": {"IsMoving": 0, "IsMovingToward": 0}}
    facts = AgentMonitor(keys).compute(scene.world, scene.t)
    assert ("bob", "post") not in props(facts, "IsMovingToward", "distance")
    zero = AgentMonitor({**keys, "body_toward_speed_threshold": 0}).compute(scene.world, scene.t)
    assert ("bob", "post") in props(zero, "IsMovingToward", "distance")
