import json
import math
from pathlib import Path

import numpy as np
import pytest

from toaster.errors import FileFormatError, UnknownEntityError
from toaster.producers import Runner, load_session
from toaster.world import LiveSource, World, load_scenario, read_obsmat, read_tracks, wrap_angle
from toaster.world.scenario import ScenarioSource

S = 1_000_000_000
EXAMPLES = Path(__file__).resolve().parents[2] / "src" / "toaster" / "examples"
DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"


@pytest.mark.parametrize(
    ("angle", "wrapped"),
    [
        (math.pi, math.pi),
        (-math.pi, math.pi),
        (3 * math.pi, math.pi),
        (0.0, 0.0),
        (2 * math.pi + 0.1, 0.1),
        (-math.pi - 0.1, math.pi - 0.1),
    ],
)
def test_wrap_angle(angle, wrapped):
    assert wrap_angle(angle) == pytest.approx(wrapped)


def test_newest_then_most_confident_wins_and_sources_switch_off():
    w = World()
    w.add_entity("bob", "human")
    w.observe("cam", ["bob"], [10], [[1, 0, 0]], conf=np.array([0.5]))
    w.observe("lidar", ["bob"], [9], [[2, 0, 0]], conf=np.array([1.0]))  # older: ignored
    assert w.pos[0, 0] == 1
    w.observe("lidar", ["bob"], [10], [[3, 0, 0]], conf=np.array([0.9]))  # same t, surer
    assert w.pos[0, 0] == 3
    w.observe("cam", ["bob", "bob"], [11, 11], [[4, 0, 0], [5, 0, 0]], conf=np.array([0.9, 0.2]))
    assert w.pos[0, 0] == 4
    w.set_source_enabled("cam", False)
    w.observe("cam", ["bob"], [20], [[9, 0, 0]])
    assert w.pos[0, 0] == 4
    with pytest.raises(UnknownEntityError, match="'ghost'"):
        w.observe("cam2", ["ghost"], [1], [[0, 0, 0]])


def test_joint_pose_reported_in_world_frame_is_kept_relative():
    w = World()
    w.add_entity("bob", "human")
    w.add_entity("bob/head", "joint", owner_id="bob", name="head")
    w.set_pose("bob", (1, 0, 0), 1, (0, 0, math.pi / 2))
    w.set_pose("bob/head", (1, 0.2, 1.7), 1)
    w.commit()
    w.set_pose("bob", (5, 5, 0), 2, (0, 0, math.pi / 2))
    w.commit()
    assert w.pos[w.row("bob/head")] == pytest.approx([5, 5.2, 1.7])


def test_joints_follow_every_kind_of_change_between_commits():
    """commit recomputes a joint only where its agent, its local pose or its world pose
    changed since they last agreed: each of those changes must still move it."""
    w = World()
    w.add_entity("bob", "human")
    w.add_entity("bob/head", "joint", owner_id="bob", name="head")
    head = w.row("bob/head")
    w.set_pose("bob", (1, 0, 0), 1, (0, 0, math.pi / 2))
    w.set_pose("bob/head", (1, 0.2, 1.7), 1, (0.1, 0.2, 0.3))
    w.commit()  # observed in world coordinates: kept as observed
    assert w.pos[head].tolist() == [1, 0.2, 1.7]
    assert w.rpy[head].tolist() == [0.1, 0.2, 0.3]
    w.set_pose("bob/head", (1, 0.3, 1.7), 2)  # the joint first, then its agent, in one tick
    w.set_pose("bob", (2, 0, 0), 2, (0, 0, math.pi / 2))
    w.commit()
    assert w.pos[head] == pytest.approx([2, 0.3, 1.7])
    w.commit()  # nothing changed: nothing moves
    assert w.pos[head] == pytest.approx([2, 0.3, 1.7])
    w.set_joint_local("bob/head", (0.5, 0, 1.5))  # a local pose set directly
    w.commit()
    assert w.pos[head] == pytest.approx([2, 0.5, 1.5])
    w.rpy[w.row("bob")] = (0, 0, 0)  # an agent's pose written into the columns
    w.commit()
    assert w.pos[head] == pytest.approx([2.5, 0, 1.5])
    w.pos[head] = (9, 9, 9)  # a joint's world pose written into the columns: local wins
    w.commit()
    assert w.pos[head] == pytest.approx([2.5, 0, 1.5])


