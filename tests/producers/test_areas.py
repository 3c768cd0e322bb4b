import math

import numpy as np
import pytest

from toaster.errors import InvalidInputError
from toaster.producers import AreaManager, area_from_original, normalize_area
from toaster.producers.areas import direction_label, multiple_relative_position, relative_position
from toaster.world import World

SQUARE = [[0, 0], [4, 0], [4, 4], [0, 4]]

S = 1_000_000_000


def facts_of(manager, scene, prop=None):
    facts = manager.compute(scene.world, scene.t)
    return [f for f in facts if prop is None or f.property == prop]


def test_room_support_and_generic_area_facts(scene):
    scene.add("bob", pos=(1, 1, 0))
    scene.add("cup", "object", pos=(5, 5, 0.8))
    scene.step()
    m = AreaManager(
        {
            "kitchen": {"points": SQUARE, "area_type": "room"},
            "table": {"shape": "circle", "center": [5, 5], "radius": 0.5, "area_type": "support"},
            "zone": {"points": SQUARE, "area_type": "danger"},
        }
    )
    facts = {(f.subject_id, f.property, f.target_id, f.sub_property) for f in facts_of(m, scene)}
    assert facts == {
        ("bob", "IsInRoom", "kitchen", "room"),
        ("cup", "IsAt", "table", "location"),
        ("bob", "IsInArea", "zone", "danger"),
    }
    f = next(f for f in facts_of(m, scene) if f.property == "IsInRoom")
    assert (f.property_type, f.confidence, f.observability, f.value_text) == (
        "position",
        1.0,
        0.8,
        "true",
    )


def test_hysteresis_enter_inner_leave_outer(scene):
    scene.add("bob", pos=(-1, 2, 0))
    m = AreaManager({"a": {"points": SQUARE, "enter_hysteresis": 0.5, "leave_hysteresis": 0.5}})
    inside = []
    for x in [-1, 0.2, 0.6, 3.8, 4.3, 4.6, 4.3, 3.8, 3.4]:
        scene.put("bob", (x, 2, 0))
        scene.step()
        inside.append(bool(facts_of(m, scene, "IsInArea")))
    #          out   between→out  inner→in  stays  outer band  out  band→out  out  inner→in
    assert inside == [False, False, True, True, True, False, False, False, True]


def test_circle_hysteresis(scene):
    scene.add("bob", pos=(0, 0, 0))
    m = AreaManager(
        {
            "c": {
                "shape": "circle",
                "center": [0, 0],
                "radius": 1.0,
                "enter_hysteresis": 0.2,
                "leave_hysteresis": 0.2,
            }
        }
    )
    seq = []
    for x in [0.9, 0.5, 1.1, 1.3, 0.9]:
        scene.put("bob", (x, 0, 0))
        scene.step()
        seq.append(bool(facts_of(m, scene)))
    assert seq == [False, True, True, False, False]


def test_owner_area_moves_and_turns_with_owner(scene):
    scene.add("robot", "robot", pos=(10, 10, 0), yaw=0.0)
    scene.add("bob", pos=(11, 10, 0))
    front = {"points": [[0, -0.5], [2, -0.5], [2, 0.5], [0, 0.5]], "owner": "robot"}
    m = AreaManager({"front": front})
    scene.step()
    f = facts_of(m, scene)
    assert [(x.subject_id, x.target_id, x.target_owner_id) for x in f] == [
        ("bob", "front", "robot")
    ]
    scene.put("robot", (10, 10, 0), yaw=math.pi / 2)  # turn left: front is now +y
    scene.step()
    assert facts_of(m, scene) == []
    scene.put("bob", (10, 11.5, 0))
    scene.step()
    assert [x.subject_id for x in facts_of(m, scene)] == ["bob"]
    scene.put("robot", (0, 0, 0), yaw=math.pi / 2)  # the area moves away with the owner
    scene.step()
    assert facts_of(m, scene) == []


def test_owner_never_inside_its_own_area(scene):
    scene.add("robot", "robot", pos=(0, 0, 0), head=(0.5, 0, 1.4))
    m = AreaManager(
        {
            "around": {
                "shape": "circle",
                "center": [0, 0],
                "radius": 3,
                "owner": "robot",
                "entity_types": "all",
            }
        }
    )
    scene.step()
    assert facts_of(m, scene) == []


