"""Rotations (toaster.world.geometry, the one place): compared with scipy's Rotation, at the
gimbal lock (pitch ±pi/2, where the hand-written conversion was 0.72 off) and in round trips."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from toaster.world import geometry as g
from toaster.world.live import quaternion_to_rpy
from toaster.world.rosmsg import TfTree
from toaster.world.state import World

RNG = np.random.default_rng(27)
LOCKED = [(r, s * math.pi / 2, y) for s in (1, -1) for r, y in ((0.3, 0.5), (-2.0, 3.0), (0, 0))]


def reference(rpy: tuple[float, float, float]) -> np.ndarray:
    """ROS's R = Rz(yaw) Ry(pitch) Rx(roll), from scipy."""
    roll, pitch, yaw = rpy
    return Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix()


def in_range(angles: np.ndarray) -> bool:
    return bool(np.all((angles > -math.pi) & (angles <= math.pi)))


@pytest.mark.parametrize("rpy", LOCKED + [tuple(v) for v in RNG.uniform(-4, 4, (20, 3))])
def test_quaternion_to_rpy_keeps_the_rotation_even_at_pitch_90_degrees(rpy: tuple) -> None:
    q = Rotation.from_matrix(reference(rpy)).as_quat()
    back = quaternion_to_rpy(*q)  # where sources and services import it from
    assert np.abs(g.rotation_matrices(np.array(back)) - reference(rpy)).max() < 1e-9
    assert in_range(np.array(back))
    assert np.allclose(Rotation.from_quat(g.rpy_to_quat(*back)).as_matrix(), reference(rpy))
    assert np.abs(quaternion_to_rpy(*(2.5 * q)) - np.array(back)).max() < 1e-12  # not unit


def test_vectorised_forms_agree_with_scipy_and_round_trip() -> None:
    rpy = np.vstack([LOCKED, RNG.uniform(-math.pi, math.pi, (200, 3))])
    matrices = g.rotation_matrices(rpy)
    assert np.abs(matrices - np.array([reference(tuple(r)) for r in rpy])).max() < 1e-12
    again = g.quats_to_rpy(g.rpy_to_quats(rpy))
    assert in_range(again)
    assert np.abs(g.rotation_matrices(again) - matrices).max() < 1e-9
    assert np.allclose(g.gaze_axis(rpy), matrices[:, :, 0])
    assert g.rotation_matrices(rpy[:204].reshape(3, -1, 3)).shape == (3, 68, 3, 3)
    assert g.rpy_to_quat(0.0, 0.0, math.pi) == pytest.approx((0.0, 0.0, 1.0, 0.0))
    assert g.quaternion_to_rpy(0.0, 0.0, 1.0, 0.0)[2] == math.pi  # pi, never -pi
    with pytest.raises(ValueError, match="non-zero quaternion"):
        g.quaternion_to_rpy(0.0, 0.0, 0.0, 0.0)


def test_frames_compose_and_invert_for_any_orientation() -> None:
    parent_pos, parent_rpy = RNG.normal(size=(50, 3)), RNG.uniform(-3, 3, (50, 3))
    parent_rpy[:6] = LOCKED
    local_pos, local_rpy = RNG.normal(size=(50, 3)), RNG.uniform(-3, 3, (50, 3))
    pos, rpy = g.from_frames(parent_pos, parent_rpy, local_pos, local_rpy)
    for i in range(50):
        parent = Rotation.from_matrix(reference(tuple(parent_rpy[i])))
        assert pos[i] == pytest.approx(parent_pos[i] + parent.apply(local_pos[i]))
        want = parent.as_matrix() @ reference(tuple(local_rpy[i]))
        assert np.abs(g.rotation_matrices(rpy[i]) - want).max() < 1e-9
    lp, lr = g.to_frames(parent_pos, parent_rpy, pos, rpy)
    assert np.allclose(lp, local_pos)
    assert np.abs(g.rotation_matrices(lr) - g.rotation_matrices(local_rpy)).max() < 1e-9
    xy = RNG.normal(size=(10, 2))
    assert np.allclose(g.from_local_xy(g.to_local_xy(xy, (1.0, 2.0), 2.5), (1.0, 2.0), 2.5), xy)
    turned = g.to_local_xy(np.array([[1.0, 1.0]]), (0.0, 1.0), math.pi / 2)
    assert turned[0] == pytest.approx([0.0, -1.0])


def test_a_joint_follows_a_pitched_agent() -> None:
    """The world composes a joint's pose with its agent's whole rotation (adding roll, pitch
    and yaw, as before, is right only for an agent turned about z alone)."""
    world = World()
    world.add_entity("bob", "human")
    world.add_entity("bob/head", "joint", owner_id="bob", name="head")
    world.set_joint_local("bob/head", (0.0, 0.0, 1.0), (0.0, 0.0, math.pi / 2))
    world.set_pose("bob", (0.0, 0.0, 0.0), 1, (0.0, math.pi / 2, 0.0))  # lying face down
    world.commit()
    head = world.row("bob/head")
    assert world.pos[head] == pytest.approx([1.0, 0.0, 0.0])  # up along his body: +x
    want = reference((0.0, math.pi / 2, 0.0)) @ reference((0.0, 0.0, math.pi / 2))
    assert np.abs(g.rotation_matrices(world.rpy[head]) - want).max() < 1e-9


def test_tf_chains_are_composed_in_one_batch_as_one_by_one() -> None:
    class Edge:
        def __init__(self, parent: str, child: str, t: np.ndarray, q: np.ndarray) -> None:
            self.child_frame_id = child
            self.header = type("H", (), {"frame_id": parent, "stamp": 5})()
            xyz, xyzw = dict(zip("xyz", t, strict=True)), dict(zip("xyzw", q, strict=True))
            self.transform = type(
                "T",
                (),
                {"translation": type("V", (), xyz)(), "rotation": type("Q", (), xyzw)()},
            )()

    tree = TfTree()
    names = ["a", "b", "c", "d"]
    rots = Rotation.random(4, random_state=3)
    moves = RNG.normal(size=(4, 3))
    edges = [
        Edge("map" if i == 0 else names[i - 1], n, moves[i], rots[i].as_quat())
        for i, n in enumerate(names)
    ]
    tree.update(type("M", (), {"transforms": edges})())
    found = tree.lookup_many(["d", "a", "nowhere", "map"])
    assert found[2] is None and found[3] == ((0.0, 0.0, 0.0), g.IDENTITY, None)
    t, q = np.zeros(3), Rotation.identity()
    for i in (3, 2, 1, 0):  # d in c in b in a in map
        t, q = moves[i] + rots[i].apply(t), rots[i] * q
    position, quat, stamp = found[0]
    assert position == pytest.approx(t) and stamp == 5
    assert Rotation.from_quat(quat).approx_equal(q, atol=1e-9)
    assert tree.lookup("a")[0] == pytest.approx(moves[0])
