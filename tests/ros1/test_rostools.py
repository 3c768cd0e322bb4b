"""Debian's ROS tools decode toaster: after `eval "$(toaster ros1 env)"`, `rostopic echo` on
each fact list of `toaster serve --ros1`, `rosservice call` of the database_manager services,
`rosmsg show` / `rossrv show` and `rostopic echo -b` on a `.bag` that `toaster run --record`
wrote, each a separate process started from a shell, as a user types them. Decoded fields are
checked against the node's database."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
import yaml
from click.testing import CliRunner

import toaster
from tests.processes import TIMEOUT, NodeProcess, wait_for
from tests.ros1.conftest import RosClient, require_ros
from toaster import queries as q
from toaster.cli import cli
from toaster.producers.registry import NAMES as PRODUCERS
from toaster.ros1 import messages, rostools
from toaster.world.rosmsg import fact_from_msg

SELF = "toaster"
SRC = Path(__file__).resolve().parents[2] / "src" / "toaster"
SALLY_ANNE = SRC / "examples" / "scenario_spatial_sally_anne.yaml"
MSGS = SRC / "ros1" / "msgs"
TF_MAP = "frames:\n  bob_hand: {kind: joint, owner: bob, joint: rightHand}\n"
HAND = (0.5, 0.0, 1.2)
CUP = (2.1, 0.0, 0.75)
ANN = (3.0, 1.0, 0.0)  # ahead of bob, who faces +x: move3d_facts sees her
KITCHEN = {
    "id": 0,
    "name": "kitchen",
    "areaType": "room",
    "entityType": "entities",
    "poly": {
        "points": [{"x": -1, "y": -1}, {"x": 5, "y": -1}, {"x": 5, "y": 3}, {"x": -1, "y": 3}]
    },
}


def pose_msg(x: float, y: float, z: float = 0.0) -> dict[str, Any]:
    return {
        "header": {"frame_id": "map", "stamp": "now"},
        "pose": {
            "position": {"x": x, "y": y, "z": z},
            "orientation": {"x": 0, "y": 0, "z": 0, "w": 1},
        },
    }


class Tools:
    """Runs a ROS tool from bash after `eval "$(toaster ros1 env)"` (the cache folder's name
    needs quoting: a space and a quote)."""

    def __init__(self, env: dict[str, str], cache: Path) -> None:
        self.env, self.cache = env, cache

    def run(self, *argv: str, timeout: float = TIMEOUT) -> str:
        script = 'eval "$("$TOASTER_PY" -m toaster ros1 env --cache "$CACHE")" && exec "$@"'
        done = subprocess.run(
            ["bash", "-c", script, "bash", *argv],
            env=self.env | {"TOASTER_PY": sys.executable, "CACHE": str(self.cache)},
            capture_output=True,
            text=True,
            timeout=timeout,
            check=False,
        )
        assert done.returncode == 0, (argv, done.stdout[-2000:], done.stderr[-2000:])
        return done.stdout

    def yaml(self, *argv: str) -> Any:
        """The tool's YAML output (rostopic echo's `---` separators dropped)."""
        docs = [d for d in yaml.safe_load_all(self.run(*argv)) if d is not None]
        assert len(docs) == 1, docs
        return docs[0]


@pytest.fixture(scope="module")
def tools(ros_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory) -> Tools:
    return Tools(ros_env, tmp_path_factory.mktemp("rostools") / "cache dir's")


@pytest.fixture(scope="module")
def node_args(tmp_path_factory: pytest.TempPathFactory) -> list[str]:
    folder = tmp_path_factory.mktemp("rostools_node")
    (folder / "frames.yaml").write_text(TF_MAP)
    (folder / "config.yaml").write_text("spatial: true\n")  # move3d_facts publishes too
    return [
        "--tf-map",
        str(folder / "frames.yaml"),
        "--config",
        str(folder / "config.yaml"),
        "--pose-topic",
        "/mocap/bob=bob:human",
        "--pose-topic",
        "/mocap/cup=cup:object",
        "--pose-topic",
        "/mocap/pen=pen:object",
        "--pose-topic",
        "/mocap/ann=ann:human",
        "--pose-topic",
        "/mocap/pr2=pr2:robot",
    ]


def holds(db: toaster.Database, prop: str, subject: str, target: str) -> bool:
    return bool(q.current_facts(db, SELF, property=prop, subject=subject, target=target))


@pytest.fixture(scope="module")
def world(node: NodeProcess, client: RosClient, db: toaster.Database) -> RosClient:
    """bob at the origin facing +x, his right hand (TF) at HAND, a cup at CUP, a pen in his
    hand, ann ahead of him, the kitchen around them: facts on every producer's list."""
    client.publish("/mocap/bob", "geometry_msgs/PoseStamped", pose_msg(0, 0), rate=20)
    client.publish("/mocap/cup", "geometry_msgs/PoseStamped", pose_msg(*CUP), rate=20)
    client.publish("/mocap/pen", "geometry_msgs/PoseStamped", pose_msg(0.5, 0.5, 0.8), rate=20)
    client.publish("/mocap/ann", "geometry_msgs/PoseStamped", pose_msg(*ANN), rate=20)
    # a robot 2 m behind bob, facing him: pdg_seen's simulated camera sees bob
    client.publish("/mocap/pr2", "geometry_msgs/PoseStamped", pose_msg(-2, 0), rate=20)
    hand = {
        "header": {"frame_id": "map", "stamp": "now"},
        "child_frame_id": "bob_hand",
        "transform": {
            "translation": dict(zip("xyz", HAND, strict=True)),
            "rotation": {"x": 0, "y": 0, "z": 0, "w": 1},
        },
    }
    client.publish("/tf", "tf2_msgs/TFMessage", {"transforms": [hand]}, rate=20, key="hand")
    assert client.call("/area_manager/add_area", "AddArea", myArea=KITCHEN)["answer"]
    wait_for(lambda: holds(db, "IsInRoom", "cup", "kitchen"), message="cup in the kitchen")
    wait_for(lambda: q.entities(db, "bob/rightHand"), message="bob's right hand")
    client.call(
        "/pdg/put_in_hand", "PutInHand", objectId="pen", agentId="bob", jointName="rightHand"
    )
    wait_for(lambda: holds(db, "IsInHand", "pen", "bob"), message="pen in bob's hand")
    wait_for(lambda: holds(db, "Distance", "bob/rightHand", "cup"), message="hand-cup distance")
    return client


