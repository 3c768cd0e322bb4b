"""The scene of bench_live.py, shared by the in-process baseline and the rospy client (it
imports nothing but math, so Debian's Python runs it too)."""

from __future__ import annotations

import math


def human_pose(i: int, humans: int, elapsed: float) -> tuple[bool, float, float]:
    """(inside the zone, x, y) of human i at ``elapsed`` seconds: inside during the first half
    of its own 1 s cycle, staggered by i / humans, from the first second on."""
    phase = (elapsed - 1.0 + i / humans) % 1.0
    inside = elapsed >= 1.0 and phase < 0.5
    angle = 2 * math.pi * i / humans
    if inside:
        return True, 0.3 * math.cos(angle), 0.3 * math.sin(angle)
    return False, 6 + 4 * math.cos(angle), 6 + 4 * math.sin(angle)


def object_pose(j: int) -> tuple[float, float, float]:
    """Where object j stands (away from the zone)."""
    return -5.0 + j % 10, -5.0 - j // 10, 0.8