def test_z_band_unbounded_by_default_and_bounded_when_given(scene):
    scene.add("lamp", "object", pos=(1, 1, 2.5))
    scene.step()
    assert facts_of(AreaManager({"a": {"points": SQUARE}}), scene)
    assert not facts_of(AreaManager({"a": {"points": SQUARE, "z_min": 0, "z_max": 2}}), scene)
    band = AreaManager({"c": {"shape": "circle", "center": [1, 1, 2], "radius": 1, "height": 1}})
    assert facts_of(band, scene)


def test_owner_z_shifts_band(scene):
    scene.add("drone", "robot", pos=(0, 0, 5))
    scene.add("bird", "object", pos=(0.5, 0, 5.2))
    scene.step()
    m = AreaManager(
        {
            "a": {
                "shape": "circle",
                "center": [0, 0],
                "radius": 1,
                "owner": "drone",
                "z_min": -0.5,
                "z_max": 0.5,
                "entity_types": "objects",
            }
        }
    )
    assert [f.subject_id for f in facts_of(m, scene)] == ["bird"]


@pytest.mark.parametrize(
    ("words", "expected"),
    [
        ("human", {"bob"}),
        ("humans", {"bob"}),
        (["robot"], {"r2"}),
        ("agents", {"bob", "r2"}),
        ("object", {"cup"}),
        ("entities", {"bob", "r2", "cup"}),
        ("joints", {"bob/head"}),
    ],
)
def test_entity_type_filter_singular_and_plural(scene, words, expected):
    scene.add("bob", pos=(1, 1, 0), head=(0, 0, 1.7))
    scene.add("r2", "robot", pos=(2, 2, 0))
    scene.add("cup", "object", pos=(3, 3, 0))
    scene.step()
    m = AreaManager({"a": {"points": SQUARE, "entity_types": words}})
    assert {f.subject_id for f in facts_of(m, scene)} == expected


def test_unknown_entity_type_rejected():
    with pytest.raises(InvalidInputError, match="unknown entity type 'people'"):
        AreaManager({"a": {"points": SQUARE, "entity_types": "people"}})


def test_bad_area_specs_rejected():
    with pytest.raises(InvalidInputError, match="radius"):
        normalize_area("c", {"shape": "circle", "center": [0, 0], "radius": -1})
    with pytest.raises(InvalidInputError, match="simple polygon"):
        normalize_area("p", {"points": [[0, 0], [1, 1]]})
    with pytest.raises(InvalidInputError, match="unknown shape"):
        normalize_area("p", {"shape": "star"})


def test_is_facing_wraps_around_pi(scene):
    # The original computed yaw − bearing without wrap: yaw 3.1, owner at bearing −3.13.
    scene.add("robot", "robot", pos=(0, 0, 0))
    bearing = -3.13
    scene.add("bob", pos=(-2 * math.cos(bearing), -2 * math.sin(bearing), 0), yaw=3.1)
    scene.step()
    m = AreaManager(
        {
            "i": {
                "shape": "circle",
                "center": [0, 0],
                "radius": 3,
                "owner": "robot",
                "facts": ["interaction"],
            }
        }
    )
    facing = facts_of(m, scene, "IsFacing")
    assert len(facing) == 1
    f = facing[0]
    assert f.target_id == "robot"
    assert f.value_text == "true"
    assert f.value_num == pytest.approx(3.1 - (bearing + 2 * math.pi))
    assert f.confidence == pytest.approx((0.5 - abs(f.value_num)) / 0.5)
    assert (f.property_type, f.sub_property, f.observability) == ("posture", "angle", 0.5)


def test_area_density_subject_is_area_name(scene):
    scene.add("robot", "robot", pos=(0, 0, 0))
    for i in range(4):
        scene.add(f"h{i}", pos=(i * 2 + 0.5, 0, 0))
    scene.step()
    m = AreaManager(
        {
            "near": {
                "shape": "circle",
                "center": [0, 0],
                "radius": 3,
                "owner": "robot",
                "facts": "density",
                "entity_types": "humans",
            }
        }
    )
    (d,) = facts_of(m, scene, "AreaDensity")
    assert (d.subject_id, d.subject_owner_id, d.value_num) == ("near", "robot", 0.5)
    assert (d.property_type, d.sub_property, d.observability) == ("density", "ratio", 0.0)


