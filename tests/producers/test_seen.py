"""IsSeen (producers/seen.py): from what a detector lists, else the robots' field of view."""

from __future__ import annotations

import math

from toaster.producers.seen import SeenFacts
from toaster.world.config import make_config

S = 1_000_000_000


def seen(facts):
    return {(f.subject_id, f.target_id, f.sub_property) for f in facts if f.property == "IsSeen"}


def test_field_of_view_of_the_robots_head_within_range(scene) -> None:
    """Simulated input: what lies within the robot's camera cone (its head joint, pitch
    included) and range is seen; behind, too far or outside the cone is not."""
    scene.add("pr2", "robot", pos=(0, 0, 0), head=(0, 0, 1.2))
    scene.add("bob", pos=(3, 0.5, 0))  # ahead, slightly left
    scene.add("mug", "object", pos=(1, 0, 0.8))
    scene.add("ann", pos=(-2, 0, 0))  # behind
    scene.add("far", "object", pos=(9, 0, 1))  # beyond view_range (8 m)
    scene.add("side", "object", pos=(0.5, 3, 1))  # 80° off the gaze: outside 120°
    scene.step()
    facts = SeenFacts().compute(scene.world, scene.t)
    assert seen(facts) == {("bob", "pr2", "view"), ("mug", "pr2", "view")}
    f = next(f for f in facts if f.subject_id == "mug")
    assert (f.property_type, f.observability, f.value_text) == ("affordance", 0.0, "true")
    # the robot turns its head toward ann: now only she is in view
    scene.world.set_joint_local("pr2/head", (0, 0, 1.2), (0.0, 0.0, math.pi))
    scene.step()
    assert seen(SeenFacts().compute(scene.world, scene.t)) == {("ann", "pr2", "view")}


def test_without_head_the_robot_looks_along_its_yaw_from_eye_height(scene) -> None:
    scene.add("r1", "robot", pos=(0, 0, 0), yaw=math.pi / 2)
    scene.add("cup", "object", pos=(0, 2, 0.8))
    scene.add("box", "object", pos=(2, 0, 0.8))
    scene.step()
    narrow = SeenFacts(make_config({"view_aperture": 1.0}))
    assert seen(narrow.compute(scene.world, scene.t)) == {("cup", "r1", "view")}


def test_no_robot_sees_nothing(scene) -> None:
    scene.add("bob", pos=(0, 0, 0))
    scene.add("mug", "object", pos=(1, 0, 0.8))
    scene.step()
    assert SeenFacts().compute(scene.world, scene.t) == []


def test_a_detectors_list_decides_for_what_it_ever_listed(scene) -> None:
    """Detected input (ROS4HRI tracked ids): listed = seen, by the observer, whatever the
    geometry; once listed by a detector, an entity follows its lists only (a stale list
    sees nothing); entities no detector lists keep the field-of-view rule."""
    scene.add("pr2", "robot", pos=(0, 0, 0), head=(0, 0, 1.2))
    scene.add("h1", pos=(-3, 0, 0))  # behind the robot, yet tracked
    scene.add("h2", pos=(3, 0, 0))  # in view, tracked, then lost
    scene.add("mug", "object", pos=(1, 0, 0.8))
    scene.step()
    producer = SeenFacts()
    producer.report("ros4hri_body", ["h1", "h2", "ghost"], "pr2", t_ns=scene.t)
    producer.report("ros4hri_face", ["h1", "pr2/head"], "pr2", t_ns=scene.t)
    facts = producer.compute(scene.world, scene.t)
    assert seen(facts) == {
        ("h1", "pr2", "detected"),
        ("h2", "pr2", "detected"),
        ("mug", "pr2", "view"),
    }
    assert len(facts) == 3  # h1 listed twice, one fact
    producer.report("ros4hri_body", ["h1"], "pr2", t_ns=scene.t)
    assert ("h2", "pr2", "view") not in seen(producer.compute(scene.world, scene.t))
    scene.step(2 * S)  # no list for 2 s (> presence_timeout): the detectors see nothing
    scene.put("pr2", (0, 0, 0))
    scene.put("h1", (-3, 0, 0))
    scene.put("h2", (3, 0, 0))
    scene.put("mug", (1, 0, 0.8))
    scene.step()
    assert seen(producer.compute(scene.world, scene.t)) == {("mug", "pr2", "view")}


def test_a_crowd_costs_one_vectorised_test_per_robot(scene) -> None:
    """3,000 people around one robot: the tick's IsSeen is the people in its cone."""
    import numpy as np

    rng = np.random.default_rng(1)
    scene.add("pr2", "robot", pos=(0, 0, 0))
    xy = rng.uniform(-10, 10, (3000, 2))
    for i, (x, y) in enumerate(xy):
        scene.add(f"p{i}", pos=(x, y, 0))
    scene.step()
    facts = SeenFacts().compute(scene.world, scene.t)
    d = np.hypot(xy[:, 0], xy[:, 1])
    eye_to_middle = np.hypot(d, 1.6 - 1.75 / 2)
    cone = np.abs(np.arctan2(xy[:, 1], xy[:, 0])) < 2.0944 / 2 - 0.05
    inside = (eye_to_middle < 7.9) & cone & (d > 1)
    ids = {f.subject_id for f in facts}
    assert {f"p{i}" for i in np.flatnonzero(inside)} <= ids
    assert len(ids) < 3000 / 2
