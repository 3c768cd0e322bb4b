"""Helpers to build hand-made scenes."""

from __future__ import annotations

import pytest

from toaster.world import World

S = 1_000_000_000


class Scene:
    """A world with a clock: ``put`` sets poses at the current time, ``step`` commits."""

    def __init__(self) -> None:
        self.world = World()
        self.t = 10 * S

    def add(
        self, eid: str, kind: str = "human", pos=(0.0, 0.0, 0.0), yaw: float = 0.0, **joints: tuple
    ) -> None:
        self.world.add_entity(eid, kind)
        self.world.set_pose(eid, pos, self.t, (0.0, 0.0, yaw))
        for name, local in joints.items():
            self.world.add_entity(f"{eid}/{name}", "joint", owner_id=eid, name=name)
            self.world.set_joint_local(
                f"{eid}/{name}", local[:3], local[3] if len(local) > 3 else (0.0, 0.0, 0.0)
            )

    def put(self, eid: str, pos, yaw: float = 0.0) -> None:
        self.world.set_pose(eid, pos, self.t, (0.0, 0.0, yaw))

    def step(self, dt_ns: int = S // 10) -> None:
        self.world.commit()
        self.t += dt_ns


@pytest.fixture
def scene() -> Scene:
    return Scene()