#: one fact each producer's list must hold in :func:`world` (subject, property, target)
EXPECTED = {
    "pdg": ("pen", "IsInHand", "bob"),
    "area_manager": ("cup", "IsInRoom", "kitchen"),
    "agent_monitor": ("bob/rightHand", "Distance", "cup"),
    "move3d_facts": ("ann", "IsVisibleBy", "bob"),
    "pdg_seen": ("bob", "IsSeen", "pr2"),
}


def decoded(fields: dict[str, Any]) -> toaster.Fact:
    """A toaster_msgs/Fact as rostopic printed it, read by toaster's own mapping."""
    return fact_from_msg(SimpleNamespace(**fields))


def key(fact: toaster.Fact | toaster.FactRow) -> tuple[str, str, str]:
    return (fact.subject_id, fact.property, fact.target_id)


@pytest.mark.slow
def test_rostopic_echo_decodes_every_fact_list(
    world: RosClient, tools: Tools, db: toaster.Database
) -> None:
    """Each producer's list, printed by `rostopic echo -n 1`, is the node's current facts of
    that producer, field for field (the world stands still)."""
    assert set(PRODUCERS) <= set(EXPECTED), "say which fact the new producer's list holds"
    for producer in PRODUCERS:
        wait_for(
            lambda p=producer: q.current_facts(  # type: ignore[misc]
                db, SELF, source=p, subject=EXPECTED[p][0], property=EXPECTED[p][1]
            ),
            message=f"{EXPECTED[producer]} stored",
        )
        msg = tools.yaml("rostopic", "echo", "-n", "1", f"/{producer}/factList")
        facts = [decoded(f) for f in msg["factList"]]
        assert EXPECTED[producer] in {key(f) for f in facts}, (producer, facts)
        stored = {row.to_fact() for row in q.current_facts(db, SELF, source=producer)}
        assert set(facts) == stored, producer
        assert all(f["time"] > 0 and f["timeEnd"] == 0 for f in msg["factList"])
    distance = next(
        f
        for f in tools.yaml("rostopic", "echo", "-n", "1", "/agent_monitor/factList")["factList"]
        if (f["subjectId"], f["targetId"]) == ("bob/rightHand", "cup")
    )
    # the original's Distance: valueType 0, the metres in doubleValue (docs/original.md)
    assert distance["valueType"] == 0 and distance["doubleValue"] == pytest.approx(
        math.dist(HAND, CUP)
    )
    assert distance["subjectOwnerId"] == "bob"


FACT = (
    "{subjectId: cup, property: IsOn, targetId: table, stringValue: 'true', "
    "propertyType: state, confidence: 0.9, factObservability: 1.0}"
)


