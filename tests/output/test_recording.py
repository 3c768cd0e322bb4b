"""Recordings: an MCAP bag written with rosbags, read back with the independent mcap reader."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

import toaster
from tests.output.conftest import T0, S, run_scenario
from toaster.errors import InvalidInputError
from toaster.recording import ENTITIES_TOPIC, FACTS_TOPIC, LINE_STRIP, TEXT, record

pytest.importorskip("rosbags")
mcap_reader = pytest.importorskip("mcap.reader")
mcap_ros2 = pytest.importorskip("mcap_ros2.decoder")

AREAS = [("kitchen", [(0.0, 0.0), (3.0, 0.0), (3.0, 2.0), (0.0, 2.0)])]


def _frames() -> list[tuple[Any, ...]]:
    """alice walks along x for 5 s; bob leaves after 2 s; the areas come with the first frame."""
    out = []
    for k in range(6):
        entities = [("pr2", "robot", 1.0, 1.0, 0.0, 0.5), ("alice", "human", 2 + k, 1, 0, 3.1),
                    ("mug", "object", 1.5, 1.5, 0.75, 0.0)]
        if k < 3:
            entities.append(("bob", "human", 0.5, 0.5, 0.0, 0.0))
        out.append((T0 + k * S, entities, AREAS if k == 0 else None))
    return out


def _read(path: Path) -> list[tuple[str, str, int, Any]]:
    with path.open("rb") as handle:
        reader = mcap_reader.make_reader(handle,
                                         decoder_factories=[mcap_ros2.DecoderFactory()])
        return [(channel.topic, schema.name, message.log_time, msg)
                for schema, channel, message, msg in reader.iter_decoded_messages()]


def test_recording_replays_frames_and_facts(run_db: toaster.Database, tmp_path: Path) -> None:
    """Entities, areas and the database's events come back, typed as ROS tools expect."""
    result = record(tmp_path / "run", _frames(), db=run_db, until=T0 + 20 * S)
    assert result.mcap.suffix == ".mcap"
    assert (result.bag / "metadata.yaml").exists()
    messages = _read(result.mcap)
    topics = {(t, s) for t, s, _, _ in messages}
    assert topics == {(ENTITIES_TOPIC, "visualization_msgs/msg/MarkerArray"),
                      ("/toaster/areas", "visualization_msgs/msg/MarkerArray"),
                      (FACTS_TOPIC, "rcl_interfaces/msg/Log")}
    frames = [m for t, _, _, m in messages if t == ENTITIES_TOPIC]
    assert len(frames) == 6
    names = [{m.text for m in f.markers if m.type == TEXT} for f in frames]
    assert names[0] == {"pr2", "alice", "mug", "bob"}
    assert names[5] == {"pr2", "alice", "mug"}  # bob left: DELETEALL first, no bob marker
    assert frames[5].markers[0].action == 3
    alice = next(m for m in frames[5].markers if m.ns == "entities" and m.type == 3)
    assert alice.pose.position.x == pytest.approx(7.0)
    outline = [m for t, _, _, a in messages if t == "/toaster/areas" for m in a.markers
               if m.type == LINE_STRIP]
    assert [(p.x, p.y) for p in outline[0].points] == [*AREAS[0][1], AREAS[0][1][0]]
    lines = [(stamp - T0, m.msg) for t, _, stamp, m in messages if t == FACTS_TOPIC]
    assert (10 * S, "pr2: mug IsOn table ended") in lines
    assert (2 * S, "alice: mug IsOn table appeared = true (confidence 0.8)") in lines
    assert all(0 <= t <= 20 * S for t, _ in lines)


def test_shipped_scenario_records(tmp_path: Path) -> None:
    """A shipped scenario's world and facts record frame by frame."""
    db = toaster.connect(f"sqlite:///{tmp_path / 'flat.db'}")
    try:
        frames = run_scenario(db, "scenario_flat.yaml", 10)
        result = record(tmp_path / "flat", frames, db=db)
    finally:
        db.close()
    messages = _read(result.mcap)
    assert result.frames == len(frames) == 101
    assert sum(t == FACTS_TOPIC for t, *_ in messages) == result.facts > 10


def test_cli_record(run_db: toaster.Database, db_url: str, tmp_path: Path) -> None:
    """``toaster record FRAMES OUT`` reads JSON-lines frames."""
    from click.testing import CliRunner

    from toaster.cli.export import record as record_cmd

    frames = tmp_path / "frames.jsonl"
    frames.write_text("".join(json.dumps({"t_ns": t, "entities": e, "areas": a}) + "\n"
                              for t, e, a in _frames()))
    done = CliRunner().invoke(record_cmd, [str(frames), str(tmp_path / "bag"), "--db", db_url])
    assert done.exit_code == 0, done.output
    assert "wrote 6 frames" in done.output


def test_bad_frames(tmp_path: Path) -> None:
    """Frames out of order, bad poses and an existing directory give one-line errors."""
    with pytest.raises(InvalidInputError, match="frames out of time order"):
        record(tmp_path / "a", [(2, [], None), (1, [], None)])
    with pytest.raises(InvalidInputError, match=r"invalid entity pose .*\(id, kind, x, y, z"):
        record(tmp_path / "b", [(1, [("pr2", "robot", "here")], None)])
    (tmp_path / "c").mkdir()
    with pytest.raises(InvalidInputError, match="it exists"):
        record(tmp_path / "c", [(1, [], None)])


def test_run_records_what_it_saw(tmp_path: Path) -> None:
    """`toaster run --record DIR` writes the run's frames and the events it stored."""
    from click.testing import CliRunner

    from toaster.cli import cli

    url = f"sqlite:///{tmp_path / 'run.db'}"
    scenario = Path(toaster.__file__).parent / "examples" / "scenario_flat.yaml"
    result = CliRunner().invoke(cli, ["--db", url, "run", str(scenario), "--until", "2s",
                                      "--record", str(tmp_path / "bag")])
    assert result.exit_code == 0, result.output
    messages = _read(next((tmp_path / "bag").glob("*.mcap")))
    topics = {topic for topic, *_ in messages}
    assert {ENTITIES_TOPIC, FACTS_TOPIC} <= topics
    with toaster.connect(url) as db:
        stored = len(toaster.queries.events(db))
    assert sum(topic == FACTS_TOPIC for topic, *_ in messages) == stored
    again = CliRunner().invoke(cli, ["--db", url, "run", str(scenario), "--record",
                                     str(tmp_path / "bag")])
    assert again.exit_code == 1
    assert "exists" in again.output