def test_history_as_of_and_time_bound():
    w = World(history_horizon_ns=S)
    w.add_entity("cup")
    for k in range(30):
        w.set_pose("cup", (k, 0, 0), k * S // 10)
        w.commit()
    rows = np.array([0])
    _, pos, _ = w.history.as_of(rows, 25 * S // 10)
    assert pos[0, 0] == 25
    _, pos, _ = w.history.as_of(rows, 0)  # older than the 1 s horizon: the oldest kept
    assert pos[0, 0] == 19


def test_live_source_push():
    w = World()
    live = LiveSource()
    live.push("bob", (1, 2), yaw=0.5, t_ns=5)
    live.push("bob", (3, 2), t_ns=50)
    live.advance(w, 10)
    assert w.pos[w.row("bob")][:2] == pytest.approx([1, 2])
    live.advance(w, 60)
    assert w.pos[w.row("bob")][0] == 3


def test_scenario_move_hand_enter_leave():
    sc = load_scenario(EXAMPLES / "scenario_flat.yaml")
    w = World()
    src = ScenarioSource(sc)
    src.setup(w)
    assert not w.active[w.row("bob")]
    for t in range(0, 17 * S, S // 10):
        src.advance(w, t)
        w.commit()
    assert w.active[w.row("bob")]
    alice = w.row("alice")
    assert w.pos[alice, :2] == pytest.approx([4.0, 3.0], abs=1e-6)
    assert w.pos[w.row("mug")] == pytest.approx(w.pos[w.row("alice/rightHand")])  # released


@pytest.mark.parametrize(
    ("doc", "message"),
    [
        (
            {
                "entities": [{"id": "bob", "kind": "human"}],
                "timeline": [{"at": "1s", "move": "bob"}],
            },
            "waypoints",
        ),
        (
            {
                "entities": [{"id": "bob", "kind": "human"}],
                "timeline": [{"at": "1s", "set_pose": "ann", "position": [0, 0]}],
            },
            "unknown entity 'ann'",
        ),
        (
            {
                "entities": [{"id": "bob", "kind": "human"}],
                "timeline": [{"at": "1 parsec", "leave": "bob"}],
            },
            "parsec",
        ),
        ({"entities": [{"id": "bob", "kind": "cat"}]}, "kind 'cat'"),
        ({"entities": [{"id": "bob", "position": [0, "north"]}]}, "non-number"),
        (
            {
                "entities": [{"id": "bob", "kind": "human"}],
                "timeline": [{"at": "1s", "move": "bob", "waypoints": [[1, 1]], "speed": "fast"}],
            },
            "speed 'fast'",
        ),
        ({"nothing": 1}, "'entities' list"),
    ],
)
def test_bad_scenarios_give_one_line_errors(tmp_path, doc, message):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(FileFormatError, match=message) as info:
        load_scenario(path)
    assert "\n" not in str(info.value)


def test_malformed_yaml(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("entities: [\n")
    with pytest.raises(FileFormatError, match="not valid YAML"):
        load_scenario(path)


def test_generic_tracks_csv_and_jsonl(tmp_path):
    csv = tmp_path / "t.csv"
    csv.write_text(
        "t_s,id,kind,x,y,z,yaw\n0.0,bob,human,0,0,0,0\n0.5,bob,human,1,0,0,0\n"
        "0.5,cup,object,2,2,0.8,0\n"
    )
    src = read_tracks(csv)
    assert (src.start_ns, src.end_ns) == (0, S // 2)
    jl = tmp_path / "t.jsonl"
    jl.write_text('{"t_ns": 5, "id": "bob", "x": 1, "y": 2}\n')
    assert read_tracks(jl).kinds == {"bob": "human"}
    bad = tmp_path / "b.csv"
    bad.write_text("t,id,x,y\n1,bob,0,0\n")
    with pytest.raises(FileFormatError, match="t_ns"):
        read_tracks(bad)


def run_file(path):
    s = load_session(path)
    r = Runner(s.world, s.sources, s.producers, agent_id=s.self_id)
    seen = []
    r.run(s.start_ns, s.end_ns, s.rate_hz, on_tick=lambda t: seen.append(r.diff._last.copy()))
    return r.stats, seen


@pytest.mark.parametrize("name", ["scenario_flat", "scenario_simu_set", "scenario_guide_robot"])
def test_examples_run_deterministically(name):
    a, snaps_a = run_file(EXAMPLES / f"{name}.yaml")
    b, snaps_b = run_file(EXAMPLES / f"{name}.yaml")
    assert a.ticks == b.ticks
    assert a.facts == b.facts
    assert a.events == b.events > 0
    assert snaps_a == snaps_b


needs_data = pytest.mark.skipif(
    not (DATA / "eth-ucy-opentraj").is_dir(), reason=f"shared data not found at {DATA}"
)


@needs_data
def test_obsmat_reader():
    src = read_obsmat(DATA / "eth-ucy-opentraj/UCY/zara01/obsmat.txt")
    assert len(src.t) == 5024
    assert len(src.kinds) == 148
    assert np.all(np.diff(src.t) >= 0)


@pytest.mark.slow
def test_quaternions_are_accepted_in_scenarios_and_tracks(tmp_path):
    """ROS gives orientations as quaternions: scenario poses and track rows take them."""
    half = math.sqrt(0.5)
    sc = load_scenario_text(
        tmp_path,
        {
            "entities": [
                {
                    "id": "bob",
                    "kind": "human",
                    "position": [0, 0],
                    "orientation": [0, 0, half, half],
                }
            ]
        },
    )
    w = World()
    src = ScenarioSource(sc)
    src.setup(w)
    src.advance(w, 0)
    assert w.rpy[w.row("bob"), 2] == pytest.approx(math.pi / 2)
    csv_path = tmp_path / "t.csv"
    csv_path.write_text(f"t_s,id,x,y,qx,qy,qz,qw\n0,ann,1,2,0,0,{half},{-half}\n")
    tracks = read_tracks(csv_path)
    assert tracks.rpy[0, 2] == pytest.approx(-math.pi / 2)
    csv_path.write_text("t_s,id,x,y,qx,qy,qz,qw\n0,ann,1,2,0,0,0,0\n")
    with pytest.raises(FileFormatError, match="line 2: quaternion"):
        read_tracks(csv_path)
    with pytest.raises(FileFormatError, match="orientation"):
        load_scenario_text(
            tmp_path, {"entities": [{"id": "bob", "kind": "human", "orientation": [0, 0, 1]}]}
        )


def load_scenario_text(tmp_path, doc):
    import yaml

    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(doc))
    return load_scenario(path)


def test_a_snapshot_keeps_its_state_while_the_world_moves_on():
    world = World()
    world.add_entity("bob", "human")
    world.set_pose("bob", (1.0, 2.0, 0.0), 1)
    world.commit()
    view = world.snapshot()
    world.set_pose("bob", (5.0, 5.0, 0.0), 2)
    world.add_entity("cup", "object")
    world.set_pose("cup", (0.5, 0.0, 0.8), 2)
    world.commit()
    assert view.n == 1 and view.ids == ["bob"] and "cup" not in view.index
    assert view.pos[view.index["bob"]].tolist() == [1.0, 2.0, 0.0]
    assert int(view.t_ns[0]) == 1
    assert world.pos[world.index["bob"]].tolist() == [5.0, 5.0, 0.0]
