"""``toaster serve --foxglove`` against an independent client in a separate process
(tests/foxglove/client.py: the websockets package, protobuf and jsonschema, no toaster or
foxglove-sdk code), and a Foxglove recording read with the ``mcap`` package: the same
channels and schemas as the live view."""

from __future__ import annotations

import base64
import json
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

import toaster

pytest.importorskip("foxglove")
pytest.importorskip("websockets")
pytest.importorskip("google.protobuf")
pytest.importorskip("jsonschema")

pytestmark = pytest.mark.slow  # processes, seconds each

CLIENT = Path(__file__).with_name("client.py")
EXAMPLES = Path(toaster.__file__).parent / "examples"
#: every channel and its schema name (toaster.outputs.foxglove.TOPICS)
CHANNELS = {
    "/toaster/scene": "foxglove.SceneUpdate",
    "/toaster/areas": "foxglove.SceneUpdate",
    "/toaster/motion": "foxglove.SceneUpdate",
    "/tf": "foxglove.FrameTransforms",
    "/toaster/log": "foxglove.Log",
    "/toaster/facts": "toaster.Facts",
    "/toaster/beliefs": "toaster.Beliefs",
    "/toaster/events": "toaster.Event",
    "/toaster/health": "toaster.Health",
}
SERVICES = [
    f"/toaster/{name}"
    for name in ("add_area", "monitor", "remove_area", "set_pose", "stream", "tell", "watch")
]


TOASTER = [sys.executable, "-m", "toaster"]


def run_args(tmp_path: Path, example: str, record: Path) -> list[str]:
    """``toaster run EXAMPLE --record RECORD --record-format`` (the format to add)."""
    db = f"sqlite:///{tmp_path / 's.db'}"
    path = str(EXAMPLES / example)
    return [*TOASTER, "--db", db, "run", path, "--record", str(record), "--record-format"]


def start_node(url: str) -> tuple[subprocess.Popen[str], int]:
    """``toaster serve --foxglove 0``, and the port it printed."""
    node = subprocess.Popen(
        [*TOASTER, "--db", url, "serve", "--foxglove", "0", "--holders", "humans"],
        stderr=subprocess.PIPE,
        text=True,
    )
    assert node.stderr is not None
    for line in node.stderr:  # the first lines come at once; a dead node ends the loop
        if "Foxglove on ws://127.0.0.1:" in line:
            return node, int(line.rsplit(":", 1)[1])
    node.wait(timeout=30)
    msg = f"no port printed; exit {node.returncode}"
    raise AssertionError(msg)


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """Sally-Anne driven over the node's services by the separate client; what it saw."""
    url = f"sqlite:///{tmp_path_factory.mktemp('fox') / 'live.db'}"
    node, port = start_node(url)
    try:
        done = subprocess.run(
            [sys.executable, str(CLIENT), f"ws://127.0.0.1:{port}", "sally"],
            capture_output=True,
            text=True,
            timeout=180,
        )
        assert done.returncode == 0, done.stderr
    finally:
        node.send_signal(signal.SIGTERM)
        _, err = node.communicate(timeout=60)
    assert node.returncode == 0, err
    assert "Traceback" not in err and "FoxgloveOutput failed" not in err, err
    return json.loads(done.stdout)


def test_every_channel_is_advertised_with_its_schema(live: dict[str, Any]) -> None:
    advertised = {topic: name for topic, _, name, _, _ in live["channels"]}
    assert advertised.pop("/toaster/watch/1") == "toaster.Event"  # opened by the watch call
    assert advertised == CHANNELS
    for topic, encoding, name, schema_encoding, _ in live["channels"]:
        assert (encoding, schema_encoding) == (
            ("protobuf", "protobuf") if name.startswith("foxglove.") else ("json", "jsonschema")
        ), topic
    assert live["services"] == SERVICES
    assert live["server"] == "toaster"


