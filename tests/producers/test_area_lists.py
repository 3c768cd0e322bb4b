"""The original's upcoming and leaving lists of an area (producers/area_lists.py)."""

from __future__ import annotations

from toaster.producers import AreaManager
from toaster.producers.area_lists import AreaLists, Lists

RING = {
    "shape": "circle",
    "center": [0, 0],
    "radius": 2.0,
    "enter_hysteresis": 0.5,
    "leave_hysteresis": 0.5,
}


def test_upcoming_then_inside_then_leaving_then_out(scene) -> None:
    """Enter only across the inner boundary (1.5 m), leave only across the outer (2.5 m):
    between them, an entity is upcoming (out) on its way in and leaving (in) on its way out."""
    manager = AreaManager({"ring": RING})
    lists = AreaLists(manager)
    scene.add("bob", pos=(1.8, 0, 0))  # coming in: between inner and nominal
    scene.add("ann", pos=(1.0, 0, 0))  # well inside
    scene.add("cup", "object", pos=(5, 0, 0))  # far out

    def tick() -> Lists:
        scene.step()
        manager.compute(scene.world, scene.t)
        return lists.lists(scene.world, scene.t)["ring"]

    assert tick() == Lists(["ann"], ["bob"], [])
    scene.put("bob", (1.2, 0, 0))
    scene.put("ann", (2.3, 0, 0))  # past the nominal boundary: still in, leaving
    assert tick() == Lists(["ann", "bob"], [], ["ann"])
    scene.put("ann", (2.6, 0, 0))  # past the outer boundary: out
    assert tick() == Lists(["bob"], [], [])


def test_owned_area_moves_with_its_owner_and_never_lists_it(scene) -> None:
    manager = AreaManager({"near": {**RING, "owner": "pr2"}})
    lists = AreaLists(manager)
    scene.add("pr2", "robot", pos=(10, 0, 0), head=(0, 0, 1.2))
    scene.add("bob", pos=(11.8, 0, 0))
    scene.step()
    manager.compute(scene.world, scene.t)
    assert lists.lists(scene.world, scene.t)["near"] == Lists([], ["bob"], [])


def test_without_hysteresis_only_inside() -> None:
    from toaster.world import World

    manager = AreaManager({"room": {"shape": "polygon", "points": [[0, 0], [4, 0], [4, 4]]}})
    world = World()
    world.add_entity("mug", "object")
    world.set_pose("mug", (3, 1, 0), 10)
    world.commit()
    manager.compute(world, 10)
    assert AreaLists(manager).lists(world, 10) == {"room": Lists(["mug"], [], [])}