@pytest.mark.slow
def test_rosservice_call_of_the_database_manager_services(
    world: RosClient, tools: Tools, db: toaster.Database
) -> None:
    """The original's database commands, typed as `rosservice call` YAML, answered and decoded."""

    def call(service: str, request: str) -> dict[str, Any]:
        return tools.yaml("rosservice", "call", f"/database_manager/{service}", request)

    assert call("set_info", f"{{add: true, infoType: FACT, facts: [{FACT}]}}")["answer"] is True
    assert holds(db, "IsOn", "cup", "table")
    found = call(
        "get_info",
        "{type: FACT, subType: VALUE, reqFact: {subjectId: cup, property: IsOn, targetId: table}}",
    )
    assert found["boolAnswer"] is True
    fact = found["resFactList"]["factList"][0]
    assert (fact["subjectId"], fact["property"], fact["targetId"]) == ("cup", "IsOn", "table")
    assert (fact["confidence"], fact["propertyType"], fact["timeEnd"]) == (0.9, "state", 0)
    stored = q.current_facts(db, SELF, subject="cup", property="IsOn")[0]
    assert fact["timeStart"] == stored.valid_from_ns
    current = call("get_info", "{type: FACT, subType: CURRENT}")["resFactList"]["factList"]
    assert {("pen", "IsInHand", "bob"), ("cup", "IsOn", "table")} <= {
        (f["subjectId"], f["property"], f["targetId"]) for f in current
    }
    assert call("execute", f"{{command: ARE_IN_TABLE, type: INDIV, facts: [{FACT}]}}") == {
        "boolAnswer": True,
        "results": ["true"],
    }
    assert call("execute", "{command: SQL, order: 'SELECT 1 + 1'}")["results"] == ["2"]
    ids = call("get_info", "{type: ID, subType: ALL}")["resId"]
    assert {"bob", "ann", "cup", "pen"} <= {i["id"] for i in ids}
    removed = call(
        "set_info",
        "{add: false, infoType: FACT, facts: [{subjectId: cup, property: IsOn, targetId: 'NULL'}]}",
    )
    assert removed["answer"] is True and not holds(db, "IsOn", "cup", "table")
    events = call("get_info", f"{{type: EVENT, subType: ALL, agentId: {SELF}}}")["resEventList"]
    assert {"IsOn", "!IsOn"} <= {e["property"] for e in events if e["subjectId"] == "cup"}
    status = tools.yaml("rosservice", "call", "/toaster/get_status")  # std_srvs/Trigger
    assert status["success"] is True and "ticks" in status["message"]


@pytest.mark.slow
def test_rosmsg_and_rossrv_show_the_shipped_definitions(tools: Tools) -> None:
    shipped = MSGS / "toaster_msgs" / "msg" / "Fact.msg"
    fields = [
        " ".join(line.split()) for line in shipped.read_text().splitlines() if line.split("#")[0]
    ]
    assert tools.run("rosmsg", "show", "toaster_msgs/Fact").split("\n")[: len(fields)] == fields
    srv = tools.run("rossrv", "show", "toaster_msgs/SetInfoDB").splitlines()
    assert {
        "bool add",
        "string infoType",
        "toaster_msgs/Fact[] facts",
        "---",
        "bool answer",
    } <= set(srv)
    md5 = tools.run("rosmsg", "md5", "toaster_msgs/Fact").strip()
    assert md5 == messages.load().msg("Fact")._md5sum  # what the bridge publishes


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, toaster.Database]:
    """Sally-Anne run with `toaster run --record x.bag`, and its database."""
    folder = tmp_path_factory.mktemp("rostools_bag")
    url = f"sqlite:///{folder / 'run.db'}"
    bag = folder / "x.bag"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "toaster",
            "--db",
            url,
            "run",
            str(SALLY_ANNE),
            "--record",
            str(bag),
        ],
        check=True,
        capture_output=True,
        timeout=600,
    )
    return bag, toaster.connect(url)


@pytest.mark.slow
def test_rosbag_and_rostopic_echo_read_a_recording(
    ros_env: dict[str, str], tools: Tools, recorded: tuple[Path, toaster.Database]
) -> None:
    """Every toaster type of a recorded .bag is known (md5 sums as the tools compute them),
    and `rostopic echo -b` decodes its fact lists and beliefs as the run stored them."""
    bag, db = recorded
    info = tools.yaml("rosbag", "info", "--yaml", str(bag))
    for entry in info["types"]:
        if entry["type"].startswith("toaster"):
            assert tools.run("rosmsg", "md5", entry["type"]).strip() == entry["md5"], entry
    topics = {t["topic"]: t["type"] for t in info["topics"]}
    robot = toaster.beliefs.self_agent(db)
    lists = [t for t, kind in topics.items() if kind == "toaster_msgs/FactList"]
    assert {"/pdg/factList", "/move3d_facts/factList"} <= set(lists)
    for topic in lists:
        facts = tools.yaml("rostopic", "echo", "-b", str(bag), "-n", "1", topic)["factList"]
        t_ns = facts[0]["time"]
        producer = topic.split("/")[1]
        # what the run stored as held then, numbers of that time included
        held = {r.to_fact() for r in q.beliefs_at(db, robot, t_ns, source=producer)}
        assert {decoded(f) for f in facts} == held, topic
    sally = tools.yaml("rostopic", "echo", "-b", str(bag), "-n", "1", "/toaster/beliefs/SALLY")
    assert (sally["holder"], sally["chain"], sally["is_self"]) == ("SALLY", ["SALLY"], False)
    t_ns = sally["header"]["stamp"]["secs"] * 10**9 + sally["header"]["stamp"]["nsecs"]
    held = q.beliefs_at(db, "SALLY", t_ns)
    assert {key(decoded(f)) for f in sally["facts"]} == {key(row) for row in held}