def test_every_channel_carries_decoded_messages(live: dict[str, Any]) -> None:
    assert set(live["counts"]) >= set(CHANNELS), live["counts"]
    last = live["last"]
    scene = {e["id"] for e in last["/toaster/scene"]["entities"]}
    assert {"SALLY", "ANNE", "MARBLE"} <= scene
    areas = {e["id"] for e in last["/toaster/areas"]["entities"]}
    assert areas == {"ROOM", "HALL", "KITCHEN"}
    frames = {t["childFrameId"] for t in last["/tf"]["transforms"]}
    assert {"SALLY/base", "ANNE/base", "MARBLE"} <= frames
    health = last["/toaster/health"]
    assert health["ticks"] > 0 and health["dropped"] == 0 and "status:" in health["status"]
    assert last["/toaster/log"]["message"]


def test_sally_anne_false_belief_seen_live(live: dict[str, Any]) -> None:
    """Sally saw the marble in ROOM; she left; it moved to KITCHEN: her belief is marked false
    (the robot holds none for ROOM) until Anne tells her."""
    assert live["first"]["false_belief"] is False
    assert live["false"]["false_belief"] is True and live["false"]["self_value"] is None
    assert "SALLY" in live["told"]["learnt"]
    assert live["corrected"]["target"] == "KITCHEN"
    kinds = [(e["kind"], e["target"]) for e in live["watched"]]
    assert ("ended", "ROOM") in kinds and ("appeared", "KITCHEN") in kinds
    assert live["refused"].endswith("no area named 'NOWHERE': see `toaster area list`")


def test_recording_has_the_live_channels_and_schemas(live: dict[str, Any], tmp_path: Path) -> None:
    """``toaster run --record FILE.mcap --record-format foxglove`` of the spatial Sally-Anne:
    the channels and schemas of the live server, and Sally's false belief at 13 s."""
    from mcap.reader import make_reader

    path = tmp_path / "sally.mcap"
    done = subprocess.run(
        [*run_args(tmp_path, "scenario_spatial_sally_anne.yaml", path), "foxglove"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        recorded = set()
        for channel in summary.channels.values():
            schema = summary.schemas[channel.schema_id]
            data = (
                base64.b64encode(schema.data).decode()
                if schema.encoding == "protobuf"
                else schema.data.decode()
            )
            recorded.add(
                (channel.topic, channel.message_encoding, schema.name, schema.encoding, data)
            )
        false = []
        for _, _, message in reader.iter_messages(topics=["/toaster/beliefs"]):
            beliefs = json.loads(message.data)
            if beliefs["holder"] == "SALLY" and message.log_time <= 13_000_000_000:
                false = [
                    (f["subject"], f["property"], f["target"])
                    for f in beliefs["facts"]
                    if f["false_belief"]
                ]
    live_channels = {tuple(c) for c in live["channels"] if c[0] != "/toaster/watch/1"}
    assert recorded == live_channels
    assert ("MARBLE", "IsIn", "BASKET") in false


def test_foxglove_format_needs_a_new_mcap_file(tmp_path: Path) -> None:
    done = subprocess.run(
        [*run_args(tmp_path, "scenario_flat.yaml", tmp_path / "rec"), "foxglove"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 1
    assert "give a FILE.mcap name" in done.stderr
    assert not (tmp_path / "s.db").exists()


def test_shipped_layout_names_only_published_topics() -> None:
    """The layout file shipped with toaster (docs/foxglove.md) draws toaster's channels and
    calls its services; every panel it places is configured."""
    import re

    from toaster.outputs.foxglove import TOPICS

    path = Path(toaster.__file__).parent / "foxglove" / "toaster-layout.json"
    layout = json.loads(path.read_text(encoding="utf-8"))
    text = json.dumps(layout["configById"])
    named = set(re.findall(r"/(?:toaster/[a-z_]+|tf)\b", text))
    services = {n for n in named if n.rsplit("/", 1)[1] in {s.rsplit("/", 1)[1] for s in SERVICES}}
    assert named - services <= set(TOPICS) and named - services
    assert services <= set(SERVICES)
    placed = set(re.findall(r'"([A-Za-z0-9]+![a-z_]+)"', json.dumps(layout["layout"])))
    assert placed == set(layout["configById"])
