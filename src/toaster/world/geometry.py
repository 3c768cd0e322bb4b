"""Small vectorised geometry helpers shared by the world model and the producers."""

from __future__ import annotations

from typing import overload

import numpy as np

TWO_PI = 2.0 * np.pi


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


def rotation_matrices(rpy: np.ndarray) -> np.ndarray:
    """Rotation matrices (…, 3, 3) from roll, pitch, yaw (z-y-x convention, as ROS)."""
    rpy = np.asarray(rpy, dtype=float)
    cr, sr = np.cos(rpy[..., 0]), np.sin(rpy[..., 0])
    cp, sp = np.cos(rpy[..., 1]), np.sin(rpy[..., 1])
    cy, sy = np.cos(rpy[..., 2]), np.sin(rpy[..., 2])
    out = np.empty((*rpy.shape[:-1], 3, 3))
    out[..., 0, 0] = cy * cp
    out[..., 0, 1] = cy * sp * sr - sy * cr
    out[..., 0, 2] = cy * sp * cr + sy * sr
    out[..., 1, 0] = sy * cp
    out[..., 1, 1] = sy * sp * sr + cy * cr
    out[..., 1, 2] = sy * sp * cr - cy * sr
    out[..., 2, 0] = -sp
    out[..., 2, 1] = cp * sr
    out[..., 2, 2] = cp * cr
    return out


def gaze_axis(rpy: np.ndarray) -> np.ndarray:
    """Unit local +x axis of poses (…, 3): (cos p cos y, cos p sin y, -sin p); roll is ignored."""
    rpy = np.asarray(rpy, dtype=float)
    cp = np.cos(rpy[..., 1])
    return np.stack(
        [cp * np.cos(rpy[..., 2]), cp * np.sin(rpy[..., 2]), -np.sin(rpy[..., 1])], axis=-1
    )


def to_local_xy(xy: np.ndarray, origin_xy: np.ndarray, yaw: float) -> np.ndarray:
    """Express world points (n, 2) in the frame of an owner at ``origin_xy`` turned by ``yaw``."""
    c, s = np.cos(yaw), np.sin(yaw)
    d = np.asarray(xy, dtype=float) - np.asarray(origin_xy, dtype=float)
    return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)
