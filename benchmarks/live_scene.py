"""The scene of bench_live.py, shared by the in-process baseline and the rospy client (it
imports nothing, so Debian's Python runs it too).

Humans stand on a grid 3 m apart, each beside its own circular zone (radius 1 m); each steps
into and out of its zone (0.8 m each way) once a second, staggered, as people do at a counter.
Objects stand in a row away from them.
"""

from __future__ import annotations

SPACING, ZONE_RADIUS = 3.0, 1.0


def zone(i: int) -> dict[str, object]:
    """Human i's zone, as an area spec."""
    x, y = SPACING * (i % 10), SPACING * (i // 10)
    return {
        "shape": "circle",
        "center": [x + 1.0, y],
        "radius": ZONE_RADIUS,
        "area_type": "interaction",
    }


def human_pose(
    i: int, humans: int, elapsed: float, cycle: float = 1.0
) -> tuple[bool, float, float]:
    """(inside its zone, x, y) of human i at ``elapsed`` seconds: inside during the first half
    of its own ``cycle`` seconds, staggered by i / humans of a cycle, from the first second
    on."""
    phase = ((elapsed - 1.0) / cycle + i / humans) % 1.0
    inside = elapsed >= 1.0 and phase < 0.5
    x, y = SPACING * (i % 10), SPACING * (i // 10)
    return inside, (x + 1.0 if inside else x - 0.6), y


def joint_offsets() -> dict[str, tuple[float, float, float]]:
    """Each human's joints, relative to its body: head and right hand."""
    return {"head": (0.0, 0.0, 1.7), "rightHand": (0.3, 0.0, 1.1)}


def object_pose(j: int) -> tuple[float, float, float]:
    """Where object j stands (a row south of the humans)."""
    return -5.0 + j % 10, -5.0 - j // 10, 0.8