def test_import_original_area_record():
    name, spec = area_from_original(
        {
            "name": "pushing",
            "myOwner": "spencer",
            "areaType": "",
            "factType": "",
            "entityType": "human",
            "isCircle": False,
            "ray": 0.0,
            "center": {"x": 0, "y": 0, "z": 0},
            "poly": [
                [-2, 1, 0],
                [0, 0, 0],
                [2, 1, 0],
                [2.5, -1, 0],
                [-2.5, -1, 0],
                [-2, 0, 0],
                [-2, 1, 0],
            ],
        }
    )
    assert name == "pushing"
    assert spec["owner"] == "spencer"
    assert len(spec["points"]) == 6
    assert spec["z_min"] is None
    assert spec["entity_types"] == ["human"]


@pytest.mark.parametrize(
    ("angle", "label"),
    [
        (0.0, "ahead"),
        (0.6, "ahead right"),
        (-0.6, "ahead left"),
        (1.5, "right"),
        (-1.5, "left"),
        (2.5, "back right"),
        (-2.5, "back left"),
        (math.pi, "back"),
        (-3.1, "back"),
    ],
)
def test_direction_labels(angle, label):
    assert direction_label(angle) == label


def test_relative_position_wraps(scene):
    scene.add("bob", pos=(0, 0, 0), yaw=3.0)
    scene.add("cup", "object", pos=(-1, -0.3, 0))  # bearing ≈ −2.85: ahead, slightly left
    scene.step()
    label, angle = relative_position(scene.world, "bob", "cup")
    assert angle == pytest.approx(3.0 - math.atan2(-0.3, -1) - 2 * math.pi)
    assert label == "ahead"
    assert angle < 0


def test_multiple_relative_position_sign_fixed(scene):
    scene.add("bob", pos=(0, 0, 0))
    scene.add("box", "object", pos=(2, 0, 0))
    scene.add("cup", "object", pos=(2, -1, 0))  # right of the box, as bob sees it
    scene.step()
    label, angle = multiple_relative_position(scene.world, "bob", "box", "cup")
    assert angle == pytest.approx(math.pi / 2)
    assert label == "right"


def test_runs_of_plain_areas_give_the_facts_of_one_group_per_area():
    """Consecutive areas without owner or density are one group (their ids as target labels):
    the facts, their order and their keys are those of the loop per area it replaced."""
    from toaster.producers.batch import FactBatch

    rng = np.random.default_rng(11)
    world = World()
    for i in range(60):
        world.add_entity(f"e{i}", ("human", "object", "robot")[i % 3])
    areas = {}
    for k in range(40):
        kind = rng.integers(0, 6)
        spec: dict = {"area_type": ["interaction", "room", "support"][k // 8 % 3]}
        if kind < 3:
            spec |= {"shape": "circle", "center": rng.uniform(0, 10, 2).tolist(), "radius": 1.5}
        else:
            x, y = rng.uniform(0, 10, 2)
            spec["points"] = [[x, y], [x + 2, y], [x + 2, y + 2], [x, y + 2]]
        if kind == 1:
            spec["facts"] = ["density"]
        if kind == 4:
            spec |= {"owner": "e3", "facts": ["interaction"]}
        spec["enter_hysteresis"] = float(rng.choice([0.0, 0.2]))
        areas[f"a{k}"] = spec
    merged, loop = AreaManager(areas), AreaManager(areas)
    loop._runs = [(i, i + 1, None) for i in range(len(loop._slots))]
    assert len(merged._runs) < len(loop._runs)
    pos = np.column_stack([rng.uniform(0, 12, (60, 2)), np.zeros(60)])
    for tick in range(20):
        pos[:, :2] += rng.normal(0, 0.3, (60, 2))
        t = (tick + 1) * S // 10
        world.observe("test", np.arange(60), np.full(60, t), pos, rng.uniform(-3, 3, (60, 3)))
        world.commit()
        a, b = merged.compute_batch(world, t), loop.compute_batch(world, t)
        assert a.facts() == b.facts()
        assert all(np.array_equal(x, y) for x, y in zip(a.keys(), b.keys(), strict=True))
        assert isinstance(a, FactBatch) and len(a.groups) <= len(b.groups)
