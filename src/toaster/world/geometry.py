"""Geometry shared by the world model, the producers and the ROS mapping: the one place where
orientations are converted and composed.

Every rotation goes through :class:`scipy.spatial.transform.Rotation` (imported on first use, so
``toaster --help`` stays fast). Orientations are ROS's: roll, pitch, yaw in radians about x, y, z,
composed as R = Rz(yaw) · Ry(pitch) · Rx(roll) (scipy's intrinsic ``"ZYX"``), quaternions as
(x, y, z, w). Angles come back wrapped to (-pi, pi]; at pitch ±pi/2 (gimbal lock) roll and yaw
are not unique and the roll is 0, the rotation itself exact.
"""

from __future__ import annotations

import math
import threading
import warnings
from functools import cache
from typing import TYPE_CHECKING, Any, overload

import numpy as np

if TYPE_CHECKING:
    from scipy.spatial.transform import Rotation  # type: ignore[import-untyped]

TWO_PI = 2.0 * np.pi
Vec = tuple[float, float, float]
Quat = tuple[float, float, float, float]  # x, y, z, w
IDENTITY: Quat = (0.0, 0.0, 0.0, 1.0)
_quiet = threading.Lock()


@cache
def _rotation() -> type[Rotation]:
    """scipy's Rotation class, imported once, on first use."""
    from scipy.spatial.transform import Rotation  # type: ignore[import-untyped]

    return Rotation


@overload
def wrap_angle(angle: float) -> float: ...
@overload
def wrap_angle(angle: np.ndarray) -> np.ndarray: ...
def wrap_angle(angle: np.ndarray | float) -> np.ndarray | float:
    """Wrap angles to (-pi, pi] (pi stays pi, -pi becomes pi); a scalar (or a 0-d array)
    gives a float."""
    wrapped = np.pi - np.mod(np.pi - np.asarray(angle, dtype=float), TWO_PI)
    if np.ndim(wrapped) == 0:
        return float(wrapped)
    return wrapped


def bearing(from_xy: np.ndarray, to_xy: np.ndarray) -> np.ndarray:
    """2D angle of the vector from ``from_xy`` to ``to_xy`` (arrays broadcast, last axis x, y)."""
    d = np.asarray(to_xy, dtype=float) - np.asarray(from_xy, dtype=float)
    return np.arctan2(d[..., 1], d[..., 0])


# -- roll, pitch, yaw <-> rotations ---------------------------------------------------------------
def rotations(rpy: Any) -> Rotation:
    """The rotations of roll, pitch, yaw rows (n, 3) or of one (3,)."""
    rpy = np.asarray(rpy, dtype=float)
    return _rotation().from_euler("ZYX", rpy[..., ::-1])


def rpy_of(rot: Rotation) -> np.ndarray:
    """Roll, pitch, yaw (n, 3) or (3,) of rotations, wrapped to (-pi, pi]."""
    # at pitch ±pi/2 scipy warns that it sets the roll to 0: that is the choice made here (the
    # lock keeps threads from restoring each other's warning filters)
    with _quiet, warnings.catch_warnings():
        warnings.filterwarnings("ignore", "Gimbal lock detected", UserWarning)
        angles = rot.as_euler("ZYX")
    return np.asarray(wrap_angle(angles[..., ::-1]))


def rotation_matrices(rpy: np.ndarray) -> np.ndarray:
    """Rotation matrices (…, 3, 3) of roll, pitch, yaw (…, 3)."""
    rpy = np.asarray(rpy, dtype=float)
    flat = rpy.reshape(-1, 3)
    if not len(flat):
        return np.zeros((*rpy.shape[:-1], 3, 3))
    return rotations(flat).as_matrix().reshape(*rpy.shape[:-1], 3, 3)