# ----------------------------------------------------------------------------- the command
def env_command(cache: Path) -> list[str]:
    return [sys.executable, "-m", "toaster", "ros1", "env", "--cache", str(cache)]


@pytest.mark.slow
def test_concurrent_calls_build_one_whole_tree(tmp_path: Path) -> None:
    """Three shells evaluating the line at once: one tree, built once, no half tree left;
    Debian's Python imports every package from it; evaluating the line again does not
    grow the variables."""
    require_ros()
    cache = tmp_path / "cache"
    procs = [
        subprocess.Popen(env_command(cache), stdout=subprocess.PIPE, text=True) for _ in range(3)
    ]
    outputs = [proc.communicate(timeout=TIMEOUT)[0] for proc in procs]
    assert [proc.returncode for proc in procs] == [0, 0, 0]
    assert len(set(outputs)) == 1
    trees = list(cache.iterdir())
    assert len(trees) == 1, trees  # no temporary folder left
    tree = trees[0]
    assert tree.name.startswith(rostools.toaster_version() + "-")
    assert (tree / "share" / "toaster_msgs" / "msg" / "Fact.msg").is_file()
    assert (tree / "share" / "toaster_msgs" / "package.xml").is_file()
    script = (
        'eval "$1"; eval "$1"; exec /usr/bin/python3 -c "'
        "import os, toaster_msgs.msg as m, toaster_msgs.srv as s, hri_msgs.msg as h, "
        "toaster_recording.msg as r; "
        "print(m.FactList._type, s.SetInfoDB._type, h.IdsList._type, r.Beliefs._type); "
        "print(os.environ['PYTHONPATH'].split(':').count('$2'))\""
    )
    done = subprocess.run(
        ["bash", "-c", script, "bash", outputs[0], str(tree / "python")],
        capture_output=True,
        text=True,
        check=True,
    )
    assert done.stdout.split() == [
        "toaster_msgs/FactList",
        "toaster_msgs/SetInfoDB",
        "hri_msgs/IdsList",
        "toaster_recording/Beliefs",
        "1",
    ]


def test_debian_packages_are_used_not_shadowed(tmp_path: Path) -> None:
    """With python3-std-srvs installed (its package in Debian's dist-packages), the tree has no
    std_srvs of its own, and it is another tree."""
    texts = rostools.definitions()
    assert {"toaster_msgs", "hri_msgs", "std_srvs", "toaster_recording"} <= set(texts)
    (tmp_path / "std_srvs").mkdir()
    with_debian = rostools.tree_packages(texts, tmp_path)
    assert set(with_debian) == set(texts) - {"std_srvs"}
    without = rostools.tree_packages(texts, tmp_path / "none")
    assert rostools.tree_name(with_debian) != rostools.tree_name(without)


def test_exports_are_quoted_and_put_first() -> None:
    cache = Path("/c/it's here")
    tree = cache / "v-1"
    environ = {"PYTHONPATH": f"/a:{cache}/v-0/python:/b", "ROS_PACKAGE_PATH": ""}
    values = rostools.ros_environment(tree, cache, environ)
    assert values == {
        "ROS_PACKAGE_PATH": f"{tree}/share",
        "PYTHONPATH": f"{tree}/python:/a:/b",
    }
    assert rostools.exports(values).splitlines()[1] == (
        "export PYTHONPATH='/c/it'\"'\"'s here/v-1/python:/a:/b'"
    )


def test_missing_ros_or_cache_is_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """No Debian Python (no ROS): one line naming the apt-get fix; a cache that cannot be
    written: one line naming --cache."""
    monkeypatch.setattr(rostools, "SYSTEM_PYTHON", str(tmp_path / "no-python3"))
    result = CliRunner().invoke(cli, ["ros1", "env", "--cache", str(tmp_path / "c")])
    assert result.exit_code == 1
    assert result.output.count("\n") == 1 and "apt-get install" in result.output
    assert "python3-genpy" in result.output and "Traceback" not in result.output
    monkeypatch.undo()
    require_ros()
    (tmp_path / "file").write_text("")
    result = CliRunner().invoke(cli, ["ros1", "env", "--cache", str(tmp_path / "file" / "c")])
    assert result.exit_code == 1
    assert result.output.count("\n") == 1 and "--cache DIR" in result.output