def from_frames(
    parent_pos: np.ndarray,
    parent_rpy: np.ndarray,
    local_pos: np.ndarray,
    local_rpy: np.ndarray,
    parents: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """World positions (n, 3) and roll, pitch, yaw (n, 3) of children posed in their parents'
    frames (a joint on its agent). ``parents``: child i's parent is row ``parents[i]`` of the
    parent arrays (each parent's rotation is then built once, not once per child)."""
    if not len(local_pos):
        return np.zeros((0, 3)), np.zeros((0, 3))
    parent = rotations(parent_rpy)
    if parents is not None:
        parent, parent_pos = parent[parents], parent_pos[parents]
    return parent_pos + parent.apply(local_pos), rpy_of(parent * rotations(local_rpy))


def to_frames(
    parent_pos: np.ndarray,
    parent_rpy: np.ndarray,
    pos: np.ndarray,
    rpy: np.ndarray,
    parents: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Positions and roll, pitch, yaw (n, 3) of world poses in their parents' frames
    (from_frames's inverse; ``parents`` as there)."""
    if not len(pos):
        return np.zeros((0, 3)), np.zeros((0, 3))
    inverse = rotations(parent_rpy).inv()
    if parents is not None:
        inverse, parent_pos = inverse[parents], parent_pos[parents]
    return inverse.apply(pos - parent_pos), rpy_of(inverse * rotations(rpy))


def gaze_axis(rpy: np.ndarray) -> np.ndarray:
    """Unit local +x axis (…, 3) of poses (…, 3): (cos p cos y, cos p sin y, -sin p)."""
    return rotation_matrices(rpy)[..., :, 0]


def to_local_xy(xy: np.ndarray, origin_xy: np.ndarray, yaw: float) -> np.ndarray:
    """Express world points (n, 2) in the frame of an owner at ``origin_xy`` turned by ``yaw``."""
    d = np.asarray(xy, dtype=float) - np.asarray(origin_xy, dtype=float)
    return _turn_xy(d, -float(yaw))


def from_local_xy(xy: np.ndarray, origin_xy: np.ndarray, yaw: float) -> np.ndarray:
    """World points (n, 2) of points given in the frame of an owner at ``origin_xy`` turned by
    ``yaw`` (to_local_xy's inverse)."""
    return _turn_xy(np.asarray(xy, dtype=float), float(yaw)) + np.asarray(origin_xy, dtype=float)


def _turn_xy(xy: np.ndarray, yaw: float) -> np.ndarray:
    xy = xy.reshape(-1, 2)
    if not len(xy):
        return np.zeros((0, 2))
    turn = _rotation().from_euler("z", yaw)
    return turn.apply(np.column_stack([xy, np.zeros(len(xy))]))[:, :2]


def to_local(v: np.ndarray, rpy: np.ndarray) -> np.ndarray:
    """Vectors (…, 3) expressed in the frame of a pose turned by ``rpy`` (3,)."""
    return rotations(rpy).inv().apply(np.asarray(v, dtype=float))


def from_local(v: np.ndarray, rpy: np.ndarray) -> np.ndarray:
    """Vectors (…, 3) given in the frame of a pose turned by ``rpy`` (3,), in world axes."""
    return rotations(rpy).apply(np.asarray(v, dtype=float))


# -- quaternions ----------------------------------------------------------------------------------
def check_quat(q: Any) -> Quat:
    """``q`` (x, y, z, w) of unit length; ValueError for a zero or non-finite quaternion (it need
    not be normalised)."""
    x, y, z, w = (float(c) for c in q)
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if not math.isfinite(norm) or norm == 0.0:
        msg = f"quaternion ({x}, {y}, {z}, {w}) has no orientation: give a non-zero quaternion"
        raise ValueError(msg)
    return (x / norm, y / norm, z / norm, w / norm)


def quats_to_rpy(quats: Any) -> np.ndarray:
    """Roll, pitch, yaw (n, 3) of non-zero quaternions (n, 4) (x, y, z, w)."""
    quats = np.asarray(quats, dtype=float).reshape(-1, 4)
    if not len(quats):
        return np.zeros((0, 3))
    return rpy_of(_rotation().from_quat(quats))


def quaternion_to_rpy(x: float, y: float, z: float, w: float) -> Vec:
    """Roll, pitch, yaw of a quaternion; it need not be normalised (ValueError when zero)."""
    r, p, yaw = quats_to_rpy([check_quat((x, y, z, w))])[0].tolist()
    return (r, p, yaw)


def rpy_to_quats(rpy: Any) -> np.ndarray:
    """Quaternions (n, 4) (x, y, z, w) of roll, pitch, yaw rows (n, 3)."""
    rpy = np.asarray(rpy, dtype=float).reshape(-1, 3)
    if not len(rpy):
        return np.zeros((0, 4))
    return rotations(rpy).as_quat(canonical=True)


def rpy_to_quat(roll: float, pitch: float, yaw: float) -> Quat:
    """Quaternion (x, y, z, w) of roll, pitch, yaw."""
    x, y, z, w = rpy_to_quats([(roll, pitch, yaw)])[0].tolist()
    return (x, y, z, w)


def quat_mul(a: Quat, b: Quat) -> Quat:
    """The rotation ``a`` after ``b`` (Hamilton product a·b) of unit quaternions."""
    rot = _rotation()
    x, y, z, w = (rot.from_quat(a) * rot.from_quat(b)).as_quat(canonical=True).tolist()
    return (x, y, z, w)


def rotate(q: Quat, v: Vec) -> Vec:
    """Vector ``v`` turned by the unit quaternion ``q``."""
    x, y, z = _rotation().from_quat(q).apply(v).tolist()
    return (x, y, z)


def compose_poses(
    parent_t: np.ndarray, parent_q: np.ndarray, child_t: np.ndarray, child_q: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Poses (n, 3) positions and (n, 4) quaternions of children given in their parents' frames:
    t = parent_t + R(parent_q)·child_t, q = parent_q·child_q."""
    if not len(parent_t):
        return np.zeros((0, 3)), np.zeros((0, 4))
    rot = _rotation()
    parent = rot.from_quat(parent_q)
    q = (parent * rot.from_quat(child_q)).as_quat(canonical=True)
    return parent_t + parent.apply(child_t), q
